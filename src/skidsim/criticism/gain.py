"""The measured gain of an extension: cross-fitted 'after' values on held-out speeds and held-out sites, and RMSE /
R^2 before and after with percentile bootstrap intervals over whole sites. Friction mu (dimensionless)."""

from __future__ import annotations

from collections import Counter
from dataclasses import asdict, replace

import numpy as np
import pandas as pd

from ..errors import InputError
from .calibration_groups import calibration_groups
from .covariates import DEFAULT_EXCLUDE, score_table, site_covariates, texture_scores
from .crossval import folds, is_section_nested
from .extensions import CovariateTerm, DrainageIFI, ExtendedModel, SharedShape, TemperatureShift
from .options import DiagnosisOptions
from .recalibration import (
    _train_sse,
    predict_extended,
    recalibrate,
    refit_correction,
    refit_design,
)
from .residuals import LEVELS, require_columns
from .scopes import Scope, centred_speed, make_scope, site_target, site_values
from .wlf import curve_form_reading, measured_curve_shape, temperature_identifiability

_DEFAULTS = DiagnosisOptions()
#: The summary keys of gain.json's ``over_texture_refit`` and ``over_shared_level`` comparisons.
_OVER_TEXTURE_KEYS = (
    "rmse_before",
    "rmse_before_ci",
    "rmse_after",
    "rmse_after_ci",
    "rmse_gain",
    "rmse_gain_ci",
    "r2_gain",
    "r2_gain_ci",
    "gain_excludes_zero",
)
_OVER_LEVEL_KEYS = (
    "rmse_before",
    "rmse_before_ci",
    "rmse_after",
    "rmse_after_ci",
    "rmse_gain",
    "rmse_gain_ci",
    "r2_before",
    "r2_before_ci",
    "r2_gain",
    "r2_gain_ci",
    "gain_excludes_zero",
)


def extension_folds(ext, scope: Scope, cov: pd.DataFrame) -> np.ndarray:
    """Fold id per site of the scope: its section, or for a section-nested categorical term its rank within the
    section."""
    sec = scope.rows.groupby("site")["section"].first().reindex(scope.sites).astype(str).to_numpy()
    nested = False
    if isinstance(ext, CovariateTerm) and not pd.api.types.is_numeric_dtype(cov[ext.name]):
        nested = is_section_nested(cov.loc[scope.sites, ext.name].astype(str).to_numpy(), sec)
    return folds(sec, nested)


def cross_fit(ext, scope: Scope, cov: pd.DataFrame) -> tuple[pd.DataFrame, list]:
    """Out-of-sample 'after' for every site: the extension is recalibrated without the site's fold
    (leave-one-section-out; one site per section for section-nested categorical terms). Returns the rows with
    columns before/after and the per-fold parameters."""
    fold = extension_folds(ext, scope, cov)
    after = np.full(len(scope.rows), np.nan)
    params = []
    for f in np.unique(fold):
        train = fold != f
        p = recalibrate(ext, scope, cov, train)
        a = predict_extended(ext, p, scope, cov, train)
        te = ~train[scope.row_site]
        after[te] = a[te]
        params.append(p)
    return scope.rows.assign(after=after), params


def shared_level_reference(ext, scope: Scope, cov: pd.DataFrame) -> np.ndarray:
    """Cross-fitted reference 'before + shared offset' for every row of the scope: the mean training residual
    (mu) of the same folds as the extension. Comparing an extension against it isolates what the named variable
    adds beyond a campaign-wide level correction of the texture model (gain.json ``over_shared_level``)."""
    fold = extension_folds(ext, scope, cov)
    before = scope.rows["before"].to_numpy(float)
    resid = scope.rows["measured"].to_numpy(float) - before
    out = np.full(len(before), np.nan)
    for f in np.unique(fold):
        tr = (fold != f)[scope.row_site]
        out[~tr] = before[~tr] + resid[tr].mean()
    return out


