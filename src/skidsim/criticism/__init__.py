"""Model criticism: where the simulation is systematically wrong, why, a model extension and its measured gain.

The modules follow the path of the data (docs/model-criticism.md describes every convention):

* :mod:`.options` -- :class:`DiagnosisOptions`, the config ``diagnosis:`` section;
* :mod:`.inputs` -- :class:`DiagnosisInputs` from the workflow's tables (g(v), between-site predictions);
* :mod:`.residuals` -- residuals ``measured - model`` within sites (calibrated simulation) and between sites
  (texture-based predictions of held-out sites), and their site x speed-bin matrices;
* :mod:`.covariates` -- the candidate causes (sites.csv columns, texture parameters, their clusters and PCs);
* :mod:`.adjustment`, :mod:`.crossval`, :mod:`.permutations` -- designs, cross-validated SSE, permutations;
* :mod:`.screening` -- every candidate tested at every level; :mod:`.fdr` -- false-discovery control;
* :mod:`.levels` -- what the tests of one level share (its residual matrix, candidates, permutations) and the
  record of one test;
* :mod:`.texture_candidate` -- the texture model as a candidate cause (richer texture models tested as one unit)
  and the share of the section effect a candidate explains; :mod:`.texture_tests` -- their tests, and the
  texture columns beyond the prediction model's terms;
* :mod:`.section_tests` -- the section effect left beyond a column and beyond the texture model;
* :mod:`.causes` -- :class:`Cause` records, their labels and categories;
* :mod:`.section_naming` -- the naming rule of a section effect (:func:`section_rule`); :mod:`.refinement` --
  parsimony between nested section-level groupings; :mod:`.ranking` -- the ranking that names the top cause;
* :mod:`.extensions` -- the physical and generic extensions and the choice for a named cause;
* :mod:`.scopes`, :mod:`.recalibration`, :mod:`.gain` -- cross-fitting on held-out speeds and sites, bootstrap
  gain; :mod:`.fe_extension` -- the viscoelastic FE extension; :mod:`.report` -- the output files.

The entry point is :func:`diagnose`. Units: speeds km/h, residuals in friction units (mu, dimensionless),
temperatures deg C, MPD mm. The analysis reads only campaign-level tables (never a truth file).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import pandas as pd

from .adjustment import added_variable, texture_model_scores
from .calibration_groups import settled_residuals
from .causes import CATEGORIES, MISFIT_CORRELATE, SECTION_UNEXPLAINED, TEXTURE_MISFIT, Cause
from .covariates import (
    DEFAULT_EXCLUDE,
    CandidateRoles,
    find_mpd_column,
    site_covariates,
    texture_clusters,
    untested_columns,
)
from .extensions import CovariateTerm, ExtendedModel, apply_extension
from .fdr import adjust_pvalues, auto_permutations
from .gain import add_calibration_groups, baseline_gain, evaluate_extension, measure_gain
from .inputs import DiagnosisInputs, read_workflow_inputs
from .options import DiagnosisOptions
from .ranking import named_cause
from .refinement import order_by_refinement, refines
from .report import write_outputs
from .residuals import LEVELS, build_residuals
from .screening import screen_candidates
from .section_naming import SECTION_SHARE_MIN, section_rule
from .texture_candidate import is_texture_model, texture_model_term
from .texture_tests import column_beyond_lead

__all__ = [
    "DiagnosisInputs",
    "DiagnosisOptions",
    "DiagnosisResult",
    "CandidateRoles",
    "Cause",
    "ExtendedModel",
    "diagnose",
    "build_residuals",
    "screen_candidates",
    "named_cause",
    "apply_extension",
    "evaluate_extension",
    "measure_gain",
    "write_outputs",
    "read_workflow_inputs",
    "site_covariates",
    "untested_columns",
    "adjust_pvalues",
    "auto_permutations",
    "order_by_refinement",
    "refines",
    "find_mpd_column",
    "texture_clusters",
    "added_variable",
    "texture_model_scores",
    "texture_model_term",
    "is_texture_model",
    "section_rule",
    "SECTION_SHARE_MIN",
    "CATEGORIES",
    "SECTION_UNEXPLAINED",
    "TEXTURE_MISFIT",
    "MISFIT_CORRELATE",
    "LEVELS",
    "DEFAULT_EXCLUDE",
]


@dataclass
class DiagnosisResult:
    """Everything :func:`diagnose` found: residual table, ranked causes, the named cause (or None), the gain dict
    (gain.json), held-out predictions before/after per scope, the candidate covariates per site, the
    added-variable data of a texture-adjusted named cause and the sites.csv columns not tested ({column: why})."""

    residuals: pd.DataFrame
    causes: list
    named: Cause | None
    gain: dict
    predictions: pd.DataFrame  # held-out rows: scope, site, speed_kmh, kind, measured, before, after
    covariates: pd.DataFrame = field(default_factory=pd.DataFrame)
    added_variable: pd.DataFrame = field(default_factory=pd.DataFrame)  # site, covariate_adj, measured_adj
    untested: dict = field(default_factory=dict)


def _beyond_lead_texture(top, residuals, cov, texture, lead, options) -> pd.DataFrame | None:
    """The texture table for the extension of a texture column named between sites: the column replaced by its
    part beyond the prediction model's terms (:func:`~skidsim.criticism.texture_tests.column_beyond_lead`), which is
    what the screening tested, at every site of the table; else the table as it is."""
    if (
        texture is None
        or top.source != "texture"
        or top.level != "between-site"
        or top.dtype != "numeric"
        or top.variable not in texture.columns
    ):
        return texture
    z = column_beyond_lead(residuals, cov, top.variable, lead, options)
    if z is None:
        return texture
    values = texture["site"].astype(str).map(z)
    if values.isna().any():
        return texture
    return texture.assign(**{top.variable: values.to_numpy(float)})


def diagnose(
    inputs: DiagnosisInputs, options: DiagnosisOptions | None = None, roles: CandidateRoles | None = None
) -> DiagnosisResult:
    """The whole diagnosis on campaign-level tables: residuals, screening, extension for the named cause,
    cross-fitted gain. With no named cause, ``gain`` holds the baseline RMSE/R^2 (after = before). ``roles``:
    which columns are candidates and which carry the temperature and MPD hypotheses (None: the defaults of
    :class:`DiagnosisOptions` and :class:`CandidateRoles`)."""
    options = DiagnosisOptions() if options is None else options
    roles = CandidateRoles() if roles is None else roles
    sites, texture, bin_kmh = inputs.sites, inputs.texture, options.speed_bin_kmh
    res_all = build_residuals(sites, inputs.measured, inputs.simulated, inputs.predicted)
    res, left_out = res_all, None
    if options.within_site_sites == "settled" and inputs.calibration is not None:
        res, left_out = settled_residuals(res_all, inputs.calibration)
    record = {}
    if left_out is not None:
        n_within = int(res.loc[res["level"] == "within-site", "site"].nunique())
        record = {"within_site_left_out": left_out, "within_site_sites_tested": n_within}
    # one texture model (the prediction model's columns when they predict better, then PCs) for all steps
    pcs, texture_model = texture_model_scores(
        res, sites, texture, bin_kmh, roles.exclude, lead=inputs.prediction_features
    )
    texture_model = {"prediction_model": inputs.prediction_model, **texture_model}
    causes = screen_candidates(
        res,
        sites,
        texture,
        options,
        roles,
        texture_pc_scores=pcs,
        texture_lead=inputs.prediction_features,
        shape_residuals=res_all,
    )
    top = named_cause(causes)
    cov, _ = site_covariates(sites, texture, exclude=roles.exclude)
    untested = untested_columns(sites, texture, exclude=roles.exclude)
    if top is None:
        gain, preds = baseline_gain(res, options)
        gain = {**gain, "texture_model": texture_model, **record}
        return DiagnosisResult(res, causes, top, gain, preds, cov, pd.DataFrame(), untested)
    term = texture_model_term(top, res, sites, texture, pcs, inputs.prediction_features, roles, bin_kmh)
    model = apply_extension(top, sites, texture, speed_bin_kmh=bin_kmh, exclude=roles.exclude, texture_design=term)
    if isinstance(model.extension, CovariateTerm) and model.fallback is None:  # not a physical extension (IFI, WLF)
        texture = _beyond_lead_texture(top, res, cov, texture, inputs.prediction_features, options)
    if term is not None:  # the figures plot the residual against the member's first column (its standardised axis)
        cov = cov.join(pd.Series([r[0] for r in term.design], index=list(term.sites), name=top.variable))
    gain, preds = evaluate_extension(
        model,
        res,
        sites,
        texture,
        options,
        texture_pc_scores=pcs,
        exclude=roles.exclude,
        measured=inputs.measured,
    )
    if "curve_form" in gain:  # which sites carry the shape: every site, tested or not
        add_calibration_groups(gain["curve_form"], res_all, inputs.calibration, options)
    av = added_variable(res, sites, texture, top, bin_kmh, roles.exclude, texture_pc_scores=pcs)
    gain = {**gain, "texture_model": texture_model, **record}
    return DiagnosisResult(res, causes, top, gain, preds, cov, av, untested)
