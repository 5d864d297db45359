"""Texture-to-friction regression: the study's PCA regression (Tables 5, 6, Figure 11) and honest alternatives.

The study (section 7) regressed each exponential-decay parameter (``mu_s``, ``mu_k`` dimensionless; ``alpha`` in
s/m, see :mod:`skidsim.friction`) on principal components of the standardised texture parameters (all bands) and
temperature, on 27 randomly chosen sites, and judged the fit on those same 27 sites. This package reproduces that
analysis and adds what it lacked: leave-one-section-out cross-validation of PCA regression against ridge,
partial least squares, lasso, a two-variable model (``profile_MPD``, ``micro_Sq``) and an intercept-only baseline,
on each parameter and on the DFT curves they imply; models of what the data identify (``<model>@curve``: the
calibrated laws' values at 20/40/60 km/h; ``<model>@dft``: the measured DFT at the prediction speeds); the simple
baseline ``ols2@dft`` (OLS of the DFT curve on at most two texture columns chosen by inner CV); and the
prediction-skill table that sets every model beside the intercept-only ``mean@dft`` and that baseline, with a
WARNING when the chosen model does not beat both.

Modules, each with the conventions that change its numbers (also in ``docs/regression.md``):

* :mod:`.design`: feature columns and :class:`Design` (:func:`assemble_design`);
* :mod:`.standardiser`: NaN and constant columns, standardisation (:class:`Standardiser`);
* :mod:`.splits`: the train/test split (:func:`split_sites`, the workflow's :func:`regression_split`) and the inner
  CV folds (:func:`inner_splits`);
* :mod:`.paths`: ridge, lasso, PLS paths and their choice by inner CV (one-standard-error rule);
* :mod:`.pca`: the PCA regression, Tables 5 and 6 (:func:`fit_pca_regression`);
* :mod:`.subset`: the ``ols2`` baseline (:func:`fit_subset_ols`);
* :mod:`.physics`: ``physics2``, OLS on MPD and micro Sq, identity or log form by inner CV (:func:`fit_physics_ols`);
* :mod:`.models`: every model by name (:func:`fit_model`);
* :mod:`.targets`: curve and DFT targets, the predicted DFT (:func:`predict_dft`);
* :mod:`.prediction`: predictions of held-out sites by model name (:func:`predict_parameters`);
* :mod:`.figure11`: Figure 11's error tables;
* :mod:`.validation`: the leave-one-section-out CV and its scores (:func:`cross_validate_models`);
* :mod:`.selection`: the best model (:func:`rank_models`);
* :mod:`.skill`: the prediction-skill table (:func:`prediction_skill`);
* :mod:`.capture`: what a texture model predicts of a hidden effect at unseen sections (:func:`effect_capture`);
* :mod:`.options`: :class:`RegressionOptions`, the config's ``regression:`` section;
* :mod:`.analysis`: the workflow's whole stage (:func:`run_analysis`, :func:`write_analysis`).
"""

from .analysis import RegressionAnalysis, run_analysis, write_analysis
from .capture import capture_tables, effect_capture, section_cv_predictions
from .design import (
    BANDS,
    PARAMETERS,
    TEMPERATURE_COLUMN,
    Design,
    assemble_design,
    feature_columns,
    split_band,
    texture_columns,
)
from .figure11 import figure11_summary, figure11_table
from .models import (
    BASE_MODELS,
    CURVE_SUFFIX,
    DEFAULT_MODELS,
    DFT_SUFFIX,
    TWO_VARIABLES,
    FittedModel,
    check_model_name,
    fit_model,
)
from .options import RegressionOptions
from .paths import (
    LASSO_ALPHA_RATIOS,
    LASSO_MAX_ITER,
    LASSO_TOL,
    PLS_MAX_COMPONENTS,
    RIDGE_ALPHAS,
    lasso_path_predictions,
    pls_path_predictions,
    ridge_path_predictions,
    select_on_path,
)
from .pca import (
    PCARegression,
    fit_pca_regression,
    fit_pca_tables,
    parse_rule,
    pcr_path_predictions,
    significance_stars,
    table5,
    table5_statistics,
    table6,
)
from .physics import PHYSICS_COLUMNS, PHYSICS_OLS, PhysicsOLS, fit_physics_ols
from .prediction import predict_parameters, predict_targets
from .selection import CRITERIA, SIMPLICITY, best_model, rank_models
from .skill import BASELINE_MODEL, MEAN_MODEL, baseline_notes, prediction_skill
from .splits import inner_splits, regression_split, split_sites
from .standardiser import MAX_NAN_FRACTION, Standardiser
from .subset import SUBSET_MAX_FEATURES, SUBSET_OLS, SubsetOLS, candidate_subsets, fit_subset_ols, subset_test_sse
from .targets import (
    CURVE_ANCHORS_KMH,
    DEFAULT_SPEEDS_KMH,
    curve_targets,
    dft_column,
    dft_speeds,
    dft_targets,
    g_values,
    law_from_curve,
    law_from_dft,
    predict_dft,
)
from .validation import cross_validate_models, cross_validated_predictions, score_predictions

__all__ = [
    "capture_tables",
    "effect_capture",
    "section_cv_predictions",
    "RegressionAnalysis",
    "run_analysis",
    "write_analysis",
    "BANDS",
    "PARAMETERS",
    "TEMPERATURE_COLUMN",
    "Design",
    "assemble_design",
    "feature_columns",
    "split_band",
    "texture_columns",
    "figure11_summary",
    "figure11_table",
    "BASE_MODELS",
    "CURVE_SUFFIX",
    "DEFAULT_MODELS",
    "DFT_SUFFIX",
    "TWO_VARIABLES",
    "FittedModel",
    "check_model_name",
    "fit_model",
    "RegressionOptions",
    "LASSO_ALPHA_RATIOS",
    "LASSO_MAX_ITER",
    "LASSO_TOL",
    "PLS_MAX_COMPONENTS",
    "RIDGE_ALPHAS",
    "lasso_path_predictions",
    "pls_path_predictions",
    "ridge_path_predictions",
    "select_on_path",
    "PCARegression",
    "fit_pca_regression",
    "fit_pca_tables",
    "parse_rule",
    "pcr_path_predictions",
    "significance_stars",
    "table5",
    "table5_statistics",
    "table6",
    "predict_parameters",
    "predict_targets",
    "CRITERIA",
    "SIMPLICITY",
    "best_model",
    "rank_models",
    "BASELINE_MODEL",
    "MEAN_MODEL",
    "baseline_notes",
    "prediction_skill",
    "inner_splits",
    "regression_split",
    "split_sites",
    "MAX_NAN_FRACTION",
    "Standardiser",
    "SUBSET_MAX_FEATURES",
    "SUBSET_OLS",
    "PHYSICS_OLS",
    "PHYSICS_COLUMNS",
    "PhysicsOLS",
    "fit_physics_ols",
    "SubsetOLS",
    "candidate_subsets",
    "fit_subset_ols",
    "subset_test_sse",
    "CURVE_ANCHORS_KMH",
    "DEFAULT_SPEEDS_KMH",
    "curve_targets",
    "dft_column",
    "dft_speeds",
    "dft_targets",
    "g_values",
    "law_from_curve",
    "law_from_dft",
    "predict_dft",
    "cross_validate_models",
    "cross_validated_predictions",
    "score_predictions",
]