def texture_refit_reference(ext, scope: Scope, cov: pd.DataFrame) -> np.ndarray:
    """Cross-fitted reference for a texture-adjusted :class:`CovariateTerm`: the same refit without the covariate
    (``[1, PC_1..k]`` only, same folds). Comparing the extension against it isolates what the named variable adds
    beyond refitting the level (slope) on the texture PCs (gain.json ``over_texture_refit``)."""
    fold = extension_folds(ext, scope, cov)
    before = scope.rows["before"].to_numpy(float)
    y = scope.rows["measured"].to_numpy(float)
    dv = centred_speed(scope)
    X = refit_design(scope, cov, ext.texture_pcs, None)
    out = np.full(len(before), np.nan)
    for f in np.unique(fold):
        train = fold != f
        beta, *_ = np.linalg.lstsq(X[train], site_target(ext.on, scope, y, dv)[train], rcond=None)
        te = ~train[scope.row_site]
        out[te] = (before + refit_correction(ext.on, beta, X, scope, before, dv))[te]
    return out


def _site_sums(p: pd.DataFrame) -> dict:
    """Per held-out site: point count, sums of measured and measured^2, SSE before/after, shape SSE (about the
    site's own mean residual) before/after."""
    rb, ra = p["measured"] - p["before"], p["measured"] - p["after"]
    g = p.assign(eb=rb**2, ea=ra**2, rb=rb, ra=ra, y2=p["measured"] ** 2).groupby("site")
    s = {
        "n": g.size().to_numpy(float),
        "s1": g["measured"].sum().to_numpy(float),
        "s2": g["y2"].sum().to_numpy(float),
        "eb": g["eb"].sum().to_numpy(float),
        "ea": g["ea"].sum().to_numpy(float),
    }
    s["sb"] = s["eb"] - g["rb"].sum().to_numpy(float) ** 2 / s["n"]
    s["sa"] = s["ea"] - g["ra"].sum().to_numpy(float) ** 2 / s["n"]
    return s


def _weighted_stats(s: dict, W: np.ndarray) -> dict:
    """RMSE, R^2 and shape RMSE before/after and their gains for every row of site weights ``W``."""
    N = W @ s["n"]
    sst = W @ s["s2"] - (W @ s["s1"]) ** 2 / N
    with np.errstate(divide="ignore", invalid="ignore"):
        stats = {
            "rmse_before": np.sqrt(W @ s["eb"] / N),
            "rmse_after": np.sqrt(W @ s["ea"] / N),
            "r2_before": 1 - (W @ s["eb"]) / sst,
            "r2_after": 1 - (W @ s["ea"]) / sst,
        }
        stats["shape_rmse_before"] = np.sqrt(W @ s["sb"] / N)
        stats["shape_rmse_after"] = np.sqrt(W @ s["sa"] / N)
    stats["rmse_gain"] = stats["rmse_before"] - stats["rmse_after"]
    stats["shape_rmse_gain"] = stats["shape_rmse_before"] - stats["shape_rmse_after"]
    stats["r2_gain"] = stats["r2_after"] - stats["r2_before"]
    return stats


