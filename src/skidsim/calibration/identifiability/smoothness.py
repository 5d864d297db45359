"""FE smoothness: where the FE missed the corrected surrogate after a small change of the law, in a verification
batch or at the validation speeds (:func:`fe_misses`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from skidsim.calibration.identifiability.mapping import SurrogateMap
from skidsim.calibration.result import CalibrationResult
from skidsim.friction import ExponentialDecay


def _batch_steps(ver: pd.DataFrame) -> pd.Series:
    """Per verification batch (``iteration``), the largest change of the law's mu at the batch's speeds from the
    law of the batch before (NaN for the first batch)."""
    laws = ver.groupby("iteration")[["mu_s", "mu_k", "alpha"]].first().sort_index()
    out = {}
    prev = None
    for k, row in laws.iterrows():
        law = ExponentialDecay(float(row["mu_s"]), float(row["mu_k"]), float(row["alpha"]))
        v = ver.loc[ver["iteration"] == k, "speed_kmh"].to_numpy(float)
        out[k] = float("nan") if prev is None else float(np.max(np.abs(law.mu_kmh(v) - prev.mu_kmh(v))))
        prev = law
    return pd.Series(out, dtype=float)


def fe_misses(
    result: CalibrationResult,
    mapping: SurrogateMap,
    validation: pd.DataFrame | None,
    cal_speeds: Sequence[float],
    *,
    small_step_mu: float,
) -> dict:
    """Surrogate-vs-FE misses (SN): verification runs after the surrogate was corrected (iteration >= 2; against
    the surrogate as its latest correction would be as a whole step, ``sn_pred_whole``, where the history has it:
    with ``correction_relaxation`` below 1 the surrogate used holds back part of each step by design), all
    verification runs (against the surrogate used), and the FE runs of the final law at the validation speeds.

    Each corrected batch also gets its step: the largest change of the law's mu (at the batch's speeds) from the
    law of the batch before, on which the surrogate was corrected. ``small_step_max`` is the largest miss over the
    batches whose step is at most ``small_step_mu``: a miss after a small change of the law is roughness of the
    FE's response; a miss after a large step that grows with the step is a response slope the surrogate does not
    have (smooth, but not the surrogate's; ``miss_per_step_median``, the median ratio miss / step, says how far)."""
    h = result.history
    out = {
        "verify_all_max": float("nan"),
        "verify_corrected_max": float("nan"),
        "n_verify": 0,
        "n_verify_corrected": 0,
        "small_step_max": float("nan"),
        "n_small_step": 0,
        "miss_per_step_median": float("nan"),
        "validation_max": float("nan"),
        "n_validation": 0,
        "validation_runs": [],
    }
    if len(h) and "stage" in h:
        ver = h[(h["stage"] == "verify") & h["sn_pred"].notna()]
        miss = (ver["sn_sim"] - ver["sn_pred"]).abs()
        out["n_verify"] = int(len(ver))
        if len(ver):
            out["verify_all_max"] = float(miss.max())
        if "sn_pred_whole" in ver:  # the whole-step surrogate: the FE's own roughness, not the relaxation's lag
            miss = (ver["sn_sim"] - ver["sn_pred_whole"].fillna(ver["sn_pred"])).abs()
        corr = miss[ver["iteration"] >= 2]
        out["n_verify_corrected"] = int(len(corr))
        if len(corr):
            out["verify_corrected_max"] = float(corr.max())
            steps = _batch_steps(ver)
            batch_miss = miss.groupby(ver["iteration"]).max()
            it = [k for k in steps.index if k >= 2 and k in batch_miss.index]
            small = [k for k in it if steps[k] <= small_step_mu]
            out["n_small_step"] = len(small)
            if small:
                out["small_step_max"] = float(batch_miss[small].max())
            ratio = [batch_miss[k] / steps[k] for k in it if steps[k] > 0]
            if ratio:
                out["miss_per_step_median"] = float(np.median(ratio))
    if validation is not None and len(validation) and result.method == "ours":
        cal = np.asarray(cal_speeds, dtype=float)
        rows = validation[~np.isclose(validation["speed_kmh"].to_numpy(float)[:, None], cal[None, :]).any(axis=1)]
        if len(rows):
            pred = mapping.predict(result.params, rows["speed_kmh"].to_numpy(float))
            d = rows["sn_sim"].to_numpy(float) - pred
            out["validation_max"] = float(np.max(np.abs(d)))
            out["n_validation"] = int(len(rows))
            out["validation_runs"] = [
                {"speed_kmh": float(v), "sn_fe": float(x), "sn_surrogate": float(p)}
                for v, x, p in zip(rows["speed_kmh"], rows["sn_sim"], pred)
            ]
    return out
