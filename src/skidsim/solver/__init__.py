"""Explicit finite-element simulation of the DFT rubber slider on a rigid pavement (NumPy).

Public API::

    from skidsim.solver import SolverConfig, simulate, simulate_batch, SimulationResult
    from skidsim.solver.surfaces import FlatPlane, TiltedPlane, SinusoidalSurface

See docs/solver.md for the model, its verification and the presets.
"""

from skidsim.solver.config import SolverConfig
from skidsim.solver.explicit import material_from_config, max_frequency_power_iteration, simulate, simulate_batch
from skidsim.solver.material import RubberMaterial
from skidsim.solver.results import ENERGY_KEYS, SimulationResult, write_trace_parquet
from skidsim.solver.surfaces import FlatPlane, RandomTexture, SinusoidalSurface, TiltedPlane

__all__ = [
    "SolverConfig",
    "simulate",
    "simulate_batch",
    "SimulationResult",
    "RubberMaterial",
    "ENERGY_KEYS",
    "FlatPlane",
    "TiltedPlane",
    "SinusoidalSurface",
    "RandomTexture",
    "material_from_config",
    "max_frequency_power_iteration",
    "write_trace_parquet",
]