def measure_gain(
    predictions: pd.DataFrame, *, n_boot: int = _DEFAULTS.n_boot, seed: int = _DEFAULTS.seed, ci: float = _DEFAULTS.ci
) -> dict:
    """RMSE and R^2 before/after on held-out rows, with percentile bootstrap intervals resampling whole sites.

    ``predictions``: columns site, measured, before, after (mu). ``rmse_gain = rmse_before - rmse_after`` and
    ``r2_gain = r2_after - r2_before`` (positive = the extension helps). R^2 = 1 - SSE/SST with SST about the mean
    of the (resampled) measured values. ``shape_rmse_*``: RMSE of the residuals about each site's mean residual
    (what a per-site level shift cannot fix), with its gain and interval. Bootstrap: ``n_boot`` multinomial
    resamples of the sites (seeded), percentile intervals at level ``ci``; ``gain_excludes_zero``: lower bound of
    the RMSE gain > 0; ``shape_gain_excludes_zero`` likewise for the shape RMSE.
    """
    require_columns(predictions, ("site", "measured", "before", "after"), "predictions")
    p = predictions.dropna(subset=["measured", "before", "after"])
    if p["site"].nunique() < 2:
        raise InputError("predictions", "held-out rows from at least 2 sites", got=int(p["site"].nunique()))
    s = _site_sums(p)
    k = len(s["n"])
    rng = np.random.default_rng(seed)
    W = np.vstack([np.ones(k), rng.multinomial(k, np.full(k, 1.0 / k), size=n_boot).astype(float)])
    q = [(1 - ci) / 2 * 100, (1 + ci) / 2 * 100]
    out = {"n_sites": int(k), "n_points": int(s["n"].sum()), "n_boot": int(n_boot), "seed": int(seed), "ci": ci}
    for name, arr in _weighted_stats(s, W).items():
        out[name] = float(arr[0])
        boot = arr[1:][np.isfinite(arr[1:])]
        out[name + "_ci"] = [float(x) for x in np.percentile(boot, q)] if len(boot) else [float("nan")] * 2
    out["gain_excludes_zero"] = bool(out["rmse_gain_ci"][0] > 0)
    out["shape_gain_excludes_zero"] = bool(out["shape_rmse_gain_ci"][0] > 0)
    return out


def _ext_describe(ext, params) -> dict:
    d = {"name": type(ext).__name__, "physical": bool(getattr(ext, "physical", False))}
    d["settings"] = dict(asdict(ext)) if hasattr(ext, "__dataclass_fields__") else {}
    d["params_per_fold"] = params
    return d


def _boot(rows: pd.DataFrame, options: DiagnosisOptions) -> dict:
    return measure_gain(rows, n_boot=options.n_boot, seed=options.seed, ci=options.ci)


def _scope_gain(ext, sc: Scope, cov: pd.DataFrame, options: DiagnosisOptions) -> tuple[dict, pd.DataFrame]:
    """Gain of one extension in one scope (with the between-site reference comparisons) and its rows."""
    rows, params = cross_fit(ext, sc, cov)
    g = _boot(rows, options)
    g["extension"] = _ext_describe(ext, params)
    if sc.name == "held_out_sites" and isinstance(ext, CovariateTerm) and ext.texture_pcs >= 0:
        g3 = _boot(rows.assign(before=texture_refit_reference(ext, sc, cov)), options)
        g["over_texture_refit"] = {k: g3[k] for k in _OVER_TEXTURE_KEYS}
    if sc.name == "held_out_sites":
        g2 = _boot(rows.assign(before=shared_level_reference(ext, sc, cov)), options)
        g["over_shared_level"] = {k: g2[k] for k in _OVER_LEVEL_KEYS}
    return g, rows.assign(scope=sc.name)


def _refit_covariates(residuals, sites, texture_wide, scopes: dict, pcs, exclude) -> pd.DataFrame:
    """The candidate covariates plus the texture PC scores ``_tpc<j>`` of the texture-refit terms: the PCs the test
    conditioned on (``pcs``) where they cover every site of the held-out-site scope; else PCs over all sites."""
    cov, info = site_covariates(sites, texture_wide, exclude=exclude)
    between = scopes["between-site"]
    if pcs is None or between is None or not set(between.sites) <= set(pcs.index):
        pcs = score_table(texture_scores(cov, info), cov.index)
    cov = cov.join(pcs)
    return cov


