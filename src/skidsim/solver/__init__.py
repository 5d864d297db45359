"""Explicit finite-element simulation of the DFT rubber slider on a rigid pavement (NumPy).

Public API::

    from skidsim.solver import SolverConfig, simulate, simulate_batch, SimulationResult
    from skidsim.solver.surfaces import FlatPlane, TiltedPlane, SinusoidalSurface

See docs/solver.md for the model, its verification and the presets.
"""

import importlib

#: public name -> the submodule that defines it; loaded on first use (PEP 562), so that ``SolverConfig`` alone (the
#: reconstruction's and the configuration's need) does not load the solver loop and pandas.
_WHERE = {
    "SolverConfig": "config",
    "material_from_config": "model",
    "max_frequency_power_iteration": "model",
    "simulate": "explicit",
    "simulate_batch": "explicit",
    "RubberMaterial": "material",
    "ENERGY_KEYS": "results",
    "SimulationResult": "results",
    "write_trace_parquet": "results",
    "FlatPlane": "surfaces",
    "RandomTexture": "surfaces",
    "SinusoidalSurface": "surfaces",
    "TiltedPlane": "surfaces",
}


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(importlib.import_module(f"skidsim.solver.{_WHERE[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'skidsim.solver' has no attribute {name!r}")


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
