"""What a DFT trace determines of the exponential-decay law, per site.

A back-calculation (:mod:`skidsim.calibration`) returns one law ``mu(s) = mu_k + (mu_s - mu_k) exp(-alpha s)``
per site. This module says how far to trust it, from what the calibration already produced (the trace, the
calibrated law with the surrogate state it was fitted under, the FE verification runs and the FE runs at the
calibration and validation speeds); it runs no FE.

Units: speeds ``v`` in km/h, slip speed ``s = v / 3.6`` in m/s inside the law, ``alpha`` in s/m; ``mu`` and SN
dimensionless (DFT scale, not x100).

The FE mapping. Our calibration models the FE as ``SN(v) = a(v) + b(v) mu(v + d(v))`` (:func:`calibrate_fast`;
``a, b, d`` per calibration speed, linear in between, constant beyond; ``d`` in km/h). The data are fitted *through
that mapping*; this module uses the calibration's final mapping (:class:`SurrogateMap`; the identity for the study's
bisection, which has none), so the law is judged on the scale the calibration fitted it.

Per site (:func:`assess`):

* **noise** (:func:`trace_noise`): the scatter of the trace around a local quadratic smooth (every point, the
  points within ``+-noise_window_kmh``), ``sigma^2 = RSS / (n - 2 tr H + tr H'H)`` (H the smoother's hat
  matrix), and the lag-one autocorrelation ``rho1`` of those residuals. Noise slower than the window counts
  as curve: on correlated noise ``sigma`` is a lower bound.
* **fit**: RMSE of the FE at the calibration and at the validation speeds against the measured curve
  (linear interpolation of the trace, as the calibration uses it), in units of ``sigma``.
* **flags** with reasons: ``not_converged``; ``at_bound`` (which parameter, which bound, and whether the
  bound costs fit); ``outside_law`` (the best law of the family, with wide bounds, through the mapping, cannot
  fit the trace points within ``outside_law_factor * sigma``); ``fe_not_smooth`` (the FE missed the surrogate by
  more than ``fe_miss_max`` in a verification run after the surrogate had been corrected and the law had changed
  by at most ``fe_smooth_step_max`` (mu), measured against the surrogate as that correction would be as a whole
  step, or at the validation speeds); ``fit_beyond_noise``
  (FE RMSE at calibration or validation speeds above ``fit_noise_factor * sigma``).
* **uncertainty**: the Jacobian ``J`` of the fitted curve (the points the calibration fitted) with respect to
  ``(mu_s, mu_k, alpha)`` at the calibrated law, the Gauss-Newton covariance ``sigma_eff^2 (J'J)^-1`` with
  ``sigma_eff^2 = max(sigma^2, s_resid^2) (1 + rho) / (1 - rho)`` (``s_resid``: the residual scatter of the law
  family's best fit within the wide bounds, larger than ``sigma`` when the curve is outside the law or the noise is
  correlated; ``rho``: the lag-one autocorrelation of those residuals in speed order, clipped to [0, 0.9], the
  AR(1) variance inflation; a calibration bound that costs fit is reported as ``bound_cost_rmse``, not taken as
  noise), standard errors, the eigen-decomposition of ``J'J`` in parameters
  scaled by their bound widths (identified directions: 95 % half-width <= ``identified_rel_halfwidth`` of the
  range), profile-likelihood intervals (``(SSE_profile - SSE_min) / sigma_eff^2 <= chi2_1(0.95)`` over the
  calibration bounds; an interval that reaches a bound is open there, "not bounded within the bounds"), and
  three curve combinations of the law over the calibration window, all in mu: the level at the window's middle,
  the slope times the half-span and half the curvature times the half-span squared (identified when their 95 %
  half-width <= ``identified_halfwidth_mu``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar
from scipy.stats import chi2

from skidsim.calibration.law_fit import box_ls2_many, fit_exponential_decay
from skidsim.calibration.measured import measured_arrays, measured_at
from skidsim.calibration.options import DEFAULT_BOUNDS, PARAMS, IdentifiabilityOptions
from skidsim.calibration.result import CalibrationResult
from skidsim.errors import InputError
from skidsim.friction import KMH_PER_MS, ExponentialDecay

FLAGS = ("not_converged", "at_bound", "outside_law", "fe_not_smooth", "fit_beyond_noise")


@dataclass(frozen=True)
class SurrogateMap:
    """The calibration's FE mapping ``SN(v) = a(v) + b(v) mu(v + d(v))`` (v, d in km/h); linear interpolation
    between ``speeds_kmh``, constant beyond (as :func:`skidsim.calibration.calibrate_fast`)."""

    speeds_kmh: tuple[float, ...]
    a: tuple[float, ...]
    b: tuple[float, ...]
    d_kmh: tuple[float, ...]

    @classmethod
    def identity(cls) -> SurrogateMap:
        return cls((40.0,), (0.0,), (1.0,), (0.0,))

    @classmethod
    def from_result(cls, result: CalibrationResult) -> SurrogateMap:
        """The final surrogate of an ``ours`` result; the identity for a result without one (the study)."""
        s = result.settings or {}
        if not all(k in s for k in ("speeds_kmh", "b")):
            return cls.identity()
        v = tuple(float(x) for x in s["speeds_kmh"])
        n = len(v)
        a = tuple(float(x) for x in (s.get("a") or [0.0] * n))
        d = (
            tuple(float(x) for x in (s.get("slip_offsets_kmh") or [0.0] * n))
            if s.get("model", "slip") == "slip"
            else (0.0,) * n
        )
        b = tuple(float(x) for x in s["b"])
        if not (len(a) == len(b) == len(d) == n):
            raise InputError(
                None,
                "surrogate settings a, b, slip_offsets_kmh of one length per calibration speed",
                got={"speeds_kmh": v, "a": a, "b": b, "d": d},
            )
        return cls(v, a, b, d)

    def terms(self, v_kmh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a, b, effective slip speed in m/s) at ``v_kmh``."""
        v = np.asarray(v_kmh, dtype=float)
        sv = np.asarray(self.speeds_kmh)
        a = np.interp(v, sv, self.a)
        b = np.interp(v, sv, self.b)
        s = (v + np.interp(v, sv, self.d_kmh)) / KMH_PER_MS
        return a, b, s

    def predict(self, law: ExponentialDecay, v_kmh) -> np.ndarray:
        """Surrogate SN of ``law`` at ``v_kmh``."""
        a, b, s = self.terms(v_kmh)
        return a + b * law.mu(s)

    def jacobian(self, law: ExponentialDecay, v_kmh) -> np.ndarray:
        """d SN / d (mu_s, mu_k, alpha[s/m]) at ``v_kmh``: shape (n, 3)."""
        _, b, s = self.terms(v_kmh)
        e = np.exp(-law.alpha * s)
        return np.column_stack([b * e, b * (1.0 - e), -b * (law.mu_s - law.mu_k) * s * e])