def evaluate_extension(
    model: ExtendedModel,
    residuals: pd.DataFrame,
    sites: pd.DataFrame,
    texture_wide: pd.DataFrame | None = None,
    options: DiagnosisOptions = _DEFAULTS,
    *,
    texture_pc_scores: pd.DataFrame | None = None,
    exclude=DEFAULT_EXCLUDE,
    measured: pd.DataFrame | None = None,
) -> tuple[dict, pd.DataFrame]:
    """Cross-fit the extension (and its generic fallback) on held-out speeds and held-out sites, measure the gain.

    The primary extension is the physical one unless its RMSE-gain interval at the cause's level does not exclude 0
    while the fallback's lower bound is higher ("no physical model fits"). ``texture_pc_scores``: the PC scores of
    the texture-adjusted test (:func:`~skidsim.criticism.covariates.between_site_texture_scores`) for the
    texture-refit terms. ``measured`` (site, speed_kmh, mu): the DFT points, whose whole curves (down to 5 km/h,
    below the simulated speeds) the WLF shift of a temperature cause is read from (:func:`~skidsim.criticism.wlf.
    wlf_curves`); None: the residual rows. Returns (gain dict, predictions)."""
    # built once, used by every extension
    level_scopes = {level: make_scope(residuals, level, measured) for level in LEVELS}
    cov = _refit_covariates(residuals, sites, texture_wide, level_scopes, texture_pc_scores, exclude)
    own = "held_out_speeds" if model.cause.level == "within-site" else "held_out_sites"
    results = []
    for ext in [model.extension] + ([model.fallback] if model.fallback is not None else []):
        scopes, preds = {}, []
        for sc in (s for s in level_scopes.values() if s is not None):
            scopes[sc.name], rows = _scope_gain(ext, sc, cov, options)
            preds.append(rows)
        results.append((ext, scopes, pd.concat(preds, ignore_index=True) if preds else pd.DataFrame()))
    best = results[0]
    if len(results) > 1 and own in best[1] and not best[1][own]["gain_excludes_zero"]:
        if results[1][1][own]["rmse_gain_ci"][0] > best[1][own]["rmse_gain_ci"][0]:
            best = results[1]
    gain = {
        "cause": model.cause.as_dict(),
        "extension": type(best[0]).__name__,
        "level": model.cause.level,
        "scope": own,
        "scopes": best[1],
        "fe_hook": None
        if model.fe_hook is None
        else {"name": "ViscoelasticFE", "solver_flags": model.fe_hook.solver_flags},
        "alternatives": [{"extension": type(e).__name__, "scopes": s} for e, s, _ in results if e is not best[0]],
    }
    gain["gain_excludes_zero"] = bool(own in best[1] and best[1][own]["gain_excludes_zero"])
    ident = physical_identifiability(results, level_scopes, cov, own)
    if ident is not None:
        gain["identifiability"] = ident
    if isinstance(model.extension, SharedShape) and model.cause.level == "within-site":
        form = measured_curve_form(level_scopes)
        if form is not None:
            gain["curve_form"] = form
    return gain, best[2]


def add_calibration_groups(
    form: dict, residuals: pd.DataFrame, calibration: pd.DataFrame | None, options: DiagnosisOptions
) -> dict:
    """``form`` (gain.json ``curve_form``) with ``by_calibration`` (:func:`~skidsim.criticism.calibration_groups.
    calibration_groups` of ``residuals``) where the measured curves are exponential and the calibration's record is
    given; the permutations of the groups' own tests drawn from ``options.seed``. In place; returns ``form``."""
    if calibration is None or not form["curve_shape"]["exponential"]:
        return form
    groups = calibration_groups(
        residuals, calibration, options.speed_bin_kmh, options.n_permutations or 999, options.seed
    )
    if groups is not None:
        form["by_calibration"] = groups
    return form


def measured_curve_form(level_scopes: dict) -> dict | None:
    """gain.json ``curve_form`` of a within-site functional form: the measured curves' shape
    (:func:`~skidsim.criticism.wlf.measured_curve_shape`) and what it says of the shared shape
    (:func:`~skidsim.criticism.wlf.curve_form_reading`); None without curves of at least 4 speeds."""
    shape = measured_curve_shape(level_scopes.get)
    if shape is None:
        return None
    return {"curve_shape": shape, "reading": curve_form_reading(shape)}


