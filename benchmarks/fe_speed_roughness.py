"""How rough is the FE's friction-to-law ratio g(v) = SN(v) / mu(v) across speeds, per slide length?

For sites of a finished workflow run (their reconstructed pavements ``results/sites/<site>/pavement.npz`` and our
calibrated laws ``calibration_ours.json``) the FE runs each site's law at speeds 20-70 km/h every ``--step`` km/h
with the solver preset ``--preset`` (the workflow's default campaign; quick for a run of config/quick.yaml) and
each slide length of ``--slides`` (mm; a slide longer than the strip is clamped to it), one batch per site and
length. Printed per site and length: CPU seconds, g at 20 and 70 km/h, and the
roughness of g, the standard deviation of g about a quadratic in speed, relative (%). The calibration sees g at
20 / 40 / 60 km/h only; what it does between them shows at the validation speeds and along the DFT trace.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fe_speed_roughness.py RUN_DIR --sites S04-3,S01-1 \\
        [--preset campaign|quick|reference] [--slides 40,80,114.3] [--step 2.5] [--load-n 11.8]

Units: speeds km/h, slides mm, mu and SN dimensionless.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from skidsim.config import solver_config
from skidsim.friction import ExponentialDecay
from skidsim.reconstruct import Heightfield
from skidsim.solver import simulate_batch


def roughness(speeds: np.ndarray, g: np.ndarray) -> float:
    """Standard deviation (relative, %) of ``g`` about the least-squares quadratic in ``speeds``."""
    fit = np.polyval(np.polyfit(speeds, g, 2), speeds)
    return float(np.std(g / fit - 1.0) * 100.0)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path, help="a workflow run's directory (holds results/sites/<site>/)")
    ap.add_argument("--sites", required=True, help="comma-separated site names")
    ap.add_argument("--preset", default="campaign", help="solver preset (campaign, quick, reference)")
    ap.add_argument("--load-n", type=float, default=11.8, help="slider load (N)")
    ap.add_argument("--slides", default="40,80,114.3", help="slide lengths (mm)")
    ap.add_argument("--step", type=float, default=2.5, help="speed step (km/h)")
    a = ap.parse_args(argv)
    speeds = np.r_[np.arange(20.0, 70.0, a.step), 70.0]
    base = solver_config({"preset": a.preset, "load_n": a.load_n})
    print(f"preset {a.preset}, {speeds.size} speeds {speeds[0]:g}-{speeds[-1]:g} km/h every {a.step:g} km/h")
    with threadpool_limits(1):
        for site in a.sites.split(","):
            d = a.run_dir / "results" / "sites" / site
            hf = Heightfield.from_npz(d / "pavement.npz")
            p = json.loads((d / "calibration_ours.json").read_text())["params"]
            law = ExponentialDecay(p["mu_s"], p["mu_k"], p["alpha"])
            mu = np.array([law.mu_kmh(v) for v in speeds])
            for length in (float(x) for x in a.slides.split(",")):
                cfg = dataclasses.replace(base, slide_length_mm=length)
                t = time.process_time()
                runs = simulate_batch(hf, [float(v) for v in speeds], [law] * speeds.size, cfg)
                g = np.array([r.sn for r in runs]) / mu
                print(
                    f"{site} slide {length:6.1f} mm: CPU {time.process_time() - t:5.1f} s, g {g[0]:.3f} at 20 km/h, "
                    f"{g[-1]:.3f} at 70 km/h, roughness {roughness(speeds, g):.2f} %"
                )


if __name__ == "__main__":
    main()
