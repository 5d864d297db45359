"""Leave-one-section-out cross-validation of the models and its error table.

Every model is fitted on all sections but one (hyper-parameters by inner leave-one-section-out CV on those, so
the outer test section is never seen, not even by the scaler) and predicts the held-out section
(:func:`cross_validated_predictions`); :func:`score_predictions` scores the predictions per model: the friction
parameters and the DFT at each speed and pooled over speeds. Out-of-sample R^2 is
``1 - SSE / sum((ref - mean ref)^2)`` over all held-out predictions.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .design import PARAMETERS
from .figure11 import figure11_table
from .models import DEFAULT_MODELS, DFT_SUFFIX
from .prediction import predict_parameters
from .targets import DEFAULT_SPEEDS_KMH, dft_column, dft_targets, predict_dft


def _section_labels(X: pd.DataFrame, Y: pd.DataFrame, groups) -> pd.Series:
    """The section of every site as strings indexed like ``X``; InputError unless X and Y share the index and
    there are at least 3 sections."""
    grp = (
        pd.Series(np.asarray(groups).astype(str), index=X.index)
        if not isinstance(groups, pd.Series)
        else groups.astype(str).reindex(X.index)
    )
    if grp.isna().any() or len(grp) != len(X):
        raise InputError(None, "a section for every site", column="section")
    if not X.index.equals(Y.index):
        raise InputError(None, "feature and friction tables indexed by the same sites in the same order", column="site")
    if grp.nunique() < 3:
        raise InputError(None, "at least 3 sections for leave-one-section-out", column="section", got=grp.nunique())
    return grp


def _aligned_dft(dft: pd.DataFrame, X: pd.DataFrame) -> pd.DataFrame:
    """The DFT targets in the row order (and index) of ``X``; InputError when a site lacks them."""
    missing = sorted(set(X.index.astype(str)) - set(dft.index.astype(str)))
    if missing:
        raise InputError(None, "DFT targets for every site", column="site", got=missing[0])
    return dft.set_axis(dft.index.astype(str)).loc[X.index.astype(str)].set_axis(X.index)


def cross_validated_predictions(
    X: pd.DataFrame,
    Y: pd.DataFrame,
    groups,
    models: Sequence[str] = DEFAULT_MODELS,
    *,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
    workers: int = 1,
    dft: pd.DataFrame | None = None,
    g: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Out-of-section predictions: for every section, each model is fitted on all other sections (hyper-
    parameters by inner leave-one-section-out CV on those) and predicts the held-out section's parameters.

    ``workers`` > 1 fits the (model, section) pairs in that many forked processes (:func:`_in_processes`): the
    fits are independent and seeded, the rows are assembled in the same order, so the result is identical to
    ``workers=1`` (tested). A thread pool gained only 1.2x on 2 cores: beside scikit-learn's lasso coordinate
    descent (about 60 % of the time, without the GIL) the fits are Python and pandas under the GIL.
    ``dft``: the DFT targets of the ``<model>@dft`` models (:func:`~.targets.dft_targets`, one row per site;
    default ``g * mu(v)`` of ``Y`` at :data:`~.targets.DEFAULT_SPEEDS_KMH`), ``g`` the geometric factors (None: 1)
    for their laws. Returns long form: site, section, model, and one predicted column per column of ``Y``;
    ``<model>@dft`` rows also fill the ``dft@<v>`` columns, ``ols2`` models the ``features`` column (NaN
    elsewhere).
    """
    grp = _section_labels(X, Y, groups)
    if dft is None and any(m.endswith(DFT_SUFFIX) for m in models):
        dft = dft_targets(Y, g=g)
    if dft is not None:
        dft = _aligned_dft(dft, X)

    kw = dict(seed=seed, inner_folds=inner_folds, selection=selection, g_test=g)
    tasks = [(model, sec, X, Y, grp, dft, kw) for model in models for sec in sorted(grp.unique())]
    if int(workers) > 1:
        rows = _in_processes(_held_out_predictions, tasks, int(workers))
    else:
        rows = [_held_out_predictions(t) for t in tasks]
    return pd.concat(rows, ignore_index=True)


def _held_out_predictions(task) -> pd.DataFrame:
    """One (model, section) pair of :func:`cross_validated_predictions`: the model fitted on every other section
    predicts this one. ``task``: ``(model, section, X, Y, section labels, DFT targets or None, keyword
    arguments of predict_parameters)``; module level, so that a process pool can run it."""
    model, sec, X, Y, grp, dft, kw = task
    te = (grp == sec).to_numpy()
    tr = ~te
    pred = predict_parameters(
        model,
        X[tr],
        Y[tr],
        X[te],
        groups_train=grp[tr].to_numpy(),
        dft_train=None if dft is None else dft[tr],
        **kw,
    )
    pred.insert(0, "model", model)
    pred.insert(0, "section", sec)
    pred.insert(0, "site", pred.index.astype(str))
    return pred.reset_index(drop=True)


def _in_processes(fn, tasks: list, workers: int) -> list:
    """``[fn(t) for t in tasks]`` in ``workers`` forked processes, in order, each with one BLAS thread (the
    processes are the parallelism); in this process where fork is not available. Small chunks balance the load (a
    lasso path costs far more than an OLS fit)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    if "fork" not in multiprocessing.get_all_start_methods():  # Windows: the fits one after the other
        return [fn(t) for t in tasks]
    chunk = max(1, len(tasks) // (8 * workers))
    ctx = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_one_blas_thread) as pool:
        return list(pool.map(fn, tasks, chunksize=chunk))


def _one_blas_thread() -> None:
    """Process-pool initializer: BLAS (and OpenMP) pools of one thread in this worker."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


