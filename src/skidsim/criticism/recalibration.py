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
from .residuals import speed_bin_centres
from .scopes import Scope, centred_speed, site_mean, site_target, site_values
from .wlf import curve_bc, decay_covariate, log10_decay_column, wlf_curves, wlf_from_curves

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


def _physical_params(ext, scope: Scope, cov: pd.DataFrame, train: np.ndarray | None = None) -> tuple[list, list]:
    """Names and bounds of the fitted parameters of a physical extension in a scope. With ``train``, T_r's upper
    bound also keeps 5 K inside the WLF pole at the temperatures the shift is evaluated at (:func:`_shift_temperatures`:
    for a texture-adjusted cause the part of T the texture does not predict, which can reach below the measured
    temperatures at a held-out site)."""
    if isinstance(ext, TemperatureShift):
        tb = ext.t_ref_bounds_c(site_values(cov, ext.column, scope.sites))
        if train is not None:
            tb = (tb[0], min(tb[1], ext.t_ref_bounds_c(_shift_temperatures(ext, scope, cov, train)[0])[1]))
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


def _shift_temperatures(ext: TemperatureShift, scope: Scope, cov: pd.DataFrame, train: np.ndarray):
    """The temperatures (deg C) at which the shift of the prediction is evaluated, per site of the scope, and the
    anchor (their training mean): the measured ones, or for a texture-adjusted cause (``texture_pcs >= 0``) the
    training mean plus the part the texture PCs do not predict."""
    T = site_values(cov, ext.column, scope.sites)
    if ext.texture_pcs >= 0:
        T = float(T[train].mean()) + _texture_partial(scope, cov, T, train, ext.texture_pcs)
    return T, float(T[train].mean())


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
    T, anchor = _shift_temperatures(ext, scope, cov, train)
    k = ext.speed_factor(T, anchor, float(theta[0]))
    bt = ext.vertical_factor(T, anchor, float(theta[1]) if len(theta) > 1 else None)
    b0, c0, a0 = scope.base
    if len(theta) > 2 and np.isfinite(float(theta[2])):
        # the decay constant from the measured curves (wlf_from_curves): alpha_ref a_T(T_i) / a_T(T_0) at the
        # site's own temperature (the decay constants follow the temperature itself, not its texture-free part)
        Tr = site_values(cov, ext.column, scope.sites)
        alpha = 10.0 ** float(theta[2]) * ext.speed_factor(Tr, float(Tr[train].mean()), float(theta[0]))
        if len(theta) > 6:  # the decay constant's texture term (theta[5] per log10 mm about theta[6])
            lx = log10_decay_column(ext, cov, scope.sites)
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


def _recalibrate_temperature_between(ext: TemperatureShift, scope: Scope, cov: pd.DataFrame, train: np.ndarray):
    """Between sites: T_r from the training sites' measured curves (:func:`wlf_from_curves`; nuisance of the
    reference decay constant: the ``texture_pcs`` texture PCs of a texture-adjusted cause), then the vertical
    factor's slope on the training rows with T_r held. None with fewer than 4 measured speeds per site."""
    curves = wlf_curves(scope)
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
    b_tr, c_tr, _ = curve_bc(V[train], Y[train], alpha_tr)
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
    names, bounds = _physical_params(ext, scope, cov, train)
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
    b = speed_bin_centres(v[rows_tr], ext.speed_bin_kmh)
    prof = pd.Series(resid[rows_tr]).groupby(b).mean()
    return {"speed_kmh": prof.index.to_list(), "h": prof.to_list()}


def _numeric_rows(on: str, zr: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """A numeric term's regressors per row, ``zr`` the covariate centred on its training mean: ``[1, z]`` (level)
    or ``[v - v_mean,i, z (v - v_mean,i)]`` (slope: a pure shape term, km/h)."""
    return np.c_[np.ones(len(dv)), zr] if on == "level" else np.c_[dv, zr * dv]


def _categorical_rows(on: str, dv: np.ndarray) -> np.ndarray:
    """A categorical term's regressors per row: ``[1]`` (level) or ``[1, v - v_mean,i]`` (slope: each group's
    residual level and speed slope, km/h)."""
    return np.ones((len(dv), 1)) if on == "level" else np.c_[np.ones(len(dv)), dv]


def _recalibrate_categorical(
    ext: CovariateTerm, col: pd.Series, scope: Scope, resid: np.ndarray, rows_tr: np.ndarray, dv: np.ndarray
) -> dict:
    """Least squares per group of the training rows' residuals on :func:`_categorical_rows`, and over all the
    training rows for a group unseen in training (``overall``)."""
    lab = col.astype(str).to_numpy()[scope.row_site]
    X = _categorical_rows(ext.on, dv)
    groups = {}
    for g in np.unique(lab[rows_tr]):
        m = rows_tr & (lab == g)
        groups[str(g)] = np.linalg.lstsq(X[m], resid[m], rcond=None)[0].tolist()
    overall = np.linalg.lstsq(X[rows_tr], resid[rows_tr], rcond=None)[0].tolist()
    return {"numeric": False, "groups": groups, "overall": overall}


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
    X = _numeric_rows(ext.on, zr, dv)
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
        return before + _numeric_rows(ext.on, zr, dv) @ np.asarray(params["beta"])
    lab = col.astype(str).to_numpy()[scope.row_site]
    coef = np.array([params["groups"].get(g, params["overall"]) for g in lab])
    return before + (_categorical_rows(ext.on, dv) * coef).sum(axis=1)


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
