"""The ``skidsim`` command: work without Snakemake.

skidsim validate CAMPAIGN_DIR                 check a campaign against the data contract
skidsim texture SCAN [-o OUT.parquet|.csv]    areal parameters of one scan (raw, macro, micro) and MPD
skidsim mpd PROFILE [-o SEGMENTS.csv]         mean profile depth (ISO 13473-1) of a text line profile
skidsim simulate SCAN --speed 40 --mu-s .. --mu-k .. --alpha ..   one FE simulation: SN, trace, VTU
skidsim synth OUT_DIR [--sites N] [--generator default|chips|spectral]
                                              write a synthetic campaign (scans, DFT, sites.csv, truth)
skidsim predict MODEL SCAN [SCAN ...] [-o OUT.csv] [--level 0.9] [--jobs N]
                                              DFT at 20-70 km/h, F60 and Sp of scans without DFT, with intervals
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from .atomic import atomic_path
from .errors import SkidsimError

log = logging.getLogger("skidsim")


def _cmd_validate(args) -> int:
    import yaml

    from . import validate
    from .config import merged

    config: dict = {}
    for path in args.configfile or []:
        try:
            with open(path, encoding="utf-8") as fh:
                config = merged(config, yaml.safe_load(fh) or {})
        except (OSError, yaml.YAMLError) as exc:
            raise validate.ConfigProblem(
                path, "a readable YAML config file", got=f"{type(exc).__name__}: {exc}"
            ) from None
    if args.speeds:  # one list: the trace must cover all of them; the config's own split is kept otherwise
        config = merged(config, {"speeds": {"calibration_kmh": args.speeds, "validation_kmh": []}})
    if args.allow_outside:
        config = merged(config, {"ingest": {"allow_outside_campaign": True}})
    source = ", ".join(args.configfile) if args.configfile else "defaults of config/config.yaml"
    req = validate.Requirements.from_config(config, source=source if args.configfile else validate.CONFIG)
    t0 = time.perf_counter()
    camp, found = validate.problems(args.campaign, req, level=args.level)
    if args.speeds:  # an explicit speed list has no calibration/validation split to cross-check
        found = [e for e in found if getattr(e, "column", None) != "speeds.validation_kmh"]
    if found:
        print(validate.format_problems(found), file=sys.stderr)
        return 2
    sites = camp.sites
    print(
        f"{args.campaign}: OK, {len(sites)} sites in {sites['section'].nunique()} sections "
        f"(level {args.level}, {time.perf_counter() - t0:.1f} s)"
    )
    print(f"metadata columns: {', '.join(camp.metadata_columns) or '(none)'}")
    print(f"temperature: {sites['temperature_c'].min():.1f} .. {sites['temperature_c'].max():.1f} deg C")
    return 0


def _texture_options(args) -> dict:
    return {"despeckle_method": args.despeckle, "macro_mm": tuple(args.macro_mm)}


def _cmd_texture(args) -> int:
    import pandas as pd

    from . import texture
    from .scans import read_scan

    t0 = time.perf_counter()
    surface = read_scan(args.scan)
    log.info("read %s: %d x %d points, dx %.4g mm, dy %.4g mm", args.scan, *surface.shape, surface.dx, surface.dy)
    table, _ = texture.characterise(surface, _texture_options(args), site=Path(args.scan).stem)
    log.info("texture parameters computed in %.1f s", time.perf_counter() - t0)
    if args.output:
        out = Path(args.output)
        with atomic_path(out) as tmp:
            if out.suffix == ".csv":
                table.to_csv(tmp, index=False)
            else:
                table.to_parquet(tmp, index=False)
        print(f"wrote {out}")
    if not args.quiet:
        wide = table.pivot_table(index=["parameter", "unit"], columns="band", values="value", aggfunc="first")
        with pd.option_context("display.max_rows", 500, "display.width", 120, "display.float_format", "{:.5g}".format):
            print(wide)
    return 0


def _fmt_mm(v: float) -> str:
    return "n/a" if v != v else f"{v:.4f}"


def _cmd_mpd(args) -> int:
    from .profiles import ProfileFormatError, read_profile
    from .texture.mpd import MPDOptions, SpacingError, evaluation_lengths, profile_segments, summarise

    prof = read_profile(
        args.profile,
        distance_col=args.distance_col,
        height_col=args.height_col,
        distance_unit=args.distance_unit,
        height_unit=args.height_unit,
    )
    opts = MPDOptions(
        segment_mm=args.segment_mm,
        resample_mm=args.resample_mm,
        spike_alpha=args.spike_alpha,
        detect_plates=args.detect_plates,
        plate_threshold_mm=args.plate_threshold_mm,
        max_dropout_pct=args.max_dropout_pct,
        evaluation_length_m=args.evaluation_length_m,
    )
    try:
        segs = profile_segments(prof.height_mm, prof.distance_mm, opts)
    except SpacingError as e:
        unit = f"distances read in {prof.units[0]} ({prof.unit_sources[0]})"
        raise ProfileFormatError(prof.path, f"{e.expected}; {unit}", column=prof.columns[0], got=e.got) from None
    res = summarise(
        segs,
        name=Path(args.profile).name,
        segment_mm=args.segment_mm,
        profile_mm=float(prof.distance_mm[-1] - prof.distance_mm[0]),
    )
    n_valid = res.n_segments - res.n_invalid_segments
    print(
        f"MPD {_fmt_mm(res.mpd_mm)} mm, SD {_fmt_mm(res.sd_mm)} mm, {n_valid} valid segment"
        f"{'' if n_valid == 1 else 's'}, {res.n_invalid_segments} invalid segment"
        f"{'' if res.n_invalid_segments == 1 else 's'}; ETD {_fmt_mm(res.etd_mm)} mm"
    )
    trim = [
        f"{lab} {v:.3f} mm"
        for lab, v in (("starts at", segs.trim_start_mm[0]), ("ends at", segs.trim_end_mm[0]))
        if v == v
    ]
    units = ", ".join(f"{u} ({src})" for u, src in zip(prof.units, prof.unit_sources))
    print(
        f"{prof.path}: {len(prof.distance_mm)} samples, {prof.distance_mm[0]:g} .. {prof.distance_mm[-1]:g} mm, "
        f"{prof.n_dropouts} dropouts; columns {prof.columns[0]!r}, {prof.columns[1]!r} in {units}; "
        f"resampled at {segs.spacing_mm:g} mm"
        + (f"; plates detected: profile {', '.join(trim)}" if trim else "")
        + (
            "; distances below 0 belong to no segment (segments are (0, L], (L, 2L], ...)"
            if prof.distance_mm[0] < 0
            else ""
        )
    )
    if args.evaluation_length_m is not None and res.n_segments:
        for r in evaluation_lengths(segs).itertuples():
            print(
                f"  evaluation length to {r.end_m:g} m: MPD {_fmt_mm(r.mpd_mm)} mm, SD {_fmt_mm(r.sd_mm)} mm, "
                f"{r.n_valid} of {r.n_segments} segments valid{'' if r.is_valid else ' (fewer than half: invalid)'}"
            )
    if args.output:
        frame = segs.to_frame().drop(columns="profile")
        frame.insert(0, "segment", range(1, len(frame) + 1))
        with atomic_path(args.output) as tmp:
            frame.to_csv(tmp, index=False, float_format="%.6g")
        print(f"wrote {args.output}")
    return 0


def _strip_length(text: str) -> float | str:
    """``--length-mm``: a positive number of mm or ``auto``."""
    if text == "auto":
        return text
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a length in mm or 'auto', got {text!r}") from None
    if not v > 0:
        raise argparse.ArgumentTypeError(f"expected a positive length in mm, got {text!r}")
    return v


def _cmd_simulate(args) -> int:
    from . import texture
    from .config import solver_config
    from .friction import ExponentialDecay
    from .reconstruct import pavement_strip
    from .runlog import Progress
    from .scans import read_scan
    from .solver import simulate

    surface = read_scan(args.scan)
    clean, _ = texture.despeckle(surface)  # the default rule (local), as the workflow
    clean = texture.fill_invalid(clean)
    pav = pavement_strip(clean, length_mm=args.length_mm, resolution_mm=args.resolution_mm)
    cfg = solver_config({"preset": args.preset, "load_n": args.load_n, "overrides": {}})
    law = ExponentialDecay(args.mu_s, args.mu_k, args.alpha)
    res = simulate(
        pav,
        args.speed,
        law,
        cfg,
        trace_path=args.trace,
        vtu_dir=args.vtu,
        progress=Progress(1, f"simulate {args.speed} km/h", log),
    )
    print(
        f"SN = {res.sn:.4f} at {args.speed} km/h (mu({args.speed} km/h) = {float(law.mu_kmh(args.speed)):.4f}); "
        f"{res.n_steps} steps of {res.dt_s * 1e6:.3f} us in {res.wall_s:.1f} s"
    )
    return 0


def _cmd_synth(args) -> int:
    from .config import merged
    from .generators import default as synthetic
    from .runlog import Progress

    if args.generator != "default":
        return _cmd_synth_independent(args)
    cfg = synthetic.default_config()
    over = {} if args.seed is None else {"seed": args.seed}
    if args.shape:
        over["shape"] = list(args.shape)
    if args.spacing_mm:
        over["spacing_mm"] = args.spacing_mm
    cfg = merged(cfg, over)
    design = synthetic.design_campaign(cfg)
    if args.sites:
        design = design.head(args.sites)
    out = Path(args.out_dir)
    truth_dir = Path(args.truth_dir) if args.truth_dir else out.parent / (out.name + "-truth")
    prog = Progress(len(design), "synthetic sites", log, every_s=0)
    for n, (_, row) in enumerate(design.iterrows(), 1):
        data = synthetic.generate_site(row, cfg)
        synthetic.write_site(
            data,
            out / "scans" / f"{row['site']}.x3p",
            out / "dft" / f"{row['site']}.csv",
            truth_dir / f"{row['site']}.json",
        )
        prog(n)
    synthetic.write_sites_csv(design, out, out / "sites.csv")
    print(f"wrote {len(design)} sites to {out} (truth in {truth_dir})")
    return 0


def _cmd_synth_independent(args) -> int:
    """``synth --generator chips|spectral``: a campaign of :mod:`skidsim.generators` (36 sites in 12 sections by
    default; ``--sites N``: N sites in max(3, round(N / 3)) sections)."""
    from . import generators
    from .runlog import Progress

    over = {} if args.seed is None else {"seed": args.seed}
    if args.sites:
        over["n_sites"] = args.sites
    if args.shape:
        over["shape"] = list(args.shape)
    if args.spacing_mm:
        over["spacing_mm"] = args.spacing_mm
    n = over.get("n_sites", generators.generator_config(args.generator)["n_sites"])
    out = Path(args.out_dir)
    truth_dir = Path(args.truth_dir) if args.truth_dir else out.parent / (out.name + "-truth")
    prog = Progress(n, f"{args.generator} sites", log, every_s=0)
    design = generators.write_campaign(out, args.generator, over, truth_dir=truth_dir, progress=prog)
    print(f"wrote {len(design)} sites ({args.generator} generator) to {out} (truth in {truth_dir})")
    return 0


def _cmd_predict(args) -> int:
    """``predict``: the model file applied to scans (docs/prediction.md): a summary line per scan, the tables to
    ``-o`` (DFT per scan and speed) and ``<OUT stem>_ifi.csv`` (F60, Sp per scan)."""
    from .prediction import load_model, summary_lines
    from .prediction.run import predict_scans, scan_paths, write_predictions
    from .runlog import Progress

    model = load_model(args.model)
    n = len(scan_paths(args.scans))
    prog = Progress(n, "scans", log, every_s=10.0) if n > 1 else None
    dft, ifi = predict_scans(
        model,
        args.scans,
        args.level,
        jobs=args.jobs,
        temperature_c=args.temperature_c,
        sites_csv=args.sites,
        progress=prog,
    )
    for line in summary_lines(dft, ifi):
        print(line)
    if args.out:
        for path in write_predictions(dft, ifi, args.out):
            print(f"wrote {path}")
    flagged = ifi[ifi["status"] != "ok"]
    if len(flagged):
        log.warning("%d of %d scans flagged or refused (column status, reason)", len(flagged), len(ifi))
    return 0


def _add_mpd_parser(sub, mpd) -> None:
    """The ``mpd`` subcommand; its defaults are those of :class:`~skidsim.texture.mpd.MPDOptions` ``mpd``."""
    m = sub.add_parser(
        "mpd",
        help="mean profile depth (ISO 13473-1:2019, as captif-slp) of a text line profile",
        description="MPD of a line profile: a text file with a header block of any length and "
        "delimited columns of distance and height (in the units the column names state, else the "
        "--distance-unit / --height-unit given, else mm; NaN, empty or non-numeric heights are "
        "dropouts). Prints 'MPD <value> mm, SD <value> mm, <n> valid segments, <n> invalid "
        "segments'.",
    )
    m.add_argument("profile", help="text profile (.csv, .txt, .dat; tab, ';', ',' or space delimited)")
    m.add_argument("--distance-col", help="distance column: name or 0-based index (default: by name, else 0)")
    m.add_argument("--height-col", help="height column: name or 0-based index (default: by name, else 1)")
    m.add_argument(
        "--distance-unit",
        help="unit of the distances when the column name states none: m, mm, um, ... (default: the name's, else mm)",
    )
    m.add_argument(
        "--height-unit",
        help="unit of the heights when the column name states none: m, mm, um, ... (default: the name's, else mm)",
    )
    m.add_argument(
        "--resample-mm",
        type=float,
        default=mpd.resample_mm,
        help="resampled spacing in mm, at most 1.0 (default: 0.5 mm, or the profile's own spacing up to 1.0 mm)",
    )
    m.add_argument(
        "--evaluation-length-m",
        type=float,
        default=mpd.evaluation_length_m,
        help="evaluation length in m of a network run (captif-slp's option): 174.2 mm high-pass, no slope "
        "removal per segment, one MPD per length",
    )
    m.add_argument(
        "--spike-alpha",
        type=float,
        default=mpd.spike_alpha,
        help="spike threshold factor: a step >= alpha x the resampled spacing is a spike (ISO 13473-1; "
        "default %(default)s)",
    )
    m.add_argument(
        "--detect-plates",
        action="store_true",
        help="exclude reference plates at the ends of the run (heights above --plate-threshold-mm)",
    )
    m.add_argument(
        "--plate-threshold-mm",
        type=float,
        default=mpd.plate_threshold_mm,
        help="plate height threshold in mm (default %(default)s)",
    )
    m.add_argument(
        "--segment-mm", type=float, default=mpd.segment_mm, help="segment length in mm (default %(default)s)"
    )
    m.add_argument(
        "--max-dropout-pct",
        type=float,
        default=mpd.max_dropout_pct,
        help="a segment with more dropouts than this %% is invalid (default %(default)s)",
    )
    m.add_argument("-o", "--output", help="write each segment (start, end, MSD, dropouts, spikes, valid) to CSV")
    m.set_defaults(func=_cmd_mpd)


def build_parser() -> argparse.ArgumentParser:
    # One home per default: options that mirror a library option take its default (tests/test_defaults.py).
    from .reconstruct import MeshOptions
    from .solver.config import SolverOptions
    from .texture.mpd import MPDOptions
    from .texture.parameters import TextureOptions

    tex, mpd, mesh, solver = TextureOptions(), MPDOptions(), MeshOptions(), SolverOptions()
    p = argparse.ArgumentParser(
        prog="skidsim",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__,
    )
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="more log output, and the Python traceback of an error (also SKIDSIM_DEBUG=1)",
    )
    sub = p.add_subparsers(dest="command", required=True)

    v = sub.add_parser("validate", help="check a campaign directory against the data contract")
    v.add_argument("campaign", help="directory holding sites.csv")
    v.add_argument(
        "--configfile",
        action="append",
        metavar="YAML",
        help="workflow config file(s) whose speeds, strip, texture band and ingest keys to check against "
        "(repeatable, merged in order over the defaults of config/config.yaml)",
    )
    v.add_argument(
        "--speeds",
        type=float,
        nargs="+",
        help="speeds in km/h every DFT trace must cover (default: the config's calibration and "
        "validation speeds, 20..70)",
    )
    v.add_argument(
        "--level",
        "--check-scans",
        dest="level",
        choices=["full", "header", "table"],
        default="full",
        help="full (default): decode every scan (checksums, valid share, heights); header: scan "
        "headers only (spacing, extent, Z increment); table: sites.csv, paths and DFT traces only",
    )
    v.add_argument("--allow-outside", action="store_true", help="accept scan/DFT paths outside the campaign directory")
    v.set_defaults(func=_cmd_validate)

    t = sub.add_parser("texture", help="areal texture parameters of one scan (raw, macro, micro) and MPD")
    t.add_argument("scan", help="X3P or grid text scan")
    t.add_argument("-o", "--output", help="write the long table to .parquet or .csv")
    t.add_argument(
        "--despeckle",
        choices=["local", "mad", "tukey", "study"],
        default=tex.despeckle_method,
        help="despeckle rule (default local: isolated 2-D outliers, right on flat-binder scans; mad and "
        "tukey: per-row fences; study = the literal limiting filter)",
    )
    t.add_argument(
        "--macro-mm",
        type=float,
        nargs=2,
        default=list(tex.macro_mm),
        metavar=("LOW", "HIGH"),
        help="macrotexture wavelength band in mm (default %(default)s)",
    )
    t.add_argument("-q", "--quiet", action="store_true", help="do not print the table")
    t.set_defaults(func=_cmd_texture)

    _add_mpd_parser(sub, mpd)

    s = sub.add_parser("simulate", help="one FE simulation of the DFT slider on a scan")
    s.add_argument("scan")
    s.add_argument("--speed", type=float, required=True, help="sliding speed in km/h")
    s.add_argument("--mu-s", type=float, required=True, help="static friction coefficient")
    s.add_argument("--mu-k", type=float, required=True, help="kinetic friction coefficient")
    s.add_argument("--alpha", type=float, required=True, help="decay coefficient in s/m")
    s.add_argument("--preset", choices=["campaign", "reference", "quick"], default=solver.preset)
    s.add_argument("--load-n", type=float, default=solver.load_n, help="normal load in N (default %(default)s)")
    s.add_argument("--resolution-mm", type=float, default=mesh.resolution_mm, help="pavement FE resolution in mm")
    s.add_argument(
        "--length-mm",
        type=_strip_length,
        default=mesh.length_mm,
        help="pavement strip length in mm (default %(default)s), or auto: the scan's length up to %(default)s mm",
    )
    s.add_argument("--trace", help="write the force trace to this parquet file")
    s.add_argument("--vtu", help="write a decimated VTU series of the slider into this directory")
    s.set_defaults(func=_cmd_simulate)

    g = sub.add_parser("synth", help="generate a synthetic campaign directory")
    g.add_argument("out_dir")
    g.add_argument("--sites", type=int, help="only the first N sites of the design")
    g.add_argument("--seed", type=int, help="random seed (default: the generator's own)")
    g.add_argument("--shape", type=int, nargs=2, metavar=("ROWS", "COLS"), help="scan size in points")
    g.add_argument("--spacing-mm", type=float, help="lateral spacing in mm")
    g.add_argument("--truth-dir", help="where the ground truth goes (default: OUT_DIR-truth beside it)")
    g.add_argument(
        "--generator",
        choices=["default", "chips", "spectral"],
        default="default",
        help="default: skidsim.generators.default (the study-like campaign); chips, spectral: the independent "
        "generators of skidsim.generators (docs/synthetic-campaign.md)",
    )
    g.set_defaults(func=_cmd_synth)

    r = sub.add_parser("predict", help="friction of scans without DFT from a model file (docs/prediction.md)")
    r.add_argument("model", help="model file (results/prediction/model.json)")
    r.add_argument("scans", nargs="+", help="scan files (X3P or grid text) or directories of them")
    r.add_argument("-o", "--out", help="DFT table (CSV, one row per scan and speed); the IFI goes to <stem>_ifi.csv")
    r.add_argument("--level", type=float, default=0.9, help="nominal coverage of the intervals (default 0.9)")
    r.add_argument("--jobs", type=int, default=1, help="scans processed at a time (default 1)")
    r.add_argument("--temperature-c", type=float, help="temperature (deg C) of every scan, for a model that uses it")
    r.add_argument("--sites", help="CSV with site (= scan file stem) and temperature_c (deg C) per scan")
    r.set_defaults(func=_cmd_predict)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand. An error skidsim raises on purpose prints one ``skidsim: error: ...`` block (no
    traceback unless ``-v`` or ``SKIDSIM_DEBUG=1``), exit status 2; Ctrl-C exits with 130 and one line."""
    import os

    args = build_parser().parse_args(argv)
    debug = args.verbose or os.environ.get("SKIDSIM_DEBUG", "") not in ("", "0")
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(message)s",
        stream=sys.stderr,
    )
    try:
        return args.func(args)
    except (SkidsimError, FileNotFoundError) as e:
        if debug:
            import traceback

            traceback.print_exc(file=sys.stderr)
        print(f"skidsim: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"skidsim: interrupted ({args.command}); run the same command again to redo it", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
