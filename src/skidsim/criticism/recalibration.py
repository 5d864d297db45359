"""Recalibration of an extension on training sites and its predictions ('after' values) in a scope.

Physical extensions (:class:`TemperatureShift`, :class:`DrainageIFI`) fit their parameters by minimising the
training rows' squared error; generic terms (:class:`SharedShape`, :class:`CovariateTerm`) by least squares or
group means on the training residuals; a texture-adjusted :class:`CovariateTerm` between sites is a texture
refit. Friction mu (dimensionless), speeds km/h, temperatures deg C.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
from scipy.optimize import minimize, minimize_scalar

from ..errors import ConfigError, InputError
from ..friction import KMH_PER_MS
from .extensions import (
    DRAINAGE_FORMS,
    CovariateTerm,
    DrainageIFI,
    SharedShape,
    TemperatureShift,
    TextureModelTerm,
    ViscoelasticFE,
    exp_curve,
    fit_exp_curves,
)
from .scopes import Scope, centred_speed, site_mean, site_target, site_values

#: Grid points of the profile of the WLF reference temperature over its bounds.
WLF_GRID = 41
#: Start values of the decay constant's slope g (log10 alpha per log10 mm of the decay column) in
#: :func:`wlf_from_curves`, and the Nelder-Mead settings of (c0, g).
DECAY_SLOPE_GRID = (-1.5, -0.75, 0.0, 0.75, 1.5)
NELDER_MEAD = {"xatol": 1e-4, "fatol": 1e-10, "maxfev": 200}

# ----------------------------------------------------------------------------------------------------------------
# texture refit
# ----------------------------------------------------------------------------------------------------------------


def refit_design(scope: Scope, cov: pd.DataFrame, k: int, column: str | None) -> np.ndarray:
    """Site design ``[1, PC_1..k]`` of the texture refit, plus the covariate ``column`` unless None (the PC scores
    are the ``_tpc<j>`` columns that :func:`skidsim.criticism.gain.evaluate_extension` adds to the covariates)."""
    S = cov.loc[scope.sites, [f"_tpc{j}" for j in range(1, k + 1)]].to_numpy(float)
    cols = [np.ones(len(scope.sites)), S] + ([cov.loc[scope.sites, column].to_numpy(float)] if column else [])
    return np.column_stack(cols)


def refit_correction(on: str, beta, X: np.ndarray, scope: Scope, before: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Per-row correction of a texture refit: the site's level (``on="level"``) or speed slope of the prediction
    is replaced by the linear model's ``X_i beta`` (fitted on the training sites' measured site means or slopes):
    ``after = before + (X_i beta - mean_i before)`` or ``+ (X_i beta - slope_i before) (v - mean_i v)``; the
    texture model's speed profile (level) is kept."""
    d = (X @ np.asarray(beta) - site_target(on, scope, before, dv))[scope.row_site]
    return d if on == "level" else d * dv


def _texture_partial(scope: Scope, cov: pd.DataFrame, z: np.ndarray, train: np.ndarray, k: int) -> np.ndarray:
    """``z`` (per site of the scope) minus its least-squares prediction from ``[1, PC_1..k]`` fitted on the
    training sites."""
    X = refit_design(scope, cov, k, None)
    c, *_ = np.linalg.lstsq(X[train], z[train], rcond=None)
    return z - X @ c


# ----------------------------------------------------------------------------------------------------------------
# physical extensions
# ----------------------------------------------------------------------------------------------------------------


def _physical_params(ext, scope: Scope, cov: pd.DataFrame) -> tuple[list, list]:
    """Names and bounds of the fitted parameters of a physical extension in a scope."""
    if isinstance(ext, TemperatureShift):
        tb = ext.t_ref_bounds_c(site_values(cov, ext.column, scope.sites))
        if ext.fit_level:
            return ["t_ref_c", "level_per_c"], [tb, ext.level_bounds_per_c]
        return ["t_ref_c"], [tb]
    if isinstance(ext, DrainageIFI):
        return ["kappa"], [ext.kappa_bounds]
    raise ConfigError(f"not a physical extension: {type(ext).__name__}")


def _training_offset(scope: Scope, train: np.ndarray, after: np.ndarray) -> float:
    """Campaign-wide level offset (mu) of an extended between-site prediction: the mean training residual
    ``measured - after`` over the training sites' rows (closed-form least squares of a constant)."""
    rtr = train[scope.row_site]
    return float(np.mean(scope.rows["measured"].to_numpy(float)[rtr] - after[rtr]))


