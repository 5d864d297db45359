# Site table, input functions, config validation and wildcard constraints shared by every rule file.
import re
import sys
from pathlib import Path

import pandas as pd
from snakemake.utils import validate

sys.path.insert(0, str(Path(workflow.basedir) / "src"))  # the library, also without `pip install -e .`

validate(config, schema="../schemas/config.schema.yaml")

from skidsim.config import plan_check, site_table  # noqa: E402

RESULTS = "results"
SYNTHETIC = not config.get("campaign")
if SYNTHETIC:
    CAMPAIGN_DIR = Path(RESULTS) / "campaign"
else:
    CAMPAIGN_DIR = Path(config["campaign"])
SITES_CSV = str(CAMPAIGN_DIR / "sites.csv")

# Before any plan is built: the config cross-checks and, for a user campaign, sites.csv, its paths and the DFT
# traces (skidsim.validate, level "table"). Problems are printed once, one per line, and the run stops (also
# `snakemake -n`). The scan contents are checked by the rule validate_campaign, on which every analysis rule
# depends.
plan_check(config, CAMPAIGN_DIR if not SYNTHETIC else None)

# The site table is known when the workflow is parsed: designed from config for the synthetic campaign, read
# from the user's sites.csv otherwise.
SITE_TABLE = site_table(config, CAMPAIGN_DIR if not SYNTHETIC else None)
SITES = list(SITE_TABLE["site"])
SECTIONS = list(dict.fromkeys(SITE_TABLE["section"]))
SECTION_OF = dict(zip(SITE_TABLE["site"], SITE_TABLE["section"]))
METHODS = list(config["calibration"]["methods"])


def scan_of(wildcards):
    """The scan file of a site: from the synthetic generator or from the user's sites.csv."""
    if SYNTHETIC:
        return f"{RESULTS}/campaign/scans/{wildcards.site}.x3p"
    return str(CAMPAIGN_DIR / SITE_TABLE.set_index("site").loc[wildcards.site, "scan"])


def dft_of(wildcards):
    """The DFT trace of a site."""
    if SYNTHETIC:
        return f"{RESULTS}/campaign/dft/{wildcards.site}.csv"
    return str(CAMPAIGN_DIR / SITE_TABLE.set_index("site").loc[wildcards.site, "dft"])


def rule_id(name):
    """A site or section id for use in a target name (letters, digits and _ kept; any other character becomes _)."""
    return re.sub(r"\W", "_", name)


def sites_of_section(section):
    return [s for s in SITES if SECTION_OF[s] == section]


def site_outputs(site):
    """Every per-site product (texture, mesh, calibrations, validation)."""
    d = f"{RESULTS}/sites/{site}"
    return [
        f"{d}/texture.parquet",
        f"{d}/mpd.json",
        f"{d}/figure7.png",
        f"{d}/pavement.npz",
        f"{d}/fe_model.png",
        f"{d}/validation.parquet",
    ] + [f"{d}/calibration_{m}.json" for m in METHODS]


def campaign_inputs(wildcards):
    if SYNTHETIC:
        return {
            "sites": SITES_CSV,
            "scans": expand(f"{RESULTS}/campaign/scans/{{site}}.x3p", site=SITES),
            "dfts": expand(f"{RESULTS}/campaign/dft/{{site}}.csv", site=SITES),
        }
    return {"sites": SITES_CSV}


INGEST = f"{RESULTS}/ingest/sites.parquet"

# Our calibration learns the FE surrogate's starting state (geometric factor, slip offsets) on a few reference
# sites spread over the table, calibrated without a prior; every other site starts from their median
# (skidsim.calibration.surrogate_prior, docs/calibration.md).
from skidsim.calibration import prior_reference_sites  # noqa: E402

PRIOR_SITES = (
    prior_reference_sites(SITES, int(config["calibration"]["ours"].get("prior_sites", 3)))
    if config["calibration"]["ours"].get("model", "slip") == "slip"
    else []
)


def calibration_prior_of(wildcards):
    """The reference calibrations a site's fit starts from: none for the study's method and the reference sites."""
    if wildcards.method != "ours" or wildcards.site in PRIOR_SITES or not PRIOR_SITES:
        return []
    return [f"{RESULTS}/sites/{s}/calibration_ours.json" for s in PRIOR_SITES]
