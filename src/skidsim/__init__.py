"""skidsim: 3D pavement texture and DFT friction to calibrated explicit FE skid-resistance simulation.

The package is a library of pure functions on arrays and dataclasses; the Snakemake workflow in the
repository root (``Snakefile``) is a thin layer of rules over it. Submodules are imported explicitly
(``from skidsim import texture``) so that importing :mod:`skidsim` stays cheap.
"""

__version__ = "0.1.0"
