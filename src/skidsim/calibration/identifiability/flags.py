"""The flags of a calibration, each with its reason (:data:`FLAGS`, :func:`site_flags`)."""

from __future__ import annotations

import math
from collections.abc import Mapping

from skidsim.calibration.options import PARAMS, IdentifiabilityOptions
from skidsim.calibration.result import CalibrationResult

FLAGS = ("not_converged", "at_bound", "outside_law", "fe_not_smooth", "fit_beyond_noise")


def site_flags(
    result: CalibrationResult,
    bounds: Mapping[str, tuple[float, float]],
    opt: IdentifiabilityOptions,
    sigma: float,
    fam: dict,
    fe: dict,
    misses: dict,
    fit_points: str,
) -> tuple[dict[str, str], list[dict]]:
    """The raised flags with their reasons, and the parameters at a bound (see the package :mod:`..identifiability`)."""
    have_sigma = math.isfinite(sigma) and sigma > 0
    flags: dict[str, str] = {}
    if not result.converged:
        flags["not_converged"] = result.message
    at_bound = []
    for p in PARAMS:
        lo, hi = bounds[p]
        val_p = float(getattr(result.params, p))
        tol_p = opt.at_bound_rel_tol * (hi - lo)
        for side, bnd in (("lower", lo), ("upper", hi)):
            if abs(val_p - bnd) <= tol_p:
                at_bound.append({"param": p, "bound": side, "bound_value": bnd, "value": val_p})
    if at_bound:
        bound_cost = fam["rmse_bounded"] - fam["rmse_wide"]
        txt = ", ".join(
            f"{d['param']} = {d['value']:.4g} at its {d['bound']} bound {d['bound_value']:g}" for d in at_bound
        )
        if have_sigma:
            txt += (
                f"; relaxing the bounds lowers the law's RMSE on the trace by {bound_cost:.3g} "
                f"({bound_cost / sigma:.2f} sigma)"
            )
        flags["at_bound"] = txt
    rmse_wide = fam["rmse_wide"]
    if have_sigma and rmse_wide > opt.outside_law_factor * sigma:
        flags["outside_law"] = (
            f"the best law of the family (mu in [0, {opt.wide_mu_max:g}], alpha in "
            f"[0, {opt.wide_alpha_max_s_per_m:g}] s/m, through the FE mapping) misses the "
            f"{fit_points} by RMSE {rmse_wide:.4g} = {rmse_wide / sigma:.2f} sigma "
            f"> {opt.outside_law_factor:g} sigma (sigma {sigma:.4g})"
        )
    miss_parts = []
    for key, label in (
        (
            "small_step_max",
            f"a verification run after a correction and a change of the law by at most {opt.fe_smooth_step_max:g} mu",
        ),
        ("validation_max", "a validation speed"),
    ):
        if math.isfinite(misses[key]) and misses[key] > opt.fe_miss_max:
            miss_parts.append(f"{label}: |SN_FE - SN_surrogate| = {misses[key]:.3g}")
    if miss_parts:
        flags["fe_not_smooth"] = "; ".join(miss_parts) + f" > {opt.fe_miss_max:g}"
    if have_sigma:
        beyond = [
            f"{k} speeds RMSE {fe[k]:.4g} = {fe[k] / sigma:.2f} sigma"
            for k in ("calibration", "validation")
            if math.isfinite(fe[k]) and fe[k] > opt.fit_noise_factor * sigma
        ]
        if beyond:
            flags["fit_beyond_noise"] = "; ".join(beyond) + f" > {opt.fit_noise_factor:g} sigma (sigma {sigma:.4g})"
    return flags, at_bound
