"""Run Snakemake so that a stopped run resumes: ``python -m skidsim.launch [snakemake arguments]``
(the command behind ``make reproduce``).

* Before starting: a lock left by a run that no longer exists (``kill -9``, a crash, a power cut) is removed
  (``snakemake --unlock``); a lock held by a live Snakemake process in the same working directory is left
  alone, and Snakemake then refuses to start as usual.
* The run has ``--rerun-incomplete``: jobs a killed run left half-done are redone; finished jobs are kept, and
  the FE cache (``results/cache/<site>/fe.parquet``, written after every FE run) means a redone calibration
  repeats no finished FE run.
* Ctrl-C or SIGTERM: Snakemake is asked to stop its jobs, and one line says how to resume; exit status 130
  (SIGINT) or 143 (SIGTERM).
* Snakemake does not outlive this process: it runs under a small leader (:func:`lead_group`) in a process group of
  its own with its jobs; when this process dies in any way, ``kill -9`` included, Linux tells the leader
  (``prctl(PR_SET_PDEATHSIG)``) and the leader stops the group as a Ctrl-C does (SIGINT to Snakemake and its jobs;
  Snakemake stops in order). The group of its own means a Ctrl-C at the terminal reaches this process only, which
  stops Snakemake once.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import subprocess
import sys
from pathlib import Path

RESUME = "run the same command again (make reproduce) to resume: finished jobs and FE runs are kept"


def _workdir(args: list[str]) -> Path:
    """The working directory Snakemake will use: ``--directory``/``-d`` or the current one."""
    for i, a in enumerate(args):
        if a in ("--directory", "-d") and i + 1 < len(args):
            return Path(args[i + 1]).absolute()
        if a.startswith("--directory="):
            return Path(a.split("=", 1)[1]).absolute()
    return Path.cwd()


def live_snakemake_in(workdir: Path, exclude: tuple[int, ...] = ()) -> list[int]:
    """Pids of running Snakemake processes whose working directory is ``workdir`` (Linux /proc; empty elsewhere)."""
    out = []
    proc = Path("/proc")
    if not proc.is_dir():
        return out
    target = os.path.realpath(workdir)
    for p in proc.iterdir():
        if not p.name.isdigit() or int(p.name) in exclude or int(p.name) == os.getpid():
            continue
        try:
            cmd = (p / "cmdline").read_bytes().split(b"\0")
            is_snakemake = (cmd and os.path.basename(cmd[0]) == b"snakemake") or (
                len(cmd) > 2 and (os.path.basename(cmd[1]) == b"snakemake" or cmd[1:3] == [b"-m", b"snakemake"])
            )
            if not is_snakemake:  # Snakemake itself, not one of its jobs (their scripts live in .snakemake/)
                continue
            if os.path.realpath(p / "cwd") == target:
                out.append(int(p.name))
        except OSError:
            continue
    return out


#: ``prctl`` option: the signal the calling process gets when its parent dies (linux/prctl.h).
PR_SET_PDEATHSIG = 1


def _on_parent_death(parent_pid: int, sig: int) -> None:
    """Ask Linux for ``sig`` when the parent ``parent_pid`` dies (``prctl(PR_SET_PDEATHSIG)``); when it is already
    gone, send ``sig`` now. Does nothing where there is no ``prctl`` (not Linux)."""
    libc_name = ctypes.util.find_library("c") if sys.platform.startswith("linux") else None
    if libc_name is None:
        return
    if ctypes.CDLL(libc_name, use_errno=True).prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) != 0:
        return  # pragma: no cover - prctl refused: the run goes on without it
    if os.getppid() != parent_pid:
        os.kill(os.getpid(), sig)


def lead_group(parent_pid: int, cmd: list[str]) -> int:
    """Run ``cmd`` (Snakemake) as the leader of the process group it and its jobs share, and stop the whole group
    as a Ctrl-C does (SIGINT to every process of it) when the launcher ``parent_pid`` dies, ``kill -9`` included.

    A SIGINT that reaches this process (the launcher stops the group) needs nothing more: Snakemake and its jobs got
    it too. Returns Snakemake's exit status (128 + N when a signal N ended it)."""
    stopping: list[int] = []
    child: list[subprocess.Popen] = []

    def parent_died(signum, _frame):
        if not stopping:
            stopping.append(signum)
            if child:
                os.killpg(0, signal.SIGINT)

    # handlers, not SIG_IGN: an ignored SIGINT would be inherited by Snakemake, which then could not be stopped
    signal.signal(signal.SIGINT, lambda *_: None)
    signal.signal(signal.SIGHUP, parent_died)
    _on_parent_death(parent_pid, signal.SIGHUP)
    child.append(subprocess.Popen(cmd))
    if stopping:  # the launcher died before Snakemake existed
        os.killpg(0, signal.SIGINT)
    rc = child[0].wait()
    return rc if rc >= 0 else 128 - rc