# ----------------------------------------------------------------------------------------------------
# noise


def trace_noise(
    v_kmh, mu, *, window_kmh: float = 15.0, range_kmh: tuple[float, float] | None = None, min_points: int = 12
) -> dict:
    """Noise of a trace: scatter around a local quadratic smooth (see the module docstring).

    Every point in ``range_kmh`` (default: all) is compared with the quadratic fitted to the trace points within
    ``+-window_kmh`` of it (the whole trace may contribute neighbours). Returns ``sigma`` (mu), ``rho1`` (lag-one
    autocorrelation of the residuals in speed order), ``n`` (points used), ``dof`` (``n - 2 tr H + tr H'H``),
    ``method``. The local smooth absorbs noise slower than the window, so on correlated noise sigma is biased
    low (default synthetic campaign, AR(1) noise: 0.012 at 15 km/h, 0.0097 at 5 km/h, true 0.0136). With fewer
    than ``min_points`` points, or a window holding fewer than 4 distinct speeds, sigma and rho1 are NaN.
    """
    v = np.asarray(v_kmh, dtype=float)
    y = np.asarray(mu, dtype=float)
    order = np.argsort(v, kind="stable")
    v, y = v[order], y[order]
    lo, hi = (v[0], v[-1]) if range_kmh is None else (float(range_kmh[0]), float(range_kmh[1]))
    idx = np.flatnonzero((v >= lo - 1e-9) & (v <= hi + 1e-9))
    out = {
        "sigma": float("nan"),
        "rho1": float("nan"),
        "n": int(idx.size),
        "dof": float("nan"),
        "method": f"local quadratic +-{window_kmh:g} km/h, sigma^2 = RSS / (n - 2 tr H + tr H'H)",
    }
    if idx.size < max(int(min_points), 5):
        return out
    resid = np.empty(idx.size)
    tr_h = 0.0
    tr_hh = 0.0
    for k, i in enumerate(idx):
        sel = np.flatnonzero(np.abs(v - v[i]) <= window_kmh)
        if np.unique(v[sel]).size < 4:
            return out
        x = v[sel] - v[i]
        X = np.column_stack([np.ones_like(x), x, x * x])
        w = np.linalg.solve(X.T @ X, X.T)[0]  # row of the hat matrix: fitted value at v[i] = w @ y[sel]
        resid[k] = y[i] - float(w @ y[sel])
        tr_h += float(w[sel == i].sum())
        tr_hh += float(w @ w)
    dof = idx.size - 2.0 * tr_h + tr_hh
    sigma = math.sqrt(float(resid @ resid) / dof) if dof > 0 else float("nan")
    r = resid - resid.mean()
    rho1 = float((r[:-1] @ r[1:]) / (r @ r)) if (r @ r) > 0 else 0.0
    out.update(sigma=sigma, rho1=rho1, dof=float(dof))
    return out


