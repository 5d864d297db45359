"""Stop and resume: Ctrl-C (SIGINT) and ``kill -9`` during a run, then the README's command (``skidsim.launch``,
behind ``make reproduce``) resumes without repeating a finished FE run, and the results equal an uninterrupted run's.

Cost: 1 small site (60 x 120 mm at 0.2 mm), the quick solver preset, our calibration only; four short
Snakemake runs (uninterrupted, interrupted, wrapper killed, Snakemake killed) and the resume.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from skidsim.cli import main as skidsim

ROOT = Path(__file__).resolve().parents[1]
SITES = ("E1-1",)
TINY = """
texture:
  groups: [height]
solver:
  preset: quick
  load_n: 11.8
calibration:
  methods: [ours]
  ours:
    prior_sites: 0
mesh_study:
  sizes_mm: []
"""
TIMING = {"overhead_s", "wall_s", "fe_wall_s", "wall_s_run", "cached", "n_cache_hits", "n_steps_run"}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    root = tmp_path_factory.mktemp("resume")
    out = root / "camp"
    assert (
        skidsim(["synth", str(out), "--sites", "1", "--shape", "300", "600", "--spacing-mm", "0.2", "--seed", "5"]) == 0
    )
    (root / "tiny.yaml").write_text(TINY)
    return out


def launch_cmd(workdir: Path, campaign: Path, wrapper: bool = True) -> list[str]:
    front = [sys.executable, "-m", "skidsim.launch"] if wrapper else [sys.executable, "-m", "snakemake"]
    return (
        front
        + [
            "-s",
            str(ROOT / "Snakefile"),
            "--directory",
            str(workdir),
            "--configfile",
            str(ROOT / "config" / "config.yaml"),
            str(campaign.parent / "tiny.yaml"),
            "--cores",
            "1",
            # no 10 s wait at exit (the default profile's job-rate timespan)
            "--max-jobs-per-timespan",
            "100/1s",
            "--config",
            f"campaign={campaign}",
            "--",
        ]
        + [f"results/sites/{s}/calibration_ours.json" for s in SITES]
    )


ENV = dict(os.environ, PYTHONPATH=str(ROOT / "src"), OMP_NUM_THREADS="1")


def cache_rows(workdir: Path) -> int:
    n = 0
    for s in SITES:
        p = workdir / "results" / "cache" / s / "fe.parquet"
        if p.is_file():
            try:
                n += len(pd.read_parquet(p))
            except Exception:  # written atomically; a read can only race the rename
                pass
    return n


def fe_runs_logged(workdir: Path, seen: dict[str, str] | None = None) -> tuple[int, dict[str, str]]:
    """FE simulations the calibration jobs ran since the snapshot ``seen`` of their logs (a rerun job rewrites its
    log; cache hits log nothing): the 'simulate: SN' lines of every log that changed. Returns the count and the
    new snapshot."""
    seen = seen or {}
    now = {p.name: p.read_text() for p in (workdir / "logs" / "calibrate").glob("*.log")}
    return sum(t.count("simulate: SN") for name, t in now.items() if t != seen.get(name)), now


def start_and_stop_when(cmd, workdir: Path, condition, sig: int, group: bool, timeout_s: float = 300):
    """Start ``cmd``; when ``condition()`` holds send ``sig`` (to its process group when ``group``)."""
    p = subprocess.Popen(
        cmd, env=ENV, cwd=workdir, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, process_group=0
    )
    t0 = time.monotonic()
    while not condition():
        assert p.poll() is None, "the run ended before it could be interrupted:\n" + p.communicate()[1][-3000:]
        assert time.monotonic() - t0 < timeout_s
        time.sleep(0.05)
    if group:  # the process and its jobs, as a crash of the machine would
        os.killpg(p.pid, sig)
    else:
        p.send_signal(sig)
    out, err = p.communicate(timeout=120)
    return p.returncode, out + err


def processes_in(workdir: Path) -> list[int]:
    """Pids of the processes whose working directory is ``workdir`` (Snakemake and its jobs; Linux /proc)."""
    out, target = [], os.path.realpath(workdir)
    for p in Path("/proc").iterdir():
        try:
            if p.name.isdigit() and os.path.realpath(p / "cwd") == target and _alive(int(p.name)):
                out.append(int(p.name))
        except OSError:
            continue
    return out


def jobs_in(workdir: Path) -> list[int]:
    """The running jobs of a Snakemake in ``workdir``: its script processes (``.snakemake/scripts/``)."""
    out = []
    for pid in processes_in(workdir):
        try:
            if b".snakemake/scripts/" in Path(f"/proc/{pid}/cmdline").read_bytes():
                out.append(pid)
        except OSError:
            continue
    return out


def calibration(workdir: Path, site: str) -> dict:
    def strip(o):
        if isinstance(o, dict):
            return {k: strip(v) for k, v in o.items() if k not in TIMING}
        if isinstance(o, list):
            return [strip(v) for v in o]
        return o

    return strip(json.loads((workdir / "results" / "sites" / site / "calibration_ours.json").read_text()))


@pytest.mark.slow
def test_interrupt_then_kill9_then_resume(campaign, tmp_path):
    ref = tmp_path / "ref"
    ref.mkdir()
    r = subprocess.run(launch_cmd(ref, campaign), env=ENV, cwd=ref, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    n_ref, _ = fe_runs_logged(ref)
    assert n_ref == cache_rows(ref) >= 3  # every FE run of the reference is a distinct cache entry

    wd = tmp_path / "run"
    wd.mkdir()
    # 1. Ctrl-C on the wrapper once at least one FE run is cached and a calibration is still running
    rc, text = start_and_stop_when(
        launch_cmd(wd, campaign), wd, lambda: 1 <= cache_rows(wd), signal.SIGINT, group=False
    )
    assert rc == 130, text[-4000:]
    assert "skidsim: stopped on request (SIGINT)" in text and "to resume" in text
    assert "Traceback" not in text
    done_1, snap = fe_runs_logged(wd)
    assert 1 <= cache_rows(wd) < n_ref

    # 2. kill -9 of the wrapper alone (what a kill of `make reproduce`'s process group does) while a job runs:
    #    Snakemake and its jobs stop with it, nothing keeps running in the background
    rc, text = start_and_stop_when(launch_cmd(wd, campaign), wd, lambda: bool(jobs_in(wd)), signal.SIGKILL, group=False)
    assert rc == -signal.SIGKILL
    t0 = time.monotonic()
    while processes_in(wd):  # communicate() returned: Snakemake and its jobs closed their output; all are gone
        assert time.monotonic() - t0 < 60, f"left running after the wrapper's kill -9: {processes_in(wd)}"
        time.sleep(0.1)
    done_2b, snap = fe_runs_logged(wd, snap)
    done_1 += done_2b

    # 3. kill -9 of a plain snakemake and its jobs (a crash) during the next FE runs: lock and incomplete marks
    before = cache_rows(wd)
    rc, text = start_and_stop_when(
        launch_cmd(wd, campaign, wrapper=False), wd, lambda: cache_rows(wd) > before, signal.SIGKILL, group=True
    )
    assert rc == -signal.SIGKILL
    assert any((wd / ".snakemake" / "locks").iterdir())  # what made a plain rerun stop with a lock message
    done_2, snap = fe_runs_logged(wd, snap)
    assert cache_rows(wd) < n_ref  # the run really was stopped before the end

    # 4. the README's command resumes: no --unlock, no --rerun-incomplete from the user
    r = subprocess.run(launch_cmd(wd, campaign), env=ENV, cwd=wd, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    assert "removing the lock" in r.stderr
    done_3, _ = fe_runs_logged(wd, snap)
    assert cache_rows(wd) == n_ref
    # every FE run happened exactly once over the three runs: cached runs were never repeated
    assert done_1 + done_2 + done_3 == n_ref, (done_1, done_2, done_3, n_ref)
    for s in SITES:
        assert calibration(wd, s) == calibration(ref, s)


FAKE_SNAKEMAKE = r"""
import os, pathlib, signal, sys, time
log = pathlib.Path(sys.argv[1])
args = sys.argv[2:]
with log.open("a") as fh:
    fh.write(" ".join(args) + "\n")
