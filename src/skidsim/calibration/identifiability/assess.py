"""The per-site record (:func:`assess`): noise, fit, flags and uncertainty of one calibration."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict

import pandas as pd

from skidsim.calibration.identifiability.fit import family_fits, fe_fit, fit_record, judged_points
from skidsim.calibration.identifiability.flags import site_flags
from skidsim.calibration.identifiability.mapping import SurrogateMap
from skidsim.calibration.identifiability.noise import trace_noise
from skidsim.calibration.identifiability.records import statement
from skidsim.calibration.identifiability.smoothness import fe_misses
from skidsim.calibration.identifiability.uncertainty import site_uncertainty
from skidsim.calibration.measured import measured_arrays, site_trace
from skidsim.calibration.options import DEFAULT_BOUNDS, PARAMS, IdentifiabilityOptions
from skidsim.calibration.result import CalibrationResult


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
    """The quality and identifiability record of one calibration (see the package :mod:`..identifiability`).

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
    v_fit, y_fit, fit_points = judged_points(st, trace, v_all, mu_all, cal, source)
    noise = trace_noise(
        v_all,
        mu_all,
        window_kmh=opt.noise_window_kmh,
        range_kmh=(min(cal + val), max(cal + val)),
        min_points=opt.noise_min_points,
    )
    sigma = noise["sigma"]
    have_sigma = math.isfinite(sigma) and sigma > 0
    fam = family_fits(mapping, law, v_fit, y_fit, bounds, opt)
    fe, fe_points = fe_fit(result, trace, validation, cal, val, v_all, source)
    misses = fe_misses(result, mapping, validation, cal, small_step_mu=opt.fe_smooth_step_max)
    flags, at_bound = site_flags(result, bounds, opt, sigma, fam, fe, misses, fit_points)
    unc = (
        site_uncertainty(law, mapping, v_fit, y_fit, bounds, cal, sigma, fam, opt)
        if have_sigma
        else {"available": False}
    )
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
        "fit": fit_record(fe, fe_points, fam, sigma),
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
        "statement": statement(have_sigma, ident, ident_c, unc),
        "options": asdict(opt),
    }


def site_record(
    result: CalibrationResult,
    traces: pd.DataFrame,
    validation: pd.DataFrame,
    *,
    site: str,
    method: str | None = None,
    options: IdentifiabilityOptions | None = None,
    calibration_speeds_kmh: Sequence[float] | None = None,
    validation_speeds_kmh: Sequence[float] = (),
    source: str | None = None,
    log=None,
) -> dict:
    """:func:`assess` of one site's calibration as the workflow makes it (``identifiability_<method>.json``, written
    by the rule validate_speeds beside the FE runs it reads): the site's trace from the campaign's trace table
    ``traces`` (site, speed_kmh, mu; sorted by speed), the rows of ``method`` (default ``result.method``) in the
    site's validation table ``validation`` (``validation.parquet``). ``source``: the trace table's path, for error
    messages. With a logger ``log``: one INFO line of noise and fit, one of the statement, and a WARNING per raised
    flag with its reason."""
    trace = site_trace(traces, site)
    method = method or result.method
    rec = assess(
        result,
        trace,
        validation[validation["method"] == method],
        options=options,
        calibration_speeds_kmh=calibration_speeds_kmh,
        validation_speeds_kmh=validation_speeds_kmh,
        site=site,
        source=source,
    )
    if log is not None:
        log.info(
            "%s %s: noise sigma %.4g (%d points), FE RMSE %.4g / %.4g at calibration / validation speeds, "
            "within noise: %s",
            site,
            method,
            rec["noise"]["sigma"],
            rec["noise"]["n"],
            rec["fit"]["rmse_fe_calibration"],
            rec["fit"]["rmse_fe_validation"],
            rec["within_noise"],
        )
        log.info("%s %s: %s", site, method, rec["statement"])
        for flag in rec["flags"]:
            log.warning("%s %s: %s: %s", site, method, flag, rec["reasons"][flag])
    return rec


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
