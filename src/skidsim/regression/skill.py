"""The prediction-skill table: every model of the CV beside the intercept-only mean and the simple baseline.

* **Skill** (:func:`prediction_skill`): pooled DFT R^2 and RMSE per model; a model "beats" a reference when its
  RMSE is lower by more than a relative 1e-9 (a model never beats itself); a WARNING when the chosen model does
  not beat both :data:`MEAN_MODEL` and :data:`BASELINE_MODEL`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .models import DFT_SUFFIX
from .subset import SUBSET_OLS

#: The simple baseline of the prediction-skill table: OLS of the DFT curve on <= 2 texture columns (inner CV).
BASELINE_MODEL = SUBSET_OLS + DFT_SUFFIX
#: The intercept-only reference of the prediction-skill table: the training sections' mean DFT at each speed.
MEAN_MODEL = "mean" + DFT_SUFFIX
#: A model beats a reference when its RMSE is below the reference's times (1 - this).
_BEATS_REL = 1e-9


def _pooled_dft(cv_table: pd.DataFrame, chosen: str, mean_model: str, baseline_model: str) -> pd.DataFrame:
    """The pooled DFT rows of ``cv_table`` indexed by model; InputError when one of the three models lacks one."""
    pooled = cv_table[(cv_table["quantity"] == "dft") & cv_table["speed_kmh"].isna()]
    if pooled.empty:
        raise InputError(None, "pooled DFT rows (quantity 'dft', speed NaN) in the CV table", column="quantity")
    t = pooled.drop_duplicates("model").set_index("model")
    for m, what in (
        (chosen, "the chosen model"),
        (mean_model, "the mean model"),
        (baseline_model, "the baseline model"),
    ):
        if m not in t.index:
            raise InputError(
                None, f"{what} {m!r} in the CV table's pooled DFT rows", column="model", got=sorted(t.index)[:12]
            )
    return t


def _chosen_warning(out: pd.DataFrame, ref: dict, chosen: str, mean_model: str, baseline_model: str) -> str:
    """The WARNING of the chosen model's row of the skill table ``out`` (empty when it beats both references)."""
    c = out[out["model"] == chosen].iloc[0]
    if bool(c["beats_both"]):
        return ""
    lost = []
    for name, mm in (("mean", mean_model), ("baseline", baseline_model)):
        if not bool(c[f"beats_{name}"]):
            rr = ref[name]
            lost.append(
                f"the {'intercept-only mean' if name == 'mean' else 'simple baseline'} {mm} "
                f"(R^2 {float(rr['r2']):.3f}, RMSE {float(rr['rmse']):.4f})"
            )
    score = (
        f"section-grouped CV R^2 {float(c['r2']):.3f}, RMSE {float(c['rmse']):.4f} of the DFT pooled "
        "over the prediction speeds"
    )
    if chosen not in (mean_model, baseline_model):
        return (
            f"WARNING: the chosen model {chosen} ({score}) does not beat "
            + " nor ".join(lost)
            + ": its predictions of friction at unseen sections are no better than that reference"
        )
    what = (
        "the intercept-only mean"
        if chosen == mean_model
        else "the simple baseline (OLS on at most two texture parameters)"
    )
    better = int((out["rmse"] < float(c["rmse"]) * (1 - _BEATS_REL)).sum())
    others = [t_ for t_, mm in zip(lost, (mean_model, baseline_model)) if mm != chosen] if len(lost) == 2 else []
    return (
        f"WARNING: the chosen model is {what} {chosen} itself ({score}): "
        + (
            f"{better} model(s) of the comparison have a lower RMSE"
            if better
            else "no other model of the comparison beats it"
        )
        + ("; it does not beat " + others[0] if others else "")
    )


def prediction_skill(
    cv_table: pd.DataFrame,
    chosen: str,
    *,
    mean_model: str = MEAN_MODEL,
    baseline_model: str = BASELINE_MODEL,
    notes: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """The prediction-skill table: per model, the section-grouped CV R^2 and RMSE of the DFT pooled over the
    prediction speeds (the ``quantity == "dft"``, ``speed_kmh`` NaN rows of ``cv_table``), beside the
    intercept-only ``mean_model`` and the simple ``baseline_model``.

    Columns: rank (by RMSE), model, role (``chosen``, ``mean``, ``baseline``, joined by ``+``), n, r2, rmse
    (friction, dimensionless), r2_minus_mean, r2_minus_baseline, beats_mean / beats_baseline (RMSE lower than
    the reference's by more than a relative 1e-9; a model never beats itself), beats_both, warning (the text
    below on the chosen model's row when it does not beat both, else empty), note (``notes[model]``, e.g. the
    baseline's chosen columns). ``attrs["warning"]`` holds the same text (empty when the chosen model beats both):
    callers must show it (the workflow logs it as a WARNING and the report flags the row).
    """
    t = _pooled_dft(cv_table, chosen, mean_model, baseline_model)
    ref = {"mean": t.loc[mean_model], "baseline": t.loc[baseline_model]}
    out = pd.DataFrame(
        {
            "model": t.index,
            "n": t["n"].astype(int).to_numpy(),
            "r2": t["r2"].to_numpy(float),
            "rmse": t["rmse"].to_numpy(float),
        }
    )
    roles = [("chosen", chosen), ("mean", mean_model), ("baseline", baseline_model)]
    out.insert(1, "role", ["+".join(name for name, mm in roles if m == mm) for m in out["model"]])
    for name in ("mean", "baseline"):
        out[f"r2_minus_{name}"] = out["r2"] - float(ref[name]["r2"])
        out[f"beats_{name}"] = (out["rmse"] < float(ref[name]["rmse"]) * (1 - _BEATS_REL)) & (
            out["model"] != (mean_model if name == "mean" else baseline_model)
        )
    out["beats_both"] = out["beats_mean"] & out["beats_baseline"]
    out = out.sort_values(["rmse", "model"], kind="stable").reset_index(drop=True)
    out.insert(0, "rank", np.arange(1, len(out) + 1))
    warning = _chosen_warning(out, ref, chosen, mean_model, baseline_model)
    out["warning"] = np.where(out["model"] == chosen, warning, "")
    out["note"] = [str((notes or {}).get(m, "")) for m in out["model"]]
    out.attrs["warning"] = warning
    return out


def baseline_notes(cv_predictions: pd.DataFrame) -> dict[str, str]:
    """For each model with a ``features`` column in ``cv_predictions`` (the ``ols2`` models): the columns chosen
    in the outer folds and in how many sections, e.g. ``"raw_Sq+micro_Vvc in 10 of 12 folds"``."""
    if "features" not in cv_predictions.columns:
        return {}
    out = {}
    for m, t in cv_predictions.groupby("model", sort=False):
        f = t.drop_duplicates("section")["features"].dropna()
        if f.empty:
            continue
        counts = f.value_counts()
        out[str(m)] = "; ".join(f"{k} in {v} of {len(f)} folds" for k, v in counts.items())
    return out
