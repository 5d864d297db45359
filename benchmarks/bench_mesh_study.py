"""The workflow's mesh study with its speeds batched per mesh against one run per (speed, size), side by side.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_mesh_study.py PAVEMENT.npz [--repeat 2] \
        [--sizes 2 1.5 1 0.75 0.5] [--speeds 20 40 60] [--config config/config.yaml]

PAVEMENT: a Heightfield ``.npz`` of skidsim.reconstruct (the workflow's ``results/sites/<site>/pavement.npz``; the
mesh study runs on the first site's). The solver settings are the workflow's
(:func:`skidsim.config.mesh_study_solver_config` of the config's ``solver:`` section), the sizes and speeds those of
its ``mesh_study:`` section unless given. The two variants alternate, ``--repeat`` times each, in one process with
BLAS on one thread; prints the CPU seconds (``time.process_time``) of each repeat, their medians and the ratio, per
element size, and checks that every SN and step count of the batched study equals the single runs' (exit status 1
otherwise).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import yaml
from threadpoolctl import threadpool_limits

from skidsim.config import mesh_study_solver_config
from skidsim.reconstruct import Heightfield
from skidsim.solver.mesh_study import MeshStudyOptions, mesh_study

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pavement")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--sizes", type=float, nargs="+", default=None, help="element sizes, mm")
    ap.add_argument("--speeds", type=float, nargs="+", default=None, help="km/h")
    ap.add_argument("--config", default=str(ROOT / "config" / "config.yaml"))
    a = ap.parse_args()
    cfg = yaml.safe_load(Path(a.config).read_text())
    study = MeshStudyOptions.from_dict(cfg.get("mesh_study"))
    sizes = a.sizes or list(study.sizes_mm)
    speeds = a.speeds or list(study.speeds_kmh)
    base = mesh_study_solver_config(cfg["solver"], progress_every_s=1e9)
    pav = Heightfield.from_npz(a.pavement)
    cpu = {True: [], False: []}
    per_size = {True: {}, False: {}}
    tables = {}
    with threadpool_limits(1):
        for _ in range(a.repeat):
            for batch in (False, True):
                t0 = time.process_time()
                tables[batch] = t = mesh_study(pav, sizes, speeds, base=base, batch=batch)
                cpu[batch].append(time.process_time() - t0)
                for h, d in t.groupby("element_mm"):  # wall s of the size's runs (CPU of one thread)
                    per_size[batch].setdefault(h, []).append(float(d["wall_s"].sum()))
                print(f"batch={batch}: {cpu[batch][-1]:.1f} CPU s", flush=True)
    same = (tables[True]["sn"].to_numpy() == tables[False]["sn"].to_numpy()).all() and (
        tables[True]["n_steps"].to_numpy() == tables[False]["n_steps"].to_numpy()
    ).all()
    old, new = statistics.median(cpu[False]), statistics.median(cpu[True])
    print(f"sizes {sizes} mm, speeds {speeds} km/h, {a.repeat} repeats; pavement {a.pavement}")
    print("| element mm | single runs, wall s (median) | batched, wall s (median) | ratio |")
    print("|---|---|---|---|")
    for h in sorted(per_size[False], reverse=True):
        o, n = statistics.median(per_size[False][h]), statistics.median(per_size[True][h])
        print(f"| {h:g} | {o:.1f} | {n:.1f} | {o / n:.2f}x |")
    print(f"| all (CPU s) | {old:.1f} | {new:.1f} | {old / new:.2f}x |")
    print("every SN and step count identical:", bool(same))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