def _after_temperature(
    ext: TemperatureShift, scope: Scope, cov: pd.DataFrame, train: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    v = scope.rows["speed_kmh"].to_numpy(float)
    before = scope.rows["before"].to_numpy(float)
    i = scope.row_site
    if scope.name == "held_out_speeds":
        # refitting the law through the calibration points at effective speeds k v gives
        # f(k v; b, c, alpha / k) = f(v; b, c, alpha): the exponential family is closed under speed scaling,
        # so a per-site calibration absorbs a temperature shift exactly and 'after' equals 'before' (the
        # vertical factor b_T scales b and c and is absorbed likewise)
        return before.copy()
    T = site_values(cov, ext.column, scope.sites)
    if ext.texture_pcs >= 0:
        T = float(T[train].mean()) + _texture_partial(scope, cov, T, train, ext.texture_pcs)
    anchor = float(T[train].mean())
    k = ext.speed_factor(T, anchor, float(theta[0]))
    bt = ext.vertical_factor(T, anchor, float(theta[1]) if len(theta) > 1 else None)
    b0, c0, a0 = scope.base
    if len(theta) > 2 and np.isfinite(float(theta[2])):
        # the decay constant from the measured curves (wlf_from_curves): alpha_ref a_T(T_i) / a_T(T_0) at the
        # site's own temperature (the decay constants follow the temperature itself, not its texture-free part)
        Tr = site_values(cov, ext.column, scope.sites)
        alpha = 10.0 ** float(theta[2]) * ext.speed_factor(Tr, float(Tr[train].mean()), float(theta[0]))
        if len(theta) > 6:  # the decay constant's texture term (theta[5] per log10 mm about theta[6])
            lx = _log10_decay_column(ext, cov, scope.sites)
            alpha = alpha * 10.0 ** (float(theta[5]) * (lx - float(theta[6])))
        if len(theta) > 4:  # the law's b and c from the texture (coefficients theta[3], theta[4] on [1, PCs])
            X = refit_design(scope, cov, max(ext.texture_pcs, 0), None)
            bb, cc = X @ np.asarray(theta[3]), X @ np.asarray(theta[4])
            a = bt[i] * exp_curve(v, bb[i], cc[i], alpha[i])
        else:
            a = before + bt[i] * exp_curve(v, b0[i], c0[i], alpha[i]) - exp_curve(v, b0[i], c0[i], a0[i])
    else:
        a = before + bt[i] * exp_curve(v * k[i], b0[i], c0[i], a0[i]) - exp_curve(v, b0[i], c0[i], a0[i])
    return a + _training_offset(scope, train, a)


def _after_drainage(
    ext: DrainageIFI, scope: Scope, cov: pd.DataFrame, train: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    v = scope.rows["speed_kmh"].to_numpy(float)
    before = scope.rows["before"].to_numpy(float)
    i = scope.row_site
    inv_sp = ext.inverse_speed_constant(site_values(cov, ext.mpd_column, scope.sites))
    if scope.name == "held_out_speeds":
        b0, c0, a0 = scope.base
        M = ext.multiplier(scope.fit_v, inv_sp[:, None], float(theta[0]))
        b1, c1, a1 = fit_exp_curves(scope.fit_v, scope.fit_y / M)
        return (
            before
            + exp_curve(v, b1[i], c1[i], a1[i]) * ext.multiplier(v, inv_sp[i], float(theta[0]))
            - exp_curve(v, b0[i], c0[i], a0[i])
        )
    if ext.form == "squeeze":  # relative to the training sites' mean 1/Sp^2 (the texture model carries it)
        d2 = inv_sp**2 - (inv_sp[train] ** 2).mean()
        m = np.maximum(ext.floor, 1.0 - theta[0] * v * v * d2[i])
    else:
        d = inv_sp - inv_sp[train].mean()
        m = np.exp(-theta[0] * v * d[i])
    return before * m / site_mean(m, i, len(scope.sites))


def after_physical(ext, scope: Scope, cov: pd.DataFrame, train: np.ndarray, theta) -> np.ndarray:
    """'after' values of every row of ``scope`` for parameters ``theta`` (anchors from the training sites).

    Within a site (held-out speeds) the law is refitted through the calibration points with the extension
    included and the change is added to the calibrated simulation: ``after = before + f_ext(v) - f_plain(v)``.
    Between sites the prediction is transformed: TemperatureShift evaluates the exponential fitted to the
    prediction at the shifted speed; DrainageIFI multiplies by ``m_i(v) / mean_site(m_i)`` with
    ``m_i(v) = exp(-kappa v (1/Sp_i - mean_train 1/Sp))``: a pure shape correction that keeps each site's mean
    predicted level over its evaluated speeds (the texture model already carries the level, and the IFI anchor
    speed then drops out). Between sites an extension that acts on the level (TemperatureShift) also refits the
    campaign-wide level offset of the texture model (:func:`_training_offset`, the mean training residual after
    the extension), as the generic level term does with its intercept b0; shape extensions (DrainageIFI, slope
    terms) keep each site's level. gain.json ``over_shared_level`` separates that offset from the cause.
    """
    if isinstance(ext, TemperatureShift):  # scalars, then (law route) two coefficient vectors
        theta = list(theta) if isinstance(theta, (list, tuple)) else list(np.ravel(np.asarray(theta, dtype=float)))
        return _after_temperature(ext, scope, cov, train, theta)
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    if isinstance(ext, DrainageIFI):
        return _after_drainage(ext, scope, cov, train, theta)
    raise ConfigError(f"not a physical extension: {type(ext).__name__}")


def _minimise_one(obj, bounds) -> list:
    """A grid of 41 points over the bounds first (the squeeze form's objective is multimodal where the multiplier
    reaches its floor), then a bounded scalar search between the best grid value's neighbours."""
    lo, hi = bounds
    grid = np.linspace(lo, hi, 41)
    vals = [obj([g]) for g in grid]
    j = int(np.argmin(vals))
    a, b = grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]
    r = minimize_scalar(obj, bounds=(a, b), method="bounded", options={"xatol": 1e-4 * (hi - lo)})
    return [float(r.x)] if r.fun <= vals[j] else [float(grid[j])]


def _minimise_many(obj, bounds) -> list:
    """A coarse 9-point grid per parameter, then bounded Powell from the best grid point."""
    grids = np.meshgrid(*[np.linspace(lo, hi, 9) for lo, hi in bounds], indexing="ij")
    cand = np.stack([g.ravel() for g in grids], axis=1)
    th0 = cand[int(np.argmin([obj(c) for c in cand]))]
    r = minimize(obj, th0, method="Powell", bounds=bounds, options={"xtol": 1e-4, "ftol": 1e-12})
    return [float(x) for x in (r.x if r.fun <= obj(th0) else th0)]


def _curve_bc(V: np.ndarray, Y: np.ndarray, alpha: np.ndarray):
    """Per site the least-squares ``(b_i, c_i)`` of ``Y_i ~ b_i + c_i exp(-alpha_i s)`` and the residuals (NaN
    padded rows as in :func:`_curve_sse`)."""
    w = np.isfinite(Y)
    e = np.exp(-alpha[:, None] * np.where(w, V, 0.0) / KMH_PER_MS) * w
    yy = np.where(w, Y, 0.0)
    n, se, see = w.sum(1), e.sum(1), (e * e).sum(1)
    sy, sey = yy.sum(1), (e * yy).sum(1)
    det = n * see - se * se
    c = np.where(np.abs(det) > 1e-300, (n * sey - se * sy) / np.where(det == 0, 1, det), 0.0)
    b = (sy - c * se) / n
    return b, c, (b[:, None] + c[:, None] * e - yy) * w


def _curve_sse(V: np.ndarray, Y: np.ndarray, alpha: np.ndarray) -> float:
    """Sum over sites of the least-squares SSE of ``Y_i ~ b_i + c_i exp(-alpha_i s)`` (b, c in closed form per
    site; ``V`` km/h and ``Y`` mu, (n, J), NaN padded)."""
    r = _curve_bc(V, Y, alpha)[2]
    return float((r * r).sum())


def wlf_from_curves(
    ext: TemperatureShift,
    T: np.ndarray,
    V: np.ndarray,
    Y: np.ndarray,
    bounds,
    n_perm: int = 0,
    seed: int = 0,
    x: np.ndarray | None = None,
) -> dict:
    """The WLF reference temperature T_r (deg C) from the sites' measured curves.

    A speed shift ``mu_i(v) = mu_ref,i(v a_T(T_i) / a_T(T_0))`` of the exponential-decay law is the law with
    ``alpha_i = alpha_ref,i a_T(T_i) / a_T(T_0)`` (``f(k v; b, c, alpha) = f(v; b, c, k alpha)``): a per-site
    calibration absorbs it, but across sites the decay constants follow temperature. Model of the measured points
    (``V`` km/h, ``Y`` mu, one row per site): ``b_i + c_i exp(-alpha_i v / 3.6)`` with ``b_i, c_i`` free per site
    (the level and the vertical shift factor) and ``log10 alpha_i = c0 + log10 a_T(T_i; T_r) - log10 a_T(T_0;
    T_r)``, ``T_0`` the mean temperature, one reference decay constant ``c0`` for the campaign, C1 and C2
    universal: T_r is profiled over ``WLF_GRID`` points of ``bounds`` (c0 by a grid and a bounded scalar search at
    each), then refined by a bounded scalar search. With ``x`` (per site, the centred log10 of
    ``ext.decay_column``, :func:`decay_covariate`) the reference decay constant follows the texture too,
    ``log10 alpha_i = c0 + g x_i + ...`` (the IFI speed constant grows with MPD, so the decay constants of a
    campaign spread with its macrotexture whatever the temperature; without ``g`` that spread is noise against
    which a narrow temperature range pins T_r poorly): ``(c0, g)`` by a grid and Nelder-Mead at each T_r, in the
    model without the WLF term too; ``decay_slope`` is g (None without ``x``).

    ``identifiable``: the best T_r lies inside its bounds (at the "no effect" bound the curves show no speed shift)
    and, with ``n_perm > 0``, the WLF term's reduction of the squared error of the model without it
    (``log10 alpha_i = c0``, or ``c0 + g x_i``) is significant at 0.05 against ``n_perm`` permutations of the
    temperatures over the sites (seeded; profile on a 21-point grid for observed and permuted alike; the sites'
    own scatter of the decay constant is the noise, not the points'; with ``x`` the slope g held at its value in
    the model without the WLF term). Returns t_ref_c, log10_alpha_ref, decay_slope, sse, sse_without (mu^2),
    perm_p (None without permutations), identifiable and, when not identifiable, ``why``."""
    T = np.asarray(T, float)
    T0 = float(T.mean())

    def inner(shift):
        return _decay_fit(V, Y, shift, x)[:2]

    def sse(tr):
        return inner(ext_log10_shift(ext, T, tr) - ext_log10_shift(ext, np.array([T0]), tr)[0])[0]

    lo, hi = bounds
    grid = np.linspace(lo, hi, WLF_GRID)
    vals = np.array([sse(g) for g in grid])
    j = int(np.argmin(vals))
    a, b = grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]
    r = minimize_scalar(sse, bounds=(a, b), method="bounded", options={"xatol": 0.05})
    tr, best = (float(r.x), float(r.fun)) if r.fun <= vals[j] else (float(grid[j]), float(vals[j]))
    null = _decay_fit(V, Y, np.zeros(len(T)), x)  # the model without the WLF term: (sse, c0, g)
    sse0 = null[0]
    _, c0, g = _decay_fit(V, Y, ext_log10_shift(ext, T, tr) - ext_log10_shift(ext, np.array([T0]), tr)[0], x)
    p = None
    if n_perm > 0:
        coarse = np.linspace(lo, hi, 21)
        # the decay slope held at the model without the WLF term (the null model's nuisance), as an offset
        offset = 0.0 if x is None else null[2] * x
        sse_null = _decay_fit(V, Y, np.zeros(len(T)) + offset, None)[0]

        def gain_of(temps):
            t0 = float(temps.mean())
            ref = np.array([t0])
            return sse_null - min(
                _decay_fit(V, Y, ext_log10_shift(ext, temps, t_r) - ext_log10_shift(ext, ref, t_r)[0] + offset, None)[0]
                for t_r in coarse
            )

        rng = np.random.default_rng(seed)
        d_obs = gain_of(T)
        d_perm = np.array([gain_of(rng.permutation(T)) for _ in range(n_perm)])
        p = float((1 + np.sum(d_perm >= d_obs * (1 - 1e-12))) / (1 + n_perm))
    out = {"t_ref_c": tr, "log10_alpha_ref": c0, "decay_slope": g, "sse": best, "sse_without": sse0, "perm_p": p}
    why = None
    if j == 0 or tr - lo < 1e-3 * (hi - lo):
        why = "the measured curves show no WLF speed shift between sites (T_r at its 'no effect' bound)"
    elif j == len(grid) - 1:
        why = "T_r runs to the WLF pole (the speed shift is steeper than the WLF form allows)"
    elif p is not None and p > 0.05:
        why = (
            f"the decay constants of the measured curves do not follow the WLF shift of temperature beyond chance "
            f"(permutation p = {p:.2g}, {n_perm} permutations of the temperatures over the sites)"
        )
    out["identifiable"] = why is None
    if why:
        out["why"] = why
    return out


