"""Shared test fixtures: one Snakemake runner, and workflow runs made once per test session.

``run_snakemake`` is the one way the tests start the workflow: ``python -m snakemake`` with the repository's
Snakefile, ``--directory`` a temporary working directory (nothing is written into the checkout) and the default
``config/config.yaml`` first; a failure raises with the command, the exit status and the tail of the output and of
Snakemake's own log.

Sharing under pytest-xdist (``make test`` runs ``--dist loadfile``): a session-scoped fixture runs once per worker
process, so a result several files need is built once into a directory beside the workers' base directories,
guarded by an exclusive lock (``fcntl.flock``; the first worker builds, the others wait and read). ``loadfile`` is
kept rather than ``loadgroup`` because several files hold module-scoped campaigns (test_validation_matrix,
test_interrupt_resume, test_independent_campaigns_*): ``loadgroup`` spreads ungrouped tests one by one, and each
worker that received one of their tests would build the module's campaign again.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import stat
import subprocess
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

import pytest

from skidsim.atomic import write_text

ROOT = Path(__file__).resolve().parents[1]
SNAKEFILE = ROOT / "Snakefile"
DEFAULT_CONFIG = ROOT / "config" / "config.yaml"
#: characters of stdout, stderr and the Snakemake log shown when a run fails
TAIL_CHARS = 4000


def snakemake_env(**extra: str) -> dict[str, str]:
    """The environment of a workflow run: this checkout's library first on the path, plus ``extra``."""
    return dict(os.environ, PYTHONPATH=str(ROOT / "src"), **extra)


def snakemake_cmd(
    *args: str | Path,
    workdir: Path,
    configfiles: Iterable[str | Path] = (),
    cores: int | None = 1,
    snakefile: Path = SNAKEFILE,
) -> list[str]:
    """``python -m snakemake -s <snakefile> --directory <workdir> --configfile config/config.yaml <configfiles...>
    [--cores N] <args...>`` (``cores=None``: no ``--cores``, for a profile that sets the jobs)."""
    cmd = [
        sys.executable,
        "-m",
        "snakemake",
        "-s",
        str(snakefile),
        "--directory",
        str(workdir),
        "--configfile",
        str(DEFAULT_CONFIG),
        *map(str, configfiles),
    ]
    if cores is not None:
        cmd += ["--cores", str(cores)]
    return cmd + [str(a) for a in args]


def snakemake_log_tail(workdir: Path, chars: int = TAIL_CHARS) -> str:
    """The end of the newest Snakemake log in ``workdir/.snakemake/log`` ('' when there is none)."""
    logs = sorted((Path(workdir) / ".snakemake" / "log").glob("*.snakemake.log"))
    return logs[-1].read_text(errors="replace")[-chars:] if logs else ""


def run_snakemake(
    *args: str | Path,
    workdir: Path,
    configfiles: Iterable[str | Path] = (),
    cores: int | None = 1,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
    timeout: float = 1800,
    check: bool = True,
    snakefile: Path = SNAKEFILE,
) -> subprocess.CompletedProcess:
    """Run the workflow (command of :func:`snakemake_cmd`) in ``cwd`` (default ``workdir``); ``timeout`` in s.

    ``check``: a non-zero exit raises AssertionError with the command, the status and the tails of stdout, stderr
    and the Snakemake log; with ``check=False`` the caller asserts on the returned process."""
    workdir = Path(workdir)
    cmd = snakemake_cmd(*args, workdir=workdir, configfiles=configfiles, cores=cores, snakefile=snakefile)
    r = subprocess.run(
        cmd, capture_output=True, text=True, env=env or snakemake_env(), cwd=cwd or workdir, timeout=timeout
    )
    if check and r.returncode != 0:
        raise AssertionError(
            f"snakemake failed (exit status {r.returncode}) in {workdir}\n$ {' '.join(cmd)}\n"
            f"--- stdout (tail) ---\n{r.stdout[-TAIL_CHARS:]}\n--- stderr (tail) ---\n{r.stderr[-TAIL_CHARS:]}\n"
            f"--- .snakemake/log (tail) ---\n{snakemake_log_tail(workdir)}"
        )
    return r


def session_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory shared by every process of this test session: the parent of the xdist workers' base
    directories (``<basetemp>/popen-gwN``), or the base directory itself without xdist."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def build_once(tmp_path_factory: pytest.TempPathFactory, name: str, build: Callable[[Path], None]) -> Path:
    """``<session root>/<name>``, filled by ``build(directory)`` once per test session across xdist workers.

    The first process to take the lock builds; a build that raised leaves no completion mark, so the next process
    to ask builds again (and fails the same way, with its own message) instead of reading a half-made directory."""
    root = session_root(tmp_path_factory)
    out, done = root / name, root / f"{name}.done"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            if out.exists():
                shutil.rmtree(out)
            out.mkdir()
            build(out)
            write_text(done, "")
    return out


@pytest.fixture(scope="session")
def default_dry_run(tmp_path_factory) -> str:
    """stdout + stderr of ``snakemake -n`` of the default target with the default config (the embedded 36-site
    synthetic campaign), made once per session: test_workflow.py and test_report_gallery.py read the plan."""

    def build(d: Path) -> None:
        wd = d / "wd"
        wd.mkdir()
        r = run_snakemake("-n", workdir=wd)
        write_text(d / "dry-run.txt", r.stdout + r.stderr)

    return (build_once(tmp_path_factory, "default-dry-run", build) / "dry-run.txt").read_text()


@pytest.fixture
def umask():
    """Set a umask for the test, restore the old one after."""
    olds = []

    def set_(mask):
        olds.append(os.umask(mask))

    yield set_
    if olds:
        os.umask(olds[0])


def file_mode(path) -> int:
    """Permission bits of ``path`` (e.g. 0o644)."""
    return stat.S_IMODE(os.stat(path).st_mode)


def corrugation_flank(slope: float, wavelength_m: float, x_m: float):
    """A long sinusoidal corrugation along x (uniform in y) whose steepest rising flank, slope ``slope``, lies at
    ``x_m`` (m); extent x 0-50 mm, y -10 to 10 mm: the surface of the onset-of-sliding tests (a block pushed up a
    slope tan theta: F_x / F_z = (mu + tan theta) / (1 - mu tan theta))."""
    import math

    from skidsim.solver import SinusoidalSurface

    k = 2 * math.pi / wavelength_m
    return SinusoidalSurface(
        amplitude_m=slope / k,
        wavelength_x_m=wavelength_m,
        wavelength_y_m=math.inf,
        phase=-math.pi / 2 - k * x_m,
        extent_m=(0.0, 0.05, -0.01, 0.01),
    )


def simulate_centre_m(hf, cfg, slider) -> tuple[float, float]:
    """The slider's plan centre (m) where :func:`skidsim.solver.simulate` starts it: rear edge ``edge_margin_mm``
    after the pavement's x_min, centred in y (for a CalculiX deck of the same placement)."""
    return (hf.extent[0] + cfg.edge_margin_mm * 1e-3 + 0.5 * slider.size_m[0], 0.5 * (hf.extent[2] + hf.extent[3]))


@pytest.fixture(scope="session")
def spectral_design_1():
    """The texture table of design 1 of the spectral generator (tests/diagnosis_rate_campaigns.py; the design of rate
    seeds 1, 5, 9 and 13 with 4 designs), for the naming tests of issue 33."""
    sys.path.insert(0, str(Path(__file__).parent))
    import diagnosis_rate_campaigns as rc

    return rc.generator_texture("spectral", 1)
