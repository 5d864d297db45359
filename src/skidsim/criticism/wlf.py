"""The WLF reference temperature from the sites' measured friction-speed curves, and whether it is identifiable
(:class:`~skidsim.criticism.extensions.TemperatureShift` between sites; docs/model-criticism.md, section 3).

A speed shift of the exponential-decay law is a change of its decay constant, so a per-site calibration absorbs
it, but across sites the decay constants follow temperature: :func:`wlf_from_curves` fits the sites' measured
points with per-site level and amplitude and a campaign decay constant shifted by ``a_T(T_i)``, C1 and C2
universal, and profiles T_r. Friction mu (dimensionless), speeds km/h, temperatures deg C.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
from scipy.optimize import minimize, minimize_scalar
from scipy.stats import f as f_dist

from ..friction import KMH_PER_MS
from .causes import LAW_FORM
from .extensions import TemperatureShift, exp_curve, fit_exp_curves
from .scopes import Scope, make_scope, site_values

#: Grid points of the profile of the WLF reference temperature over its bounds.
WLF_GRID = 41
#: Start values of the decay constant's slope g (log10 alpha per log10 mm of the decay column) in
#: :func:`wlf_from_curves`, and the Nelder-Mead settings of (c0, g).
DECAY_SLOPE_GRID = (-1.5, -0.75, 0.0, 0.75, 1.5)
NELDER_MEAD = {"xatol": 1e-4, "fatol": 1e-10, "maxfev": 200}
#: Exponents p of the stretched exponential ``b + c exp(-(alpha s)^p)`` that :func:`curve_shape` profiles (1: the
#: exponential decay).
SHAPE_EXPONENTS = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6)
#: Level of :func:`curve_shape`'s F test: below it the measured curves are not exponential decays of speed.
SHAPE_LEVEL = 0.01
#: Tolerance of the exponent :func:`curve_shape` refines between the grid's neighbours where the exponential is
#: rejected (``stretch_exponent_fit``, the form the WLF shift is then read with).
SHAPE_EXPONENT_TOL = 0.002


def stretched_speeds(V, p: float = 1.0):
    """Speeds (km/h) at which the stretched exponential ``exp(-(alpha s)^p)`` is the exponential ``exp(-alpha^p
    s')`` (``s' = s^p``, s = v / 3.6 m/s): ``3.6 (v / 3.6)^p``; ``V`` itself for ``p = 1``. A speed factor k is
    then the factor ``k^p`` on ``alpha^p``: the stretched form is closed under speed scaling as the exponential is.
    NaN stays NaN."""
    V = np.asarray(V, float)
    return V if p == 1.0 else KMH_PER_MS * (V / KMH_PER_MS) ** p


def reading_exponent(shape: dict | None) -> float:
    """The exponent p of the curves the WLF shift is read from (:func:`wlf_from_curves`): 1 (the exponential
    decay) unless :func:`curve_shape` rejects the exponential form, then its refined ``stretch_exponent_fit``."""
    return 1.0 if shape is None or shape["exponential"] else float(shape["stretch_exponent_fit"])


def curve_bc(V: np.ndarray, Y: np.ndarray, alpha: np.ndarray):
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
    r = curve_bc(V, Y, alpha)[2]
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
    stretch: float = 1.0,
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

    ``stretch`` (p, :func:`reading_exponent`): the curves are read as stretched exponentials ``b_i + c_i
    exp(-(alpha_i s)^p)``, which a speed factor also maps to a factor on ``alpha_i`` (:func:`stretched_speeds`),
    with the same model of ``log10 alpha_i``; p = 1 is the exponential decay. Read with the wrong form, the decay
    constants follow a speed shift by less (or more) than its size and T_r is biased (docs/model-criticism.md,
    section 3, "T_r read with the curves' own form").

    ``identifiable``: the best T_r lies inside its bounds (at the "no effect" bound the curves show no speed shift)
    and, with ``n_perm > 0``, the WLF term's reduction of the squared error of the model without it
    (``log10 alpha_i = c0``, or ``c0 + g x_i``) is significant at 0.05 against ``n_perm`` permutations of the
    temperatures over the sites (seeded; profile on a 21-point grid for observed and permuted alike; the sites'
    own scatter of the decay constant is the noise, not the points'; with ``x`` the slope g held at its value in
    the model without the WLF term). Returns t_ref_c, log10_alpha_ref, decay_slope, sse, sse_without (mu^2),
    perm_p (None without permutations), identifiable and, when not identifiable, ``why``."""
    T = np.asarray(T, float)
    p = float(stretch)
    V = stretched_speeds(V, p)  # alpha^p on s^p: every log10 alpha below is p log10 alpha of the stretched form

    def shift_of(temps, t_r):
        """p log10 (a_T(T_i) / a_T(mean T)) at T_r = ``t_r``: the WLF term of log10 alpha_i^p."""
        return p * (ext_log10_shift(ext, temps, t_r) - ext_log10_shift(ext, np.array([float(temps.mean())]), t_r)[0])

    def sse(tr):
        return _decay_fit(V, Y, shift_of(T, tr), x)[0]

    lo, hi = bounds
    grid = np.linspace(lo, hi, WLF_GRID)
    vals = np.array([sse(g) for g in grid])
    j = int(np.argmin(vals))
    a, b = grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]
    r = minimize_scalar(sse, bounds=(a, b), method="bounded", options={"xatol": 0.05})
    tr, best = (float(r.x), float(r.fun)) if r.fun <= vals[j] else (float(grid[j]), float(vals[j]))
    null = _decay_fit(V, Y, np.zeros(len(T)), x)  # the model without the WLF term: (sse, c0, g)
    sse0 = null[0]
    _, c0, g = _decay_fit(V, Y, shift_of(T, tr), x)
    perm_p = None
    if n_perm > 0:
        coarse = np.linspace(lo, hi, 21)
        # the decay slope held at the model without the WLF term (the null model's nuisance), as an offset
        offset = 0.0 if x is None else null[2] * x
        sse_null = _decay_fit(V, Y, np.zeros(len(T)) + offset, None)[0]

        def gain_of(temps):
            return sse_null - min(_decay_fit(V, Y, shift_of(temps, t_r) + offset, None)[0] for t_r in coarse)

        rng = np.random.default_rng(seed)
        d_obs = gain_of(T)
        d_perm = np.array([gain_of(rng.permutation(T)) for _ in range(n_perm)])
        perm_p = float((1 + np.sum(d_perm >= d_obs * (1 - 1e-12))) / (1 + n_perm))
    out = {
        "t_ref_c": tr,
        "log10_alpha_ref": c0 / p,
        "decay_slope": None if g is None else g / p,
        "stretch_exponent": p,
        "sse": best,
        "sse_without": sse0,
        "perm_p": perm_p,
    }
    why = None
    if j == 0 or tr - lo < 1e-3 * (hi - lo):
        why = "the measured curves show no WLF speed shift between sites (T_r at its 'no effect' bound)"
    elif j == len(grid) - 1:
        why = "T_r runs to the WLF pole (the speed shift is steeper than the WLF form allows)"
    elif perm_p is not None and perm_p > 0.05:
        why = (
            f"the decay constants of the measured curves do not follow the WLF shift of temperature beyond chance "
            f"(permutation p = {perm_p:.2g}, {n_perm} permutations of the temperatures over the sites)"
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


def curve_shape(V: np.ndarray, Y: np.ndarray, level: float = SHAPE_LEVEL) -> dict | None:
    """Whether the sites' measured curves are exponential decays of speed, the form :func:`wlf_from_curves` reads
    the WLF shift from (a speed factor k is a factor k on the decay constant only for such curves).

    ``V`` (km/h), ``Y`` (mu): one row per site, NaN padded (:func:`site_curves`); sites with fewer than 4 points
    are left out (3 points fix the 3 parameters of their curve). Each site gets its own ``b_i + c_i exp(-(alpha_i
    s)^p)`` (s = v / 3.6 m/s; :func:`~skidsim.criticism.extensions.fit_exp_curves` on the speeds ``3.6 s^p``, where
    the stretched exponential is an exponential with decay constant ``alpha_i^p``), one exponent ``p`` for the
    campaign, profiled over :data:`SHAPE_EXPONENTS`. The F ratio of the exponential (``p = 1``) against the best
    ``p``, ``(SSE_1 - SSE_p) / (SSE_p / (N - 3 n - 1))`` on 1 and ``N - 3 n - 1`` degrees of freedom (N points, n
    sites), tests the exponential form; ``exponential`` is false below ``level``. The curves of a log-normal
    (Rado) speed model over 20-70 km/h are stretched (p about 0.3-0.7); PIARC/IFI curves are exponential. No size
    threshold beside the test: T_r is that sensitive to the form (on stretched curves of exponent 0.9 / 1.1 with a
    WLF shift of T_r 20 deg C at 18-22 deg C, the exponential reading gives T_r about 3 / 30 deg C; docs).

    Returns ``stretch_exponent`` (the best p on the grid), ``stretch_exponent_fit`` (where the exponential is
    rejected, p refined between the grid's neighbours to :data:`SHAPE_EXPONENT_TOL`; else the grid's), ``f_ratio``,
    ``df``, ``p_value``, ``exponential``, the RMSE (mu) of both forms (the grid's p), and ``why`` (what a T_r read
    from decay constants is worth on such curves; None when exponential);
    None with fewer than 2 sites of 4 points or no degree of freedom left."""
    V, Y = np.asarray(V, float), np.asarray(Y, float)
    keep = (np.isfinite(V) & np.isfinite(Y)).sum(axis=1) >= 4
    V, Y = V[keep], Y[keep]
    n_sites, n_points = int(keep.sum()), int((np.isfinite(V) & np.isfinite(Y)).sum())
    df2 = n_points - 3 * n_sites - 1
    if n_sites < 2 or df2 < 1:
        return None
    Y = np.where(np.isfinite(V), Y, np.nan)

    def sse_of(p):
        vp = stretched_speeds(np.where(np.isfinite(V), V, 1.0), p)
        b, c, a = fit_exp_curves(vp, Y)
        r = exp_curve(vp, b[:, None], c[:, None], a[:, None]) - Y
        return float(np.nansum(r * r))

    sse = {p: sse_of(p) for p in SHAPE_EXPONENTS}
    best = min(sse, key=sse.get)
    f_ratio = max(sse[1.0] - sse[best], 0.0) / (sse[best] / df2) if sse[best] > 0 else 0.0
    p_value = float(f_dist.sf(f_ratio, 1, df2))
    exponential = bool(p_value > level)
    p_fit = float(best)
    if not exponential:  # the exponent the WLF shift is read with (reading_exponent): between the grid's neighbours
        step = SHAPE_EXPONENTS[1] - SHAPE_EXPONENTS[0]
        lo_p, hi_p = max(SHAPE_EXPONENTS[0], best - step), min(SHAPE_EXPONENTS[-1], best + step)
        r = minimize_scalar(sse_of, bounds=(lo_p, hi_p), method="bounded", options={"xatol": SHAPE_EXPONENT_TOL})
        p_fit = float(r.x) if r.fun <= sse[best] else p_fit
    return {
        "stretch_exponent": float(best),
        "stretch_exponent_fit": p_fit,
        "f_ratio": float(f_ratio),
        "df": [1, int(df2)],
        "p_value": p_value,
        "exponential": exponential,
        "rmse_exponential": float(np.sqrt(sse[1.0] / n_points)),
        "rmse_stretched": float(np.sqrt(sse[best] / n_points)),
        "why": None
        if exponential
        else (
            f"the measured curves are not exponential decays of speed (a {stretch_word(best)} exponential "
            f"exp(-(alpha s)^{best:g}) fits them better: F {f_ratio:.1f}, p {p_value:.2g}), so T_r, read from the "
            "decay constants of exponential fits, is biased on them (a curve form of exponent 0.9 or 1.1 moves it "
            "by 12-18 deg C; on log-normal, Rado, curves it comes out tens of deg C low)"
        ),
    }


def stretch_word(p: float) -> str:
    """``stretched`` for an exponent ``p`` of ``exp(-(alpha s)^p)`` below 1 (a slower than exponential decay at
    high speeds), ``compressed`` above 1."""
    return "stretched" if p < 1.0 else "compressed"


def curve_form_reading(shape: dict) -> str:
    """What :func:`curve_shape`'s verdict says of a shape misfit shared by the sites at held-out speeds (the named
    within-site functional form): where the measured curves are exponential decays of speed, the calibrated law
    can follow them and the misfit is the simulated curve's (the FE's response to the law, or the law fitted at
    the calibration speeds); where they are not, the misfit is the exponential-decay law's form."""
    test = f"F {shape['f_ratio']:.1f}, p {shape['p_value']:.2g}"
    if shape["exponential"]:
        return (
            f"the measured curves are exponential decays of speed ({test} for a stretched exponential): the "
            "exponential-decay law can follow them, so the shape shared at held-out speeds is the simulated "
            "curve's (the FE's response to the law, or the law fitted at the calibration speeds), not the law's form"
        )
    return (
        f"the measured curves are not exponential decays of speed (a {stretch_word(shape['stretch_exponent'])} "
        f"exponential exp(-(alpha s)^{shape['stretch_exponent']:g}) fits them better: {test}; RMSE "
        f"{shape['rmse_exponential']:.4f} -> {shape['rmse_stretched']:.4f}): the shape shared at held-out speeds "
        "is the exponential-decay law's form, which cannot follow them"
    )


def measured_curve_shape(scope_of) -> dict | None:
    """:func:`curve_shape` of the measured curves (:func:`site_curves`) of the between-site scope (every measured
    row of every site), else of the within-site scope (the held-out speeds): the one rule for gain.json's
    ``curve_form`` and :func:`label_law_form`. ``scope_of(level)`` gives the scope of a level or None (a dict's
    ``get``, or :func:`~skidsim.criticism.scopes.make_scope` on the residuals, called for the within-site level only
    without a between-site scope). None without a scope or curves of at least 4 speeds."""
    scope = scope_of("between-site") or scope_of("within-site")
    curves = site_curves(scope) if scope is not None else None
    return curve_shape(*curves) if curves is not None else None


def label_law_form(causes: list, residuals: pd.DataFrame) -> list:
    """The within-site functional form labelled :data:`~skidsim.criticism.causes.LAW_FORM` (category ``friction
    law``) where the measured curves' shape (:func:`measured_curve_shape`, as gain.json's ``curve_form``) is not
    an exponential decay of speed: the shape the sites share at held-out speeds is then the law's form, which the
    calibrated law cannot follow (:func:`curve_form_reading`). Ranks, p-values and significance stay as they are.
    In place; returns ``causes``."""
    k = next((k for k, c in enumerate(causes) if c.variable == "functional_form" and c.level == "within-site"), None)
    if k is None or "measured" not in residuals.columns:
        return causes
    shape = measured_curve_shape(lambda level: make_scope(residuals, level))
    if shape is not None and not shape["exponential"]:
        p = shape["stretch_exponent"]
        causes[k] = replace(
            causes[k],
            label=f"{LAW_FORM}: the measured curves are {stretch_word(p)} exponentials exp(-(alpha s)^{p:g}), not "
            f"exponential decays of speed (F {shape['f_ratio']:.1f}, p {shape['p_value']:.2g})",
        )
    return causes


def log10_decay_column(ext: TemperatureShift, cov: pd.DataFrame, sites: list) -> np.ndarray | None:
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
    lx = log10_decay_column(ext, cov, sites)
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


def wlf_curves(scope: Scope):
    """The measured curves the WLF shift is read from: the scope's whole measured DFT curves where it holds them
    (:func:`~skidsim.criticism.scopes.measured_curves`: down to 5 km/h, where the decay constant shows), else its
    rows (:func:`site_curves`)."""
    return scope.curves if scope.curves is not None else site_curves(scope)


def temperature_identifiability(ext: TemperatureShift, scope: Scope, cov: pd.DataFrame, n_perm: int = 99) -> dict:
    """:func:`wlf_from_curves` on every site of the held-out-site scope with ``n_perm`` permutations of the
    temperatures (gain.json ``identifiability``), and :func:`curve_shape` of the same curves (``curve_shape``);
    None without measured curves. The curves are :func:`wlf_curves`. Where they are not exponential decays of speed,
    ``stretched_reading`` holds T_r read with their own stretched form (:func:`reading_exponent`;
    ``stretch_exponent``, ``t_ref_c`` deg C, ``sse`` mu^2): how far the exponential reading's T_r, which the folds
    and the prediction use, is moved by the form."""
    curves = wlf_curves(scope)
    if curves is None:
        return None
    T = site_values(cov, ext.column, scope.sites)
    x, _ = decay_covariate(ext, cov, scope.sites)
    out = wlf_from_curves(ext, T, *curves, ext.t_ref_bounds_c(T), n_perm=n_perm, seed=0, x=x)
    shape = out["curve_shape"] = curve_shape(*curves)
    p = reading_exponent(shape)
    if p != 1.0:  # the curves' own form: the reading the exponential's bias is measured against
        read = wlf_from_curves(ext, T, *curves, ext.t_ref_bounds_c(T), x=x, stretch=p)
        out["stretched_reading"] = {"stretch_exponent": p, "t_ref_c": read["t_ref_c"], "sse": read["sse"]}
    return out
