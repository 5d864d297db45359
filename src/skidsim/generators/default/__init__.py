"""The embedded default campaign: a deterministic synthetic LTPP SPS-10-like field campaign.

When the user gives no campaign, the workflow designs the campaign (:func:`design_campaign`, cheap), generates
each site (:func:`generate_site`: an LS-40-like texture scan and a DFT spin-down trace from the documented truth
model of :mod:`skidsim.generators.truth`), writes it (:func:`write_site`) and writes
``sites.csv`` (:func:`write_sites_csv`).
The rest of the pipeline treats the result exactly like measured data. See ``docs/synthetic-campaign.md``.

One module per idea:

* :mod:`.config`: every generator setting with its default (study Table 1's section designs, the aggregate
  components and gradations), :func:`default_config` and :func:`resolve_config`;
* :mod:`.design`: the campaign's site table, :func:`design_campaign`;
* :mod:`.surface`: the surface of a site (stones, mastic, microtexture, :func:`micro_field`,
  :func:`synthesize_surface`) and the scanner's artefacts; the conventions that change numbers are its docstring;
* :mod:`.site`: one site (:class:`SiteData`, :func:`generate_site`) and the files (:func:`write_site`,
  :func:`write_sites_csv`).
"""

from .config import COMPONENTS, DEFAULTS, GRADATIONS, SECTION_DESIGNS, default_config, resolve_config
from .design import METADATA_COLUMNS, design_campaign
from .site import SiteData, generate_site, write_site, write_sites_csv
from .surface import micro_field, synthesize_surface

__all__ = [
    "COMPONENTS",
    "DEFAULTS",
    "GRADATIONS",
    "METADATA_COLUMNS",
    "SECTION_DESIGNS",
    "SiteData",
    "default_config",
    "design_campaign",
    "generate_site",
    "micro_field",
    "resolve_config",
    "synthesize_surface",
    "write_site",
    "write_sites_csv",
]