#: The command that runs :func:`lead_group` in a fresh Python: ``[python, -c, LEADER, parent pid, cmd...]``.
LEADER = "import sys; from skidsim.launch import lead_group; sys.exit(lead_group(int(sys.argv[1]), sys.argv[2:]))"


def stale_lock(workdir: Path) -> bool:
    """True when ``workdir/.snakemake/locks`` holds lock files and no Snakemake process runs there."""
    locks = workdir / ".snakemake" / "locks"
    return locks.is_dir() and any(locks.iterdir()) and not live_snakemake_in(workdir)


def main(argv: list[str] | None = None, snakemake: list[str] | None = None) -> int:
    """Run ``snakemake --rerun-incomplete ARGS`` after removing a stale lock; see the module docstring.

    ``snakemake``: the command to start Snakemake (default: this Python's ``-m snakemake``)."""
    args = list(sys.argv[1:] if argv is None else argv)
    cmd = list(snakemake or [sys.executable, "-m", "snakemake"])
    workdir = _workdir(args)
    if stale_lock(workdir):
        print(
            f"skidsim: removing the lock a stopped run left in {workdir / '.snakemake' / 'locks'}",
            file=sys.stderr,
            flush=True,
        )
        subprocess.run(cmd + ["--unlock"] + args, check=False, stdout=subprocess.DEVNULL)
    received: list[int] = []
    children: list[subprocess.Popen] = []

    def forward(signum, _frame):
        received.append(signum)
        for child in children:
            try:  # what a Ctrl-C does to a plain snakemake: SIGINT to it and its jobs; Snakemake stops in order
                os.killpg(child.pid, signal.SIGINT)
            except ProcessLookupError:
                pass

    # handlers first: Snakemake then starts with SIGINT at its default (an ignored SIGINT, as in a background
    # shell job, would be inherited and Snakemake could not be stopped)
    old = {s: signal.signal(s, forward) for s in (signal.SIGINT, signal.SIGTERM)}
    # its own process group: a Ctrl-C at the terminal reaches this process only, which stops Snakemake once; the
    # leader stops the group when this process dies, so that a kill -9 of it leaves no Snakemake behind
    leader = [sys.executable, "-c", LEADER, str(os.getpid())]
    children.append(subprocess.Popen(leader + cmd + ["--rerun-incomplete"] + args, process_group=0))
    child = children[0]
    if received:  # a signal came before the child existed
        os.killpg(child.pid, signal.SIGINT)
    try:
        while True:
            try:
                rc = child.wait()
                break
            except KeyboardInterrupt:  # pragma: no cover - the handler above takes SIGINT
                continue
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    if received or rc in (-signal.SIGINT, -signal.SIGTERM, 130):
        sig = received[0] if received else signal.SIGINT
        print(f"skidsim: stopped on request ({signal.Signals(sig).name}); {RESUME}", file=sys.stderr, flush=True)
        return 128 + int(sig)
    return rc


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
