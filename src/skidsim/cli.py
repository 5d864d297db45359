"""The ``skidsim`` command: work without Snakemake.

    skidsim validate CAMPAIGN_DIR                 check a campaign against the data contract
    skidsim texture SCAN [-o OUT.parquet|.csv]    areal parameters of one scan (raw, macro, micro) and MPD
    skidsim simulate SCAN --speed 40 --mu-s .. --mu-k .. --alpha ..   one FE simulation: SN, trace, VTU
    skidsim synth OUT_DIR [--sites N]             write a synthetic campaign (scans, DFT, sites.csv, truth)
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from .errors import SkidsimError

log = logging.getLogger("skidsim")


def _cmd_validate(args) -> int:
    from .campaign import load_campaign

    camp = load_campaign(args.campaign, speeds_kmh=args.speeds, check_scans=args.check_scans)
    sites = camp.sites
    print(f"{args.campaign}: OK, {len(sites)} sites in {sites['section'].nunique()} sections")
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
        if out.suffix == ".csv":
            table.to_csv(out, index=False)
        else:
            table.to_parquet(out, index=False)
        print(f"wrote {out}")
    if not args.quiet:
        wide = table.pivot_table(index=["parameter", "unit"], columns="band", values="value", aggfunc="first")
        with pd.option_context("display.max_rows", 500, "display.width", 120, "display.float_format", "{:.5g}".format):
            print(wide)
    return 0


def _cmd_simulate(args) -> int:
    from . import texture
    from .friction import ExponentialDecay
    from .reconstruct import pavement_strip
    from .runlog import Progress
    from .scans import read_scan
    from .solver import simulate
    from .workflow_support import solver_config

    surface = read_scan(args.scan)
    clean, _ = texture.despeckle(surface, method="mad")
    clean = texture.fill_invalid(clean)
    pav = pavement_strip(clean, resolution_mm=args.resolution_mm)
    cfg = solver_config({"preset": args.preset, "load_n": args.load_n, "overrides": {}})
    law = ExponentialDecay(args.mu_s, args.mu_k, args.alpha)
    res = simulate(pav, args.speed, law, cfg, trace_path=args.trace, vtu_dir=args.vtu,
                   progress=Progress(1, f"simulate {args.speed} km/h", log))
    print(f"SN = {res.sn:.4f} at {args.speed} km/h (mu({args.speed} km/h) = {float(law.mu_kmh(args.speed)):.4f}); "
          f"{res.n_steps} steps of {res.dt_s * 1e6:.3f} us in {res.wall_s:.1f} s")
    return 0


def _cmd_synth(args) -> int:
    from . import synthetic
    from .runlog import Progress
    from .workflow_support import merged

    cfg = synthetic.default_config()
    over = {"seed": args.seed}
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
        synthetic.write_site(data, out / "scans" / f"{row['site']}.x3p", out / "dft" / f"{row['site']}.csv",
                             truth_dir / f"{row['site']}.json")
        prog(n)
    synthetic.write_sites_csv(design, out, out / "sites.csv")
    print(f"wrote {len(design)} sites to {out} (truth in {truth_dir})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="skidsim", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    p.add_argument("-v", "--verbose", action="store_true", help="more log output")
    sub = p.add_subparsers(dest="command", required=True)

    v = sub.add_parser("validate", help="check a campaign directory against the data contract")
    v.add_argument("campaign", help="directory holding sites.csv")
    v.add_argument("--speeds", type=float, nargs="+", default=[20, 30, 40, 50, 60, 70],
                   help="speeds in km/h every DFT trace must cover (default 20..70)")
    v.add_argument("--check-scans", choices=["header", "full"], default="header",
                   help="header: checksum and size of each scan; full: decode each scan")
    v.set_defaults(func=_cmd_validate)

    t = sub.add_parser("texture", help="areal texture parameters of one scan (raw, macro, micro) and MPD")
    t.add_argument("scan", help="X3P or grid text scan")
    t.add_argument("-o", "--output", help="write the long table to .parquet or .csv")
    t.add_argument("--despeckle", choices=["mad", "tukey", "study"], default="mad",
                   help="despeckle fences (default mad; study = the literal limiting filter)")
    t.add_argument("--macro-mm", type=float, nargs=2, default=[0.5, 50.0], metavar=("LOW", "HIGH"),
                   help="macrotexture wavelength band in mm (default 0.5 50)")
    t.add_argument("-q", "--quiet", action="store_true", help="do not print the table")
    t.set_defaults(func=_cmd_texture)

    s = sub.add_parser("simulate", help="one FE simulation of the DFT slider on a scan")
    s.add_argument("scan")
    s.add_argument("--speed", type=float, required=True, help="sliding speed in km/h")
    s.add_argument("--mu-s", type=float, required=True, help="static friction coefficient")
    s.add_argument("--mu-k", type=float, required=True, help="kinetic friction coefficient")
    s.add_argument("--alpha", type=float, required=True, help="decay coefficient in s/m")
    s.add_argument("--preset", choices=["campaign", "reference", "quick"], default="campaign")
    s.add_argument("--load-n", type=float, default=11.8, help="normal load in N (default 11.8)")
    s.add_argument("--resolution-mm", type=float, default=0.5, help="pavement FE resolution in mm")
    s.add_argument("--trace", help="write the force trace to this parquet file")
    s.add_argument("--vtu", help="write a decimated VTU series of the slider into this directory")
    s.set_defaults(func=_cmd_simulate)

    g = sub.add_parser("synth", help="generate a synthetic campaign directory")
    g.add_argument("out_dir")
    g.add_argument("--sites", type=int, help="only the first N sites of the design")
    g.add_argument("--seed", type=int, default=20170117)
    g.add_argument("--shape", type=int, nargs=2, metavar=("ROWS", "COLS"), help="scan size in points")
    g.add_argument("--spacing-mm", type=float, help="lateral spacing in mm")
    g.add_argument("--truth-dir", help="where the ground truth goes (default: OUT_DIR-truth beside it)")
    g.set_defaults(func=_cmd_synth)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(asctime)s %(levelname)s %(message)s", stream=sys.stderr)
    try:
        return args.func(args)
    except SkidsimError as e:
        print(f"skidsim: error: {e}", file=sys.stderr)
        return 2
    except FileNotFoundError as e:
        print(f"skidsim: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