def _decay_fit(V: np.ndarray, Y: np.ndarray, shift: np.ndarray, x: np.ndarray | None) -> tuple:
    """``(sse, c0, g)`` of the curves ``Y_i ~ b_i + c_i exp(-alpha_i v)`` with ``log10 alpha_i = c0 + g x_i +
    shift_i`` (:func:`wlf_from_curves`): c0 by a 15-point grid and a bounded scalar search without ``x`` (g None);
    with ``x`` c0 by the grid at g = 0, then g on :data:`DECAY_SLOPE_GRID` at that c0, then Nelder-Mead on (c0, g)
    from the best of these."""

    def f(c0, g=0.0):
        return _curve_sse(V, Y, 10.0 ** np.clip(c0 + shift + (0.0 if x is None else g * x), -4.0, 1.0))

    grid_c0 = np.linspace(-3.0, 0.5, 15)
    if x is None:
        vals_c0 = [f(c) for c in grid_c0]
        m = int(np.argmin(vals_c0))
        lo_c, hi_c = grid_c0[max(m - 1, 0)], grid_c0[min(m + 1, len(grid_c0) - 1)]
        r = minimize_scalar(f, bounds=(lo_c, hi_c), method="bounded", options={"xatol": 1e-4})
        if r.fun <= vals_c0[m]:
            return float(r.fun), float(r.x), None
        return float(vals_c0[m]), float(grid_c0[m]), None
    c_best = min((f(c), c) for c in grid_c0)[1]
    best = min((f(c_best, g), c_best, g) for g in DECAY_SLOPE_GRID)
    r = minimize(lambda p: f(p[0], p[1]), [best[1], best[2]], method="Nelder-Mead", options=NELDER_MEAD)
    if r.fun <= best[0]:
        return float(r.fun), float(r.x[0]), float(r.x[1])
    return float(best[0]), float(best[1]), float(best[2])


