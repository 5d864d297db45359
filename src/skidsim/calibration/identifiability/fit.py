"""How well the law family and the FE fit the trace: the points the calibration judged, the family's best fits
within the calibration and wide bounds, the FE's RMSE at the calibration and validation speeds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import pandas as pd

from skidsim.calibration.identifiability.mapping import SurrogateMap
from skidsim.calibration.law_fit import fit_exponential_decay
from skidsim.calibration.measured import measured_at
from skidsim.calibration.options import IdentifiabilityOptions
from skidsim.calibration.result import CalibrationResult
from skidsim.friction import KMH_PER_MS, ExponentialDecay


def rmse(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def judged_points(
    settings: Mapping, trace, v_all: np.ndarray, mu_all: np.ndarray, cal: list[float], source
) -> tuple[np.ndarray, np.ndarray, str]:
    """The points the law is judged on: those the calibration fitted (fit_on trace: the trace in the fit range,
    default the calibration speeds' range; else the measured values at the calibration speeds). Returns
    (speeds km/h, mu, description)."""
    if settings.get("fit_on", "trace") == "trace":
        fr = settings.get("fit_range_kmh") or [cal[0], cal[-1]]
        sel = (v_all >= float(fr[0]) - 1e-9) & (v_all <= float(fr[1]) + 1e-9)
        return v_all[sel], mu_all[sel], f"trace points {float(fr[0]):g}-{float(fr[1]):g} km/h"
    v_fit = np.asarray(cal)
    return v_fit, measured_at(trace, v_fit, source=source), "measured values at the calibration speeds"


def family_fits(
    mapping: SurrogateMap,
    law: ExponentialDecay,
    v_fit: np.ndarray,
    y_fit: np.ndarray,
    bounds: Mapping[str, tuple[float, float]],
    opt: IdentifiabilityOptions,
) -> dict:
    """The law family's best fit through the mapping within the calibration bounds (``law_b``) and within wide
    bounds (``law_w``, its reach); their RMSEs and the calibrated law's; the residual lag-one autocorrelation
    ``rho_res`` of the wide fit and its AR(1) variance inflation (rho clipped to [0, 0.9]). The wide fit's residuals
    are the noise scale of the uncertainty: a bound that costs fit is reported as such, not mistaken for noise, and a
    curve outside the law widens the intervals."""
    n = int(v_fit.size)
    a, b, s = mapping.terms(v_fit)
    v_eff = s * KMH_PER_MS
    law_b, sse_b = fit_exponential_decay(v_eff, y_fit, a=a, b=b, bounds=bounds)
    wide = {"mu_s": (0.0, opt.wide_mu_max), "mu_k": (0.0, opt.wide_mu_max), "alpha": (0.0, opt.wide_alpha_max_s_per_m)}
    law_w, sse_w = fit_exponential_decay(v_eff, y_fit, a=a, b=b, bounds=wide)
    order = np.argsort(v_fit, kind="stable")
    res_w = (mapping.predict(law_w, v_fit) - y_fit)[order]
    res_w = res_w - res_w.mean()
    rho_res = float((res_w[:-1] @ res_w[1:]) / (res_w @ res_w)) if n > 2 and (res_w @ res_w) > 0 else 0.0
    rho = min(max(rho_res, 0.0), 0.9)
    return {
        "n": n,
        "law_b": law_b,
        "law_w": law_w,
        "sse_w": sse_w,
        "rho_res": rho_res,
        "inflation": (1.0 + rho) / (1.0 - rho),
        "rmse_cal_law": rmse(mapping.predict(law, v_fit) - y_fit),
        "rmse_bounded": math.sqrt(sse_b / n),
        "rmse_wide": math.sqrt(sse_w / n),
    }


def fe_fit(
    result: CalibrationResult,
    trace,
    validation: pd.DataFrame | None,
    cal: list[float],
    val: list[float],
    v_all: np.ndarray,
    source,
) -> tuple[dict, list[dict]]:
    """RMSE (SN) of the FE runs of the final law against the measured curve at the calibration and validation
    speeds the trace covers (from ``validation``; at the calibration speeds, without it, the result's own runs of
    its final law), and the points compared."""
    fe = {"calibration": float("nan"), "validation": float("nan")}
    fe_points = []
    if validation is not None and len(validation):
        for kind, speeds in (("calibration", cal), ("validation", val)):
            rows = (
                validation[
                    np.isclose(
                        validation["speed_kmh"].to_numpy(float)[:, None], np.asarray(speeds, dtype=float)[None, :]
                    ).any(axis=1)
                ]
                if speeds
                else validation.iloc[:0]
            )
            inside = (rows["speed_kmh"] >= v_all[0] - 1e-9) & (rows["speed_kmh"] <= v_all[-1] + 1e-9)
            rows = rows[inside]  # a speed the trace does not cover has no measured value to compare with
            if len(rows):
                m = measured_at(trace, rows["speed_kmh"].to_numpy(float), source=source)
                fe[kind] = rmse(rows["sn_sim"].to_numpy(float) - m)
                fe_points += [
                    {"speed_kmh": float(vv), "kind": kind, "sn_fe": float(x), "mu_measured": float(mm)}
                    for vv, x, mm in zip(rows["speed_kmh"], rows["sn_sim"], m)
                ]
    if not math.isfinite(fe["calibration"]):
        fs = result.final_sn()
        pts = [(vv, fs[vv]) for vv in fs if any(abs(vv - c) < 1e-9 for c in cal)]
        if pts:
            m = measured_at(trace, [p[0] for p in pts], source=source)
            fe["calibration"] = rmse(np.array([p[1] for p in pts]) - m)
    return fe, fe_points


def fit_record(fe: dict, fe_points: list[dict], fam: dict, sigma: float) -> dict:
    """The record's ``fit`` part: FE RMSEs vs measured (SN, and in sigma), the law family's fits and RMSEs."""
    have_sigma = math.isfinite(sigma) and sigma > 0
    return {
        "rmse_fe_calibration": fe["calibration"],
        "rmse_fe_validation": fe["validation"],
        "rmse_fe_calibration_sigma": fe["calibration"] / sigma if have_sigma else float("nan"),
        "rmse_fe_validation_sigma": fe["validation"] / sigma if have_sigma else float("nan"),
        "rmse_law_on_trace": fam["rmse_cal_law"],
        "rmse_best_law_bounded": fam["rmse_bounded"],
        "rmse_best_law_wide": fam["rmse_wide"],
        "bound_cost_rmse": fam["rmse_bounded"] - fam["rmse_wide"],
        "best_law_bounded": fam["law_b"].as_dict(),
        "best_law_wide": fam["law_w"].as_dict(),
        "fe_points": fe_points,
    }