# ----------------------------------------------------------------------------------------------------
# profile likelihood


def _profile_sse(
    param: str,
    values: np.ndarray,
    s: np.ndarray,
    b: np.ndarray,
    z: np.ndarray,
    bounds: Mapping[str, tuple[float, float]],
    alphas: np.ndarray,
) -> np.ndarray:
    """min SSE over the other two parameters (box-bounded) with ``param`` fixed at each of ``values``.

    Model ``z = b (mu_k (1 - e) + mu_s e)``, ``e = exp(-alpha s)``. For fixed alpha the model is linear in
    (mu_k, mu_s): alpha fixed -> the exact 2-unknown box problem; mu_k or mu_s fixed -> the exact 1-unknown box
    problem on every alpha of the grid ``alphas``, minimum over the grid refined by bounded Brent between the
    best grid value's neighbours.
    """
    lo2 = np.array([bounds["mu_k"][0], bounds["mu_s"][0]], dtype=float)
    hi2 = np.array([bounds["mu_k"][1], bounds["mu_s"][1]], dtype=float)
    if param == "alpha":
        e = np.exp(-np.outer(values, s))
        _, sse = box_ls2_many(b * (1.0 - e), b * e, z, lo2, hi2)
        return sse
    e = np.exp(-np.outer(alphas, s))  # (A, n)
    if param == "mu_k":
        fixed_col, free_col, free = b * (1.0 - e), b * e, "mu_s"
    elif param == "mu_s":
        fixed_col, free_col, free = b * e, b * (1.0 - e), "mu_k"
    else:
        raise ValueError(f"unknown parameter {param!r}")
    flo, fhi = (float(x) for x in bounds[free])

    def sse_at(c: float, fixed, freec) -> np.ndarray:
        r = z[None, :] - c * fixed  # (A, n)
        ff = np.einsum("an,an->a", freec, freec)
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.where(ff > 0, np.einsum("an,an->a", freec, r) / ff, flo)
        res = r - np.clip(p, flo, fhi)[:, None] * freec
        return np.einsum("an,an->a", res, res)

    def cols(al: float):
        e1 = np.exp(-al * s)[None, :]
        return (b * (1.0 - e1), b * e1) if param == "mu_k" else (b * e1, b * (1.0 - e1))

    out = np.empty(values.size)
    for k, c in enumerate(values):
        sse = sse_at(float(c), fixed_col, free_col)
        i = int(np.argmin(sse))
        best = float(sse[i])
        left, right = float(alphas[max(i - 1, 0)]), float(alphas[min(i + 1, alphas.size - 1)])
        if right > left:  # refine alpha between the grid neighbours (the profile is sharp when the rest is pinned)
            res = minimize_scalar(
                lambda al, c=c: float(sse_at(float(c), *cols(al))[0]),
                bounds=(left, right),
                method="bounded",
                options={"xatol": 1e-10},
            )
            if res.success and float(res.fun) < best:
                best = float(res.fun)
        out[k] = best
    return out


