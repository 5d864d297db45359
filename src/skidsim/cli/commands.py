"""The subcommands of ``skidsim`` (:mod:`skidsim.cli`): each reads its arguments, calls the library and writes
its output at the end (nothing half-written)."""

from __future__ import annotations

import logging
import sys
import time
from pathlib import Path

from ..atomic import atomic_path

log = logging.getLogger("skidsim")


def _cmd_validate(args) -> int:
    import yaml

    from .. import validate
    from ..config import merged

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

    from .. import texture
    from ..scans import read_scan

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
    from ..profiles import ProfileFormatError, read_profile
    from ..texture.mpd import MPDOptions, SpacingError, evaluation_lengths, profile_segments, summarise

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


def _cmd_simulate(args) -> int:
    from .. import texture
    from ..config import solver_config
    from ..friction import ExponentialDecay
    from ..reconstruct import pavement_strip
    from ..runlog import Progress
    from ..scans import read_scan
    from ..solver import simulate

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
    from ..config import merged
    from ..generators import default as synthetic
    from ..runlog import Progress

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
    from .. import generators
    from ..runlog import Progress

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
    from ..prediction import load_model, summary_lines
    from ..prediction.run import predict_scans, scan_paths, write_predictions
    from ..runlog import Progress

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
