"""Friction for scans that have no DFT: the model file users keep and apply (docs/prediction.md).

One idea per module: ``scan`` (the workflow's texture pipeline on one scan), ``linear`` (a fitted ``<model>@dft``
as an explicit linear map), ``intervals`` (CV+ prediction intervals with sections as folds), ``domain`` (the
training texture domain, a scan's distance to it and the extrapolation threshold), ``model_file`` (the JSON model
file: train, save, load), ``apply`` (a model applied to texture rows: DFT, intervals, IFI, flags), ``coverage``
(coverage and transfer measured at unseen sections and campaigns) and ``tables`` (texture and DFT tables of a
campaign directory without the workflow).
"""

from .apply import DFT_COLUMNS, IFI_COLUMNS, predict_rows, summary_lines
from .coverage import heldout_coverage, transfer_scores
from .domain import Domain, fit_domain
from .intervals import SectionCVPlus, check_level, fit_cvplus
from .linear import LinearMap, fit_map
from .model_file import (
    BASELINE,
    FORMAT,
    FORMAT_VERSION,
    ModelPart,
    PredictionModel,
    load_model,
    model_from_dict,
    save_model,
    train_model,
)
from .scan import ScanFeatures, feature_table, scan_features
from .tables import campaign_tables

__all__ = [
    "BASELINE",
    "DFT_COLUMNS",
    "FORMAT",
    "FORMAT_VERSION",
    "IFI_COLUMNS",
    "Domain",
    "LinearMap",
    "ModelPart",
    "PredictionModel",
    "ScanFeatures",
    "SectionCVPlus",
    "campaign_tables",
    "check_level",
    "feature_table",
    "fit_cvplus",
    "fit_domain",
    "fit_map",
    "heldout_coverage",
    "load_model",
    "model_from_dict",
    "predict_rows",
    "save_model",
    "scan_features",
    "summary_lines",
    "train_model",
    "transfer_scores",
]
