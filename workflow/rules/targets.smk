import re

from snakemake.logging import logger

# Target rules: everything, one section, one site. Section and site rules are generated from the site table:
#   snakemake --cores 2 section_E1        # the section's sites: texture, meshes, calibrations, validation
#   snakemake --cores 2 site_E1_1         # one site (characters other than letters, digits, _ become _)
# File targets work too, e.g. results/sites/E1-1/calibration_ours.json (docs/workflow.md lists them).


#: The fan-in statistics (regression, cross-validation by section, model criticism) need a population of sites:
#: with fewer sites or sections the workflow stops after texture, meshes, calibration and validation.
MIN_SITES, MIN_SECTIONS = 8, 3
POPULATION = len(SITES) >= MIN_SITES and len(SECTIONS) >= MIN_SECTIONS
if not POPULATION:
    logger.warning(
        f"campaign has {len(SITES)} sites in {len(SECTIONS)} sections: regression and model criticism "
        f"need at least {MIN_SITES} sites in {MIN_SECTIONS} sections and are skipped"
    )


def all_targets():
    targets = [f"{RESULTS}/texture/table4.csv", f"{RESULTS}/calibration/figure10.png"]
    targets += [f"{RESULTS}/ifi/ifi.csv", f"{RESULTS}/ifi/validation.csv"]
    if config["mesh_study"]["sizes_mm"]:
        targets.append(f"{RESULTS}/mesh_study/figure9.png")
    if POPULATION:
        targets += [f"{RESULTS}/regression/figure11.png", f"{DIAG}/causes.json", f"{DIAG}/fe_gain.json"]
        targets += prediction_targets()  # results/prediction/ (prediction.smk)
    if SYNTHETIC:
        targets.append(f"{RESULTS}/truth/campaign.json")
    for s in SITES:
        targets += site_outputs(s)
    targets += list(rules.report_gallery.output)  # the per-site figures as the report shows them
    return targets


for _section in SECTIONS:

    rule:
        name:
            f"section_{rule_id(_section)}"
        input:
            [p for s in sites_of_section(_section) for p in site_outputs(s)],
        localrule: True


for _site in SITES:

    rule:
        name:
            f"site_{rule_id(_site)}"
        input:
            site_outputs(_site),
        localrule: True
