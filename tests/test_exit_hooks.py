"""Snakemake exits as soon as its run ends: the scheduler's rate-limiter timers are cancelled by the Snakefile's
``onsuccess``/``onerror`` hooks (skidsim.exit_hooks)."""

from __future__ import annotations

import inspect
import subprocess
import sys
import threading
import time

from conftest import ROOT, snakemake_env

from skidsim.exit_hooks import RESCHEDULING_METHOD, cancel_rescheduling_timers


class _Scheduler:
    """Stands in for Snakemake's JobScheduler: the same method name, the same kind of timer."""

    def __init__(self):
        self.woken = threading.Event()

    def _schedule_reevalutation(self, delay: float) -> threading.Timer:
        t = threading.Timer(delay, lambda: self.woken.set())
        t.start()
        return t


def test_only_the_schedulers_timers_are_cancelled():
    sched = _Scheduler()
    timer = sched._schedule_reevalutation(30.0)
    other = threading.Timer(30.0, lambda: None)
    other.start()
    try:
        assert cancel_rescheduling_timers() == 1
        timer.join(timeout=2.0)
        assert not timer.is_alive()
        assert not sched.woken.is_set()  # cancelled, not fired
        assert other.is_alive()
        assert cancel_rescheduling_timers() == 0
    finally:
        other.cancel()
        timer.cancel()


def test_snakemake_still_names_its_rescheduling_timer_so():
    from snakemake.scheduling.job_scheduler import JobScheduler

    method = getattr(JobScheduler, RESCHEDULING_METHOD)
    assert "threading.Timer" in inspect.getsource(method)


SNAKEFILE = """
rule all:
    input: "b.txt"
rule a:
    output: "a.txt"
    shell: "echo a > {output}"
rule b:
    input: "a.txt"
    output: "b.txt"
    shell: "echo b > {output}"
onsuccess:
    from skidsim.exit_hooks import cancel_rescheduling_timers
    print("cancelled", cancel_rescheduling_timers())
"""


def test_a_finished_run_does_not_wait_for_the_rate_limiter(tmp_path):
    """With a 120 s timespan Snakemake would wait 120 s at exit for its newest timer; with the hook it does not."""
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    cmd = [sys.executable, "-m", "snakemake", "--cores", "1", "--max-jobs-per-timespan", "1000/120s", "all"]
    t0 = time.monotonic()
    out = subprocess.run(cmd, cwd=tmp_path, env=snakemake_env(), capture_output=True, text=True, timeout=110)
    wall_s = time.monotonic() - t0
    assert out.returncode == 0, out.stderr[-2000:]
    assert (tmp_path / "b.txt").read_text() == "b\n"
    assert "cancelled 0" not in out.stdout and "cancelled" in out.stdout
    assert wall_s < 60.0


def test_the_workflow_registers_the_hook_for_success_and_failure():
    text = (ROOT / "Snakefile").read_text()
    for hook in ("onsuccess:", "onerror:"):
        body = text.split(hook, 1)[1].split("\n\n\n", 1)[0]
        assert "cancel_rescheduling_timers()" in body, hook
