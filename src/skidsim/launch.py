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
"""

from __future__ import annotations

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
    # its own process group: a Ctrl-C at the terminal reaches this process only, which stops Snakemake once
    children.append(subprocess.Popen(cmd + ["--rerun-incomplete"] + args, process_group=0))
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