def _log10_decay_column(ext: TemperatureShift, cov: pd.DataFrame, sites: list) -> np.ndarray | None:
    """log10 of ``ext.decay_column`` (mm) per site of ``sites``; None without a decay column or where it is
    missing, not finite or not positive at a site."""
    col = ext.decay_column
    if col is None or col not in cov.columns:
        return None
    v = pd.to_numeric(cov.loc[sites, col], errors="coerce").to_numpy(float)
    if not (np.isfinite(v).all() and (v > 0).all()):
        return None
    return np.log10(v)


def decay_covariate(ext: TemperatureShift, cov: pd.DataFrame, sites: list, centre: np.ndarray | None = None):
    """Per site of ``sites`` the log10 of ``ext.decay_column`` (mm) minus its mean over the sites where
    ``centre`` (bool mask; None: all) is true: the ``x`` of :func:`wlf_from_curves`, and that mean (log10 mm).
    ``(None, None)`` without a decay column or where it is missing, not finite or not positive at a site (the
    campaign's one reference decay constant)."""
    lx = _log10_decay_column(ext, cov, sites)
    if lx is None:
        return None, None
    mean = float(lx[centre].mean() if centre is not None else lx.mean())
    return lx - mean, mean


def ext_log10_shift(ext: TemperatureShift, T: np.ndarray, t_ref_c: float) -> np.ndarray:
    """log10 a_T(T) (deg C) of the extension's WLF constants; T at or below the pole gives +inf (excluded)."""
    dt = np.asarray(T, float) - float(t_ref_c)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ext.c2_k + dt > 0, -ext.c1 * dt / (ext.c2_k + dt), np.inf)


