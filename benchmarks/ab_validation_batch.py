"""Two checkouts of the solver side by side on the workflow's own FE batch: the runs of ``validate_speeds`` (every
method's law at every calibration and validation speed, one batch, as the rule runs them) on the pavements of a
stored run, CPU seconds per site, the checkouts alternating.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/ab_validation_batch.py RESULTS CONFIG \
        --old ../skidsim-OLD --new . --sites C1-1 C5-2 E3-3 E6-1 [--repeats 2]

RESULTS: a run's ``results/`` (``sites/<site>/pavement.npz`` and ``calibration_<method>.json``); CONFIG: the
config file that run used (its ``solver`` and ``speeds``). Each checkout's ``src`` goes first on ``PYTHONPATH`` of
a fresh interpreter per repeat; the FE cache is an empty temporary file, so every run is simulated. Prints CPU s per
site and in total per checkout and repeat, the ratio new / old of the medians, and whether every SN agrees exactly.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

CHILD = r"""
import json, sys, tempfile, time
import yaml
from skidsim import calibration
from skidsim.calibration.cache import prefetch
from skidsim.calibration.site import site_simulator
results, config, sites = sys.argv[1], sys.argv[2], sys.argv[3:]
cfg = yaml.safe_load(open(config))
sp = cfg["speeds"]
speeds = sorted({float(v) for v in sp["calibration_kmh"]} | {float(v) for v in sp["validation_kmh"]})
methods = cfg["calibration"]["methods"]
out = {}
for site in sites:
    with tempfile.TemporaryDirectory() as d:
        simulate, _, _ = site_simulator(f"{results}/sites/{site}/pavement.npz", cfg["solver"], f"{d}/fe.parquet", site)
        laws = [
            calibration.CalibrationResult.from_json(f"{results}/sites/{site}/calibration_{m}.json") for m in methods
        ]
        t = time.process_time()
        prefetch(simulate, [(v, r.params) for r in laws for v in speeds])
        sn = [calibration.simulate_speeds(simulate, r.params, speeds)["sn_sim"].tolist() for r in laws]
        out[site] = [time.process_time() - t, sn]
print(json.dumps(out))
"""


def run_child(checkout: Path, child: str, *args: str) -> dict:
    """Run the script ``child`` with ``args`` in a fresh interpreter whose ``PYTHONPATH`` starts with
    ``checkout``'s ``src`` (one BLAS thread); return the JSON object of its last line of output."""
    env = dict(os.environ, PYTHONPATH=str(checkout / "src"), OMP_NUM_THREADS="1")
    p = subprocess.run([sys.executable, "-c", child, *args], env=env, capture_output=True, text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def run(checkout: Path, results: str, config: str, sites: list[str]) -> dict:
    return run_child(checkout, CHILD, results, config, *sites)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results")
    ap.add_argument("config")
    ap.add_argument("--old", type=Path, required=True, help="checkout of the old code (its src/ is used)")
    ap.add_argument("--new", type=Path, default=Path("."), help="checkout of the new code (default: this one)")
    ap.add_argument("--sites", nargs="+", required=True)
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args(argv)
    totals = {"old": [], "new": []}
    first = {}
    for r in range(a.repeats):
        for name, path in (("old", a.old), ("new", a.new)):
            out = run(path.resolve(), a.results, a.config, a.sites)
            first.setdefault(name, out)
            total = sum(v[0] for v in out.values())
            totals[name].append(total)
            per_site = ", ".join(f"{s} {v[0]:.2f}" for s, v in out.items())
            print(f"repeat {r + 1} {name}: {per_site}; total {total:.2f} CPU s")
    same = all(first["old"][s][1] == first["new"][s][1] for s in a.sites)
    m_old, m_new = statistics.median(totals["old"]), statistics.median(totals["new"])
    print(f"median total: old {m_old:.2f}, new {m_new:.2f} CPU s; new / old {m_new / m_old:.3f}; SN identical: {same}")


if __name__ == "__main__":
    main()
