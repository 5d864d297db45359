"""Benchmark of the texture stage on one LS-40-sized scan (2048 x 2448 points, 0.05 mm), and of surfalize
0.19.2 (test-only peer, GPL-3.0; imported here, never by the library) on the same parameter subset.

Prints: wall time (median over --repeats) and peak RSS of the whole stage (despeckle, fill, form, bands, all
parameters on raw/macro/micro, MPD), per-step times, and for the subset Sa Sq Sdr Sal Str Sk S10z on each band
ours vs surfalize with the ratio. Targets: whole stage <= 15 s and <= 2.5 GB on 2 cores; subset >= 3x faster
than surfalize.

    .venv/bin/python benchmarks/bench_texture.py [--repeats 3] [--no-peer] [--workers 2] [--rows 2048 --cols 2448]

Timings on a shared machine are disturbed by other load: report them with the load average printed here.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import time

import numpy as np
from scipy import ndimage

from skidsim.surface import Surface
from skidsim.texture import TextureOptions, areal_parameters, characterise, despeckle, separate_bands
from skidsim.texture.features import feature_parameters
from skidsim.texture.height import height_parameters
from skidsim.texture.hybrid import sdr
from skidsim.texture.material_ratio import material_ratio_parameters
from skidsim.texture.mpd import mean_profile_depth
from skidsim.texture.spatial import spatial_parameters


def synthetic_scan(rows: int, cols: int, seed: int = 0) -> Surface:
    """Pavement-like heights (mm): negatively skewed aggregate macrotexture (~2 mm features), microtexture
    (~0.1 mm, 0.02 mm rms), a 0.3 deg tilt, 0.01 % speckles and 0.5 % dropouts."""
    rng = np.random.default_rng(seed)
    f = ndimage.gaussian_filter(rng.standard_normal((rows, cols)), 15.0)
    f /= f.std()
    z = 0.6 * np.minimum(f, 0.7)  # flat-topped aggregates, deep voids: negative skew
    m = ndimage.gaussian_filter(rng.standard_normal((rows, cols)), 1.2)
    z += 0.02 * m / m.std()
    del f, m
    z += np.tan(np.radians(0.3)) * 0.05 * np.arange(cols)[None, :]
    sp = rng.random((rows, cols)) < 1e-4
    z[sp] += rng.choice([-8.0, 8.0], size=int(sp.sum()))
    z[rng.random((rows, cols)) < 5e-3] = np.nan
    return Surface(z, 0.05, 0.05, name="bench")


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def ours_subset(s: Surface, workers: int) -> dict:
    z = s.heights - s.heights.mean()
    hp = height_parameters(z)
    sp = spatial_parameters(z, s.dx, s.dy, workers=workers)
    mr = material_ratio_parameters(z)
    fp = feature_parameters(z, s.dx, s.dy, exclude_edge=True)
    return {"Sa": hp["Sa"], "Sq": hp["Sq"], "Sdr": sdr(z, s.dx, s.dy), "Sal": sp.Sal, "Str": sp.Str, "Sk": mr["Sk"],
            "S10z": fp["S10z"]}


def peer_subset(s: Surface) -> dict:
    import surfalize

    p = surfalize.Surface(s.heights, s.dx, s.dy)
    return {"Sa": p.Sa(), "Sq": p.Sq(), "Sdr": p.Sdr(), "Sal": p.Sal(), "Str": p.Str(), "Sk": p.Sk(),
            "S10z": p.S10z()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=2048)
    ap.add_argument("--cols", type=int, default=2448)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-peer", action="store_true")
    ap.add_argument("--bands", default="raw,macro,micro")
    a = ap.parse_args()
    print(f"load average before: {os.getloadavg()}; cpus: {os.cpu_count()}")
    scan = synthetic_scan(a.rows, a.cols)
    base = rss_mb()
    opt = TextureOptions(workers=a.workers)
    times, cpu = [], []
    for _ in range(a.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        table, bands = characterise(scan, opt)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    peak = rss_mb()
    print(f"whole stage ({a.rows} x {a.cols}, workers {a.workers}): median wall {statistics.median(times):.2f} s "
          f"over {a.repeats} run(s) {[round(t, 2) for t in times]}, CPU {statistics.median(cpu):.2f} s; "
          f"peak RSS {peak:.0f} MB (input and interpreter {base:.0f} MB)")
    # per-step breakdown (one run)
    t = time.perf_counter()
    des, _ = despeckle(scan)
    t_des = time.perf_counter() - t
    t = time.perf_counter()
    mean_profile_depth(des)
    t_mpd = time.perf_counter() - t
    t = time.perf_counter()
    b = separate_bands(des, workers=a.workers)
    t_bands = time.perf_counter() - t
    print(f"  despeckle {t_des:.2f} s, MPD {t_mpd:.2f} s, fill+form+bands {t_bands:.2f} s")
    for band in ("raw", "macro", "micro"):
        parts = []
        for g in ("height", "spatial", "hybrid", "material_ratio", "features", "furrows", "motifs"):
            t = time.perf_counter()
            areal_parameters(b[band], band, TextureOptions(workers=a.workers, groups=(g,)))
            parts.append(f"{g} {time.perf_counter() - t:.2f}")
        print(f"  {band}: " + ", ".join(parts) + " s")
    print(f"  load average after ours: {os.getloadavg()}")
    if a.no_peer:
        return
    t_ours = t_peer = 0.0
    for band in a.bands.split(","):
        s = b[band]
        t = time.perf_counter()
        o = ours_subset(s, a.workers)
        dt_o = time.perf_counter() - t
        t = time.perf_counter()
        p = peer_subset(s)
        dt_p = time.perf_counter() - t
        t_ours += dt_o
        t_peer += dt_p
        rel = {k: (o[k] / p[k] - 1) if p[k] else np.nan for k in o}
        print(f"  subset {band}: ours {dt_o:.2f} s, surfalize {dt_p:.2f} s, ratio {dt_p / dt_o:.1f}x; "
              "relative differences " + ", ".join(f"{k} {v:+.2e}" for k, v in rel.items()))
    print(f"subset Sa Sq Sdr Sal Str Sk S10z on {a.bands}: ours {t_ours:.2f} s, surfalize {t_peer:.2f} s, "
          f"speed-up {t_peer / t_ours:.1f}x; peak RSS incl. surfalize {rss_mb():.0f} MB")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
