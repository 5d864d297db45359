"""An older checkout's single FE runs against this checkout's single and batched runs, side by side.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/ab_solver_paths.py --old ../skidsim-OLD [--new .] [--repeats 2]

The cases of ``bench_solver.py --batch --pavement-kind heightfield``: the campaign preset (full 114.3 mm slide) on
RandomTexture(seed 0) sampled at 0.5 mm on a 122.4 x 100 mm strip; a calibration batch (20/40/60 km/h, one law) and
a validation batch (2 laws x 20/30/.../70 km/h). Each checkout's ``src`` goes first on ``PYTHONPATH`` of a fresh
interpreter per repeat, the checkouts alternating; BLAS one thread. The old checkout runs every case one
``simulate`` at a time (and ``simulate_batch`` too where it has one); the new one both ways. Prints the median CPU
s per FE run of each path, the ratios old single / new single and old single / new batch, and whether every SN
agrees (largest relative difference).
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

from ab_validation_batch import run_child  # benchmarks/ is the script's directory, first on sys.path

CHILD = r"""
import json, time
from threadpoolctl import threadpool_limits
from skidsim.friction import ExponentialDecay
from skidsim.solver import RandomTexture, SolverConfig, simulate
from skidsim.solver.surfaces import to_heightfield
try:
    from skidsim.solver import simulate_batch
except ImportError:
    simulate_batch = None
LAW = ExponentialDecay(0.4, 0.35, 0.6)
LAWS = (LAW, ExponentialDecay(0.45, 0.3, 0.5))
pav = to_heightfield(RandomTexture(seed=0, extent_m=(0, 0.1224, -0.05, 0.05)), spacing_m=0.5e-3)
cfg = SolverConfig.campaign(progress_every_s=1e9)
cases = {
    "calibration": ([20.0, 40.0, 60.0], [LAW] * 3),
    "validation": ([float(v) for _ in LAWS for v in (20, 30, 40, 50, 60, 70)], [w for w in LAWS for _ in range(6)]),
}
out = {}
with threadpool_limits(1):
    for name, (speeds, laws) in cases.items():
        t = time.process_time()
        runs = [simulate(pav, v, w, cfg) for v, w in zip(speeds, laws)]
        out[name] = {"single_s": (time.process_time() - t) / len(speeds), "sn": [r.sn for r in runs]}
        if simulate_batch is not None:
            t = time.process_time()
            runs = simulate_batch(pav, speeds, laws, cfg)
            out[name]["batch_s"] = (time.process_time() - t) / len(speeds)
            out[name]["batch_sn"] = [r.sn for r in runs]
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--old", type=Path, required=True, help="checkout of the older commit")
    ap.add_argument("--new", type=Path, default=Path(__file__).resolve().parents[1])
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args()
    got = {"old": [], "new": []}
    for _ in range(a.repeats):
        for side in ("old", "new"):
            got[side].append(run_child(getattr(a, side), CHILD))
    print(f"CPU s per campaign FE run, median of {a.repeats} alternating fresh interpreters per checkout")
    for case in got["new"][0]:
        old = statistics.median(r[case]["single_s"] for r in got["old"])
        new_single = statistics.median(r[case]["single_s"] for r in got["new"])
        new_batch = statistics.median(r[case]["batch_s"] for r in got["new"])
        sn_old = got["old"][0][case]["sn"]
        sns = [r[case][k] for r in got["new"] for k in ("sn", "batch_sn")]
        d_sn = max(abs(s / o - 1.0) for sn in sns for s, o in zip(sn, sn_old))
        print(
            f"  {case} ({len(sn_old)} runs): old single {old:.3f}, new single {new_single:.3f} "
            f"({old / new_single:.2f}x), new batch {new_batch:.3f} ({old / new_batch:.2f}x); "
            f"max |SN_new / SN_old - 1| {d_sn:.1e}"
        )


if __name__ == "__main__":
    main()