if "--unlock" in args:
    for p in pathlib.Path(".snakemake/locks").glob("*"):
        p.unlink()
    sys.exit(0)
def stop(signum, frame):
    with log.open("a") as fh:
        fh.write(f"got {signal.Signals(signum).name}\n")
    sys.exit(130)
signal.signal(signal.SIGINT, stop)
pathlib.Path("started").write_text(str(os.getpid()))
time.sleep(60)
sys.exit(0)
"""


def fake_launch(tmp_path: Path, *args: str) -> subprocess.Popen:
    """``skidsim.launch`` in ``tmp_path`` with a stand-in for Snakemake that records its arguments and signals."""
    (tmp_path / "fake.py").write_text(FAKE_SNAKEMAKE)
    code = (
        "import sys; from skidsim.launch import main; "
        f"sys.exit(main(sys.argv[1:], snakemake=[sys.executable, {str(tmp_path / 'fake.py')!r}, "
        f"{str(tmp_path / 'calls.txt')!r}]))"
    )
    return subprocess.Popen(
        [sys.executable, "-c", code, *args],
        cwd=tmp_path,
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.parametrize("sig,status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_launch_stops_snakemake_on_sigterm_and_sigint(tmp_path, sig, status):
    p = fake_launch(tmp_path, "--cores", "2")
    t0 = time.monotonic()
    while not (tmp_path / "started").exists():
        assert p.poll() is None and time.monotonic() - t0 < 30
        time.sleep(0.02)
    p.send_signal(sig)
    _, err = p.communicate(timeout=30)
    assert p.returncode == status
    lines = err.strip().splitlines()
    assert lines == [
        f"skidsim: stopped on request ({sig.name}); run the same command again (make reproduce) to "
        "resume: finished jobs and FE runs are kept"
    ]
    calls = (tmp_path / "calls.txt").read_text().splitlines()
    assert calls == ["--rerun-incomplete --cores 2", "got SIGINT"]  # Snakemake gets its orderly-stop signal once


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"  # a zombie has ended; only its parent's wait is missing


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_snakemake_does_not_outlive_a_killed_launcher(tmp_path):
    p = fake_launch(tmp_path, "--cores", "2")
    t0 = time.monotonic()
    while not (tmp_path / "started").exists() or not (tmp_path / "started").read_text():
        assert p.poll() is None and time.monotonic() - t0 < 30
        time.sleep(0.02)
    snakemake_pid = int((tmp_path / "started").read_text())
    assert _alive(snakemake_pid)
    p.kill()  # kill -9 of the launcher: no handler runs in it
    p.communicate(timeout=30)
    t0 = time.monotonic()
    while _alive(snakemake_pid):
        assert time.monotonic() - t0 < 30, "Snakemake outlived the launcher"
        time.sleep(0.05)
    calls = (tmp_path / "calls.txt").read_text().splitlines()
    assert calls == ["--rerun-incomplete --cores 2", "got SIGINT"]  # its orderly stop, as on Ctrl-C


def test_launch_removes_only_a_stale_lock(tmp_path):
    locks = tmp_path / ".snakemake" / "locks"
    locks.mkdir(parents=True)
    (locks / "0.input.lock").write_text("x")
    p = fake_launch(tmp_path, "--cores", "1", "--", "target")
    t0 = time.monotonic()
    while not (tmp_path / "started").exists():
        assert p.poll() is None and time.monotonic() - t0 < 30
        time.sleep(0.02)
    calls = (tmp_path / "calls.txt").read_text().splitlines()
    # --unlock before the "--" that ends the options; the lock is gone when the run starts
    assert calls == ["--unlock --cores 1 -- target", "--rerun-incomplete --cores 1 -- target"]
    assert not any(locks.iterdir())
    p.send_signal(signal.SIGINT)
    p.communicate(timeout=30)


def test_lock_of_a_live_snakemake_is_not_stale(tmp_path):
    from skidsim.launch import live_snakemake_in, stale_lock

    locks = tmp_path / ".snakemake" / "locks"
    locks.mkdir(parents=True)
    (locks / "0.input.lock").write_text("x")
    exe = tmp_path / "bin" / "snakemake"  # a process that looks like Snakemake to /proc
    exe.parent.mkdir()
    exe.write_text(f"#!{sys.executable}\nimport time\ntime.sleep(30)\n")
    exe.chmod(0o755)
    live = subprocess.Popen([str(exe)], cwd=tmp_path)
    try:
        t0 = time.monotonic()
        while live_snakemake_in(tmp_path) != [live.pid]:
            assert time.monotonic() - t0 < 10
            time.sleep(0.02)
        assert not stale_lock(tmp_path)
        assert live_snakemake_in(tmp_path.parent) == []  # another directory
    finally:
        live.kill()
        live.wait()
    assert stale_lock(tmp_path)