def site_curves(scope: Scope):
    """Per site of the scope its measured points (speeds km/h, mu; NaN padded, equal speeds averaged) as
    ``(V, Y)`` (n_sites, J); None with fewer than 4 speeds at the best-measured site."""
    g = scope.rows.groupby(["site", "speed_kmh"], as_index=False)["measured"].mean()
    J = int(g.groupby("site").size().max())
    if J < 4:
        return None
    pos = {site: k for k, site in enumerate(scope.sites)}
    V = np.full((len(scope.sites), J), np.nan)
    Y = np.full((len(scope.sites), J), np.nan)
    for site, gs in g.groupby("site"):
        V[pos[site], : len(gs)] = gs["speed_kmh"].to_numpy(float)
        Y[pos[site], : len(gs)] = gs["measured"].to_numpy(float)
    return V, Y


def temperature_identifiability(ext: TemperatureShift, scope: Scope, cov: pd.DataFrame, n_perm: int = 99) -> dict:
    """:func:`wlf_from_curves` on every site of the held-out-site scope with ``n_perm`` permutations of the
    temperatures (gain.json ``identifiability``); None without measured curves."""
    curves = site_curves(scope)
    if curves is None:
        return None
    T = site_values(cov, ext.column, scope.sites)
    x, _ = decay_covariate(ext, cov, scope.sites)
    return wlf_from_curves(ext, T, *curves, ext.t_ref_bounds_c(T), n_perm=n_perm, seed=0, x=x)


