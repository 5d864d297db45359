"""The best model of the cross-validation: :func:`rank_models` and :func:`best_model`.

* **Criterion**: pooled DFT RMSE over speeds when the CV table has DFT rows, else the mean over parameters of
  ``1 - R2`` (out of sample); lower is better; exact ties go to the simpler model (:data:`SIMPLICITY`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .design import PARAMETERS
from .physics import PHYSICS_OLS
from .subset import SUBSET_OLS

#: Order used to break exact ties (simpler first; suffixes ``@curve``/``@dft`` and ``:<rule>`` ignored).
SIMPLICITY = ("mean", SUBSET_OLS, PHYSICS_OLS, "two_variable", "pca", "pls", "ridge", "lasso")
#: The criteria of :func:`rank_models`.
CRITERIA = ("auto", "dft_rmse", "param_r2")


def rank_models(cv_table: pd.DataFrame, criterion: str = "auto") -> pd.DataFrame:
    """Rank models by ``criterion`` (lower score is better), with the gap to the best.

    ``"dft_rmse"``: RMSE of the DFT pooled over all speeds (what the FE input is for); ``"param_r2"``: the mean
    over the friction parameters of ``1 - R2`` (out-of-sample relative squared error; each parameter weighs the
    same whatever its unit); ``"auto"``: ``"dft_rmse"`` when the table has DFT rows, else ``"param_r2"``.
    Columns: model, score, gap (score - best score), ratio (score / best score).
    """
    has_dft = ((cv_table["quantity"] == "dft") & cv_table["speed_kmh"].isna()).any()
    if criterion == "auto":
        criterion = "dft_rmse" if has_dft else "param_r2"
    if criterion == "dft_rmse":
        if not has_dft:
            raise InputError(None, "pooled DFT rows in the CV table for criterion 'dft_rmse'", column="quantity")
        s = cv_table[(cv_table["quantity"] == "dft") & cv_table["speed_kmh"].isna()].set_index("model")["rmse"]
    elif criterion == "param_r2":
        t = cv_table[cv_table["quantity"].isin(PARAMETERS)]
        if t.empty:
            raise InputError(None, "parameter rows in the CV table", column="quantity")
        s = 1 - t.groupby("model", sort=False)["r2"].mean()
    else:
        raise InputError(None, "criterion 'auto', 'dft_rmse' or 'param_r2'", column="criterion", got=criterion)
    order = {m: i for i, m in enumerate(SIMPLICITY)}
    r = pd.DataFrame({"model": s.index, "score": s.to_numpy(float)})
    r["simplicity"] = [order.get(m.split("@")[0].split(":")[0], len(order)) for m in r["model"]]
    r = r.sort_values(["score", "simplicity"], kind="stable").drop(columns="simplicity").reset_index(drop=True)
    r["gap"] = r["score"] - r["score"].iloc[0]
    r["ratio"] = r["score"] / r["score"].iloc[0] if r["score"].iloc[0] > 0 else np.nan
    r.attrs["criterion"] = criterion
    return r


def best_model(cv_table: pd.DataFrame, criterion: str = "auto") -> str:
    """The winner of :func:`rank_models` (lowest score; exact ties go to the simpler model)."""
    return str(rank_models(cv_table, criterion)["model"].iloc[0])
