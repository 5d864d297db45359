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

import logging
import sys

from ..errors import SkidsimError
from .parser import build_parser

__all__ = ["build_parser", "main"]


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