def physical_identifiability(results, level_scopes: dict, cov: pd.DataFrame, own: str | None = None) -> dict | None:
    """Whether the physical extension's own parameter is identified (gain.json ``identifiability``): for
    :class:`~skidsim.criticism.extensions.TemperatureShift` between sites, the WLF reference temperature from the
    measured curves of all sites with a permutation test of the temperatures
    (:func:`skidsim.criticism.wlf.temperature_identifiability`), and per fold the T_r fitted on the
    training sections (median, deg C), the folds whose T_r stayed inside its bounds and the route chosen (curves,
    or the shift of the texture model's prediction), the decay constant's texture slope of the all-sites fit
    (``decay_slope``, log10 alpha per log10 mm of ``TemperatureShift.decay_column``; None without one), and how
    precisely the sections pin T_r: the leave-one-section-out jackknife of the folds' T_r,
    ``t_ref_c_jackknife_se = sqrt((k - 1)/k sum (T_j - mean T)^2)`` over the k folds (deg C), and the interval
    ``t_ref_c_all_sites +- 1.96 se`` (``t_ref_c_interval_95``), with :func:`t_ref_precision`'s verdict on that
    interval (``t_ref_c_pinned``, ``t_ref_c_precision``). ``why`` says why T_r is not identified (None where it
    is). For :class:`~skidsim.criticism.extensions.DrainageIFI`, kappa in the scope ``own`` (the cause's):
    :func:`drainage_identifiability`. None for other extensions."""
    drainage = next((r for r in results if isinstance(r[0], DrainageIFI)), None)
    if drainage is not None:
        name = own if own in drainage[1] else next(iter(drainage[1]), None)
        scope = next((s for s in level_scopes.values() if s is not None and s.name == name), None)
        if scope is not None and drainage[1][name].get("extension", {}).get("params_per_fold"):
            return drainage_identifiability(drainage[0], scope, cov, drainage[1][name]["extension"]["params_per_fold"])
    between = level_scopes.get("between-site")
    for ext, scopes, _ in results:
        if not isinstance(ext, TemperatureShift) or "held_out_sites" not in scopes or between is None:
            continue
        whole = temperature_identifiability(ext, between, cov)
        if whole is None:
            return None
        folds = scopes["held_out_sites"]["extension"]["params_per_fold"]
        t = np.array([f["t_ref_c"] for f in folds], dtype=float)
        se = _jackknife_se(t)
        temps = site_values(cov, ext.column, between.sites)
        temps = temps[np.isfinite(temps)]
        precision = t_ref_precision(
            se,
            (float(temps.min()), float(temps.max())) if temps.size else None,
            whole.get("curve_shape"),
            whole.get("stretched_reading"),
        )
        return {
            "extension": "TemperatureShift",
            "parameter": "t_ref_c",
            "identifiable": bool(whole["identifiable"]),
            "why": whole.get("why"),
            "t_ref_c_all_sites": whole["t_ref_c"],
            "perm_p": whole["perm_p"],
            "folds": len(folds),
            "identifiable_folds": int(sum(bool(f.get("wlf_identifiable")) for f in folds)),
            "t_ref_c_median": float(np.median(t)),
            "t_ref_c_jackknife_se": se,
            "t_ref_c_interval_95": [whole["t_ref_c"] - 1.96 * se, whole["t_ref_c"] + 1.96 * se],
            **precision,
            "decay_slope": whole.get("decay_slope"),
            "routes": {r: int(sum(f.get("route") == r for f in folds)) for r in ("curves", "prediction")},
            "curve_shape": whole.get("curve_shape"),
            "stretched_reading": whole.get("stretched_reading"),
        }
    return None


def _jackknife_se(values: np.ndarray) -> float:
    """Leave-one-out (here: leave-one-section-out fold) jackknife standard error ``sqrt((k - 1)/k sum (x_j -
    mean x)^2)`` of ``k`` fold estimates, in their unit; NaN for fewer than 2."""
    x = np.asarray(values, dtype=float)
    return float(np.sqrt((len(x) - 1) / len(x) * np.sum((x - x.mean()) ** 2))) if len(x) > 1 else float("nan")


#: Permutations of the MPD column over the sites in :func:`drainage_identifiability` (p floor 1/50).
DRAINAGE_PERMUTATIONS = 49


