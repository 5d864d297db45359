"""Snakemake adapter: the study's PCA regression (Tables 5-6) and the cross-validated model comparison."""

from pathlib import Path

import pandas as pd

from skidsim import regression
from skidsim.calibration import geometric_factors
from skidsim.plotting.regression import plot_cv_comparison, plot_prediction_skill, plot_table6
from skidsim.runlog import setup_logging

log = setup_logging(snakemake.log[0])
options = regression.RegressionOptions.from_config(snakemake.params.cfg)
wide = pd.read_parquet(snakemake.input.wide)
params = pd.read_parquet(snakemake.input.params)
friction = params[params["method"] == options.calibration_method][["site", "mu_s", "mu_k", "alpha"]]
design = regression.assemble_design(
    wide, friction, campaign_file=snakemake.input.wide, friction_file=snakemake.input.params
)

# Geometric factor g(v) = SN_sim / mu(v) of every site from its own FE runs (texture-only information).
val = pd.read_parquet(snakemake.input.validation)
g = geometric_factors(val[val["method"] == options.calibration_method], friction)
measured = pd.read_parquet(snakemake.input.dft)[["site", "speed_kmh", "mu"]]

# the workflow's split (known at parse time; smaller campaigns hold out the same share as 9 of 36)
n_train = len(design.X) - len(snakemake.params.test)
analysis = regression.run_analysis(
    design, options, n_train=n_train, g=g, measured_dft=measured, workers=snakemake.threads
)
if sorted(analysis.test_ids) != sorted(snakemake.params.test):
    raise RuntimeError(f"split mismatch: workflow held out {snakemake.params.test}, analysis {analysis.test_ids}")
paths = regression.write_analysis(analysis, Path(snakemake.output.table5).parent)
plot_cv_comparison(analysis.cv_table, snakemake.output.cv_figure)
t6 = analysis.table6
plot_table6(t6[t6["rule"] == options.rule], snakemake.output.table6_figure)
log.info("best model by leave-one-section-out CV: %s", analysis.best)
skill = analysis.skill
plot_prediction_skill(skill, snakemake.output.skill_figure)
log.info(
    "prediction skill (section-grouped CV of the DFT pooled over %s km/h):\n%s",
    list(options.prediction_speeds_kmh),
    skill.drop(columns=["warning"]).to_string(index=False),
)
if skill.attrs["warning"]:
    log.warning("%s (%s)", skill.attrs["warning"], snakemake.output.skill)
