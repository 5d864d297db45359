"""The inputs of the model criticism, built from the workflow's tables.

Within-site residuals: measured DFT (points at calibration/validation speeds and the trace between them) minus the
calibrated FE simulation. Between-site residuals: measured minus texture-based predictions of sites the model never
saw: the leave-one-section-out predicted friction parameters of the best regression model times the site's FE
geometric factor g(v) = SN_sim(v) / mu_cal(v) (:func:`skidsim.regression.predict_dft`). Only campaign-derived
tables are read, never a truth file. Speeds km/h, friction mu and SN dimensionless.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..calibration.tables import geometric_factors
from ..errors import InputError
from ..regression import predict_dft
from .residuals import require_columns


@dataclass(frozen=True)
class DiagnosisInputs:
    """Campaign-level tables of :func:`skidsim.criticism.diagnose`: ``sites`` (site, section, candidate columns),
    ``measured`` (site, speed_kmh, mu, kind in calibration/validation/trace), ``simulated`` (site, speed_kmh, sn:
    the calibrated simulation), ``predicted`` (site, speed_kmh, sn_pred: texture-based predictions of held-out
    sites, or None), ``texture`` (texture parameters per site, or None), ``prediction_model`` (the regression
    model behind ``predicted``, for the record) and ``calibration`` (site, flags, at_bound_params: the
    calibration's record of each site, :func:`calibration_record`; or None), read by
    :mod:`skidsim.criticism.calibration_groups`."""

    sites: pd.DataFrame
    measured: pd.DataFrame
    simulated: pd.DataFrame
    predicted: pd.DataFrame | None = None
    texture: pd.DataFrame | None = None
    prediction_model: str | None = None
    prediction_features: tuple[str, ...] = ()
    calibration: pd.DataFrame | None = None


def measured_table(
    dft_points: pd.DataFrame,
    traces: pd.DataFrame,
    calibration_speeds_kmh: Sequence[float],
    validation_speeds_kmh: Sequence[float],
) -> pd.DataFrame:
    """Measured DFT mu with its ``kind``: points at calibration speeds, at validation speeds, any other point and
    every trace sample ("trace")."""
    require_columns(dft_points, ("site", "speed_kmh", "mu"), "dft points table")
    require_columns(traces, ("site", "speed_kmh", "mu"), "dft traces table")
    cal = {float(v) for v in calibration_speeds_kmh}
    val = {float(v) for v in validation_speeds_kmh}
    points = dft_points[["site", "speed_kmh", "mu"]].copy()
    points["kind"] = np.where(
        points["speed_kmh"].isin(cal), "calibration", np.where(points["speed_kmh"].isin(val), "validation", "trace")
    )
    return pd.concat([points, traces[["site", "speed_kmh", "mu"]].assign(kind="trace")], ignore_index=True)


def method_rows(table: pd.DataFrame, method: str, name: str) -> pd.DataFrame:
    """The rows of one calibration ``method``; :class:`InputError` when there are none."""
    require_columns(table, ("site", "method"), name)
    out = table[table["method"] == method]
    if out.empty:
        raise InputError(
            name,
            f"rows of calibration method '{method}'",
            column="method",
            got=sorted(map(str, table["method"].unique()))[:5],
        )
    return out


def between_site_predictions(g: pd.DataFrame, cv_predictions: pd.DataFrame, model: str) -> pd.DataFrame:
    """Texture-based predictions (site, speed_kmh, sn_pred) of held-out sites at the speeds of ``g``: the
    leave-one-section-out parameters of ``model`` in ``cv_predictions`` (site, model, mu_s, mu_k, alpha), clipped
    to physical values, times g(v) (:func:`skidsim.regression.predict_dft`). Sites without both are left out."""
    require_columns(cv_predictions, ("site", "model", "mu_s", "mu_k", "alpha"), "cv predictions table")
    params = cv_predictions.loc[cv_predictions["model"] == model, ["site", "mu_s", "mu_k", "alpha"]]
    params = params.astype({"site": str})
    g = g.assign(site=g["site"].astype(str))
    frames = []
    for site, gs in g[g["site"].isin(set(params["site"]))].groupby("site", sort=False):
        p = predict_dft(params[params["site"] == site], gs, gs["speed_kmh"].to_numpy(float))
        frames.append(p.rename(columns={"mu": "sn_pred"})[["site", "speed_kmh", "sn_pred"]])
    if not frames:
        raise InputError(
            "cv predictions table", f"predicted parameters of model '{model}' for a simulated site", column="model"
        )
    return pd.concat(frames, ignore_index=True)


def prediction_features(cv_predictions: pd.DataFrame, model: str) -> tuple[str, ...]:
    """The texture columns ``model`` predicts from, from the ``features`` column of ``cv_predictions`` (one entry
    per held-out site, e.g. ``"profile_MPD+micro_Sq"`` or ``"log(profile_MPD)+log(micro_Sq)"``): the terms of the
    entry most held-out sites share (ties: the first in the table), or ``()`` when the model records none."""
    if "features" not in cv_predictions.columns:
        return ()
    f = cv_predictions.loc[cv_predictions["model"] == model, "features"].dropna().astype(str).str.strip()
    f = f[f != ""]
    if f.empty:
        return ()
    counts = f.value_counts(sort=False)
    best = counts.index[int(np.argmax(counts.to_numpy()))]
    return tuple(t.strip() for t in best.split("+") if t.strip())


def calibration_record(identifiability: pd.DataFrame, method: str, name: str) -> pd.DataFrame:
    """site, flags (such as ``not_converged``) and at_bound_params (such as ``mu_s:upper``), each joined by ``;``,
    of ``method``'s rows of the calibration's identifiability table (results/calibration/identifiability.csv,
    ``name`` its path)."""
    rows = method_rows(identifiability, method, name)
    require_columns(rows, ("site", "flags", "at_bound_params"), name)
    return rows[["site", "flags", "at_bound_params"]].astype({"site": str}).reset_index(drop=True)


def read_workflow_inputs(
    paths, method: str, calibration_speeds_kmh: Sequence[float], validation_speeds_kmh: Sequence[float]
) -> DiagnosisInputs:
    """The inputs from the workflow's files: ``paths`` maps ingest (sites), dft (points), traces, wide (texture
    table), params (calibration parameters), validation (simulated SN), cv_predictions and best_model (the
    regression's) and, where given, identifiability (the calibration's identifiability table: ``calibration``) to their
    paths (the diagnosis rule's ``input``); ``method``: the calibration method whose simulation and laws are
    criticised."""

    def path(key):
        try:
            return getattr(paths, key) if not isinstance(paths, dict) else paths[key]
        except (AttributeError, KeyError):
            raise InputError(None, f"an input named '{key}' for the diagnosis") from None

    vt = method_rows(pd.read_parquet(path("validation")), method, path("validation"))
    params = method_rows(pd.read_parquet(path("params")), method, path("params"))
    best = Path(path("best_model")).read_text().strip()
    g = geometric_factors(vt, params)
    cv = pd.read_csv(path("cv_predictions"))
    has_record = "identifiability" in paths if isinstance(paths, dict) else hasattr(paths, "identifiability")
    record = (
        calibration_record(pd.read_csv(path("identifiability")), method, path("identifiability"))
        if has_record
        else None
    )
    return DiagnosisInputs(
        sites=pd.read_parquet(path("ingest")),
        measured=measured_table(
            pd.read_parquet(path("dft")), pd.read_parquet(path("traces")), calibration_speeds_kmh, validation_speeds_kmh
        ),
        simulated=vt[["site", "speed_kmh", "sn_sim"]].rename(columns={"sn_sim": "sn"}),
        predicted=between_site_predictions(g, cv, best),
        texture=pd.read_parquet(path("wide")),
        prediction_model=best,
        prediction_features=prediction_features(cv, best),
        calibration=record,
    )
