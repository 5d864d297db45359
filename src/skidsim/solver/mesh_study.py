"""Mesh study like the study's Figure 9: SN against slider element size at several speeds.

The discretisation error of each element size is ``|SN(h) - SN(h_finest)| / SN(h_finest)`` in % at the same
speed (the finest mesh of the study is the reference, as in the study's Figure 9); compute time is the wall time
of one simulation in s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from skidsim.errors import ConfigError
from skidsim.friction import ExponentialDecay
from skidsim.options import section_items

from .config import SolverConfig
from .explicit import simulate, simulate_batch

#: The friction law of the study's mesh study (mu_s, mu_k, alpha in s/m).
STUDY_MESH_LAW = ExponentialDecay(0.4, 0.35, 0.6)


@dataclass(frozen=True)
class MeshStudyOptions:
    """The workflow's mesh study (config keys under ``mesh_study:``).

    site: the site whose pavement is used (None: the first site of the campaign); sizes_mm: slider element sizes
    in mm (empty: no mesh study; the finest is the reference of the error); speeds_kmh: sliding speeds in km/h.
    """

    site: str | None = None
    sizes_mm: tuple[float, ...] = (2.0, 1.5, 1.0, 0.75, 0.5)
    speeds_kmh: tuple[float, ...] = (20.0, 40.0, 60.0)

    def __post_init__(self) -> None:
        for key in ("sizes_mm", "speeds_kmh"):
            values = tuple(getattr(self, key))
            if not all(isinstance(v, (int, float)) and v > 0 for v in values):
                raise ConfigError(f"mesh_study.{key}: expected a list of positive numbers, got {list(values)!r}")
            object.__setattr__(self, key, tuple(float(v) for v in values))
        if not self.speeds_kmh:
            raise ConfigError("mesh_study.speeds_kmh: expected at least one speed in km/h, got []")

    @classmethod
    def from_dict(cls, d: dict | None) -> MeshStudyOptions:
        """From the ``mesh_study:`` config block; an unknown key raises :class:`ConfigError`."""
        d = section_items(cls, d, "mesh_study")
        return cls(**d)


def mesh_study(
    pavement,
    sizes_mm: Sequence[float],
    speeds_kmh: Sequence[float],
    *,
    law: ExponentialDecay = STUDY_MESH_LAW,
    base: SolverConfig | None = None,
    log=None,
    batch: bool = False,
) -> pd.DataFrame:
    """One simulation per (speed, element size); returns the table with ``error_pct`` against the finest mesh.

    Columns: speed_kmh, element_mm, sn, wall_s (s), n_steps, n_elements, dt_s (s), element_steps_per_s, slide_mm,
    energy_residual_frac, mean_contact_area_mm2, max_penetration_um, mu_at_speed, sn_friction and sn_geometric
    (SN split into the friction forces' and the contact-normal forces' x parts over the mean normal force; they
    add up to sn), mean_normal_n (N, window mean of the vertical pavement force), mean_contact_nodes (bottom
    nodes in contact), stick_fraction (share of the contact nodes held by the stick limit, or in the elastic
    stick regime of the penalty friction), mean_slip_speed_ms (m/s, the slip speed the friction law sees, normal-
    force-weighted), friction_model, slide_damping_model, sn_finest,
    error_pct (%).
    ``base``: the other solver settings (default: the reference preset); only ``element_mm`` varies.
    ``batch``: the speeds of one mesh run as one :func:`skidsim.solver.simulate_batch` (the same mesh, pavement and
    time step; every result but ``wall_s`` and the energy residual equals the single run's bit for bit, ``wall_s`` is
    the batch's wall time shared in proportion to the members' steps, the energy residual agrees to rounding);
    False (the default): one :func:`skidsim.solver.simulate` per run, because on the workflow's study (site E1-1,
    2 to 0.5 mm, 20/40/60 km/h) the batch is slower in all (single / batched CPU time 0.89x): 1.32x faster at 2 mm,
    0.82x at 0.5 mm, where a step is arithmetic on three times the arrays (a larger working set, not traced further)
    (``benchmarks/bench_mesh_study.py``, docs/solver.md).
    """
    base = base or SolverConfig.reference()
    speeds = [float(v) for v in speeds_kmh]
    runs = {}
    for h in sorted(sizes_mm, reverse=True):
        cfg = replace(base, element_mm=float(h))
        if batch:
            for v, r in zip(speeds, simulate_batch(pavement, speeds, law, cfg)):
                runs[v, float(h)] = r
        else:
            for v in speeds:
                runs[v, float(h)] = simulate(pavement, v, law, cfg)
    rows = []
    for v in speeds:
        for h in sorted(sizes_mm, reverse=True):
            r = runs[v, float(h)]
            tr = r.trace
            w = tr[(tr["position_mm"] >= r.window_mm[0]) & (tr["position_mm"] <= r.window_mm[1])]
            fn = float(w["normal_n"].mean())
            nodes = float(w["contact_nodes"].mean())
            rows.append(
                dict(
                    speed_kmh=float(v),
                    element_mm=float(h),
                    sn=r.sn,
                    wall_s=r.wall_s,
                    n_steps=r.n_steps,
                    n_elements=r.n_elements,
                    dt_s=r.dt_s,
                    element_steps_per_s=r.element_steps_per_s,
                    slide_mm=r.slide_length_mm,
                    energy_residual_frac=r.energy_residual_fraction(),
                    mean_contact_area_mm2=r.mean_contact_area_mm2,
                    max_penetration_um=r.max_penetration_um,
                    mu_at_speed=float(law.mu_kmh(v)),
                    sn_friction=float(w["friction_x_n"].mean()) / fn,
                    sn_geometric=float((w["tangential_n"] - w["friction_x_n"]).mean()) / fn,
                    mean_normal_n=fn,
                    mean_contact_nodes=nodes,
                    stick_fraction=float(w["stick_nodes"].mean()) / nodes if nodes > 0 else 0.0,
                    mean_slip_speed_ms=r.mean_slip_speed_ms,
                    friction_model=base.friction_model,
                    slide_damping_model=base.slide_damping_model,
                )
            )
            if log is not None:
                log.info("%5.0f km/h %5.2f mm: SN %.4f, %.1f s, %d steps", v, h, r.sn, r.wall_s, r.n_steps)
    t = pd.DataFrame(rows)
    finest = t.loc[t.groupby("speed_kmh")["element_mm"].idxmin(), ["speed_kmh", "sn"]].set_index("speed_kmh")["sn"]
    t["sn_finest"] = t["speed_kmh"].map(finest)
    t["error_pct"] = 100.0 * (t["sn"] - t["sn_finest"]).abs() / t["sn_finest"]
    return t


def richardson(h_mm: Sequence[float], values: Sequence[float], *, max_iter: int = 200) -> dict:
    """Richardson extrapolation of three solutions on meshes ``h_mm`` (any order, non-uniform ratios allowed).

    The procedure of Celik et al. (2008, J. Fluids Eng. 130, 078001; Roache's grid convergence index): with
    ``h1 < h2 < h3``, ``r21 = h2/h1``, ``r32 = h3/h2``, ``e21 = f2 - f1``, ``e32 = f3 - f2`` (same sign: monotone
    convergence), the observed order ``p`` solves ``p = |ln|e32/e21| + ln((r21^p - 1)/(r32^p - 1))| / ln r21``
    (fixed-point iteration); the extrapolated value is ``f_ext = (r21^p f1 - f2)/(r21^p - 1)``.

    Returns dict ``value`` (the extrapolated, converged estimate), ``order`` (observed p), ``monotone`` (False when
    the differences change sign: oscillatory convergence, p and the extrapolation are then not meaningful and
    ``value`` is NaN), ``error_pct`` (``100 (f(h) - value)/value`` per mesh, in the order of ``h_mm``).
    """
    h = np.asarray(h_mm, dtype=float)
    f = np.asarray(values, dtype=float)
    if h.size != 3 or f.size != 3 or len(set(h.tolist())) != 3:
        raise ValueError(f"richardson: expected three solutions on three distinct meshes, got h = {list(h)}")
    order = np.argsort(h)
    (h1, h2, h3), (f1, f2, f3) = h[order].tolist(), f[order].tolist()
    r21, r32 = h2 / h1, h3 / h2
    e21, e32 = f2 - f1, f3 - f2
    nan = dict(value=math.nan, order=math.nan, monotone=False, error_pct=[math.nan] * 3)
    if e21 == 0.0 or e32 == 0.0:
        return nan if e21 != e32 else dict(value=f1, order=math.inf, monotone=True, error_pct=[0.0] * 3)
    if e32 / e21 < 0:
        return nan
    p = abs(math.log(abs(e32 / e21))) / math.log(r21)
    for _ in range(max_iter):
        p_new = abs(math.log(abs(e32 / e21)) + math.log((r21**p - 1.0) / (r32**p - 1.0))) / math.log(r21)
        if abs(p_new - p) < 1e-12:
            p = p_new
            break
        p = p_new
    value = float((r21**p * f1 - f2) / (r21**p - 1.0))
    return dict(value=value, order=float(p), monotone=True, error_pct=[float(100.0 * (fi - value) / value) for fi in f])
