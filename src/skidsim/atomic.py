"""Atomic file writes: a result appears whole under its final name or not at all.

Every writer in skidsim goes through :func:`atomic_path`: the data is written to a temporary sibling (same
directory, so the final ``os.replace`` is a rename on one file system), which is renamed to the final name only
when the block succeeds. A failed or interrupted step leaves no half-written file behind, which is what Snakemake
relies on when it resumes. The temporary file gets the permissions a plain ``open(path, "w")`` would give
(``0o666 & ~umask``), not the 0600 of ``tempfile.mkstemp``.
"""

from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "write_bytes", "write_text", "write_json", "write_parquet", "current_umask", "honour_umask"]


def current_umask() -> int:
    """The process umask (read from /proc where it exists, so the process umask is never changed, else set and
    restored at once)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def honour_umask(path: str | Path) -> None:
    """Give ``path`` the permissions a plain ``open(path, "w")`` would: ``0o666 & ~umask``."""
    os.chmod(path, 0o666 & ~current_umask())


@contextmanager
def atomic_path(path: str | Path, suffix: str | None = None):
    """Yield a unique temporary sibling of ``path``; rename it to ``path`` only if the block succeeds.

    The temporary name keeps the final suffix (``suffix`` overrides it), because some writers (pandas, meshio,
    numpy) infer the format from it. On any exception, including ``KeyboardInterrupt``, the temporary file is
    removed and ``path`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(
        prefix=f".{path.stem}.", suffix=path.suffix if suffix is None else suffix, dir=path.parent
    )
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        honour_umask(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_bytes(path: str | Path, data: bytes, *, fsync: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically (``fsync``: flush to disk before the rename)."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            if fsync:
                fh.flush()
                os.fsync(fh.fileno())
    return Path(path)


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | Path, obj, *, indent: int | None = 1, **kwargs) -> Path:
    """Write ``obj`` as JSON to ``path`` atomically (``kwargs`` go to :func:`json.dumps`, e.g. ``default=``)."""
    return write_text(path, json.dumps(obj, indent=indent, **kwargs))


def write_parquet(path: str | Path, df, *, index: bool = False) -> Path:
    """Write the DataFrame ``df`` to ``path`` as parquet atomically."""
    with atomic_path(path) as tmp:
        df.to_parquet(tmp, index=index)
    return Path(path)
