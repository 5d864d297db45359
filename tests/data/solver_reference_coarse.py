"""Write the solver reference of tests/test_solver_batch.py with the solver on ``PYTHONPATH`` (all units SI/mm as in
:class:`skidsim.solver.SolverConfig`). Made with the solver of commit 64ab885::

    git worktree add /tmp/wt64 64ab885
    PYTHONPATH=/tmp/wt64/src:tests OMP_NUM_THREADS=1 .venv/bin/python tests/data/solver_reference_coarse.py \
        tests/data/solver_reference_coarse_avx512.npz

Per case: the scalars of :data:`solver_reference_cases.SCALARS` (``<case>/sn``), the energies in name order
(``<case>/energies``, ``<case>/energy_names``) and every trace column (``<case>/trace/<column>``,
``<case>/trace_columns``).
"""

from __future__ import annotations

import sys

import numpy as np
from solver_reference_cases import LAW, energies, reference_cases, scalars

from skidsim.solver import simulate


def main(path: str) -> None:
    out = {}
    for name, cfg, pav, v in reference_cases():
        r = simulate(pav, v, LAW, cfg)
        out[f"{name}/sn"] = scalars(r)
        out[f"{name}/energies"] = energies(r)
        out[f"{name}/energy_names"] = np.array(sorted(r.energies))
        out[f"{name}/trace_columns"] = np.array(list(r.trace.columns))
        for c in r.trace.columns:
            out[f"{name}/trace/{c}"] = r.trace[c].to_numpy()
    np.savez_compressed(path, **out)


if __name__ == "__main__":
    main(sys.argv[1])