def _scores(pred: np.ndarray, ref: np.ndarray, ref_all: np.ndarray) -> dict:
    e = pred - ref
    sst = np.sum((ref_all - ref_all.mean()) ** 2) if len(ref_all) > 1 else np.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = e / ref
    return {
        "n": int(len(e)),
        "rmse": float(np.sqrt(np.mean(e**2))),
        "mae": float(np.mean(np.abs(e))),
        "bias": float(np.mean(e)),
        "r2": float(1 - np.sum(e**2) / sst) if sst > 0 else float("nan"),
        "mean_abs_rel_error": float(np.mean(np.abs(rel))),
        "share_within_10pct": float(np.mean(np.abs(rel) <= 0.10)),
    }


def _predicted_dft(p: pd.DataFrame, params: list[str], g, speeds_kmh) -> pd.DataFrame | None:
    """The predicted DFT (long form site, speed_kmh, mu) of one model's rows: its own ``dft@<v>`` values when
    it fills them at every speed (a ``<model>@dft`` model), else ``g * mu(v)`` of its predicted parameters, else
    None (not every parameter predicted)."""
    direct = [dft_column(v) for v in speeds_kmh]
    if all(c in p.columns for c in direct) and p[direct].notna().all().all():
        return pd.DataFrame(
            {
                "site": np.repeat(p["site"].astype(str).to_numpy(), len(direct)),
                "speed_kmh": np.tile(np.asarray(speeds_kmh, dtype=float), len(p)),
                "mu": p[direct].to_numpy(dtype=float).ravel(),
            }
        )
    if all(c in params for c in PARAMETERS):
        return predict_dft(p.set_index(p["site"].astype(str)), g, speeds_kmh)
    return None


def _dft_rows(model: str, predicted: pd.DataFrame, measured: pd.DataFrame) -> list[dict]:
    """Score rows of one model's DFT: one per speed and one pooled over speeds (``speed_kmh`` NaN)."""
    t = figure11_table(predicted, measured, pred_file=f"predicted DFT ({model})")
    out = []
    for v, tv in t.groupby("speed_kmh", sort=True):
        out.append(
            {
                "model": model,
                "quantity": "dft",
                "speed_kmh": float(v),
                **_scores(tv["predicted"].to_numpy(), tv["measured"].to_numpy(), tv["measured"].to_numpy()),
            }
        )
    out.append(
        {
            "model": model,
            "quantity": "dft",
            "speed_kmh": float("nan"),
            **_scores(t["predicted"].to_numpy(), t["measured"].to_numpy(), t["measured"].to_numpy()),
        }
    )
    return out


def score_predictions(
    predictions: pd.DataFrame,
    Y: pd.DataFrame,
    *,
    g: pd.DataFrame | None = None,
    measured_dft: pd.DataFrame | None = None,
    speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH,
) -> pd.DataFrame:
    """Score out-of-sample predictions (from :func:`cross_validated_predictions`) per model.

    Rows: ``quantity`` in the parameters (``speed_kmh`` NaN) and ``"dft"`` at each speed plus pooled over speeds
    (``speed_kmh`` NaN). Columns n, rmse, mae, bias, r2 (out-of-sample, ``1 - SSE / sum((ref - mean ref)^2)``),
    mean_abs_rel_error, share_within_10pct. The DFT is ``g * mu(v)`` of the predicted parameters; the reference is
    ``measured_dft`` (site, speed_kmh, mu) or, if None, ``g * mu(v)`` of the calibrated parameters ``Y``.
    A model whose rows fill the ``dft@<v>`` columns of every speed (``<model>@dft``) is scored on those
    predicted values directly.
    """
    out = []
    params = [c for c in Y.columns if c in predictions.columns]
    for model, p in predictions.groupby("model", sort=False):
        ref = Y.loc[p["site"].astype(str)]
        for c in params:
            out.append(
                {
                    "model": model,
                    "quantity": c,
                    "speed_kmh": float("nan"),
                    **_scores(p[c].to_numpy(float), ref[c].to_numpy(float), ref[c].to_numpy(float)),
                }
            )
        predicted = _predicted_dft(p, params, g, speeds_kmh)
        if predicted is not None:
            measured = predict_dft(ref, g, speeds_kmh) if measured_dft is None else measured_dft
            out += _dft_rows(model, predicted, measured)
    return pd.DataFrame(out)


def cross_validate_models(
    X: pd.DataFrame,
    Y: pd.DataFrame,
    groups,
    models: Sequence[str] = DEFAULT_MODELS,
    *,
    g: pd.DataFrame | None = None,
    measured_dft: pd.DataFrame | None = None,
    speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
) -> pd.DataFrame:
    """Leave-one-section-out comparison of ``models`` (see :func:`score_predictions` for the table); the
    ``<model>@dft`` targets are the same DFT reference the table scores against (:func:`~.targets.dft_targets`)."""
    dft = None
    if any(m.endswith(DFT_SUFFIX) for m in models):
        dft = dft_targets(Y, measured_dft=measured_dft, g=g, speeds_kmh=speeds_kmh)
    pred = cross_validated_predictions(
        X, Y, groups, models, seed=seed, inner_folds=inner_folds, selection=selection, dft=dft, g=g
    )
    return score_predictions(pred, Y, g=g, measured_dft=measured_dft, speeds_kmh=speeds_kmh)
