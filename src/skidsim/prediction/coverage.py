"""What the intervals and the domain flags are worth at sections the model has not seen (table level, no FE).

* :func:`heldout_coverage`: every section of a campaign is held out in turn; on the other sections the whole
  model-file content is fitted (the model, its section folds and residuals for CV+, its domain), and the held-out
  sites are predicted. Reported over all held-out sites and speeds: the share of measured DFT values inside the
  interval (``coverage``, nominal ``level``), the mean interval width (friction) beside the RMSE of the point
  predictions (which are the workflow's leave-one-section-out predictions), and the share of sites flagged as
  extrapolation. Intervals are scored on every site here, flagged or not, so the coverage is that of the
  interval itself; ``coverage_unflagged`` is over the sites that are not flagged (the ones that get an interval).
* :func:`transfer_scores`: a model part trained on one campaign applied to the texture and DFT tables of
  another: RMSE, coverage, mean width and share flagged.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .domain import DOMAIN_ALPHA
from .model_file import ModelPart, _part


def _scores(D: pd.DataFrame, P: np.ndarray, lo: np.ndarray, hi: np.ndarray, ext: np.ndarray) -> dict:
    y = D.to_numpy(dtype=float)
    inside = (y >= lo) & (y <= hi)
    ok = ~ext
    return {
        "n_sites": int(len(y)),
        "rmse": float(np.sqrt(np.mean((y - P) ** 2))),
        "r2": float(1.0 - np.sum((y - P) ** 2) / np.sum((y - y.mean()) ** 2)),
        "coverage": float(np.mean(inside)),
        "mean_width": float(np.mean(hi - lo)),
        "share_flagged": float(np.mean(ext)),
        "coverage_unflagged": float(np.mean(inside[ok])) if ok.any() else float("nan"),
        "rmse_flagged": float(np.sqrt(np.mean((y[ext] - P[ext]) ** 2))) if ext.any() else float("nan"),
        "rmse_unflagged": float(np.sqrt(np.mean((y[ok] - P[ok]) ** 2))) if ok.any() else float("nan"),
    }


def _apply(part: ModelPart, X: pd.DataFrame, level: float):
    P = part.map.predict(X).to_numpy(dtype=float)
    lo, hi = part.intervals.interval(X, level)
    T = part.map.transformed(X)
    T = T[:, [part.map.features.index(c) for c in part.domain.features]]
    return P, lo, hi, part.domain.distance(T) > part.domain.threshold


def transfer_scores(part: ModelPart, X: pd.DataFrame, D: pd.DataFrame, level: float = 0.9) -> dict:
    """Scores of a trained model part on another campaign's texture table ``X`` and DFT table ``D`` (same sites,
    the part's ``dft@<v>`` columns, friction); see the module docstring."""
    P, lo, hi, ext = _apply(part, X, level)
    return _scores(D.loc[X.index, list(part.map.targets)], P, lo, hi, np.repeat(ext[:, None], P.shape[1], axis=1))


def heldout_coverage(
    X: pd.DataFrame,
    D: pd.DataFrame,
    groups,
    model: str,
    level: float = 0.9,
    *,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
    domain_alpha: float = DOMAIN_ALPHA,
) -> tuple[dict, pd.DataFrame]:
    """Coverage, mean width, RMSE and share flagged at unseen sections (module docstring). Returns the scores
    and the per-site table (site, section, speed_kmh, measured, predicted, lo, hi, extrapolation)."""
    groups = np.asarray(groups).astype(str)
    fit_kw = dict(seed=seed, inner_folds=inner_folds, selection=selection)
    P = np.full(D.shape, np.nan)
    lo, hi, ext = P.copy(), P.copy(), np.zeros(D.shape, dtype=bool)
    for s in sorted(pd.unique(groups)):
        te = groups == s
        part = _part(model, X[~te], D[~te], groups[~te], fit_kw, domain_alpha)
        p, a, b, e = _apply(part, X[te], level)
        P[te], lo[te], hi[te], ext[te] = p, a, b, e[:, None]
    scores = _scores(D, P, lo, hi, ext)
    scores.update(model=model, level=float(level), n_sections=int(len(set(groups))))
    speeds = [float(c[4:]) for c in D.columns]
    table = pd.DataFrame(
        {
            "site": np.repeat(D.index.astype(str), D.shape[1]),
            "section": np.repeat(groups, D.shape[1]),
            "speed_kmh": np.tile(speeds, len(D)),
            "measured": D.to_numpy(dtype=float).ravel(),
            "predicted": P.ravel(),
            "lo": lo.ravel(),
            "hi": hi.ravel(),
            "extrapolation": ext.ravel(),
        }
    )
    return scores, table
