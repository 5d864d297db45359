"""The study's binary-search back-calculation (section 6.2), exactly: :func:`calibrate_study`.

``mu_k`` at 60 km/h, then ``mu_s`` at 20 km/h holding ``mu_k``, then ``alpha`` at 40 km/h holding both; each
search stops when ``|SN_sim - SN_measured| / SN_measured < tol`` (10 %). Conventions (also in
``docs/calibration.md``):

* **Search intervals.** ``mu_s`` in [0, 0.85], ``mu_k`` in [0, 0.7], ``alpha`` in [0, 1] s/m: the ranges the
  study lists in its text. Its worked example uses [0, 0.85] for ``mu_k``; we keep [0, 0.7] by default.
* **Start values.** Parameters not yet searched are held at ``start = (mu_s, mu_k, alpha) = (0.4, 0.35, 0.6)``,
  the values of the study's mesh study. The first evaluation of each search is the midpoint of its interval
  (study step 1), never the start value.
* **Direction.** SN grows with ``mu_k`` and ``mu_s``; with ``alpha`` it falls when ``mu_s > mu_k`` and grows when
  ``mu_s < mu_k`` (the sign of d mu / d alpha). A positive error (simulation too high) keeps the half-interval on
  the side that lowers SN.
* **Max iterations.** ``max_iter`` FE evaluations per parameter. When a search exhausts it, ``on_max_iter="flag"``
  keeps the evaluated value with the smallest ``|error|``, records a message naming the parameter, speed, interval
  and last error, marks the result not converged and goes on; ``"raise"`` raises :class:`CalibrationError`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from skidsim.calibration.cache import Simulator
from skidsim.calibration.measured import measured_dict
from skidsim.calibration.options import PARAMS, STUDY_ORDER, StudyOptions
from skidsim.calibration.result import CalibrationError, CalibrationResult, Evaluator
from skidsim.friction import ExponentialDecay


def calibrate_study(
    simulate: Simulator,
    measured,
    options: StudyOptions | None = None,
    *,
    order: Sequence[tuple[str, float]] = STUDY_ORDER,
    source: str | Path | None = None,
) -> CalibrationResult:
    """The study's nested bisection of one site.

    measured: ``{speed_kmh: mu}`` with the speeds of ``order`` (20, 40, 60 km/h), or a measured curve (see
    :func:`measured_at`). options: :class:`StudyOptions` (None: the defaults, config ``calibration.study``).
    order: (parameter, speed km/h) searched one after the other. source: the measured data's file, for errors.
    """
    t_start = time.perf_counter()
    opt = options or StudyOptions()
    for name, _ in order:
        if name not in PARAMS:
            raise ValueError(f"unknown parameter {name!r} in order; expected one of {PARAMS}")
    meas = measured_dict(measured, [float(v) for _, v in order], opt.window_kmh, source)
    current = dict(zip(PARAMS, (float(x) for x in opt.start)))
    ev = Evaluator(simulate, "study")
    messages = []
    for name, speed in order:
        msg = _search(ev, current, name, float(speed), meas[float(speed)], opt)
        if msg is not None:
            messages.append(msg)
    converged = not messages
    msg = "converged: every search met the tolerance" if converged else "; ".join(messages)
    return CalibrationResult(
        method="study",
        params=ExponentialDecay(**current),
        history=ev.history(),
        converged=converged,
        message=msg,
        measured_kmh=meas,
        overhead_s=ev.overhead_s(t_start),
        settings=_settings(opt, order),
    )


def _search(ev: Evaluator, current: dict, name: str, speed: float, target: float, opt: StudyOptions) -> str | None:
    """Bisect ``name`` at ``speed`` (km/h) toward the measured ``target``; sets ``current[name]``. Returns None when
    the tolerance was met, else the message naming the exhausted search (or raises, ``on_max_iter="raise"``)."""
    lo, hi = (float(x) for x in opt.intervals[name])
    tried: list[tuple[float, float]] = []  # (value, rel_err)
    for it in range(1, int(opt.max_iter) + 1):
        mid = 0.5 * (lo + hi)
        trial = dict(current, **{name: mid})
        out = ev(speed, ExponentialDecay(**trial), stage=name, iteration=it, sn_measured=target, lo=lo, hi=hi)
        err = out.sn / target - 1.0
        tried.append((mid, err))
        if abs(err) < opt.tol:
            current[name] = mid
            return None
        increasing = True if name != "alpha" else (trial["mu_s"] < trial["mu_k"])
        if (err > 0) == increasing:  # SN too high and growing with the parameter, or too low and falling
            hi = mid
        else:
            lo = mid
    best_val, best_err = min(tried, key=lambda t: abs(t[1]))
    msg = (
        f"study bisection: {name} at {speed:g} km/h did not reach |SN_sim - SN_measured|/SN_measured "
        f"< {opt.tol:g} within max_iter={opt.max_iter} FE evaluations (last interval [{lo:.6g}, {hi:.6g}], "
        f"last error {tried[-1][1]:+.3%}, measured {target:.4g}); kept the best evaluated "
        f"{name}={best_val:.6g} (error {best_err:+.3%})"
    )
    if opt.on_max_iter == "raise":
        raise CalibrationError(msg)
    current[name] = best_val
    return msg


def _settings(opt: StudyOptions, order: Sequence[tuple[str, float]]) -> dict:
    """The settings recorded with the result (JSON-ready)."""
    return {
        "intervals": {k: list(v) for k, v in opt.intervals.items()},
        "start": list(opt.start),
        "tol": opt.tol,
        "max_iter": int(opt.max_iter),
        "order": [[n, float(v)] for n, v in order],
        "on_max_iter": opt.on_max_iter,
        "window_kmh": opt.window_kmh,
    }