def drainage_identifiability(
    ext: DrainageIFI, scope: Scope, cov: pd.DataFrame, folds: list[dict], n_perm: int = DRAINAGE_PERMUTATIONS
) -> dict:
    """Whether the drainage extension's kappa (dimensionless) is identified (gain.json ``identifiability``): the
    extension recalibrated on every site of ``scope`` (``kappa_all_sites``, ``form_all_sites``; form ``auto``: the
    curve form with the smaller training error), the folds' forms (``forms``: count per form) and kappa (median
    over the folds of the all-sites form), and how precisely the sections pin kappa: the leave-one-section-out
    jackknife over those folds, ``kappa_jackknife_se = sqrt((k - 1)/k sum (kappa_j - mean kappa)^2)``, and
    ``kappa_interval_95 = kappa_all_sites +- 1.96 se``. Drainage is a speed shape that scales with the site's
    macrotexture (1/Sp, Sp = 14.2 + 89.7 MPD); a speed shape common to every site (the calibrated law's functional
    form) also lowers the error for kappa > 0. So the all-sites fit is repeated with the MPD column permuted over
    the sites (``n_perm`` seeded permutations, the all-sites form): ``perm_p = (1 + #{SSE_perm <= SSE}) / (1 +
    n_perm)``. ``identifiable`` is false, with ``why``, when kappa sits at a bound of ``ext.kappa_bounds`` (at 0: no
    drainage speed shape; at the upper bound: the curve form cannot follow the measured shape), when the shape does
    not follow MPD (``perm_p`` > 0.05), when fewer than half of the folds choose the all-sites form, or when the
    interval reaches 0 (the sections do not separate the shape from none)."""
    lo, hi = (float(b) for b in ext.kappa_bounds)
    every = np.ones(len(scope.sites), dtype=bool)
    whole = recalibrate(ext, scope, cov, every)
    kappa, form = float(whole["kappa"]), whole.get("form", ext.form)
    fixed = ext if ext.form != "auto" else replace(ext, form=form)
    sse = _train_sse(fixed, whole, scope, cov, every)
    rng = np.random.default_rng(0)
    mpd = cov.loc[scope.sites, ext.mpd_column].to_numpy(float)
    hits = 0
    for _ in range(n_perm):
        perm = cov.copy()
        perm.loc[scope.sites, ext.mpd_column] = rng.permutation(mpd)
        hits += _train_sse(fixed, recalibrate(fixed, scope, perm, every), scope, perm, every) <= sse
    perm_p = (1 + hits) / (1 + n_perm)
    fold_forms = [f.get("form", ext.form) for f in folds]
    forms = dict(Counter(fold_forms))
    same = np.array([float(f["kappa"]) for f, fm in zip(folds, fold_forms) if fm == form], dtype=float)
    se = _jackknife_se(same)
    interval = [kappa - 1.96 * se, kappa + 1.96 * se]
    eps = 1e-6 * (hi - lo)
    if kappa <= lo + eps:
        why = f"kappa at its 'no drainage' bound {lo:g}: the measured curves show no drainage speed shape"
    elif kappa >= hi - eps:
        why = f"kappa runs to its upper bound {hi:g}: the {form} form does not follow the measured speed shape"
    elif perm_p > 0.05:
        why = (
            f"the speed shape does not follow MPD: with MPD permuted over the sites the fit is as good (permutation p "
            f"{perm_p:.2g}); a shape common to the sites, not drainage through the macrotexture"
        )
    elif 2 * len(same) < len(folds):
        why = f"the folds disagree on the curve form ({', '.join(f'{k} {n}' for k, n in sorted(forms.items()))})"
    elif not np.isfinite(se) or interval[0] <= lo:
        why = (
            f"the sections do not pin kappa: its 95 % jackknife interval [{interval[0]:.3g}, {interval[1]:.3g}] "
            f"reaches {lo:g} (no drainage)"
        )
    else:
        why = None
    return {
        "extension": "DrainageIFI",
        "parameter": "kappa",
        "identifiable": why is None,
        "why": why,
        "kappa_all_sites": kappa,
        "form_all_sites": form,
        "folds": len(folds),
        "forms": forms,
        "kappa_median": float(np.median(same)) if len(same) else float("nan"),
        "kappa_jackknife_se": se,
        "kappa_interval_95": interval,
        "perm_p": perm_p,
    }


