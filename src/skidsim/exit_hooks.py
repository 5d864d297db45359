"""What the Snakefile's ``onsuccess`` and ``onerror`` hooks do in Snakemake's own process at the end of a run.

Snakemake's job-rate limiter (``max-jobs-per-timespan``; ``profiles/default``: ``1000/10s``) starts a
``threading.Timer`` of the timespan after every scheduling round, to wake the scheduler when the limit frees up
(``JobScheduler._schedule_reevalutation``, Snakemake 9). The timers are not daemon threads, so once the last job has
finished the interpreter still waits for the newest one: up to 10 s at the end of every run, finished or failed,
with nothing left to schedule. :func:`cancel_rescheduling_timers` cancels them when the hooks run, after the
scheduler has returned; Snakemake then exits at once. Measured in docs/performance.md.
"""

from __future__ import annotations

import threading

#: The name of Snakemake's method whose timers are cancelled (its spelling, Snakemake 9.x).
RESCHEDULING_METHOD = "_schedule_reevalutation"


def _is_rescheduling_timer(thread: threading.Thread) -> bool:
    """True for a ``threading.Timer`` started by Snakemake's scheduler re-evaluation (by its callback's name)."""
    if not isinstance(thread, threading.Timer):
        return False
    qualname = getattr(getattr(thread, "function", None), "__qualname__", "")
    return f"{RESCHEDULING_METHOD}.<locals>" in qualname


def cancel_rescheduling_timers() -> int:
    """Cancel every pending scheduler re-evaluation timer of this process; return how many were pending.

    Other timers are left alone. Call it only when the scheduler has returned (Snakemake's ``onsuccess`` and
    ``onerror`` hooks): a cancelled timer never wakes the scheduler again."""
    timers = [t for t in threading.enumerate() if _is_rescheduling_timer(t)]
    for t in timers:
        t.cancel()
    return len(timers)
