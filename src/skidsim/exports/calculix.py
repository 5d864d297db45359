"""Runs CalculiX (``ccx``) on a deck of :mod:`.inp` and reads its .dat output: total forces, displacements, contact
stresses, and the history of a push step."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skidsim.atomic import write_text
from skidsim.errors import InputError, SkidsimError

from .inp import InpDeck


class CalculixError(SkidsimError):
    """CalculiX failed, did not converge, or wrote output that cannot be parsed."""


@dataclass(frozen=True)
class CalculixResult:
    """Results of the last increment of a CalculiX run of a :func:`write_inp` deck (SI units).

    ``total_force_n``: sum of the reaction forces (N) at the fixed pavement nodes ``(fx, fy, fz)``: what the
    support exerts on the pavement, equal and opposite to the slider's total contact force on it.
    ``normal_force_n = fz`` (positive when the slider presses down; equals the load in equilibrium).
    ``contact_nodes``/``contact_pressure_pa``: slave node ids with a contact element and their pressure.
    ``contact_area_mm2``: summed tributary area (mm^2) of slave nodes with positive pressure (needs the
    deck; ``None`` otherwise). ``node_ids``/``displacements_m``: the slider nodes printed in the .dat, and
    ``slider_displacements_m`` the same in ``SliderMesh`` flat order when the deck is given.
    """

    time: float
    total_force_n: tuple[float, float, float]
    normal_force_n: float
    contact_nodes: np.ndarray
    contact_pressure_pa: np.ndarray
    contact_area_mm2: float | None
    node_ids: np.ndarray
    displacements_m: np.ndarray
    slider_displacements_m: np.ndarray | None
    workdir: Path
    log: str


_FLOAT = r"[-+]?\d+\.\d*(?:[EeDd][-+]?\d+)?"


def parse_dat(path: str | Path) -> dict:
    """Parse the last time block of each table in a CalculiX ``.dat`` file (:func:`parse_dat_history`'s blocks).

    Returns ``{"time": float, "total_force": (fx, fy, fz) | None, "displacements": (ids, (n, 3)) | None,
    "contact": (ids, (n, 3) press/tang1/tang2) | None}``; raises :class:`CalculixError` on a bad file.
    """
    blocks = parse_dat_history(path)
    last = {b["kind"]: b for b in blocks}  # file order: the last block of each kind wins
    out: dict = {"time": max(b["time"] for b in blocks), "total_force": None, "displacements": None, "contact": None}
    if "total force" in last and len(last["total force"]["rows"]):
        out["total_force"] = tuple(float(x) for x in last["total force"]["rows"][0][:3])
    for key, name in (("displacements", "displacements"), ("contact stress", "contact")):
        if key in last and len(last[key]["rows"]):
            a = last[key]["rows"]
            out[name] = (a[:, 0].astype(np.int64), a[:, 1:4])
    return out


def parse_dat_history(path: str | Path) -> list[dict]:
    """Every table block of a CalculiX ``.dat`` file, in file order (one per output increment and set).

    Each block is ``{"kind": "total force" | "displacements" | "contact stress", "set": str | None, "time":
    float, "rows": (n, k) array}``; ``time`` is CalculiX's total time (step 1 ends at 1.0, step 2 at 2.0, ...);
    the rows are as printed (``fx, fy, fz`` in N for totals; node id then values, SI, otherwise). Raises
    :class:`CalculixError` when the file cannot be read or has no table.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise CalculixError(f"{path}: cannot read CalculiX output ({exc})") from None
    head = re.compile(
        r"^\s*(total force|displacements|contact stress)\b(?:.*?for set (\S+) )?.*time\s+(" + _FLOAT + r")\s*$",
        re.IGNORECASE,
    )
    blocks: list[dict] = []
    rows = None
    for line in text.splitlines():
        m = head.match(line)
        if m:
            rows = []
            blocks.append({"kind": m.group(1).lower(), "set": m.group(2), "time": float(m.group(3)), "rows": rows})
            continue
        if rows is None or not line.split():
            continue
        try:
            rows.append([float(p.replace("D", "E")) for p in line.split()])
        except ValueError:
            rows = None
    if not blocks:
        raise CalculixError(f"{path}: no result tables (total force, displacements, contact stress) found")
    for b in blocks:  # a header followed by no number row gives a (0, 0) table
        b["rows"] = np.array(b["rows"], dtype=float) if b["rows"] else np.empty((0, 0))
    return blocks


@dataclass(frozen=True)
class PushHistory:
    """Per-increment results of step 2 of a ``step="push"`` deck (:func:`write_inp`), SI units.

    ``time``: CalculiX total time (1 < t <= 2 in the push step); ``holder_x_m``: x displacement of the holder
    (reference top node, m); ``force_n``: ``(n, 3)`` sum of the reaction forces (N) at the fixed pavement nodes,
    as :attr:`CalculixResult.total_force_n` (``force_n[:, 2]`` the normal load, positive; ``force_n[:, 0]``
    negative when the slider is pushed in +x); ``ratio = -force_n[:, 0] / force_n[:, 2]``: the resisting
    tangential over the normal force (the SN of :func:`skidsim.solver.simulate`); ``contact_nodes``:
    slave nodes with positive pressure; ``slip_nodes``: those whose shear stress is at the Coulomb limit
    (``|tau| >= (1 - slip_tolerance) mu p``).
    """

    time: np.ndarray
    holder_x_m: np.ndarray
    force_n: np.ndarray
    ratio: np.ndarray
    contact_nodes: np.ndarray
    slip_nodes: np.ndarray

    def onset_index(self) -> int | None:
        """Index of the first increment in which every contact node slips (gross sliding), or ``None``."""
        full = np.flatnonzero((self.contact_nodes > 0) & (self.slip_nodes == self.contact_nodes))
        return int(full[0]) if full.size else None


def parse_push_history(path: str | Path, deck: InpDeck, slip_tolerance: float = 1e-3) -> PushHistory:
    """Read the push step's increments from the ``.dat`` of a :func:`write_inp` ``step="push"`` deck.

    Per increment of time > 1: the total reaction force of the ``PAVE_ALL`` set, the holder displacement (the
    deck's reference node) and the contact state (pressure and shear stresses of ``*CONTACT PRINT``, Pa).
    Raises :class:`CalculixError` when a table is missing.
    """
    if deck.step != "push" or deck.mu_equivalent is None:
        raise InputError(None, "a deck written with step='push'", column="deck", got=deck.step)
    blocks = parse_dat_history(path)
    by_time: dict[float, dict] = {}
    for b in blocks:
        if b["time"] > 1.0 + 1e-9:
            by_time.setdefault(b["time"], {})[b["kind"]] = b
    times = sorted(by_time)
    if not times:
        raise CalculixError(f"{path}: no increment of the push step (time > 1) found")
    mu = deck.mu_equivalent
    hx, force, n_c, n_s = [], [], [], []
    for t in times:
        rec = by_time[t]
        if "total force" not in rec or "displacements" not in rec:
            raise CalculixError(f"{path}: time {t}: missing total force or displacements table")
        force.append(rec["total force"]["rows"][0, :3])
        d = rec["displacements"]["rows"]
        hit = np.flatnonzero(d[:, 0].astype(np.int64) == deck.ref_node)
        if not hit.size:
            raise CalculixError(f"{path}: time {t}: no displacement of the holder node {deck.ref_node}")
        hx.append(d[hit[0], 1])
        c = rec.get("contact stress")
        if c is None or not len(c["rows"]):
            n_c.append(0)
            n_s.append(0)
            continue
        p, tau = c["rows"][:, 1], np.hypot(c["rows"][:, 2], c["rows"][:, 3])
        on = p > 0
        n_c.append(int(on.sum()))
        n_s.append(int((on & (tau >= (1.0 - slip_tolerance) * mu * p)).sum()))
    force = np.array(force)
    return PushHistory(np.array(times), np.array(hx), force, -force[:, 0] / force[:, 2], np.array(n_c), np.array(n_s))


def run_calculix(
    inp_path: str | Path,
    workdir: str | Path | None = None,
    deck: InpDeck | None = None,
    ccx: str = "ccx",
    timeout_s: float = 600.0,
    threads: int = 1,
) -> CalculixResult:
    """Run CalculiX on ``inp_path`` in ``workdir`` (default: the deck's directory) and parse its ``.dat``.

    Raises :class:`CalculixError` when ``ccx`` is missing, fails, reports an ``*ERROR`` or does not finish.
    ``threads`` sets ``OMP_NUM_THREADS``/``CCX_NPROC_EQUATION_SOLVER`` (default 1: shared machines).
    """
    inp_path = Path(inp_path)
    exe = shutil.which(ccx)
    if exe is None:
        raise CalculixError(f"{ccx!r} not found on PATH: install CalculiX (Debian package calculix-ccx)")
    if not inp_path.is_file():
        raise InputError(inp_path, "an existing .inp file", got="missing")
    workdir = Path(workdir) if workdir is not None else inp_path.parent
    workdir.mkdir(parents=True, exist_ok=True)
    job = inp_path.stem
    target = workdir / inp_path.name
    if target.resolve() != inp_path.resolve():
        shutil.copyfile(inp_path, target)
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), CCX_NPROC_EQUATION_SOLVER=str(threads))
    try:
        proc = subprocess.run([exe, "-i", job], cwd=workdir, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise CalculixError(f"{inp_path}: CalculiX did not finish within {timeout_s} s") from None
    log = proc.stdout + proc.stderr
    write_text(workdir / (job + ".log"), log)
    errors = [ln.strip() for ln in log.splitlines() if "*ERROR" in ln]
    if proc.returncode != 0 or errors or "Job finished" not in log:
        raise CalculixError(
            f"{inp_path}: CalculiX failed (exit {proc.returncode}): " + ("; ".join(errors[:3]) or log[-500:])
        )
    res = parse_dat(workdir / (job + ".dat"))
    if res["total_force"] is None:
        raise CalculixError(f"{workdir / (job + '.dat')}: no 'total force' table (NODE PRINT TOTALS=ONLY RF)")
    f = tuple(float(v) for v in res["total_force"])
    ids, u = res["displacements"] if res["displacements"] is not None else (np.zeros(0, np.int64), np.zeros((0, 3)))
    cn, cs = res["contact"] if res["contact"] is not None else (np.zeros(0, np.int64), np.zeros((0, 3)))
    area = None
    su = None
    if deck is not None:
        amap = dict(zip(deck.bottom_node_ids.tolist(), deck.bottom_tributary_area_m2.tolist()))
        area = 1e6 * float(sum(amap.get(int(n), 0.0) for n, p in zip(cn, cs[:, 0]) if p > 0))
        if len(ids):
            pos = {int(n): k for k, n in enumerate(ids)}
            sel = [pos.get(int(n), -1) for n in deck.slider_node_ids]
            if min(sel) >= 0:
                su = u[sel]
    return CalculixResult(res["time"], f, f[2], cn, cs[:, 0].copy(), area, ids, u, su, workdir, log)