def _recalibrate_temperature_between(ext: TemperatureShift, scope: Scope, cov: pd.DataFrame, train: np.ndarray):
    """Between sites: T_r from the training sites' measured curves (:func:`wlf_from_curves`; nuisance of the
    reference decay constant: the ``texture_pcs`` texture PCs of a texture-adjusted cause), then the vertical
    factor's slope on the training rows with T_r held. None with fewer than 4 measured speeds per site."""
    curves = site_curves(scope)
    if curves is None:
        return None
    V, Y = curves
    T = site_values(cov, ext.column, scope.sites)
    x, x_mean = decay_covariate(ext, cov, scope.sites, centre=train)
    fit = wlf_from_curves(ext, T[train], V[train], Y[train], ext.t_ref_bounds_c(T), x=None if x is None else x[train])
    fit["n_sites"] = int(train.sum())
    alpha_ref = fit["log10_alpha_ref"]
    params = {"t_ref_c": fit["t_ref_c"], "level_per_c": float(ext.level_per_c), "log10_alpha_ref": alpha_ref}
    decay = [] if x is None else [fit["decay_slope"], x_mean]  # theta[5:7] of after_physical
    # the law's b and c of every training site at its WLF decay constant, regressed on the texture
    Ttr = T[train]
    alpha_tr = 10.0**alpha_ref * ext.speed_factor(Ttr, float(Ttr.mean()), fit["t_ref_c"])
    if x is not None:
        alpha_tr = alpha_tr * 10.0 ** (fit["decay_slope"] * x[train])
    b_tr, c_tr, _ = _curve_bc(V[train], Y[train], alpha_tr)
    X = refit_design(scope, cov, max(ext.texture_pcs, 0), None)
    beta_b = np.linalg.lstsq(X[train], b_tr, rcond=None)[0]
    beta_c = np.linalg.lstsq(X[train], c_tr, rcond=None)[0]
    law = [beta_b.tolist(), beta_c.tolist()]
    if ext.fit_level:
        rows_tr = train[scope.row_site]
        y = scope.rows["measured"].to_numpy(float)

        def obj(th):
            theta = [fit["t_ref_c"], float(np.ravel(th)[0]), alpha_ref, *law, *decay]
            a = after_physical(ext, scope, cov, train, theta)
            return float(np.sum((a[rows_tr] - y[rows_tr]) ** 2))

        params["level_per_c"] = _minimise_one(obj, ext.level_bounds_per_c)[0]
    params.update({f"wlf_{key}": v for key, v in fit.items() if key != "t_ref_c"})
    if x is not None:
        params["decay_slope"], params["decay_log10_mean"] = decay
    params["t_ref_source"] = "measured curves (decay constants across sites)"
    params["law_b_beta"], params["law_c_beta"] = law
    return params


def _Plain(ext: TemperatureShift) -> TemperatureShift:
    """The extension marked for the prediction route only (a copy; ``_plain`` is not a dataclass field)."""
    out = replace(ext)
    object.__setattr__(out, "_plain", True)
    return out


def _recalibrate_physical(ext, scope: Scope, cov: pd.DataFrame, train: np.ndarray) -> dict:
    if isinstance(ext, TemperatureShift) and scope.name == "held_out_speeds":
        _physical_params(ext, scope, cov)  # the temperature column must exist
        return {"t_ref_c": float(ext.t_ref_c), "level_per_c": float(ext.level_per_c), "identifiable": False}
    if isinstance(ext, TemperatureShift) and scope.name == "held_out_sites" and not getattr(ext, "_plain", False):
        # two routes, the smaller training error wins (no held-out data): the WLF shift identified from the
        # measured curves with the law's b and c from the texture, and the shift of the texture model's prediction
        curves = _recalibrate_temperature_between(ext, scope, cov, train)
        if curves is not None:
            plain = _recalibrate_physical(_Plain(ext), scope, cov, train)
            sse_c = _train_sse(ext, curves, scope, cov, train)
            sse_p = _train_sse(ext, plain, scope, cov, train)
            wlf = {k: v for k, v in curves.items() if k.startswith("wlf_") or k == "t_ref_source"}
            if sse_c <= sse_p:
                return {**curves, "route": "curves", "train_sse": sse_c, "train_sse_other": sse_p}
            return {
                **plain,
                **wlf,
                "t_ref_c_curves": curves["t_ref_c"],
                "route": "prediction",
                "train_sse": sse_p,
                "train_sse_other": sse_c,
            }
    if isinstance(ext, DrainageIFI) and ext.form == "auto":
        # each curve form fitted on the training data; the smaller training error wins (no held-out data)
        fits = [dict(recalibrate(replace(ext, form=f), scope, cov, train), form=f) for f in DRAINAGE_FORMS]
        for fit in fits:
            fit["train_sse"] = _train_sse(replace(ext, form=fit["form"]), fit, scope, cov, train)
        return min(fits, key=lambda fit: fit["train_sse"])
    names, bounds = _physical_params(ext, scope, cov)
    rows_tr = train[scope.row_site]
    y = scope.rows["measured"].to_numpy(float)

    def obj(th):
        a = after_physical(ext, scope, cov, train, th)
        return float(np.sum((a[rows_tr] - y[rows_tr]) ** 2))

    th = _minimise_one(obj, bounds[0]) if len(names) == 1 else _minimise_many(obj, bounds)
    return dict(zip(names, th))