def _interval_from_profile(grid: np.ndarray, dev: np.ndarray, crit: float, lo: float, hi: float) -> dict:
    """The confidence set {dev <= crit} on ``grid``: its hull (ends interpolated), whether each end is open at a
    bound, and the number of disjoint pieces (two branches give 2)."""
    inside = dev <= crit
    if not inside.any():  # numerical: the minimum lies between grid points
        k = int(np.argmin(dev))
        return {
            "lower": float(grid[k]),
            "upper": float(grid[k]),
            "lower_open": False,
            "upper_open": False,
            "n_pieces": 1,
        }
    ks = np.flatnonzero(inside)
    i0, i1 = int(ks[0]), int(ks[-1])
    pieces = 1 + int(np.sum(np.diff(ks) > 1))

    def cross(i_out, i_in):
        d0, d1 = dev[i_out], dev[i_in]
        t = (crit - d0) / (d1 - d0) if d1 != d0 else 0.5
        return float(grid[i_out] + t * (grid[i_in] - grid[i_out]))

    lower = float(grid[0]) if i0 == 0 else cross(i0 - 1, i0)
    upper = float(grid[-1]) if i1 == grid.size - 1 else cross(i1 + 1, i1)
    return {
        "lower": lower,
        "upper": upper,
        "lower_open": i0 == 0 and lo == grid[0],
        "upper_open": i1 == grid.size - 1 and hi == grid[-1],
        "n_pieces": pieces,
    }


def profile_intervals(
    v_kmh,
    y,
    mapping: SurrogateMap,
    bounds: Mapping[str, tuple[float, float]],
    sigma_eff: float,
    *,
    confidence: float = 0.95,
    points: int = 121,
    alpha_points: int = 801,
) -> dict:
    """Profile-likelihood intervals of (mu_s, mu_k, alpha) within ``bounds`` for data ``y`` at ``v_kmh`` (km/h)
    through ``mapping``, noise sd ``sigma_eff`` (mu). Each profile is evaluated on ``points`` values over the
    bounds, and again on ``points`` values around the confidence set when fewer than 5 of them fall inside it (a
    parameter pinned by the data or by the other parameters' bounds). Returns ``{"sse_min", "params": {name:
    {lower, upper, lower_open, upper_open, n_pieces, grid, deviance}}}`` (deviance = (SSE_profile - SSE_min) /
    sigma_eff^2)."""
    v = np.asarray(v_kmh, dtype=float)
    a, b, s = mapping.terms(v)
    z = np.asarray(y, dtype=float) - a
    crit = float(chi2.ppf(confidence, 1))
    alphas = np.linspace(float(bounds["alpha"][0]), float(bounds["alpha"][1]), int(alpha_points))
    profiles = {}
    for p in PARAMS:
        lo, hi = (float(x) for x in bounds[p])
        grid = np.linspace(lo, hi, int(points))
        profiles[p] = (grid, _profile_sse(p, grid, s, b, z, bounds, alphas))
    _, sse_fit = fit_exponential_decay(s * KMH_PER_MS, y, a=a, b=b, bounds=bounds)
    sse_min = min(float(sse_fit), *(float(np.min(pr[1])) for pr in profiles.values()))
    # a sharp profile (fewer than 5 grid values inside the set) is profiled again on a fine grid around the set
    for p, (grid, sse) in list(profiles.items()):
        ks = np.flatnonzero((sse - sse_min) / sigma_eff**2 <= crit)
        if ks.size >= 5:
            continue
        k0, k1 = (int(ks[0]), int(ks[-1])) if ks.size else (int(np.argmin(sse)),) * 2
        i0, i1 = max(k0 - 1, 0), min(k1 + 1, grid.size - 1)
        fine = np.linspace(grid[i0], grid[i1], int(points))
        both = np.concatenate([grid, fine])
        order = np.argsort(both, kind="stable")
        vals = np.concatenate([sse, _profile_sse(p, fine, s, b, z, bounds, alphas)])[order]
        both = both[order]
        keep = np.concatenate([[True], np.diff(both) > 0])
        profiles[p] = (both[keep], vals[keep])
    sse_min = min(sse_min, *(float(np.min(pr[1])) for pr in profiles.values()))
    out = {"sse_min": sse_min, "critical_deviance": crit, "params": {}}
    for p, (grid, sse) in profiles.items():
        lo, hi = (float(x) for x in bounds[p])
        dev = (sse - sse_min) / sigma_eff**2
        rec = _interval_from_profile(grid, dev, crit, lo, hi)
        rec.update(grid=grid.tolist(), deviance=dev.tolist())
        out["params"][p] = rec
    return out


