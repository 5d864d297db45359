"""``make test-slurm`` stops the cluster it started, also when a test fails or the target is interrupted.

The target runs here with a stand-in for ``cluster/single-node-slurm.sh`` (it records each call and keeps the
"running" state in a file) and a stand-in ``python`` whose pytest fails; no SLURM is needed.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FAKE_CLUSTER = """#!/bin/bash
echo "$*" >> "{log}"
case "$1" in
  status) [ -f "{state}" ] ;;
  start) touch "{state}" ;;
  stop) rm -f "{state}" ;;
esac
"""

FAKE_PYTHON = """#!/bin/bash
echo "pytest SKIDSIM_SLURM_ACCOUNTING=$SKIDSIM_SLURM_ACCOUNTING" >> "{log}"
{body}
"""


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _make(tmp: Path, pytest_body: str, running: bool = False, wait: bool = True):
    log, state = tmp / "calls.log", tmp / "running"
    if running:
        state.touch()
    cluster = tmp / "cluster.sh"
    cluster.write_text(FAKE_CLUSTER.format(log=log, state=state))
    bin_dir = tmp / "bin"
    bin_dir.mkdir()
    python = bin_dir / "python"
    python.write_text(FAKE_PYTHON.format(log=log, body=pytest_body))
    for f in (cluster, python):
        f.chmod(0o755)
    cmd = [
        shutil.which("make"),
        "-s",
        "-o",
        "setup-test",
        "test-slurm",
        f"SLURM_CLUSTER={cluster}",
        f"BIN={bin_dir}",
        f"SLURM_REPORT={tmp}/out/report.jsonl",
    ]
    if not wait:
        # Ctrl-C as at a terminal: make in the foreground with the default SIGINT action. A suite started in the
        # background of a non-interactive shell (`make test &`) runs with SIGINT ignored, which every child inherits
        # and which no trap can undo: there make would run its 30 s out
        proc = subprocess.Popen(cmd, cwd=ROOT, start_new_session=True, preexec_fn=_default_sigint)
        return proc, log, state
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=60)
    return r, log.read_text().splitlines(), state.exists()


pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="needs make")


def test_a_failing_test_runs_both_modes_then_stops_the_cluster(tmp_path):
    r, calls, running = _make(tmp_path, "exit 1")
    assert r.returncode != 0
    assert calls == [
        "status",
        "start",
        "pytest SKIDSIM_SLURM_ACCOUNTING=0",
        "start --accounting",
        "pytest SKIDSIM_SLURM_ACCOUNTING=1",
        "stop",
    ]
    assert not running


def test_passing_tests_exit_0_and_stop_the_cluster(tmp_path):
    r, calls, running = _make(tmp_path, "exit 0")
    assert r.returncode == 0, r.stderr
    assert calls[-1] == "stop" and not running


def test_a_cluster_that_was_running_is_left_running(tmp_path):
    r, calls, running = _make(tmp_path, "exit 1", running=True)
    assert r.returncode != 0
    assert "stop" not in calls and running


def test_an_interrupted_run_stops_the_cluster(tmp_path):
    proc, log, state = _make(tmp_path, "exec sleep 30", wait=False)
    deadline = time.monotonic() + 30
    while "pytest" not in (log.read_text() if log.exists() else ""):
        assert time.monotonic() < deadline, "the target never reached pytest"
        time.sleep(0.1)
    time.sleep(1.0)  # Ctrl-C while the test runs, not before it started
    os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: the whole foreground process group
    assert proc.wait(timeout=30) != 0
    calls = log.read_text().splitlines()
    assert calls[-1] == "stop" and "start --accounting" not in calls
    assert not state.exists()
