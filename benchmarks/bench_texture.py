"""Benchmark of the texture stage on one LS-40-sized scan (2048 x 2448 points, 0.05 mm), and of surfalize
0.19.2 (test-only peer, GPL-3.0; imported here, never by the library) on the same parameter subset.

Prints: wall time (median over --repeats) and peak RSS of the whole stage (despeckle, fill, form, bands, all
parameters on raw/macro/micro, MPD), per-step times, the CPU seconds of the workflow's ``texture_parameters``
step (every parameter on raw, macro and micro, one thread; median over --repeats), and for the subset Sa Sq Sdr
Sal Str Sk S10z on each band ours vs surfalize with the ratio (CPU seconds, one thread each). Targets: whole
stage <= 15 s and <= 2.5 GB on 2 cores; subset >= 15x faster than surfalize (issue 36).

The process first calls ``skidsim.texture.allocator.retain_freed_memory`` as the workflow's texture scripts do;
``--default-malloc`` leaves glibc's defaults (2-4 s more system time per scan).

    .venv/bin/python benchmarks/bench_texture.py [--repeats 3] [--no-peer] [--workers 2] [--rows 2048 --cols 2448]
    .venv/bin/python benchmarks/bench_texture.py --despeckle-study docs/figures/texture-despeckle-flat-binder.png

``--despeckle-study`` runs only the despeckle rules on LS-40-sized flat-binder scans (the builder of
tests/test_texture_despeckle.py: 29, 55 and 67 % binder, 0.01 mm codes), clean and with 0.05 % spikes of 3-5 mm:
per rule the replaced share, the MPD and raw-Sq errors against the clean scan, spike recall and seconds per scan,
and writes the before/after figure of docs/texture.md.

    .venv/bin/python benchmarks/bench_texture.py --despeckle-synthetic E1-1 E1-2

``--despeckle-synthetic`` compares the rules on sites of the embedded synthetic campaign (default config) against
the same scan without speckle (same tilt, dropouts and codes): replaced share, speckle recall, genuine points
replaced, and the height parameters and MPD of ``characterise`` (error against the speckle-free scan).

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
from skidsim.texture import (
    TextureOptions,
    areal_parameters,
    characterise,
    despeckle,
    despeckle_detail,
    fill_invalid,
    remove_form,
    separate_bands,
)
from skidsim.texture.allocator import retain_freed_memory
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
    return {
        "Sa": hp["Sa"],
        "Sq": hp["Sq"],
        "Sdr": sdr(z, s.dx, s.dy),
        "Sal": sp.Sal,
        "Str": sp.Str,
        "Sk": mr["Sk"],
        "S10z": fp["S10z"],
    }


def peer_subset(s: Surface) -> dict:
    import surfalize

    p = surfalize.Surface(s.heights, s.dx, s.dy)
    return {"Sa": p.Sa(), "Sq": p.Sq(), "Sdr": p.Sdr(), "Sal": p.Sal(), "Str": p.Str(), "Sk": p.Sk(), "S10z": p.S10z()}


def _raw_sq(s: Surface) -> float:
    """Sq (mm) of the filled, plane-removed scan: the raw band without the Butterworth step."""
    return float(np.std(remove_form(fill_invalid(s), "plane").heights))


def despeckle_study(path: str) -> None:
    """The flat-binder despeckle study of docs/texture.md (see the module docstring); prints a table and writes
    the figure to ``path``."""
    import importlib.util
    from pathlib import Path

    from skidsim.plotting.texture import plot_despeckle_flat_binder

    spec = importlib.util.spec_from_file_location(
        "flat_binder", Path(__file__).resolve().parents[1] / "tests" / "test_texture_despeckle.py"
    )
    fb = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fb)
    shape = (2048, 2448)
    cases = []
    print(
        "case | rule | replaced on clean % | MPD error on clean % | raw Sq error on clean % | "
        "recall (3-5 mm spikes) | genuine replaced on spiked % | MPD error on spiked % | CPU s per scan"
    )
    for n, share in enumerate((0.29, 0.55, 0.67)):
        h = fb.flat_binder_scan(share, seed=n, shape=shape)
        hs, mask = fb.inject_spikes(h, seed=100 + n)
        clean, spiked = Surface(h, 0.05, 0.05), Surface(hs, 0.05, 0.05)
        at_code = float(np.mean(h == 0.0))
        rows_half = float(np.mean([np.unique(r, return_counts=True)[1].max() > 0.5 * r.size for r in h]))
        mpd0, sq0 = mean_profile_depth(clean).mpd_mm, _raw_sq(clean)
        label = (
            f"binder {100 * at_code:.0f} % of the points at one height code ({100 * rows_half:.0f} % of rows "
            f"more than half on one code); clean MPD {mpd0:.3f} mm"
        )
        print(f"-- {label}")
        # the figure's window: 30 mm around a spike, on a row more than half on the binder code (where there is
        # one), with the most stone points in the window
        best = (-1, 0, 0)
        for i, j in zip(*np.nonzero(mask)):
            if rows_half > 0 and np.mean(h[i] == 0.0) <= 0.5:
                continue
            j0 = int(np.clip(j - 300, 0, shape[1] - 601))
            best = max(best, (int(np.sum(h[i, j0 : j0 + 601] > 0.3)), int(i), j0))
        _, row, j0 = best
        case = {
            "label": label + f"; row {row}",
            "dx_mm": 0.05,
            "row": hs[row],
            "rules": {},
            "replaced_pct": {},
            "mpd_err_pct": {},
            "x0_mm": j0 * 0.05,
        }
        for rule in ("mad", "tukey", "local"):
            t = time.process_time()
            rc = despeckle_detail(clean, rule)
            dt = time.process_time() - t
            rs = despeckle_detail(spiked, rule)
            mpd_c = mean_profile_depth(rc.surface).mpd_mm
            mpd_s = mean_profile_depth(rs.surface).mpd_mm
            err_c, err_s = 100 * (mpd_c / mpd0 - 1), 100 * (mpd_s / mpd0 - 1)
            print(
                f"{share:.2f} | {rule} | {100 * rc.n_replaced / h.size:.4f} | {err_c:+.1f} | "
                f"{100 * (_raw_sq(rc.surface) / sq0 - 1):+.1f} | {(rs.mask & mask).sum() / mask.sum():.4f} | "
                f"{100 * (rs.mask & ~mask).sum() / h.size:.4f} | {err_s:+.1f} | {dt:.2f}"
            )
            case["rules"][rule] = rs.surface.heights[row]
            case["replaced_pct"][rule] = 100 * rs.n_replaced / h.size
            case["mpd_err_pct"][rule] = err_s
        cases.append(case)
    plot_despeckle_flat_binder(cases, path)
    print(f"wrote {path}")


def despeckle_synthetic(sites: list[str]) -> None:
    """See the module docstring (``--despeckle-synthetic``)."""
    from skidsim.generators import default as syn

    c = syn.resolve_config(None)
    design = syn.design_campaign(c)
    dx = float(c["spacing_mm"])
    meta = {"x3p_dtype": "I", "z_increment_mm": float(c["z_quantum_mm"])}
    keys = [
        ("raw", "Sq"),
        ("raw", "Ssk"),
        ("raw", "Sp"),
        ("macro", "Sq"),
        ("micro", "Sq"),
        ("micro", "Sku"),
        ("profile", "MPD"),
    ]
    opt = {"groups": ("height",)}
    for site in sites:
        row = design[design.site == site].iloc[0].to_dict()
        heights, _ = syn.synthesize_surface(row, c)
        rng_seed = syn._site_seed(c["seed"], site).spawn(4)[2]  # the scanner's draws, as generate_site
        spiked = syn._scanner(np.random.default_rng(rng_seed), heights, c, dx)
        clean = syn._scanner(np.random.default_rng(rng_seed), heights, dict(c, speckle_fraction=0.0), dx)
        speckle = np.isfinite(spiked) & (spiked != clean)
        ref = characterise(Surface(clean, dx, dx, meta=meta), dict(opt, despeckle_method="local"))[0]
        ref = ref.set_index(["band", "parameter"])["value"]
        print(f"{site}: {speckle.sum()} speckle points ({100 * speckle.mean():.4f} %)")
        for rule in ("mad", "local"):
            s = Surface(spiked, dx, dx, meta=meta)
            t = time.process_time()
            res = despeckle_detail(s, rule)
            dt = time.process_time() - t
            tab = characterise(s, dict(opt, despeckle_method=rule))[0].set_index(["band", "parameter"])["value"]
            errs = ", ".join(
                f"{b} {p} {tab[(b, p)]:.4g} ({100 * (tab[(b, p)] / ref[(b, p)] - 1):+.2f} %)" for b, p in keys
            )
            print(
                f"  {rule}: replaced {100 * res.n_replaced / spiked.size:.4f} %, speckle recall "
                f"{(res.mask & speckle).sum() / speckle.sum():.3f}, genuine replaced {(res.mask & ~speckle).sum()}, "
                f"CPU {dt:.2f} s; vs speckle-free: {errs}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=2048)
    ap.add_argument("--cols", type=int, default=2448)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-peer", action="store_true")
    ap.add_argument("--default-malloc", action="store_true", help="leave glibc's malloc settings as they are")
    ap.add_argument("--bands", default="raw,macro,micro")
    ap.add_argument("--despeckle-study", metavar="PNG", help="only the flat-binder despeckle study (figure path)")
    ap.add_argument("--despeckle-synthetic", nargs="+", metavar="SITE", help="only the synthetic-site comparison")
    a = ap.parse_args()
    if a.despeckle_synthetic:
        despeckle_synthetic(a.despeckle_synthetic)
        return
    if a.despeckle_study:
        despeckle_study(a.despeckle_study)
        return
    retained = False if a.default_malloc else retain_freed_memory()
    print(f"load average before: {os.getloadavg()}; cpus: {os.cpu_count()}; freed memory retained: {retained}")
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
    print(
        f"whole stage ({a.rows} x {a.cols}, workers {a.workers}): median wall {statistics.median(times):.2f} s "
        f"over {a.repeats} run(s) {[round(t, 2) for t in times]}, CPU {statistics.median(cpu):.2f} s; "
        f"peak RSS {peak:.0f} MB (input and interpreter {base:.0f} MB)"
    )
    # per-step breakdown (one run)
    t_rule = {}
    for rule in ("mad", "tukey", "local"):
        t, c = time.perf_counter(), time.process_time()
        des, _ = despeckle(scan, rule)
        t_rule[rule] = (time.perf_counter() - t, time.process_time() - c)  # the last, local (the default), goes on
    t_des = t_rule["local"][0]
    print(
        "  despeckle per rule (wall / CPU): " + ", ".join(f"{k} {v[0]:.2f} / {v[1]:.2f} s" for k, v in t_rule.items())
    )
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
    step = []
    one = TextureOptions(workers=1)
    for _ in range(a.repeats):
        c = time.process_time()
        for band in ("raw", "macro", "micro"):
            areal_parameters(b[band], band, one)
        step.append(time.process_time() - c)
    print(
        f"texture_parameters step (raw, macro, micro; one thread): CPU median {statistics.median(step):.2f} s "
        f"over {a.repeats} run(s) {[round(t, 2) for t in step]}"
    )
    print(f"  load average after ours: {os.getloadavg()}")
    if a.no_peer:
        return
    t_ours = t_peer = 0.0
    for band in a.bands.split(","):
        s = b[band]
        t = time.process_time()
        o = ours_subset(s, 1)
        dt_o = time.process_time() - t
        t = time.process_time()
        p = peer_subset(s)
        dt_p = time.process_time() - t
        t_ours += dt_o
        t_peer += dt_p
        rel = {k: (o[k] / p[k] - 1) if p[k] else np.nan for k in o}
        print(
            f"  subset {band} (CPU): ours {dt_o:.2f} s, surfalize {dt_p:.2f} s, ratio {dt_p / dt_o:.1f}x; "
            "relative differences " + ", ".join(f"{k} {v:+.2e}" for k, v in rel.items())
        )
    print(
        f"subset Sa Sq Sdr Sal Str Sk S10z on {a.bands} (CPU): ours {t_ours:.2f} s, surfalize {t_peer:.2f} s, "
        f"speed-up {t_peer / t_ours:.1f}x; peak RSS incl. surfalize {rss_mb():.0f} MB"
    )
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
