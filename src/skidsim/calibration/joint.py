"""Our calibration: all three parameters fitted jointly to the measured curve through a surrogate of the FE.

The simulated skid number is close to ``g * mu(v + d(v))`` with a site geometric factor ``g`` and, in the real
solver, an effective slip-speed excess ``d`` (``model="slip"``; ``model="ratio"`` is the field notes'
``SN = a(v) + b(v) mu(v)``). :func:`calibrate_fast` fits the three parameters to the whole measured curve by bounded
least squares *without* FE, then verifies with one FE run per calibration speed (after one cheap pilot run, or
starting from the campaign prior of :func:`surrogate_prior`); the surrogate is corrected from the FE runs until they
agree with it within ``tol`` (0.01, below the DFT's repeatability). Speeds in km/h, alpha in s/m, SN dimensionless.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from skidsim.calibration.cache import Simulator, prefetch
from skidsim.calibration.law_fit import fit_exponential_decay, invert_law_kmh
from skidsim.calibration.measured import measured_arrays, measured_at, measured_dict
from skidsim.calibration.options import CALIBRATION_SPEEDS_KMH, DEFAULT_BOUNDS, PARAMS, JointOptions
from skidsim.calibration.result import CalibrationResult, Evaluator
from skidsim.errors import InputError
from skidsim.friction import ExponentialDecay


def calibrate_fast(
    simulate: Simulator,
    measured_curve,
    options: JointOptions | None = None,
    *,
    speeds_kmh: Sequence[float] = CALIBRATION_SPEEDS_KMH,
    source: str | Path | None = None,
    prior: Mapping[str, Sequence[float]] | None = None,
) -> CalibrationResult:
    """Fit all three parameters to the measured curve with few FE runs (ours).

    Model: ``SN_FE(v) ~ a(v) + b(v) mu(v + d(v))``, per calibration speed ``v_i`` (km/h); between them a, b and d
    are interpolated linearly in speed (constant beyond). Start ``a = 0, b = g_prior, d = 0``.
    Pilot (``pilot_speed_kmh``, default ``"fastest"`` = the highest calibration speed, the FE run with the fewest
    time steps; None = no pilot): one FE run sets the level ``b = SN / mu`` at every speed before the first full
    batch (g is close to speed independent), which saves a whole batch when g differs from ``g_prior`` by more
    than the tolerance. ``model="slip"`` pilots a constant law (mu_s = mu_k = mean measured / g_prior, alpha 0);
    ``model="ratio"`` the first fit.
    Loop: (1) fit (mu_s, mu_k, alpha) to the measured data by bounded least squares under the model (no FE,
    :func:`fit_exponential_decay`); (2) one FE run per calibration speed with that law; (3) the largest
    ``|SN_FE - SN_model|`` over the speeds is the model error: stop when it is <= ``tol``; else correct the
    surrogate per speed (:meth:`_Surrogate.correct`).

    measured_curve: DataFrame (speed_kmh, mu), DftTrace or ``{speed_kmh: mu}`` (a dict is always fitted on the
    calibration speeds). options: :class:`JointOptions` (None: the defaults, config ``calibration.ours``).
    speeds_kmh: the calibration speeds (km/h). source: the measured data's file, for errors.
    prior: the surrogate's starting state learned on other sites of the campaign (:func:`surrogate_prior`):
    ``{"speeds_kmh": [...], "b": [...], "slip_offsets_kmh": [...]}`` (g and d in km/h at those speeds,
    interpolated linearly to ``speeds_kmh``, constant beyond). With a prior the pilot run is skipped: the first
    batch is usually already within ``tol`` (docs/calibration.md). Only for ``model="slip"``.
    """
    t_start = time.perf_counter()
    opt = options or JointOptions()
    spd = _calibration_speeds(speeds_kmh, opt)
    bnd = dict(DEFAULT_BOUNDS if opt.bounds is None else opt.bounds)
    meas = measured_dict(measured_curve, spd, opt.window_kmh, source)
    m_cal = np.array([meas[float(v)] for v in spd])
    v_fit, y_fit, mode = _fit_points(measured_curve, spd, m_cal, opt, source)
    sur = _Surrogate(spd, opt)
    pilot = opt.pilot_speed_kmh
    if prior is not None:
        sur.start_from_prior(prior)
        pilot = None
    elif pilot == "fastest":
        pilot = float(spd[-1])
    ev = Evaluator(simulate, "ours")
    if pilot is not None:
        pilot = float(pilot)
        _pilot_run(ev, sur, pilot, measured_curve, v_fit, y_fit, m_cal, bnd, opt, source)
    bnd, reach = _reach(sur, v_fit, y_fit, bnd, opt)
    params, converged, message = _iterate(ev, sur, v_fit, y_fit, m_cal, bnd, opt)
    settings = {
        "speeds_kmh": spd.tolist(),
        "tol": opt.tol,
        "max_fe_runs": int(opt.max_fe_runs),
        "fit_on": mode,
        "fit_range_kmh": None if opt.fit_range_kmh is None else list(opt.fit_range_kmh),
        "bounds": {k: list(v) for k, v in bnd.items()},
        "reach": reach,
        "g_prior": opt.g_prior,
        "pilot_speed_kmh": pilot,
        "model": opt.model,
        "slip_offsets_kmh": sur.d.tolist(),
        "b": sur.b.tolist(),
        # the surrogate state that reproduces the converged batch (None: not converged); the campaign prior's source
        "fe_implied": None
        if sur.implied is None
        else {"b": sur.implied[0].tolist(), "slip_offsets_kmh": sur.implied[1].tolist()},
        "a": sur.a.tolist(),
        "secant_min_dmu": opt.secant_min_dmu,
        "window_kmh": opt.window_kmh,
        "alpha_step_factor": opt.alpha_step_factor,
        "alpha_steps_limited": int(sur.limited),
        "correction_relaxation": opt.correction_relaxation,
        "relaxation_on_reversal": opt.relaxation_on_reversal,
        "fit_gain_tol": opt.fit_gain_tol,
        "prior": None
        if prior is None
        else {k: [float(x) for x in prior[k]] for k in ("speeds_kmh", "b", "slip_offsets_kmh")},
    }
    return CalibrationResult(
        method="ours",
        params=params,
        history=ev.history(),
        converged=converged,
        message=message,
        measured_kmh=meas,
        overhead_s=ev.overhead_s(t_start),
        settings=settings,
    )


def _reach(sur: _Surrogate, v_fit, y_fit, bnd: dict, opt: JointOptions) -> tuple[dict, dict | None]:
    """The bounds of the site's fit: ``bnd``, or ``bnd`` with mu_s up to ``opt.reach_mu_s_max`` where that lowers
    the surrogate's RMSE on the fitted points (mu) by more than ``opt.reach_min_gain_mu`` (no FE run). Returns
    (bounds, record: the two RMSEs, the wider upper bound and whether it is used; None when there is no wider
    bound to try)."""
    hi = opt.reach_mu_s_max
    if hi is None or hi <= bnd["mu_s"][1]:
        return bnd, None
    wide = {**bnd, "mu_s": (bnd["mu_s"][0], float(hi))}
    _, rmse = sur.fit(v_fit, y_fit, bnd)
    _, rmse_wide = sur.fit(v_fit, y_fit, wide)
    used = rmse - rmse_wide > opt.reach_min_gain_mu
    record = {"rmse_bounds": float(rmse), "rmse_wide": float(rmse_wide), "mu_s_max_wide": float(hi), "used": bool(used)}
    return (wide if used else bnd), record


def _calibration_speeds(speeds_kmh: Sequence[float], opt: JointOptions) -> np.ndarray:
    """The calibration speeds (km/h) ascending; checks them against the FE budget."""
    spd = np.array(sorted(float(v) for v in speeds_kmh))
    if spd.size < 1 or len(set(spd)) != spd.size:
        raise ValueError(f"speeds_kmh must be distinct speeds in km/h, got {speeds_kmh!r}")
    if opt.max_fe_runs < spd.size:
        raise ValueError(f"max_fe_runs={opt.max_fe_runs} is below one run per calibration speed ({spd.size})")
    return spd


def _fit_points(
    measured_curve, spd: np.ndarray, m_cal: np.ndarray, opt: JointOptions, source
) -> tuple[np.ndarray, np.ndarray, str]:
    """(speeds km/h, mu, mode) the law is fitted to: the trace within ``fit_range_kmh`` (default the calibration
    speed range) for ``fit_on="trace"``, else the measured values at the calibration speeds (mode "speeds")."""
    if opt.fit_on == "trace" and not isinstance(measured_curve, Mapping):
        v_all, mu_all = measured_arrays(measured_curve, source=source)
        lo_v, hi_v = (spd[0], spd[-1]) if opt.fit_range_kmh is None else opt.fit_range_kmh
        sel = (v_all >= lo_v - 1e-9) & (v_all <= hi_v + 1e-9)
        v_fit, y_fit = v_all[sel], mu_all[sel]
        if np.unique(v_fit).size < 3:
            raise InputError(
                source,
                f"at least 3 measured speeds within {lo_v:g}..{hi_v:g} km/h",
                column="speed_kmh",
                got=int(np.unique(v_fit).size),
            )
        return v_fit, y_fit, "trace"
    if spd.size < 3:
        raise ValueError("fit_on='speeds' needs >= 3 calibration speeds for three parameters")
    return spd, m_cal, "speeds"


class _Surrogate:
    """The FE surrogate ``SN(v) = a(v) + b(v) mu(v + d(v))`` with a, b, d (d in km/h) per calibration speed,
    linear in between and constant beyond, and the latest (mu, SN) run per speed (the ratio model's secant)."""

    def __init__(self, spd: np.ndarray, opt: JointOptions):
        self.spd = spd
        self.model = opt.model
        self.secant_min_dmu = opt.secant_min_dmu
        self.a = np.zeros(spd.size)
        self.b = np.full(spd.size, float(opt.g_prior))
        self.d = np.zeros(spd.size)  # effective slip-speed offsets, km/h (model="slip")
        self.last: list[tuple[float, float] | None] = [None] * spd.size
        self.limited = 0  # refits the alpha trust region moved (alpha_step_factor)
        self.relaxation = float(opt.correction_relaxation)
        self.on_reversal = bool(opt.relaxation_on_reversal)
        self.miss = np.zeros(spd.size)  # the latest FE batch's miss of the surrogate (SN), per speed
        self.reversed = False  # a batch's miss changed sign or did not halve at a speed (relaxation_on_reversal)
        self.n_corrections = 0
        self.whole: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # (a, b, d) of the latest whole step
        # (b, d) that reproduce the converged batch: a batch within tol of the surrogate still measures the FE's
        # slip offsets (a reference converging in its first batch after the pilot never corrects d from 0)
        self.implied: tuple[np.ndarray, np.ndarray] | None = None

    def start_from_prior(self, prior: Mapping[str, Sequence[float]]) -> None:
        """b and d from the campaign prior (:func:`surrogate_prior`), interpolated to the calibration speeds."""
        if self.model != "slip":
            raise ValueError("a surrogate prior is only defined for model='slip'")
        try:
            pv = np.asarray(prior["speeds_kmh"], dtype=float)
            pb = np.asarray(prior["b"], dtype=float)
            pd_ = np.asarray(prior["slip_offsets_kmh"], dtype=float)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(
                f"prior must map speeds_kmh, b and slip_offsets_kmh to number lists, got {prior!r}"
            ) from exc
        if not (
            pv.ndim == 1
            and pv.size >= 1
            and pb.shape == pv.shape
            and pd_.shape == pv.shape
            and np.all(np.isfinite(pb))
            and np.all(pb > 0)
            and np.all(np.isfinite(pd_))
            and np.all(np.diff(pv) > 0)
        ):
            raise ValueError(
                f"prior needs increasing speeds_kmh and finite b > 0 and slip_offsets_kmh of the same "
                f"length, got {prior!r}"
            )
        self.b = np.interp(self.spd, pv, pb)
        self.d = np.interp(self.spd, pv, pd_)

    def fit(self, v_fit: np.ndarray, y_fit: np.ndarray, bounds: Mapping) -> tuple[ExponentialDecay, float]:
        """The bounded least-squares law of the data under the surrogate (no FE) and its RMSE (mu) on the points."""
        a_fit = np.interp(v_fit, self.spd, self.a)
        b_fit = np.interp(v_fit, self.spd, self.b)
        v_eff_fit = v_fit + np.interp(v_fit, self.spd, self.d)
        law, sse = fit_exponential_decay(v_eff_fit, y_fit, a=a_fit, b=b_fit, bounds=bounds)
        return law, float(np.sqrt(sse / max(len(y_fit), 1)))

    def predict(self, law: ExponentialDecay) -> tuple[np.ndarray, np.ndarray]:
        """(mu at the effective speeds, surrogate SN) at the calibration speeds."""
        mu_i = law.mu_kmh(self.spd + self.d)
        return mu_i, self.a + self.b * mu_i

    def predict_whole(self, law: ExponentialDecay) -> np.ndarray:
        """Surrogate SN at the calibration speeds as the latest correction would have left it as a whole step
        (the surrogate that reproduces the latest FE batch at its law); :meth:`predict` before any correction
        and wherever the corrections are whole. Its miss on the next batch measures how smoothly the FE responds
        to the change of law; the relaxed surrogate's miss also carries the share of the step it held back."""
        if self.whole is None:
            return self.predict(law)[1]
        a, b, d = self.whole
        return a + b * law.mu_kmh(self.spd + d)

    def correct(self, law: ExponentialDecay, mu_i: np.ndarray, sn: np.ndarray) -> None:
        """Update the surrogate from one batch of FE runs ``sn`` of ``law``.

        ``model="slip"``: the offset d_i from inverting the law, ``mu(v_i + d_i) = (SN_i - a_i) / b_i`` (kept within
        0.25..4 times the speed; where not invertible - flat law, value outside [mu_k, mu_s] - the ratio
        ``b_i = SN_i / mu_i``); from the second correction on, b and d move only the share ``correction_relaxation``
        of the way to those values (with ``relaxation_on_reversal``: only from the first batch on whose miss of the
        surrogate, ``sn`` minus its prediction, changed sign or did not halve against the previous batch's at any
        speed; whole steps before it). ``model="ratio"``: ``b = SN/mu, a = 0`` (fixed point on g) or, once two runs at
        that speed differ in mu by >= ``secant_min_dmu``, the secant line through them (slope within 0.2..5).
        """
        self.n_corrections += 1
        if self.on_reversal:  # the miss is only needed by the option
            miss = np.asarray(sn, dtype=float) - self.predict(law)[1]
            if self.n_corrections >= 2:
                self.reversed = self.reversed or bool(
                    np.any(miss * self.miss < 0) or np.any(np.abs(miss) > 0.5 * np.abs(self.miss))
                )
            self.miss = miss
        b_old, d_old = self.b.copy(), self.d.copy()
        self._correct_whole(law, mu_i, sn)
        self.whole = (self.a.copy(), self.b.copy(), self.d.copy())
        if self.model == "slip" and self.n_corrections >= 2 and self.relaxation < 1.0:
            r = self.relaxation if (self.reversed or not self.on_reversal) else 1.0
            self.b = b_old + r * (self.b - b_old)
            self.d = d_old + r * (self.d - d_old)

    def corrected(self, law: ExponentialDecay, mu_i: np.ndarray, sn: np.ndarray) -> _Surrogate:
        """A copy of the surrogate after the whole correction of :meth:`correct` from the FE batch ``sn`` of ``law``
        (it reproduces that batch); this surrogate is unchanged."""
        new = copy.copy(self)
        new.a, new.b, new.d, new.last = self.a.copy(), self.b.copy(), self.d.copy(), list(self.last)
        new._correct_whole(law, mu_i, sn)
        return new

    def _correct_whole(self, law: ExponentialDecay, mu_i: np.ndarray, sn: np.ndarray) -> None:
        """The correction of :meth:`correct` as a whole step (the values the latest batch implies)."""
        a_i, b_i, d_i, spd = self.a, self.b, self.d, self.spd
        for j in range(spd.size):
            mu_j, sn_j = float(mu_i[j]), float(sn[j])
            prev = self.last[j]
            if self.model == "slip":
                d_new = invert_law_kmh(law, (sn_j - a_i[j]) / b_i[j])
                if d_new is not None and 0.25 * spd[j] <= d_new <= 4.0 * spd[j]:
                    d_i[j] = d_new - spd[j]
                else:
                    b_i[j] = sn_j / mu_j if mu_j > 0 else b_i[j]
                continue
            if prev is not None and abs(mu_j - prev[0]) >= self.secant_min_dmu:
                bj = (sn_j - prev[1]) / (mu_j - prev[0])
                if 0.2 <= bj <= 5.0:
                    a_i[j], b_i[j] = sn_j - bj * mu_j, bj
                else:
                    a_i[j], b_i[j] = 0.0, sn_j / mu_j if mu_j > 0 else b_i[j]
            else:
                a_i[j], b_i[j] = 0.0, (sn_j / mu_j if mu_j > 0 else b_i[j])
            self.last[j] = (mu_j, sn_j)


def _pilot_run(
    ev: Evaluator,
    sur: _Surrogate,
    pilot_kmh: float,
    measured_curve,
    v_fit,
    y_fit,
    m_cal,
    bnd,
    opt: JointOptions,
    source,
) -> None:
    """One FE run at ``pilot_kmh`` that sets the level ``b = SN / mu`` at every calibration speed."""
    spd = sur.spd
    if opt.max_fe_runs < spd.size + 1:
        raise ValueError(f"max_fe_runs={opt.max_fe_runs} leaves no room for the pilot run and one batch")
    if opt.model == "slip":
        mu_c = float(np.mean(m_cal)) / float(opt.g_prior)
        mu_c = min(max(mu_c, max(bnd["mu_s"][0], bnd["mu_k"][0])), min(bnd["mu_s"][1], bnd["mu_k"][1]))
        law0 = ExponentialDecay(mu_s=mu_c, mu_k=mu_c, alpha=0.0)
    else:
        law0, _ = fit_exponential_decay(
            v_fit, y_fit, a=np.interp(v_fit, spd, sur.a), b=np.interp(v_fit, spd, sur.b), bounds=bnd
        )
    mu0 = float(law0.mu_kmh(pilot_kmh))
    try:
        pm = float(measured_at(measured_curve, [pilot_kmh], window_kmh=opt.window_kmh, source=source)[0])
    except InputError:  # a pilot speed the data do not cover: no measured value to report, still usable
        pm = float("nan")
    out = ev(
        pilot_kmh,
        law0,
        stage="pilot",
        iteration=0,
        sn_measured=pm,
        sn_pred=float(np.interp(pilot_kmh, spd, sur.a) + np.interp(pilot_kmh, spd, sur.b) * mu0),
    )
    if mu0 > 0:
        sur.b[:] = out.sn / mu0
        sur.a[:] = 0.0
    jp = np.flatnonzero(np.abs(spd - pilot_kmh) < 1e-9)
    if jp.size:
        sur.last[int(jp[0])] = (mu0, float(out.sn))


def _iterate(
    ev: Evaluator, sur: _Surrogate, v_fit, y_fit, m_cal, bnd, opt: JointOptions
) -> tuple[ExponentialDecay, bool, str]:
    """Fit, verify with one FE batch, correct, until the FE agrees with the surrogate within ``tol``, the law stops
    changing, or the budget is spent. Returns (law, converged, message); not converged: the verified law with the
    smallest RMSE vs measured at the calibration speeds."""
    spd, tol = sur.spd, opt.tol
    verified: list[tuple[ExponentialDecay, float, float]] = []  # (law, rmse vs measured, model error)
    prev_law = None
    it = 0
    while True:
        it += 1
        law, rmse_fit = sur.fit(v_fit, y_fit, bnd)
        if prev_law is not None:
            window = alpha_window(prev_law.alpha, bnd["alpha"], opt)
            if window is not None and not (window[0] <= law.alpha <= window[1]):
                near, rmse_near = sur.fit(v_fit, y_fit, {**bnd, "alpha": window})
                if rmse_near - rmse_fit <= opt.alpha_step_max_cost:
                    law = near
                    sur.limited += 1
        if prev_law is not None and all(abs(getattr(law, p) - getattr(prev_law, p)) < 1e-12 for p in PARAMS):
            message = (
                f"fast calibration stalled: the model update did not change the law after iteration "
                f"{it - 1} (model error above tol={tol:g})"
            )
            break
        if len(ev.rows) + spd.size > opt.max_fe_runs:
            message = (
                f"fast calibration: FE budget max_fe_runs={opt.max_fe_runs} reached after {len(ev.rows)} "
                f"runs without the FE runs agreeing with the surrogate within tol={tol:g}"
            )
            break
        mu_i, pred = sur.predict(law)
        pred_whole = sur.predict_whole(law)
        sn = np.empty(spd.size)
        t_batch = time.perf_counter()  # the batch's speeds are independent: one batched FE run (same SN)
        prefetch(ev.simulate, [(float(v), law) for v in spd])
        ev.sim_wall += time.perf_counter() - t_batch
        for j, v in enumerate(spd):
            out = ev(
                v,
                law,
                stage="verify",
                iteration=it,
                sn_measured=float(m_cal[j]),
                sn_pred=float(pred[j]),
                sn_pred_whole=float(pred_whole[j]),
            )
            sn[j] = out.sn
        model_err = float(np.max(np.abs(sn - pred)))
        rmse = float(np.sqrt(np.mean((sn - m_cal) ** 2)))
        verified.append((law, rmse, model_err))
        if model_err <= tol:
            after = sur.corrected(law, mu_i, sn)
            gain = _further_gain(after, v_fit, y_fit, m_cal, bnd, rmse)
            if opt.fit_gain_tol is None or gain <= opt.fit_gain_tol or len(ev.rows) + spd.size > opt.max_fe_runs:
                sur.implied = (after.b, after.d)
                return law, True, _converged_message(it, model_err, tol, rmse, gain, opt.fit_gain_tol)
        sur.correct(law, mu_i, sn)
        prev_law = law
    if not verified:  # pragma: no cover - max_fe_runs >= speeds guarantees one batch
        return law, False, message
    best = min(verified, key=lambda t: t[1])[0]
    return best, False, message + f"; kept the verified law with the smallest RMSE vs measured ({best})"


def _further_gain(after: _Surrogate, v_fit, y_fit, m_cal, bnd, rmse: float) -> float:
    """RMSE (mu) at the calibration speeds that one more batch would gain by the surrogate ``after`` (corrected on
    the batch just verified, whose RMSE vs measured there is ``rmse``): ``rmse`` minus the surrogate's RMSE of its
    refit law. <= 0 when the refit does not fit the calibration speeds better."""
    law2, _ = after.fit(v_fit, y_fit, bnd)
    _, pred2 = after.predict(law2)
    return rmse - float(np.sqrt(np.mean((pred2 - m_cal) ** 2)))


def _converged_message(it: int, model_err: float, tol: float, rmse: float, gain: float, gain_tol) -> str:
    msg = (
        f"converged after {it} iteration(s): FE agrees with the surrogate within {model_err:.2g} <= tol={tol:g}; "
        f"RMSE vs measured at calibration speeds {rmse:.4g}"
    )
    if gain_tol is not None:
        msg += f"; a further batch would gain {gain:.2g} <= fit_gain_tol={gain_tol:g} in that RMSE (predicted)"
    return msg


def alpha_window(alpha_prev: float, bound: Sequence[float], opt: JointOptions) -> tuple[float, float] | None:
    """The trust region (s/m) of the next refit's alpha after a batch verified a law with ``alpha_prev``:
    ``[alpha_prev / f, alpha_prev * f + floor]`` within the calibration ``bound`` (f = ``alpha_step_factor``,
    floor = ``alpha_step_floor_s_per_m``); None without a limit. :func:`calibrate_fast` refits within it when the
    free refit's alpha falls outside and the law within the window fits the data under the surrogate at most
    ``alpha_step_max_cost`` (mu, RMSE) worse: the data then cannot tell the two laws apart, and the FE's response
    was measured near the verified one."""
    f = opt.alpha_step_factor
    if f is None:
        return None
    lo = max(float(bound[0]), alpha_prev / f)
    hi = min(float(bound[1]), alpha_prev * f + opt.alpha_step_floor_s_per_m)
    return (lo, hi) if lo < hi else None


def surrogate_prior(results: Sequence[CalibrationResult]) -> dict:
    """The campaign prior of our method: the median, over reference sites calibrated without a prior, of the
    geometric factor ``b`` and slip offsets ``d`` (km/h) at each calibration speed that reproduce each reference's
    converged FE batch (``settings["fe_implied"]``: the whole correction of that batch; results written before
    it existed give the surrogate's final ``b`` and ``d``).

    Both are properties of the FE slider's dynamics (how much faster its contact nodes slip than the holder
    moves, and the ratio of SN to mu at the effective slip speed) and vary little between sites of one campaign.
    The converged batch, not the surrogate's final state, is the measurement: a reference that converges in the
    batch after its pilot never corrects d, so its final d is the start value 0, whatever the FE did
    (docs/calibration.md, "Campaign prior").
    Raises ValueError when no result is usable (converged, model "slip", same calibration speeds).
    """
    usable = [
        r
        for r in results
        if r.method == "ours" and r.converged and r.settings.get("model") == "slip" and r.settings.get("prior") is None
    ]
    if not usable:
        raise ValueError("surrogate_prior: no converged prior-free 'ours' calibration with model 'slip' to learn from")
    speeds = [tuple(float(v) for v in r.settings["speeds_kmh"]) for r in usable]
    if len(set(speeds)) != 1:
        raise ValueError(f"surrogate_prior: reference calibrations used different speeds {sorted(set(speeds))}")
    states = [r.settings.get("fe_implied") or r.settings for r in usable]
    b = np.median(np.array([s["b"] for s in states], dtype=float), axis=0)
    d = np.median(np.array([s["slip_offsets_kmh"] for s in states], dtype=float), axis=0)
    return {"speeds_kmh": list(speeds[0]), "b": b.tolist(), "slip_offsets_kmh": d.tolist(), "n_sites": len(usable)}


def prior_reference_sites(sites: Sequence[str], n: int) -> list[str]:
    """The ``n`` reference sites whose prior-free calibrations make the prior: evenly spread over the site
    table's order (indices ``round(linspace(0, len - 1, n))``), all sites when ``n >= len(sites)``, none for 0."""
    sites = list(sites)
    if n <= 0 or not sites:
        return []
    if n >= len(sites):
        return sites
    idx = sorted({int(round(x)) for x in np.linspace(0, len(sites) - 1, n)})
    return [sites[i] for i in idx]