#: Half-width (deg C) of the 95 % jackknife interval of the WLF reference temperature within which T_r counts as
#: pinned by the campaign: issue 33's "recovers t_ref within 5 deg C".
T_REF_PINNED_C = 5.0


def t_ref_precision(
    se_c: float, temperature_range_c: tuple[float, float] | None, shape: dict | None = None, stretched=None
) -> dict:
    """How precisely the sections pin the WLF reference temperature: ``t_ref_c_pinned`` is whether the 95 %
    jackknife half-width ``1.96 se_c`` (deg C) is at most :data:`T_REF_PINNED_C`; ``t_ref_c_precision`` says it in
    words, with the sites' temperature range (deg C, min and max; None if unknown). The WLF sensitivity
    ``d log10 a_T/dT = -C1 C2/(C2 + T - T_r)^2`` is all that T_r sets, and over a narrow range of temperatures it
    changes too little for the sites' scatter to pin it: T_r then moves the shift's size, not whether there is
    one (the permutation test of ``identifiable``), so a shift can be identified while its T_r is not pinned.
    ``shape``: :func:`skidsim.criticism.wlf.curve_shape` of the measured curves; where they are not exponential
    decays of speed, T_r is biased whatever its precision: never pinned, and the sentence says why, with T_r read
    with the curves' own stretched form where ``stretched`` (:func:`skidsim.criticism.wlf.temperature_identifiability`'s
    ``stretched_reading``) holds it."""
    out = _t_ref_precision(se_c, temperature_range_c)
    if shape is not None and not shape["exponential"]:
        text = f"{out['t_ref_c_precision']}; {shape['why']}"
        if stretched:
            text += (
                f"; read with the curves' own form exp(-(alpha s)^{stretched['stretch_exponent']:.2f}) T_r is "
                f"{stretched['t_ref_c']:.1f} deg C"
            )
        out = {"t_ref_c_pinned": False, "t_ref_c_precision": text}
    return out


def _t_ref_precision(se_c: float, temperature_range_c: tuple[float, float] | None) -> dict:
    half = 1.96 * float(se_c)
    span = (
        ""
        if temperature_range_c is None
        else (f" from sites at {temperature_range_c[0]:.1f}-{temperature_range_c[1]:.1f} deg C")
    )
    if not np.isfinite(half):
        return {"t_ref_c_pinned": False, "t_ref_c_precision": "T_r's precision is unknown (fewer than 2 folds)"}
    if half <= T_REF_PINNED_C:
        return {"t_ref_c_pinned": True, "t_ref_c_precision": f"T_r pinned to +-{half:.1f} deg C (95 %){span}"}
    return {
        "t_ref_c_pinned": False,
        "t_ref_c_precision": (
            f"T_r pinned only to +-{half:.1f} deg C (95 %){span}: over that range the WLF sensitivity, all that "
            f"T_r sets, changes too little for the sections to fix T_r within {T_REF_PINNED_C:.0f} deg C; read T_r "
            "as that interval, not as a value"
        ),
    }


def baseline_gain(residuals: pd.DataFrame, options: DiagnosisOptions = _DEFAULTS) -> tuple[dict, pd.DataFrame]:
    """The gain record without a named cause: RMSE/R^2 of the model as it is (after = before) in every scope."""
    scopes, frames = {}, []
    for level in LEVELS:
        sc = make_scope(residuals, level)
        if sc is None:
            continue
        rows = sc.rows.assign(after=sc.rows["before"])
        scopes[sc.name] = _boot(rows, options)
        frames.append(rows.assign(scope=sc.name))
    gain = {
        "cause": None,
        "extension": None,
        "level": None,
        "scope": None,
        "scopes": scopes,
        "fe_hook": None,
        "alternatives": [],
        "gain_excludes_zero": False,
    }
    return gain, pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
