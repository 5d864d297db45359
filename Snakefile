# skidsim: in-situ 3D pavement texture + DFT friction -> calibrated explicit FE skid-resistance simulation.
#
#   snakemake --cores 2                      # everything on the embedded default campaign (or config `campaign`)
#   snakemake --cores 2 section_E1           # one section (texture, meshes, calibrations, validation)
#   snakemake --cores 2 results/sites/E1-1/calibration_ours.json   # one site's output (see docs/workflow.md)
#   snakemake --cores 2 --configfile config/quick.yaml             # quick look (coarse settings, docs/quick.md)
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"


wildcard_constraints:
    site="[A-Za-z0-9][A-Za-z0-9_.-]*",
    section="[A-Za-z0-9][A-Za-z0-9_.-]*",
    method="|".join(METHODS),


include: "workflow/rules/campaign.smk"
include: "workflow/rules/texture.smk"
include: "workflow/rules/mesh.smk"
include: "workflow/rules/solver.smk"
include: "workflow/rules/calibration.smk"
include: "workflow/rules/ifi.smk"
include: "workflow/rules/regression.smk"
include: "workflow/rules/prediction.smk"
include: "workflow/rules/diagnosis.smk"
include: "workflow/rules/fe_extension.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/targets.smk"


rule all:
    default_target: True
    input:
        all_targets(),
    localrule: True


# A failed job's skidsim error (bad input, interrupt) is its script's one line in its log; they are printed once
# more, together, after Snakemake's own report, so the reason is the last thing on the screen.
import time as _time

_STARTED = _time.time()


onerror:
    from skidsim.exit_hooks import cancel_rescheduling_timers
    from skidsim.runlog import failure_report

    cancel_rescheduling_timers()
    failure_report("logs", since=_STARTED - 1.0)


# Snakemake exits at once instead of waiting up to the rate limiter's timespan (profiles/default: 10 s) for its
# last scheduler timer (skidsim.exit_hooks).
onsuccess:
    from skidsim.exit_hooks import cancel_rescheduling_timers

    cancel_rescheduling_timers()
