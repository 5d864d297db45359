"""Logging and atomic-output helpers shared by the workflow scripts and the CLI (no Snakemake import)."""

from __future__ import annotations

import json
import logging
import os
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def setup_logging(log_path: str | Path | None = None, level: int = logging.INFO) -> logging.Logger:
    """Send log records to ``log_path`` (and warnings to stderr; everything when there is no file)."""
    root = logging.getLogger()
    for h in list(root.handlers):
        root.removeHandler(h)
    console = logging.StreamHandler(sys.stderr)
    handlers: list[logging.Handler] = [console]
    if log_path:  # with a log file, the console (Snakemake's output) only gets warnings and errors
        console.setLevel(logging.WARNING)
        Path(log_path).parent.mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(log_path, mode="w"))
    for h in handlers:
        h.setFormatter(logging.Formatter(LOG_FORMAT))
        root.addHandler(h)
    root.setLevel(level)
    logger = logging.getLogger("skidsim")

    def _hook(exc_type, exc, tb, _default=sys.excepthook):  # failures reach the rule's log file too
        logger.error("failed: %s: %s", exc_type.__name__, exc, exc_info=(exc_type, exc, tb))
        for h in handlers:
            h.flush()

    sys.excepthook = _hook
    return logger


@contextmanager
def atomic_path(path: str | Path, suffix: str | None = None):
    """Yield a temporary sibling path; rename it to ``path`` only if the block succeeds.

    The temporary name keeps the final suffix (some writers infer the format from it).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sfx = suffix if suffix is not None else path.suffix
    tmp = path.with_name(f".{path.stem}.tmp{os.getpid()}{sfx}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


class _Encoder(json.JSONEncoder):
    def default(self, o):  # noqa: D401 - json hook
        if isinstance(o, (np.integer,)):
            return int(o)
        if isinstance(o, (np.floating,)):
            return None if not np.isfinite(o) else float(o)
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (np.bool_,)):
            return bool(o)
        if isinstance(o, Path):
            return str(o)
        return super().default(o)


def write_json(path: str | Path, obj) -> None:
    """Write JSON atomically (NumPy scalars and arrays converted; NaN written as null)."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(_sanitize(obj), cls=_Encoder, indent=2, sort_keys=False) + "\n")


def _sanitize(obj):
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {str(k): _sanitize(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_sanitize(v) for v in obj]
    return obj


def write_parquet(path: str | Path, df) -> None:
    """Write a DataFrame to parquet atomically."""
    with atomic_path(path) as tmp:
        df.to_parquet(tmp, index=False)


def write_csv(path: str | Path, df, **kw) -> None:
    """Write a DataFrame to CSV atomically."""
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=kw.pop("index", False), **kw)


class Progress:
    """Logs progress with elapsed time and an estimate of the time left, at most every ``every_s`` seconds."""

    def __init__(self, total: int, label: str, logger: logging.Logger | None = None, every_s: float = 10.0):
        self.total = max(int(total), 1)
        self.label = label
        self.log = logger or logging.getLogger("skidsim")
        self.every_s = every_s
        self.t0 = time.perf_counter()
        self._last = self.t0

    def __call__(self, done: int) -> None:
        now = time.perf_counter()
        if now - self._last < self.every_s and done < self.total:
            return
        self._last = now
        el = now - self.t0
        frac = min(max(done / self.total, 1e-9), 1.0)
        left = el * (1 - frac) / frac
        self.log.info("%s: %d/%d (%.0f %%), %.1f s elapsed, ~%.1f s left", self.label, done, self.total,
                      100 * frac, el, left)