# ----------------------------------------------------------------------------------------------------------------
# generic terms
# ----------------------------------------------------------------------------------------------------------------


def _recalibrate_shape(ext: SharedShape, scope: Scope, resid: np.ndarray, rows_tr: np.ndarray) -> dict:
    v = scope.rows["speed_kmh"].to_numpy(float)
    b = np.round(v[rows_tr] / ext.speed_bin_kmh) * ext.speed_bin_kmh
    prof = pd.Series(resid[rows_tr]).groupby(b).mean()
    return {"speed_kmh": prof.index.to_list(), "h": prof.to_list()}


def _recalibrate_categorical(
    ext: CovariateTerm, col: pd.Series, scope: Scope, resid: np.ndarray, rows_tr: np.ndarray, dv: np.ndarray
) -> dict:
    lab = col.astype(str).to_numpy()[scope.row_site]
    groups = {}
    for g in np.unique(lab[rows_tr]):
        m = rows_tr & (lab == g)
        X = np.ones((m.sum(), 1)) if ext.on == "level" else dv[m][:, None]
        groups[str(g)] = np.linalg.lstsq(X, resid[m], rcond=None)[0].tolist()
    X = np.ones((rows_tr.sum(), 1)) if ext.on == "level" else dv[rows_tr][:, None]
    return {"numeric": False, "groups": groups, "overall": np.linalg.lstsq(X, resid[rows_tr], rcond=None)[0].tolist()}


def _recalibrate_covariate(ext: CovariateTerm, scope: Scope, cov: pd.DataFrame, train: np.ndarray) -> dict:
    if ext.name not in cov.columns:
        raise InputError("sites table / texture table", f"column '{ext.name}'", column=ext.name)
    rows_tr = train[scope.row_site]
    y = scope.rows["measured"].to_numpy(float)
    resid = y - scope.rows["before"].to_numpy(float)
    dv = centred_speed(scope)
    col = cov.loc[scope.sites, ext.name]
    if not pd.api.types.is_numeric_dtype(col):
        return _recalibrate_categorical(ext, col, scope, resid, rows_tr, dv)
    if ext.texture_pcs >= 0 and scope.name == "held_out_sites":
        # texture refit: [1, PCs, z] fitted to the training sites' measured site means (speed slopes)
        X = refit_design(scope, cov, ext.texture_pcs, ext.name)
        beta, *_ = np.linalg.lstsq(X[train], site_target(ext.on, scope, y, dv)[train], rcond=None)
        return {"numeric": True, "texture_pcs": ext.texture_pcs, "beta": beta.tolist()}
    z = col.to_numpy(float)
    zr = (z - z[train].mean())[scope.row_site]
    X = np.c_[np.ones(len(dv)), zr] if ext.on == "level" else np.c_[dv, zr * dv]
    beta, *_ = np.linalg.lstsq(X[rows_tr], resid[rows_tr], rcond=None)
    return {"numeric": True, "z_mean": float(z[train].mean()), "beta": beta.tolist()}


def _texture_model_rows(ext: TextureModelTerm, scope: Scope) -> np.ndarray:
    """Per row of the scope, the texture-model term's regressors: ``[1, Z_i]`` (level) or ``[1, Z_i] (v -
    v_mean,i)`` (slope, km/h)."""
    X = np.c_[np.ones(len(scope.sites)), ext.design_of(scope.sites)][scope.row_site]
    return X if ext.on == "level" else X * centred_speed(scope)[:, None]


def _recalibrate_texture_model(ext: TextureModelTerm, scope: Scope, train: np.ndarray) -> dict:
    """Between sites: least squares of the training sites' mean residual (mu) on ``[1, Z]`` (level), or of their
    residual rows on ``[1, Z] (v - v_mean,i)`` (slope); nothing within a site."""
    if scope.name != "held_out_sites":
        return {"beta": None}
    resid = scope.rows["measured"].to_numpy(float) - scope.rows["before"].to_numpy(float)
    if ext.on == "level":
        X = np.c_[np.ones(len(scope.sites)), ext.design_of(scope.sites)]
        y = site_target("level", scope, resid, centred_speed(scope))
        beta, *_ = np.linalg.lstsq(X[train], y[train], rcond=None)
    else:
        rows_tr = train[scope.row_site]
        beta, *_ = np.linalg.lstsq(_texture_model_rows(ext, scope)[rows_tr], resid[rows_tr], rcond=None)
    return {"beta": beta.tolist()}


