"""Local (Gauss-Newton) uncertainty of the calibrated law: standard errors and identified directions from the
Jacobian (:func:`local_uncertainty`), the three curve combinations over the calibration window
(:func:`curve_combinations`), and the per-site uncertainty record with the profile intervals
(:func:`site_uncertainty`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from skidsim.calibration.identifiability.mapping import SurrogateMap, sse_of
from skidsim.calibration.identifiability.profile import chi2_ppf, profile_intervals
from skidsim.calibration.options import PARAMS, IdentifiabilityOptions
from skidsim.friction import KMH_PER_MS, ExponentialDecay


def curve_combinations(law: ExponentialDecay, v_mid_kmh: float, half_span_kmh: float) -> tuple[np.ndarray, np.ndarray]:
    """Three combinations of the law over a speed window, all in mu, and their gradients wrt (mu_s, mu_k, alpha).

    level = mu(v_mid); slope = mu'(v_mid) * h; curvature = mu''(v_mid) * h^2 / 2 (derivatives in km/h, h the
    half-span in km/h): the coefficients of the law's quadratic expansion on the window in ``(v - v_mid) / h``.
    Returns (values (3,), gradients (3, 3): row per combination).
    """
    c = 1.0 / KMH_PER_MS
    s = v_mid_kmh * c
    h = half_span_kmh
    al, amp = law.alpha, law.mu_s - law.mu_k
    e = math.exp(-al * s)
    level = law.mu_k + amp * e
    slope = -amp * al * c * e * h
    curv = 0.5 * amp * (al * c) ** 2 * e * h * h
    g_level = [e, 1.0 - e, -amp * s * e]
    g_slope = [-al * c * e * h, al * c * e * h, -amp * c * h * e * (1.0 - al * s)]
    g_curv = [
        0.5 * (al * c) ** 2 * e * h * h,
        -0.5 * (al * c) ** 2 * e * h * h,
        0.5 * amp * c * c * h * h * e * (2.0 * al - al * al * s),
    ]
    return np.array([level, slope, curv]), np.array([g_level, g_slope, g_curv])


def local_uncertainty(J: np.ndarray, sigma_eff: float, widths: np.ndarray, *, z: float) -> dict:
    """Gauss-Newton covariance ``sigma_eff^2 (J'J)^-1`` (through the eigen-decomposition, eigenvalues floored at
    1e-14 of the largest), standard errors, and the eigen-decomposition of ``J'J`` in parameters scaled by
    ``widths`` (their bound widths): per direction, the eigenvalue, the unit eigenvector (mu_s, mu_k, alpha in
    range fractions) and the 95 % half-width along it in range fractions ``z sigma_eff / sqrt(lambda)``."""
    S = np.diag(widths)
    F = S @ (J.T @ J) @ S
    lam, vec = np.linalg.eigh(F)
    lam_f = np.maximum(lam, 1e-14 * max(float(lam[-1]), 1e-300))
    cov_scaled = (vec / lam_f) @ vec.T * sigma_eff**2
    cov = S @ cov_scaled @ S
    directions = []
    for k in np.argsort(lam):  # smallest eigenvalue (least determined) first
        u = vec[:, k]
        u = u if u[np.argmax(np.abs(u))] > 0 else -u
        directions.append(
            {
                "eigenvalue": float(lam[k]),
                "vector_range_units": dict(zip(PARAMS, map(float, u))),
                "halfwidth_range_fraction": float(z * sigma_eff / math.sqrt(lam_f[k])),
            }
        )
    return {
        "cov": cov,
        "se": np.sqrt(np.maximum(np.diag(cov), 0.0)),
        "directions": directions,
        "condition_number": float(lam_f[-1] / lam_f[0]),
    }


def site_uncertainty(
    law: ExponentialDecay,
    mapping: SurrogateMap,
    v_fit: np.ndarray,
    y_fit: np.ndarray,
    bounds: Mapping[str, tuple[float, float]],
    cal: list[float],
    sigma: float,
    fam: dict,
    opt: IdentifiabilityOptions,
) -> dict:
    """Standard errors, profile-likelihood intervals, eigen-directions and curve combinations of the law at noise
    ``sigma_eff^2 = max(sigma^2, s_resid^2) (1 + rho) / (1 - rho)`` (see the package :mod:`..identifiability`;
    needs sigma > 0)."""
    z = float(math.sqrt(chi2_ppf(opt.confidence, 1)))
    n = fam["n"]
    s_resid = math.sqrt(fam["sse_w"] / max(n - 3, 1))
    sigma_eff = math.sqrt(max(sigma**2, s_resid**2) * fam["inflation"])
    widths = np.array([bounds[p][1] - bounds[p][0] for p in PARAMS], dtype=float)
    loc = local_uncertainty(mapping.jacobian(law, v_fit), sigma_eff, widths, z=z)
    prof = profile_intervals(
        v_fit,
        y_fit,
        mapping,
        bounds,
        sigma_eff,
        confidence=opt.confidence,
        points=opt.profile_points,
        alpha_points=opt.alpha_grid_points,
    )
    v_mid, half = 0.5 * (cal[0] + cal[-1]), 0.5 * (cal[-1] - cal[0])
    params = {
        p: _param_record(law, p, prof["params"][p], float(loc["se"][k]), widths[k], opt) for k, p in enumerate(PARAMS)
    }
    combos = _combination_records(law, v_mid, half, loc["cov"], z, opt)
    for d in loc["directions"]:
        d["identified"] = bool(d["halfwidth_range_fraction"] <= opt.identified_rel_halfwidth)
    joint = (sse_of(mapping, law, v_fit, y_fit) - prof["sse_min"]) / sigma_eff**2
    return {
        "available": True,
        "sigma_eff": sigma_eff,
        "residual_rho1": fam["rho_res"],
        "ar1_inflation": fam["inflation"],
        "residual_sd": s_resid,
        "params": params,
        "combinations": combos,
        "directions": loc["directions"],
        "condition_number": loc["condition_number"],
        "cov": {p: dict(zip(PARAMS, map(float, loc["cov"][i]))) for i, p in enumerate(PARAMS)},
        "joint_deviance_of_law": float(joint),
        "law_in_joint_region": bool(joint <= chi2_ppf(opt.confidence, 3)),
        "profiles": {p: {"grid": prof["params"][p]["grid"], "deviance": prof["params"][p]["deviance"]} for p in PARAMS},
    }


def _param_record(
    law: ExponentialDecay, p: str, pr: dict, se: float, width: float, opt: IdentifiabilityOptions
) -> dict:
    """One parameter's value, standard error and profile interval; identified when the interval is closed, in one
    piece and its half-width at most ``identified_rel_halfwidth`` of the bound width."""
    closed = not (pr["lower_open"] or pr["upper_open"])
    return {
        "value": float(getattr(law, p)),
        "se": se,
        "profile_lower": pr["lower"],
        "profile_upper": pr["upper"],
        "lower_open": bool(pr["lower_open"]),
        "upper_open": bool(pr["upper_open"]),
        "n_pieces": int(pr["n_pieces"]),
        "identified": bool(
            closed and pr["n_pieces"] == 1 and 0.5 * (pr["upper"] - pr["lower"]) <= opt.identified_rel_halfwidth * width
        ),
        "deviance_at_value": float(np.interp(getattr(law, p), pr["grid"], pr["deviance"])),
    }


def _combination_records(
    law: ExponentialDecay, v_mid: float, half: float, cov: np.ndarray, z: float, opt: IdentifiabilityOptions
) -> dict:
    """Level, slope and curvature of the law over the calibration window (mu) with their standard errors from the
    local covariance ``cov``; identified when the 95 % half-width is at most ``identified_halfwidth_mu``."""
    cvals, cgrad = curve_combinations(law, v_mid, half)
    cse = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", cgrad, cov, cgrad), 0.0))
    combos = {}
    for name, cv, cs, unit in zip(
        ("level", "slope", "curvature"),
        cvals,
        cse,
        (f"mu at {v_mid:g} km/h", f"mu'(v) * {half:g} km/h", f"mu''(v) * ({half:g} km/h)^2 / 2"),
    ):
        combos[name] = {
            "value": float(cv),
            "se": float(cs),
            "halfwidth": float(z * cs),
            "definition": unit,
            "identified": bool(z * cs <= opt.identified_halfwidth_mu),
        }
    return combos
