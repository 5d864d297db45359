"""Snakemake adapter: model criticism (residuals, candidate causes, extension for the named cause, gain); the
library (skidsim.criticism) builds the inputs from the workflow's tables, never from results/truth/."""

from pathlib import Path

from skidsim import criticism
from skidsim.plotting.diagnosis import diagnosis_figures
from skidsim.runlog import setup_logging

log = setup_logging(snakemake.log[0])
options = criticism.DiagnosisOptions.from_config(snakemake.params.cfg)
inputs = criticism.read_workflow_inputs(
    snakemake.input,
    snakemake.params.calibration_method,
    snakemake.params.calibration_speeds,
    snakemake.params.validation_speeds,
)
log.info(
    "diagnosis: %d measured points, %d sites, between-site predictions from model %s",
    len(inputs.measured),
    len(inputs.sites),
    inputs.prediction_model,
)
result = criticism.diagnose(inputs, options)
figs = diagnosis_figures(result, snakemake.output.figures)
criticism.write_outputs(
    Path(snakemake.output.causes).parent, result.residuals, result.causes, result.gain, figs, untested=result.untested
)
for column, why in result.untested.items():  # too few values is worth a warning; constants and identifiers are not
    (log.warning if why.startswith("values at") else log.info)(
        "sites.csv column %s not tested as a cause: %s", column, why
    )
top = result.named
log.info(
    "named cause: %s",
    None
    if top is None
    else f"{top.variable}{' = ' + top.label if top.label else ''} ({top.level}, p_adj={top.p_adjusted:.3g})",
)
