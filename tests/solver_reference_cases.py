"""The cases of the solver references in ``tests/data/solver_reference_coarse*.npz`` (tests/test_solver_batch.py).

Only names that the solver of commit 64ab885 already had are imported here, so that
``tests/data/solver_reference_coarse.py`` can recompute the references with that solver.
"""

from __future__ import annotations

import itertools

import numpy as np

from skidsim.friction import ExponentialDecay
from skidsim.solver import SolverConfig
from skidsim.solver.surfaces import RandomTexture, TiltedPlane, to_heightfield

LAW = ExponentialDecay(0.4, 0.35, 0.6)
PAV = to_heightfield(RandomTexture(), 0.25e-3)
BASE = dict(element_mm=2.0, slide_length_mm=6.0, window_start_mm=2.0, progress_every_s=1e9)
SCALARS = (
    "sn",
    "tangential_n",
    "normal_n",
    "dt_s",
    "n_steps",
    "preload_steps",
    "max_penetration_um",
    "mean_contact_area_mm2",
    "mean_slip_speed_ms",
    "preload_contact_force_n",
    "preload_contact_area_mm2",
    "omega_max_rad_s",
)


def reference_cases():
    """(name, config, pavement, speed km/h) of the stored reference: every friction model x slide damping x
    contact gap, Prony terms with both dampings, a penalty length, the campaign preset, an analytic plane."""
    for fm, sd, gap in itertools.product(("penalty", "stick_limit"), ("rayleigh", "mass"), ("vertical", "normal")):
        cfg = SolverConfig(**BASE, friction_model=fm, slide_damping_model=sd, contact_gap=gap)
        yield f"{fm}-{sd}-{gap}", cfg, PAV, 40.0
    for sd in ("rayleigh", "mass"):
        cfg = SolverConfig(**BASE, slide_damping_model=sd, prony_g=(0.3,), prony_tau_s=(2e-5,))
        yield f"prony-{sd}", cfg, PAV, 40.0
    yield "penalty_length", SolverConfig(**BASE, penalty_length_mm=0.5), PAV, 60.0
    campaign = SolverConfig.campaign(slide_length_mm=8.0, window_start_mm=2.0, progress_every_s=1e9)
    yield "campaign", campaign, PAV, 20.0
    yield "tilted", SolverConfig(**BASE), TiltedPlane(0.1), 40.0


def scalars(r) -> np.ndarray:
    """The scalars of :data:`SCALARS` of a simulation result, as float64."""
    return np.array([getattr(r, k) for k in SCALARS], dtype=float)


def energies(r) -> np.ndarray:
    """The energy table of a simulation result in name order."""
    return np.array([r.energies[k] for k in sorted(r.energies)])
