"""The argument parser of ``skidsim`` (:mod:`skidsim.cli`); options that mirror a library option take its
default."""

from __future__ import annotations

import argparse
import sys

from .commands import (
    _cmd_mpd,
    _cmd_predict,
    _cmd_simulate,
    _cmd_synth,
    _cmd_texture,
    _cmd_validate,
)


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
    from ..reconstruct import MeshOptions
    from ..solver.config import SolverOptions
    from ..texture.mpd import MPDOptions
    from ..texture.parameters import TextureOptions

    tex, mpd, mesh, solver = TextureOptions(), MPDOptions(), MeshOptions(), SolverOptions()
    usage = sys.modules[__package__].__doc__  # skidsim.cli's docstring: the command's synopsis
    p = argparse.ArgumentParser(
        prog="skidsim",
        description=usage.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=usage,
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
