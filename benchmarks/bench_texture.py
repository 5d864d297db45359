"""Benchmark of the texture stage on one LS-40-sized scan (2048 x 2448 points, 0.05 mm), and of surfalize
0.19.2 (test-only peer, GPL-3.0; imported here, never by the library) on the same parameter subset.

Prints: wall time (median over --repeats) and peak RSS of the whole stage (despeckle, fill, form, bands, all
parameters on raw/macro/micro, MPD), per-step times, the CPU seconds of the workflow's ``texture_parameters``
step (every parameter on raw, macro and micro, one thread; median over --repeats), and for the subset Sa Sq Sdr
Sal Str Sk S10z on each band ours vs surfalize with the ratio (CPU seconds, one thread each; the two alternate band
by band, --repeats times; medians, and the ratio of each run). Targets: whole stage <= 15 s and <= 2.5 GB on 2
cores; subset >= 15x faster than surfalize (issue 36).

The process first calls ``skidsim.allocator.scan_process_memory`` as the workflow's texture scripts do (glibc's
heap for every array, NumPy's huge-page advice off); ``--default-malloc`` leaves glibc's and NumPy's defaults.

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

    .venv/bin/python benchmarks/bench_texture.py --old /tmp/skidsim-old [--scan synthetic|site:E1-1|binder:67|FILE.x3p]

``--old PATH`` compares the texture stage of another checkout (``git worktree add /tmp/skidsim-old HEAD``: its
``src/skidsim/texture`` is imported as a separate package, the rest of skidsim from this tree) with this tree's on
the same scan, in the same process: per workflow step (despeckle: ``despeckle_detail`` + ``scan_quality`` +
``fill_invalid``; separate_bands; mpd; texture_parameters: ``areal_parameters`` on raw, macro and micro (and
``cross_band_parameters``, the contact zone, where the checkout has it), one
thread) the CPU seconds of each, old and new alternating after one untimed run of each (imports, memoised
tables), median of ``--compare-repeats`` (3), the ratio new/old, and every number of the steps' outputs compared
(each parameter of the three bands, the MPD, its SD, counts and segment depths, the scan-quality measures, the
despeckled and band heights): identical, or the largest relative difference. ``--scan`` picks the scan:
``synthetic`` (below, the default), ``site:NAME`` (a site of the embedded synthetic campaign as its scanner writes
it: 0.01 mm integer codes, tilt, dropouts, speckle), ``binder:PCT`` (the flat-binder scan of
tests/test_texture_despeckle.py at that binder share: 0.01 mm codes, 0.5 % dropouts, 0.05 % spikes) or an X3P or
text scan file. ``--compare-only`` skips the rest.

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

from skidsim.allocator import scan_process_memory
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
from skidsim.texture.features import ten_point_height
from skidsim.texture.height import sa_sq
from skidsim.texture.hybrid import sdr
from skidsim.texture.material_ratio import core_height
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


def site_scan(site: str) -> Surface:
    """A site of the embedded synthetic campaign (default config) as its scanner writes it (0.01 mm codes, tilt,
    dropouts, speckle), with the X3P metadata the despeckle reads (integer codes, Z increment)."""
    from skidsim.generators import default as syn
    from skidsim.generators.default import surface

    c = syn.resolve_config(None)
    design = syn.design_campaign(c)
    row = design[design.site == site].iloc[0].to_dict()
    heights, _ = syn.synthesize_surface(row, c)
    dx = float(c["spacing_mm"])
    scan = surface._scanner(np.random.default_rng(surface._site_seed(c["seed"], site).spawn(4)[2]), heights, c, dx)
    meta = {"x3p_dtype": "I", "z_increment_mm": float(c["z_quantum_mm"])}
    return Surface(scan, dx, dx, name=site, meta=meta)


def binder_scan(pct: float, rows: int, cols: int) -> Surface:
    """The flat-binder scan of tests/test_texture_despeckle.py (``pct`` % binder at one 0.01 mm code), with 0.5 %
    dropouts and 0.05 % spikes of 3-5 mm."""
    fb = _flat_binder_module()
    h = fb.flat_binder_scan(pct / 100.0, seed=7, shape=(rows, cols), dropout_share=0.005)
    hs, _ = fb.inject_spikes(h, seed=107)
    return Surface(hs, 0.05, 0.05, name=f"binder {pct:g} %")


def _flat_binder_module():
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "flat_binder", Path(__file__).resolve().parents[1] / "tests" / "test_texture_despeckle.py"
    )
    fb = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fb)
    return fb


def pick_scan(spec: str, rows: int, cols: int) -> Surface:
    """``--scan``: synthetic, site:NAME, binder:PCT or a scan file."""
    if spec == "synthetic":
        return synthetic_scan(rows, cols)
    if spec.startswith("site:"):
        return site_scan(spec[5:])
    if spec.startswith("binder:"):
        return binder_scan(float(spec[7:]), rows, cols)
    from skidsim.scans import read_scan

    return read_scan(spec)


def load_texture_package(root: str, name: str = "_old_texture"):
    """``ROOT/src/skidsim/texture`` of another checkout as the package ``name`` (its relative imports stay inside
    it; ``skidsim.surface`` and the other absolute imports come from this tree)."""
    import importlib
    import importlib.util
    import sys
    from pathlib import Path

    pkg = Path(root) / "src" / "skidsim" / "texture"
    if not (pkg / "__init__.py").is_file():
        raise SystemExit(f"--old {root}: no src/skidsim/texture in it (a checkout: git worktree add {root} HEAD)")
    spec = importlib.util.spec_from_file_location(name, pkg / "__init__.py", submodule_search_locations=[str(pkg)])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod, importlib.import_module(f"{name}.quality")


def texture_steps(tex, quality, scan: Surface, workers: int = 1):
    """The work of the workflow's four texture rules on ``scan`` with the package ``tex`` and its ``quality``
    module: ``[(step, function)]``, each function taking the previous outputs."""
    opt = tex.TextureOptions(workers=workers)

    def despeckle_step(_):
        res = tex.despeckle_detail(scan, opt.despeckle_method, opt.despeckle_k, opt.despeckle_axis)
        q = quality.scan_quality(scan.name, scan, res.mask, res.step_mm, res.step_source)
        return {"clean": tex.fill_invalid(res.surface, opt.fill), "quality": q.to_dict()}

    def bands_step(out):
        return {"bands": tex.separate_bands(out["clean"], macro=opt.macro_mm, order=opt.butterworth_order)}

    def mpd_step(out):
        return {"mpd": tex.mean_profile_depth(out["clean"], **opt.mpd_kwargs())}

    def params_step(out):
        params = {b: tex.areal_parameters(out["bands"][b], b, opt) for b in ("raw", "macro", "micro")}
        cross = getattr(tex, "cross_band_parameters", None)  # the contact zone, as the workflow's rule (newer trees)
        for b, extra in (cross(out["bands"], opt) if cross is not None else {}).items():
            params[b].update(extra)
        return {"params": params}

    return [
        ("despeckle", despeckle_step),
        ("separate_bands", bands_step),
        ("mpd", mpd_step),
        ("texture_parameters", params_step),
    ]


def _rel(a: float, b: float) -> float:
    """Relative difference of b against a (0 when identical, both NaN included)."""
    if a == b or (np.isnan(a) and np.isnan(b)):
        return 0.0
    return abs(b - a) / abs(a) if a else np.inf


def compare_outputs(old: dict, new: dict) -> tuple[dict, int]:
    """``({name: largest relative difference}, number of values compared)`` over every output of the steps."""
    diffs: dict[str, float] = {}
    n = 0

    def put(key, a, b):
        nonlocal n
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        n += a.size
        if a.shape != b.shape:
            diffs[key] = np.inf
            return
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        if not same.all():
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.abs(b - a)[~same] / np.abs(a)[~same]
            diffs[key] = float(np.nanmax(np.where(np.isfinite(r), r, np.inf)))
        else:
            diffs[key] = 0.0

    put("despeckled heights", old["clean"].heights, new["clean"].heights)
    for k, v in old["quality"].items():
        if isinstance(v, (int, float)):
            put(f"quality {k}", v, new["quality"][k])
    for b in old["bands"]:
        put(f"{b} band heights", old["bands"][b].heights, new["bands"][b].heights)
    mo, mn = old["mpd"], new["mpd"]
    for k in ("mpd_mm", "sd_mm", "n_segments", "n_invalid_segments", "etd_mm", "msd_mm"):
        put(f"profile {k}", getattr(mo, k), getattr(mn, k))
    for b, params in old["params"].items():
        for k, (v, _) in params.items():
            put(f"{b} {k}", v, new["params"][b][k][0])
    return diffs, n


def compare_old_new(root: str, scan: Surface, repeats: int) -> None:
    """``--old``: old and new texture steps on ``scan`` (see the module docstring)."""
    import skidsim.texture as new_tex
    from skidsim.texture import quality as new_quality

    old_tex, old_quality = load_texture_package(root)
    steps = {"old": texture_steps(old_tex, old_quality, scan), "new": texture_steps(new_tex, new_quality, scan)}
    cpu = {k: {name: [] for name, _ in steps[k]} for k in steps}
    outputs = {}
    for which in ("old", "new"):  # one untimed run each: imports (scipy.signal for the MPD), memoised tables
        out = {}
        for _, fn in steps[which]:
            out.update(fn(out))
        del out
    for _ in range(repeats):
        for which in ("old", "new"):  # alternating, so that both see the same load
            out = {}
            for name, fn in steps[which]:
                t = time.process_time()
                out.update(fn(out))
                cpu[which][name].append(time.process_time() - t)
            outputs[which] = out
            del out
    print(
        f"old ({root}) against new (this tree) on {scan.name!r} {scan.shape}, CPU s (process time, one thread), "
        f"median of {repeats} alternating run(s) after one untimed run each:"
    )
    print(f"  {'step':20s} {'old s':>8s} {'new s':>8s} {'new/old':>8s}")
    tot_o = tot_n = 0.0
    for name in cpu["old"]:
        o, n = statistics.median(cpu["old"][name]), statistics.median(cpu["new"][name])
        tot_o, tot_n = tot_o + o, tot_n + n
        print(f"  {name:20s} {o:8.2f} {n:8.2f} {n / o:8.2f}")
    print(f"  {'total':20s} {tot_o:8.2f} {tot_n:8.2f} {tot_n / tot_o:8.2f}  (speed-up {tot_o / tot_n:.2f}x)")
    diffs, n = compare_outputs(outputs["old"], outputs["new"])
    changed = {k: v for k, v in diffs.items() if v}
    if not changed:
        print(f"  outputs: all {n} values identical ({len(diffs)} quantities: heights, quality, MPD, parameters)")
    else:
        print(f"  outputs: {len(changed)} of {len(diffs)} quantities differ (largest relative difference):")
        for k, v in sorted(changed.items(), key=lambda kv: -kv[1]):
            print(f"    {k}: {v:.3e}")


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def ours_subset(s: Surface, workers: int) -> dict:
    z = s.heights - s.heights.mean()
    hp = sa_sq(z)  # Sa and Sq alone, as surfalize's: not the moments and extremes of height_parameters
    sp = spatial_parameters(z, s.dx, s.dy, workers=workers, direction=False)  # Sal and Str, as surfalize's: no Std
    sk = core_height(z)  # Sk alone, as surfalize's Sk: not the volumes and ratios of material_ratio_parameters
    fp = ten_point_height(z, s.dx, s.dy, exclude_edge=True)  # surfalize's convention: edge motifs dropped
    return {
        "Sa": hp["Sa"],
        "Sq": hp["Sq"],
        "Sdr": sdr(z, s.dx, s.dy),
        "Sal": sp.Sal,
        "Str": sp.Str,
        "Sk": sk,
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
    from skidsim.plotting.texture import plot_despeckle_flat_binder

    fb = _flat_binder_module()
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
    from skidsim.generators.default import surface

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
        rng_seed = surface._site_seed(c["seed"], site).spawn(4)[2]  # the scanner's draws, as generate_site
        spiked = surface._scanner(np.random.default_rng(rng_seed), heights, c, dx)
        clean = surface._scanner(np.random.default_rng(rng_seed), heights, dict(c, speckle_fraction=0.0), dx)
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
    ap.add_argument(
        "--default-malloc", action="store_true", help="leave glibc's malloc and NumPy's huge-page advice as they are"
    )
    ap.add_argument("--bands", default="raw,macro,micro")
    ap.add_argument("--despeckle-study", metavar="PNG", help="only the flat-binder despeckle study (figure path)")
    ap.add_argument("--despeckle-synthetic", nargs="+", metavar="SITE", help="only the synthetic-site comparison")
    ap.add_argument("--old", metavar="PATH", help="another checkout (a git worktree): compare its texture steps")
    ap.add_argument("--compare-repeats", type=int, default=3, help="alternating old/new runs for --old (median)")
    ap.add_argument(
        "--scan", default="synthetic", help="synthetic (default), site:NAME, binder:PCT or a scan file (--old only)"
    )
    ap.add_argument("--compare-only", action="store_true", help="with --old: only the old/new comparison")
    a = ap.parse_args()
    if a.despeckle_synthetic:
        despeckle_synthetic(a.despeckle_synthetic)
        return
    if a.despeckle_study:
        despeckle_study(a.despeckle_study)
        return
    retained = {} if a.default_malloc else scan_process_memory()
    print(f"load average before: {os.getloadavg()}; cpus: {os.cpu_count()}; memory settings: {retained}")
    if a.old:
        compare_old_new(a.old, pick_scan(a.scan, a.rows, a.cols), max(1, a.compare_repeats))
        print(f"  load average after the comparison: {os.getloadavg()}")
        if a.compare_only:
            return
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
    bands = a.bands.split(",")
    ours_t = {band: [] for band in bands}
    peer_t = {band: [] for band in bands}
    for r in range(a.repeats):  # ours and surfalize alternate, band by band
        for band in bands:
            s = b[band]
            t = time.process_time()
            o = ours_subset(s, 1)
            ours_t[band].append(time.process_time() - t)
            t = time.process_time()
            p = peer_subset(s)
            peer_t[band].append(time.process_time() - t)
            if r == 0:
                rel = {k: (o[k] / p[k] - 1) if p[k] else np.nan for k in o}
                print(f"  subset {band}: relative differences " + ", ".join(f"{k} {v:+.2e}" for k, v in rel.items()))
    for band in bands:
        dt_o, dt_p = statistics.median(ours_t[band]), statistics.median(peer_t[band])
        print(f"  subset {band} (CPU, median): ours {dt_o:.2f} s, surfalize {dt_p:.2f} s, ratio {dt_p / dt_o:.1f}x")
    tot_o = [sum(ours_t[band][r] for band in bands) for r in range(a.repeats)]
    tot_p = [sum(peer_t[band][r] for band in bands) for r in range(a.repeats)]
    t_ours, t_peer = statistics.median(tot_o), statistics.median(tot_p)
    print(
        f"subset Sa Sq Sdr Sal Str Sk S10z on {a.bands} (CPU, median of {a.repeats}): ours {t_ours:.2f} s, surfalize "
        f"{t_peer:.2f} s, speed-up {t_peer / t_ours:.1f}x (per run: "
        + ", ".join(f"{tp / to:.1f}x" for to, tp in zip(tot_o, tot_p))
        + f"); peak RSS incl. surfalize {rss_mb():.0f} MB"
    )
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