def recalibrate(ext, scope: Scope, cov: pd.DataFrame, train: np.ndarray) -> dict:
    """Fit the extension's parameters on the training sites (boolean mask over ``scope.sites``).

    Physical extensions: TemperatureShift T_r (deg C); DrainageIFI kappa (and, for ``form="auto"``, the curve form
    with the smaller training error); minimising the training rows' squared error (one parameter: a 41-point grid
    over the bounds, then a bounded scalar search between the best point's neighbours; two: a coarse grid +
    bounded Powell); within a site the law is refitted through the calibration points with the extension
    included. Generic terms: least squares / group means on the training residuals. Returns the fitted
    parameters (JSON-ready)."""
    if getattr(ext, "physical", False) and not isinstance(ext, ViscoelasticFE):
        return _recalibrate_physical(ext, scope, cov, train)
    if isinstance(ext, SharedShape):
        resid = scope.rows["measured"].to_numpy(float) - scope.rows["before"].to_numpy(float)
        return _recalibrate_shape(ext, scope, resid, train[scope.row_site])
    if isinstance(ext, CovariateTerm):
        return _recalibrate_covariate(ext, scope, cov, train)
    if isinstance(ext, TextureModelTerm):
        return _recalibrate_texture_model(ext, scope, train)
    raise ConfigError(f"cannot recalibrate extension {type(ext).__name__}")


def _train_sse(ext, params: dict, scope: Scope, cov: pd.DataFrame, train: np.ndarray) -> float:
    """Squared error (mu^2) of the fitted extension over the training sites' rows."""
    rows_tr = train[scope.row_site]
    a = predict_extended(ext, params, scope, cov, train)
    return float(np.sum((a[rows_tr] - scope.rows["measured"].to_numpy(float)[rows_tr]) ** 2))


def _predict_covariate(ext: CovariateTerm, params: dict, scope: Scope, cov: pd.DataFrame) -> np.ndarray:
    before = scope.rows["before"].to_numpy(float)
    col = cov.loc[scope.sites, ext.name]
    dv = centred_speed(scope)
    if params.get("texture_pcs", -1) >= 0:
        X = refit_design(scope, cov, params["texture_pcs"], ext.name)
        return before + refit_correction(ext.on, params["beta"], X, scope, before, dv)
    if params["numeric"]:
        zr = (col.to_numpy(float) - params["z_mean"])[scope.row_site]
        X = np.c_[np.ones(len(dv)), zr] if ext.on == "level" else np.c_[dv, zr * dv]
        return before + X @ np.asarray(params["beta"])
    lab = col.astype(str).to_numpy()[scope.row_site]
    out = before.copy()
    for j in range(len(dv)):
        c = params["groups"].get(lab[j], params["overall"])
        out[j] += c[0] * (1.0 if ext.on == "level" else dv[j])
    return out


def predict_extended(ext, params: dict, scope: Scope, cov: pd.DataFrame, train: np.ndarray) -> np.ndarray:
    """'after' values for every row of the scope with fitted ``params`` (use the rows of held-out sites)."""
    if isinstance(ext, DrainageIFI) and "form" in params:
        ext = replace(ext, form=params["form"])
    if getattr(ext, "physical", False):
        if isinstance(ext, TemperatureShift) and "log10_alpha_ref" in params:
            theta = [params["t_ref_c"], params.get("level_per_c", ext.level_per_c), params["log10_alpha_ref"]]
            if "law_b_beta" in params:
                theta += [params["law_b_beta"], params["law_c_beta"]]
                if "decay_slope" in params:
                    theta += [params["decay_slope"], params["decay_log10_mean"]]
            return after_physical(ext, scope, cov, train, theta)
        return after_physical(ext, scope, cov, train, [params[k] for k in _physical_params(ext, scope, cov)[0]])
    if isinstance(ext, TextureModelTerm):
        before = scope.rows["before"].to_numpy(float)
        if params.get("beta") is None:
            return before.copy()
        return before + _texture_model_rows(ext, scope) @ np.asarray(params["beta"])
    if isinstance(ext, SharedShape):
        return scope.rows["before"].to_numpy(float) + np.interp(
            scope.rows["speed_kmh"].to_numpy(float), params["speed_kmh"], params["h"]
        )
    return _predict_covariate(ext, params, scope, cov)
