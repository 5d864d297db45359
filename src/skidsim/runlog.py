"""Logging and table/JSON writers shared by the workflow scripts and the CLI (no Snakemake import).

The writers go through :mod:`skidsim.atomic`, the one atomic-write helper of the project."""

from __future__ import annotations

import json
import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

from . import atomic

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
    if log_path:  # a script's failure line goes to its log; the workflow's onerror handler prints it at the end
        console.addFilter(lambda record: not getattr(record, "file_only", False))
    for h in handlers:
        h.setFormatter(logging.Formatter(LOG_FORMAT))
        root.addHandler(h)
    root.setLevel(level)
    logger = logging.getLogger("skidsim")

    def _hook(exc_type, exc, tb, _default=sys.excepthook):  # failures reach the rule's log file too
        _report_failure(logger, exc_type, exc, tb)
        for h in handlers:
            h.flush()

    sys.excepthook = _hook
    _sigterm_as_interrupt()
    return logger


def _sigterm_as_interrupt() -> None:
    """SIGTERM (Snakemake stopping its jobs, a scheduler's time limit) ends a script like Ctrl-C: the hook above
    logs one line ``skidsim-error: interrupted`` and the workflow's summary says how to resume."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return

    def _raise(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    signal.signal(signal.SIGTERM, _raise)


ERROR_MARK = "skidsim-error:"
"""Prefix of the one line a failed script writes to its log (the workflow's ``onerror`` handler collects them)."""


def debug_requested() -> bool:
    """True when ``SKIDSIM_DEBUG`` is set to anything but empty or 0: tracebacks of expected errors are shown."""
    return os.environ.get("SKIDSIM_DEBUG", "") not in ("", "0")


def _report_failure(logger: logging.Logger, exc_type, exc, tb) -> None:
    """Log a script's failure: one line ``skidsim-error: <message>`` for an error skidsim raises on purpose (bad
    input: the traceback only with ``SKIDSIM_DEBUG=1``) and for an interrupt; the traceback for anything else (a
    bug)."""
    from .errors import SkidsimError

    quiet = {"file_only": True}  # not on the console when there is a log file (see setup_logging)
    if issubclass(exc_type, KeyboardInterrupt):
        logger.error("%s interrupted", ERROR_MARK, extra=quiet)
    elif issubclass(exc_type, SkidsimError):
        text = str(exc)
        logger.error(
            "%s %s",
            ERROR_MARK,
            text.replace("\n", "\n" + " " * (len(ERROR_MARK) + 1)),
            exc_info=(exc_type, exc, tb) if debug_requested() else None,
            extra=quiet,
        )
    else:
        logger.error("failed: %s: %s", exc_type.__name__, exc, exc_info=(exc_type, exc, tb))


def collect_failures(log_dir: str | Path = "logs", since: float = 0.0) -> list[tuple[str, str]]:
    """``(log file, message)`` of every script that failed with a skidsim error (or was interrupted) and wrote
    its log at or after ``since`` (epoch seconds): the lines after :data:`ERROR_MARK`, continuation lines
    included. Sorted by log file; one entry per log."""
    out = []
    root = Path(log_dir)
    if not root.is_dir():
        return out
    for p in sorted(root.rglob("*.log")):
        try:
            if p.stat().st_mtime < since:
                continue
            lines = p.read_text(errors="replace").splitlines()
        except OSError:
            continue
        for i, line in enumerate(lines):
            k = line.find(ERROR_MARK)
            if k < 0:
                continue
            msg = [line[k + len(ERROR_MARK) :].strip()]
            indent = " " * (len(ERROR_MARK) + 1)
            msg += [ln[len(indent) :] for ln in lines[i + 1 :] if ln.startswith(indent)]
            out.append((str(p), "\n".join(msg)))
            break
    return out


class _Encoder(json.JSONEncoder):
    def default(self, o):
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
    atomic.write_text(path, json.dumps(_sanitize(obj), cls=_Encoder, indent=2, sort_keys=False) + "\n")


def _sanitize(obj):
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {str(k): _sanitize(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_sanitize(v) for v in obj]
    return obj


def write_parquet(path: str | Path, df) -> None:
    """Write a DataFrame to parquet atomically (no index)."""
    atomic.write_parquet(path, df, index=False)


def write_csv(path: str | Path, df, **kw) -> None:
    """Write a DataFrame to CSV atomically."""
    with atomic.atomic_path(path) as tmp:
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

    def __call__(self, done: int, total: int | None = None, *_timing) -> None:
        """``done`` of ``total`` (default: the total given at construction); extra arguments (the solver's
        ``elapsed_s, eta_s``) are ignored, so a Progress is also a solver ``progress`` callback."""
        if total is not None:
            self.total = max(int(total), 1)
        now = time.perf_counter()
        if now - self._last < self.every_s and done < self.total:
            return
        self._last = now
        el = now - self.t0
        frac = min(max(done / self.total, 1e-9), 1.0)
        left = el * (1 - frac) / frac
        self.log.info(
            "%s: %d/%d (%.0f %%), %.1f s elapsed, ~%.1f s left", self.label, done, self.total, 100 * frac, el, left
        )


RESUME_HINT = "run the same command again to resume: finished jobs and FE runs are kept (make reproduce, or see README)"


def failure_report(log_dir: str | Path = "logs", since: float = 0.0, stream=None) -> None:
    """Print the messages of :func:`collect_failures` as one block (the workflow's ``onerror`` handler)."""
    out = stream or sys.stderr
    found = collect_failures(log_dir, since)
    if not found:
        return
    interrupted = [f for f, m in found if m == "interrupted"]
    errors = [(f, m) for f, m in found if m != "interrupted"]
    lines = ["", "=" * 100]
    if errors:
        lines.append(f"skidsim: {len(errors)} job(s) stopped on bad input (details in each log):")
        for f, m in errors:
            lines.append(f"  {f}:")
            lines += [f"    {ln}" for ln in m.splitlines()]
    if interrupted:
        lines.append(f"skidsim: {len(interrupted)} job(s) interrupted; {RESUME_HINT}")
    lines.append("=" * 100)
    print("\n".join(lines), file=out)
    out.flush()