# ----------------------------------------------------------------------------------------------------
# local (Gauss-Newton) uncertainty


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


# ----------------------------------------------------------------------------------------------------
# the per-site record


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


def _fe_misses(
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


def _rmse(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def assess(
    result: CalibrationResult,
    trace,
    validation: pd.DataFrame | None = None,
    *,
    options: IdentifiabilityOptions | None = None,
    calibration_speeds_kmh: Sequence[float] | None = None,
    validation_speeds_kmh: Sequence[float] = (),
    site: str | None = None,
    source: str | None = None,
) -> dict:
    """The quality and identifiability record of one calibration (see the module docstring).

    result: the site's :class:`CalibrationResult` (ours or the study's); trace: the site's measured DFT curve
    (DataFrame speed_kmh [km/h], mu); validation: the site's FE runs of this method's final law (rows of
    ``validation.parquet`` for this method: speed_kmh, sn_sim, kind) or None; calibration_speeds_kmh: default the
    result's measured speeds. Returns a JSON-ready dict (NaN where undecided).
    """
    opt = options or IdentifiabilityOptions()
    v_all, mu_all = measured_arrays(trace, source=source)
    st = result.settings or {}
    cal, val, bounds = _speeds_and_bounds(result, calibration_speeds_kmh, validation_speeds_kmh)
    law = result.params
    mapping = SurrogateMap.from_result(result)
    v_fit, y_fit, fit_points = _judged_points(st, trace, v_all, mu_all, cal, source)
    noise = trace_noise(
        v_all,
        mu_all,
        window_kmh=opt.noise_window_kmh,
        range_kmh=(min(cal + val), max(cal + val)),
        min_points=opt.noise_min_points,
    )
    sigma = noise["sigma"]
    have_sigma = math.isfinite(sigma) and sigma > 0
    fam = _family_fits(mapping, law, v_fit, y_fit, bounds, opt)
    fe, fe_points = _fe_fit(result, trace, validation, cal, val, v_all, source)
    misses = _fe_misses(result, mapping, validation, cal, small_step_mu=opt.fe_smooth_step_max)
    flags, at_bound = _flags(result, bounds, opt, sigma, fam, fe, misses, fit_points)
    unc = _uncertainty(law, mapping, v_fit, y_fit, bounds, cal, sigma, fam, opt) if have_sigma else {"available": False}
    within = have_sigma and "fit_beyond_noise" not in flags and math.isfinite(fe["calibration"])
    ident = [p for p in PARAMS if unc.get("params", {}).get(p, {}).get("identified")]
    ident_c = [c for c, r in unc.get("combinations", {}).items() if r["identified"]]
    return {
        "site": site,
        "method": result.method,
        "law": law.as_dict(),
        "converged": bool(result.converged),
        "bounds": {k: list(v) for k, v in bounds.items()},
        "fit_points": fit_points,
        "n_fit_points": fam["n"],
        "noise": noise,
        "within_noise": bool(within),
        "flags": sorted(flags),
        "reasons": flags,
        "at_bound": at_bound,
        "fit": _fit_record(fe, fe_points, fam, sigma),
        "surrogate": {
            "speeds_kmh": list(mapping.speeds_kmh),
            "a": list(mapping.a),
            "b": list(mapping.b),
            "slip_offsets_kmh": list(mapping.d_kmh),
        },
        "fe_misses": misses,
        "uncertainty": unc,
        "identified_params": ident,
        "identified_combinations": ident_c,
        "statement": _statement(have_sigma, ident, ident_c, unc),
        "options": asdict(opt),
    }


def _speeds_and_bounds(
    result: CalibrationResult, calibration_speeds_kmh: Sequence[float] | None, validation_speeds_kmh: Sequence[float]
) -> tuple[list[float], list[float], dict[str, tuple[float, float]]]:
    """Calibration speeds (km/h; default the result's), validation speeds (km/h), and the calibration's bounds
    (its ``bounds`` or ``intervals`` setting, else :data:`DEFAULT_BOUNDS`)."""
    st = result.settings or {}
    cal_src = calibration_speeds_kmh
    if cal_src is None:
        cal_src = st.get("speeds_kmh") or sorted(result.measured_kmh)
    cal = sorted(float(v) for v in cal_src)
    val = sorted(float(v) for v in validation_speeds_kmh)
    src = st.get("bounds") or st.get("intervals") or DEFAULT_BOUNDS
    return cal, val, {k: tuple(float(x) for x in v) for k, v in src.items()}


def _fit_record(fe: dict, fe_points: list[dict], fam: dict, sigma: float) -> dict:
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


def _judged_points(
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


def _family_fits(
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
        "rmse_cal_law": _rmse(mapping.predict(law, v_fit) - y_fit),
        "rmse_bounded": math.sqrt(sse_b / n),
        "rmse_wide": math.sqrt(sse_w / n),
    }


def _fe_fit(
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
                fe[kind] = _rmse(rows["sn_sim"].to_numpy(float) - m)
                fe_points += [
                    {"speed_kmh": float(vv), "kind": kind, "sn_fe": float(x), "mu_measured": float(mm)}
                    for vv, x, mm in zip(rows["speed_kmh"], rows["sn_sim"], m)
                ]
    if not math.isfinite(fe["calibration"]):
        fs = result.final_sn()
        pts = [(vv, fs[vv]) for vv in fs if any(abs(vv - c) < 1e-9 for c in cal)]
        if pts:
            m = measured_at(trace, [p[0] for p in pts], source=source)
            fe["calibration"] = _rmse(np.array([p[1] for p in pts]) - m)
    return fe, fe_points


def _flags(
    result: CalibrationResult,
    bounds: Mapping[str, tuple[float, float]],
    opt: IdentifiabilityOptions,
    sigma: float,
    fam: dict,
    fe: dict,
    misses: dict,
    fit_points: str,
) -> tuple[dict[str, str], list[dict]]:
    """The raised flags with their reasons, and the parameters at a bound (see the module docstring)."""
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


def _uncertainty(
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
    ``sigma_eff^2 = max(sigma^2, s_resid^2) (1 + rho) / (1 - rho)`` (see the module docstring; needs sigma > 0)."""
    z = float(math.sqrt(chi2.ppf(opt.confidence, 1)))
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
        "law_in_joint_region": bool(joint <= chi2.ppf(opt.confidence, 3)),
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


def sse_of(mapping: SurrogateMap, law: ExponentialDecay, v_kmh, y) -> float:
    """Sum of squared differences between the surrogate curve of ``law`` and ``y`` at ``v_kmh``."""
    r = mapping.predict(law, v_kmh) - np.asarray(y, dtype=float)
    return float(r @ r)


def _statement(have_sigma: bool, ident: list[str], ident_c: list[str], unc: dict) -> str:
    if not have_sigma:
        return "noise not estimable from the trace (too few points): uncertainty not computed"
    parts = []
    parts.append("identified parameters: " + (", ".join(ident) if ident else "none"))
    parts.append("identified curve combinations: " + (", ".join(ident_c) if ident_c else "none"))
    weak = [d for d in unc["directions"] if not d["identified"]]
    for d in weak:
        vec = d["vector_range_units"]
        parts.append(
            "not identified: the direction "
            + " ".join(f"{vec[p]:+.2f} {p}" for p in PARAMS)
            + f" (range units; 95 % half-width {d['halfwidth_range_fraction']:.2g} of the range)"
        )
    return "; ".join(parts)


def table_row(rec: Mapping) -> dict:
    """One flat row of the campaign table ``identifiability.csv`` from a record of :func:`assess`."""
    row = {
        "site": rec["site"],
        "method": rec["method"],
        "mu_s": rec["law"]["mu_s"],
        "mu_k": rec["law"]["mu_k"],
        "alpha_s_per_m": rec["law"]["alpha"],
        "converged": bool(rec["converged"]),
        "sigma": rec["noise"]["sigma"],
        "rho1": rec["noise"]["rho1"],
        "within_noise": bool(rec["within_noise"]),
        "flags": ";".join(rec["flags"]),
        "n_flags": len(rec["flags"]),
    }
    for f in FLAGS:
        row[f] = f in rec["flags"]
    row["at_bound_params"] = ";".join(f"{d['param']}:{d['bound']}" for d in rec["at_bound"])
    for k in (
        "rmse_fe_calibration",
        "rmse_fe_validation",
        "rmse_fe_calibration_sigma",
        "rmse_fe_validation_sigma",
        "rmse_best_law_wide",
        "bound_cost_rmse",
    ):
        row[k] = rec["fit"][k]
    row["fe_miss_verify_corrected_max"] = rec["fe_misses"]["verify_corrected_max"]
    row["fe_miss_small_step_max"] = rec["fe_misses"]["small_step_max"]
    row["fe_miss_per_step_median"] = rec["fe_misses"]["miss_per_step_median"]
    row["fe_miss_validation_max"] = rec["fe_misses"]["validation_max"]
    unc = rec["uncertainty"]
    for p in PARAMS:
        pr = unc.get("params", {}).get(p, {})
        row[f"{p}_se"] = pr.get("se", float("nan"))
        row[f"{p}_lower"] = pr.get("profile_lower", float("nan"))
        row[f"{p}_upper"] = pr.get("profile_upper", float("nan"))
        row[f"{p}_open"] = ("lower" if pr.get("lower_open") else "") + ("upper" if pr.get("upper_open") else "")
        row[f"{p}_identified"] = bool(pr.get("identified", False))
    for c in ("level", "slope", "curvature"):
        cr = unc.get("combinations", {}).get(c, {})
        row[f"{c}_value"] = cr.get("value", float("nan"))
        row[f"{c}_halfwidth"] = cr.get("halfwidth", float("nan"))
    dirs = unc.get("directions") or []
    row["n_identified_directions"] = sum(bool(d["identified"]) for d in dirs)
    if dirs:
        w = dirs[0]["vector_range_units"]
        row["weakest_direction"] = " ".join(f"{w[p]:+.2f}{p}" for p in PARAMS)
        row["weakest_halfwidth_range_fraction"] = dirs[0]["halfwidth_range_fraction"]
    else:
        row["weakest_direction"] = ""
        row["weakest_halfwidth_range_fraction"] = float("nan")
    row["identified_params"] = ";".join(rec["identified_params"])
    row["identified_combinations"] = ";".join(rec["identified_combinations"])
    return row
