"""Mesh study like the study's Figure 9: SN against slider element size at several speeds.

The discretisation error of each element size is ``|SN(h) - SN(h_finest)| / SN(h_finest)`` in % at the same
speed (the finest mesh of the study is the reference, as in the study's Figure 9); compute time is the wall time
of one simulation in s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import pandas as pd

from skidsim.friction import ExponentialDecay

from .config import SolverConfig
from .explicit import simulate

#: The friction law of the study's mesh study (mu_s, mu_k, alpha in s/m).
STUDY_MESH_LAW = ExponentialDecay(0.4, 0.35, 0.6)


def mesh_study(pavement, sizes_mm: Sequence[float], speeds_kmh: Sequence[float], *,
               law: ExponentialDecay = STUDY_MESH_LAW, base: SolverConfig | None = None, log=None) -> pd.DataFrame:
    """One simulation per (speed, element size); returns the table with ``error_pct`` against the finest mesh.

    Columns: speed_kmh, element_mm, sn, wall_s (s), n_steps, n_elements, dt_s (s), element_steps_per_s, slide_mm,
    energy_residual_frac, mean_contact_area_mm2, max_penetration_um, mu_at_speed, sn_friction and sn_geometric
    (SN split into the friction forces' and the contact-normal forces' x parts over the mean normal force; they
    add up to sn), mean_normal_n (N, window mean of the vertical pavement force), mean_contact_nodes (bottom
    nodes in contact), stick_fraction (share of the contact nodes held by the stick limit), sn_finest,
    error_pct (%).
    ``base``: the other solver settings (default: the reference preset); only ``element_mm`` varies.
    """
    base = base or SolverConfig.reference()
    rows = []
    for v in speeds_kmh:
        for h in sorted(sizes_mm, reverse=True):
            r = simulate(pavement, float(v), law, replace(base, element_mm=float(h)))
            tr = r.trace
            w = tr[(tr["position_mm"] >= r.window_mm[0]) & (tr["position_mm"] <= r.window_mm[1])]
            fn = float(w["normal_n"].mean())
            nodes = float(w["contact_nodes"].mean())
            rows.append(dict(speed_kmh=float(v), element_mm=float(h), sn=r.sn, wall_s=r.wall_s, n_steps=r.n_steps,
                             n_elements=r.n_elements, dt_s=r.dt_s, element_steps_per_s=r.element_steps_per_s,
                             slide_mm=r.slide_length_mm, energy_residual_frac=r.energy_residual_fraction(),
                             mean_contact_area_mm2=r.mean_contact_area_mm2, max_penetration_um=r.max_penetration_um,
                             mu_at_speed=float(law.mu_kmh(v)), sn_friction=float(w["friction_x_n"].mean()) / fn,
                             sn_geometric=float((w["tangential_n"] - w["friction_x_n"]).mean()) / fn,
                             mean_normal_n=fn, mean_contact_nodes=nodes,
                             stick_fraction=float(w["stick_nodes"].mean()) / nodes if nodes > 0 else 0.0))
            if log is not None:
                log.info("%5.0f km/h %5.2f mm: SN %.4f, %.1f s, %d steps", v, h, r.sn, r.wall_s, r.n_steps)
    t = pd.DataFrame(rows)
    finest = t.loc[t.groupby("speed_kmh")["element_mm"].idxmin(), ["speed_kmh", "sn"]].set_index("speed_kmh")["sn"]
    t["sn_finest"] = t["speed_kmh"].map(finest)
    t["error_pct"] = 100.0 * (t["sn"] - t["sn_finest"]).abs() / t["sn_finest"]
    return t
