"""How much of a hidden effect on the DFT a texture model predicts at unseen sections.

A campaign generated twice from the same seeds, once without and once with an effect on friction (the scans and
the trace noise identical, only the friction curves differ), gives the effect itself at every site and speed:
``e = D_with - D_without`` (friction, dimensionless). A texture model cross-validated by section on each campaign
gives held-out predictions ``P_without`` and ``P_with``; what it predicts of the effect at unseen sections is
``P_with - P_without``. Reported, pooled over sites and speeds (docs/regression.md, "A hidden effect at unseen
sections"):

* ``captured_share = 1 - sum((e - (P_with - P_without))^2) / sum(e^2)``: 1 when the held-out predictions move by
  exactly the effect, 0 when they do not move (or move as far off as the effect is large), negative when worse;
* ``slope``: least-squares slope of ``P_with - P_without`` on ``e`` through the origin (1: the full effect, 0:
  none);
* ``captured_share_between_sites`` and ``slope_between_sites``: the same on the effect's differences between sites
  (``e`` and ``P_with - P_without`` less their mean over the sites at each speed). The campaign-wide part of the
  effect (its mean per speed) is predicted by any model with an intercept per speed; this is the part that rides
  on texture, the one a texture model has to carry (``between_site_rms``: its size);
* ``effect_rms`` and ``effect_by_speed`` (mean of ``e`` per speed, friction): the size of what is to be found;
* ``r2_without`` / ``r2_with``: the model's section-grouped CV R^2 of the DFT pooled over the speeds
  (``1 - SSE / SS about the pooled mean``, as the workflow's CV table) on each campaign.

The model is a callable ``fit(X_train, Y_train, groups_train) -> object with .predict(X_test)``; the default is
``physics2`` (:func:`~.physics.fit_physics_ols`), the model the workflow chooses on the independent generators.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .physics import fit_physics_ols
from .targets import DEFAULT_SPEEDS_KMH, dft_targets


def capture_tables(
    texture_wide: pd.DataFrame, dft_points: pd.DataFrame, speeds_kmh=DEFAULT_SPEEDS_KMH
) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray]:
    """The inputs of :func:`effect_capture` from the workflow's tables: the texture table (``results/texture/
    campaign.parquet``, indexed by site), the DFT table (sites x ``dft@<v>`` columns, friction, at ``speeds_kmh``
    km/h, from ``results/ingest/dft_points.parquet``: site, speed_kmh, mu) and the section of each site."""
    X = texture_wide.set_index(texture_wide["site"].astype(str))
    D = dft_targets(
        None, measured_dft=dft_points[["site", "speed_kmh", "mu"]], speeds_kmh=speeds_kmh, sites=list(X.index)
    )
    return X, D, X["section"].astype(str).to_numpy()


def _physics2(X: pd.DataFrame, Y: pd.DataFrame, groups: np.ndarray):
    return fit_physics_ols(X, Y, groups=groups)


def section_cv_predictions(X: pd.DataFrame, D: pd.DataFrame, groups, fit: Callable | None = None) -> pd.DataFrame:
    """Leave-one-section-out predictions of the DFT table ``D`` (sites x ``dft@<v>`` columns, friction) from the
    texture table ``X`` (same site index): for each section, ``fit`` on the other sections, predict its sites."""
    fit = fit or _physics2
    groups = np.asarray(groups)
    if len(X) != len(D) or len(groups) != len(D) or not X.index.equals(D.index):
        raise InputError(None, "texture table, DFT table and sections on the same sites in the same order")
    out = pd.DataFrame(np.nan, index=D.index, columns=D.columns)
    for g in pd.unique(groups):
        te = groups == g
        if te.all():
            raise InputError(None, "at least two sections for a section-grouped CV", column="section")
        model = fit(X[~te], D[~te], groups[~te])
        out.loc[te] = model.predict(X[te]).to_numpy(float)
    return out


def _r2(pred: pd.DataFrame, D: pd.DataFrame) -> float:
    y = D.to_numpy(float)
    return float(1.0 - np.sum((y - pred.to_numpy(float)) ** 2) / np.sum((y - y.mean()) ** 2))


def effect_capture(
    X: pd.DataFrame, D_without: pd.DataFrame, D_with: pd.DataFrame, groups, fit: Callable | None = None
) -> dict:
    """What a texture model predicts at unseen sections of the effect ``D_with - D_without`` (module docstring)."""
    if not D_without.index.equals(D_with.index) or list(D_without.columns) != list(D_with.columns):
        raise InputError(None, "the two DFT tables on the same sites and speeds")
    p0 = section_cv_predictions(X, D_without, groups, fit)
    p1 = section_cv_predictions(X, D_with, groups, fit)
    e = (D_with - D_without).to_numpy(float)
    dp = (p1 - p0).to_numpy(float)
    ss = float(np.sum(e * e))
    if ss == 0.0:
        raise InputError(None, "an effect that changes the DFT somewhere (D_with equals D_without)")
    ec, dpc = e - e.mean(axis=0), dp - dp.mean(axis=0)
    ssc = float(np.sum(ec * ec))
    return {
        "captured_share": float(1.0 - np.sum((e - dp) ** 2) / ss),
        "slope": float(np.sum(e * dp) / ss),
        "captured_share_between_sites": float(1.0 - np.sum((ec - dpc) ** 2) / ssc) if ssc > 0 else float("nan"),
        "slope_between_sites": float(np.sum(ec * dpc) / ssc) if ssc > 0 else float("nan"),
        "between_site_rms": float(np.sqrt(np.mean(ec * ec))),
        "effect_rms": float(np.sqrt(np.mean(e * e))),
        "effect_by_speed": {str(c): float(v) for c, v in zip(D_with.columns, e.mean(axis=0))},
        "r2_without": _r2(p0, D_without),
        "r2_with": _r2(p1, D_with),
        "n_sites": int(len(D_with)),
        "n_sections": int(len(pd.unique(np.asarray(groups)))),
    }
