"""One validation of a campaign and its configuration, used by ``skidsim validate``, by the workflow when it
builds its plan (``workflow/rules/common.smk``) and by its first rule (``validate_campaign``).

Every check returns problems, never stops at the first one: each problem is a :class:`~skidsim.errors.InputError`
naming the file, the row or field, what was expected and what was found. :func:`check_campaign` gathers them
and raises one :class:`~skidsim.errors.CampaignError` listing all of them (``err.errors``).

Levels (cheapest first; each includes the ones before it):

* ``table``: ``sites.csv`` (columns, ids safe for file names, unique ids, temperatures), every path inside the
  campaign directory (unless allowed), every named file exists, the DFT traces (read in full: they are small)
  covering every calibration and validation speed, config cross-checks. No scan is opened. The workflow runs
  this level when it builds its plan.
* ``header``: plus DFT samples at 2 speeds within the smoothing window of each speed; each scan's header: X3P
  archive, checksum of main.xml, data sizes, a Z increment for integer codes; spacing and extent against the strip
  and the texture band. Text grids are read in full.
* ``full`` (default): plus every scan decoded: MD5 of data.bin and valid.bin, share of valid points, height span.
  About 0.2-0.4 s per LS-40 scan (2048 x 2448 points).

What the configuration asks of the data is a :class:`Requirements`, built from the workflow's config mapping
(:meth:`Requirements.from_config`) or left at the defaults, which are those of the options dataclass of each config
section (:class:`SpeedOptions`, :class:`IngestOptions`, :class:`~skidsim.reconstruct.MeshOptions`,
:class:`~skidsim.texture.TextureOptions`, :class:`~skidsim.solver.mesh_study.MeshStudyOptions`);
``tests/test_defaults.py`` keeps ``config/config.yaml`` and the schema equal to them.
"""

from __future__ import annotations

from .campaign_checks import (
    ConfigProblem,
    check_campaign,
    check_config,
    check_plan,
    check_table,
    format_problems,
    problems,
    summary_error,
)
from .requirements import CHECK_SCANS_LEVEL, CONFIG, LEVELS, IngestOptions, Requirements, SpeedOptions
from .scan_checks import check_geometry, check_relief, check_scan

__all__ = [
    "CHECK_SCANS_LEVEL",
    "CONFIG",
    "LEVELS",
    "ConfigProblem",
    "IngestOptions",
    "Requirements",
    "SpeedOptions",
    "check_campaign",
    "check_config",
    "check_geometry",
    "check_plan",
    "check_relief",
    "check_scan",
    "check_table",
    "format_problems",
    "problems",
    "summary_error",
]
