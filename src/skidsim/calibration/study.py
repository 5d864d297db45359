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
* **Look-ahead** (``look_ahead``, default ``"stages"``). The FE runs of later iterations are announced with
  this one's (:func:`~skidsim.calibration.cache.prefetch`: one batch of runs at the same speed for a simulator
  that batches); the evaluations, decisions, history, law and messages are those of the sequential bisection
  bit for bit. Announced runs the bisection did not use are withdrawn and counted in the result's ``settings``
  (``speculative_fe_runs``, ``speculative_fe_steps``, ``speculative_fe_steps_run``, ``speculative_fe_wall_s``
  in s), not in its history, ``n_fe_runs`` or ``n_steps`` (the cost of the study's method). ``"stages"``
  (default) is ``"predicted"`` for the first search; at the start of each later one whose first midpoint was not
  announced it announces the predicted paths of that search and of all after it (each from the value the one
  before is predicted to keep, with the ``g`` measured so far) as one batch: ``mu_s`` at 20 km/h and ``alpha`` at
  40 km/h run together.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from skidsim.calibration.cache import FEOutcome, Simulator, prefetch, withdraw
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
    spec = _Speculative()
    messages = []
    ahead: dict[tuple[float, ExponentialDecay], str] = {}  # announced, not yet evaluated -> its search
    for k, (name, speed) in enumerate(order):
        if opt.look_ahead == "stages" and ev.rows:
            _announce_stages(ev, current, order[k:], meas, opt, ahead)
        msg = _search(ev, current, name, float(speed), meas[float(speed)], opt, spec, ahead)
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
        settings=_settings(opt, order) | spec.settings(),
    )


def _search(
    ev: Evaluator,
    current: dict,
    name: str,
    speed: float,
    target: float,
    opt: StudyOptions,
    spec: _Speculative,
    ahead: dict[tuple[float, ExponentialDecay], str],
) -> str | None:
    """Bisect ``name`` at ``speed`` (km/h) toward the measured ``target``; sets ``current[name]``. Returns None when
    the tolerance was met, else the message naming the exhausted search (or raises, ``on_max_iter="raise"``).

    With ``opt.look_ahead`` the midpoints of later iterations are announced to the simulator together with this
    one's (:func:`_look_ahead`); the sequence evaluated is the same, the announced points of this search not
    evaluated are withdrawn at its end and counted in ``spec``. ``ahead``: the announced requests not yet
    evaluated, each with the search it was announced for (shared by the searches of one calibration)."""
    lo, hi = (float(x) for x in opt.intervals[name])
    tried: list[tuple[float, float]] = []  # (value, rel_err)
    try:
        for it in range(1, int(opt.max_iter) + 1):
            mid = 0.5 * (lo + hi)
            trial = dict(current, **{name: mid})
            law = ExponentialDecay(**trial)
            if opt.look_ahead != "none" and (speed, law) not in ahead:
                for request in _look_ahead(ev, current, name, speed, target, opt, lo, hi, it):
                    ahead.setdefault(request, name)
            ahead.pop((speed, law), None)
            out = ev(speed, law, stage=name, iteration=it, sn_measured=target, lo=lo, hi=hi)
            err = out.sn / target - 1.0
            tried.append((mid, err))
            if abs(err) < opt.tol:
                current[name] = mid
                return None
            lo, hi = _next_interval(name, trial, err, lo, hi)
    finally:
        mine = [r for r, stage in ahead.items() if stage == name]
        for r in mine:
            del ahead[r]
        spec.withdraw(ev, mine)
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


def _next_interval(name: str, trial: dict, err: float, lo: float, hi: float) -> tuple[float, float]:
    """The half of [lo, hi] the bisection keeps after the relative error ``err`` at its midpoint ``trial[name]``."""
    mid = trial[name]
    increasing = True if name != "alpha" else (trial["mu_s"] < trial["mu_k"])
    if (err > 0) == increasing:  # SN too high and growing with the parameter, or too low and falling
        return lo, mid
    return mid, hi


def _look_ahead(
    ev: Evaluator,
    current: dict,
    name: str,
    speed: float,
    target: float,
    opt: StudyOptions,
    lo: float,
    hi: float,
    it: int,
) -> set[tuple[float, ExponentialDecay]]:
    """Announce (:func:`prefetch`) the midpoint of [lo, hi] and midpoints of later iterations (at most
    ``max_iter``), so that a simulator that batches runs them as one batch of the same speed. Returns the
    requests announced.

    ``"quarters"``: the midpoint and both quarter points (one of them is the next iteration's midpoint unless
    the search stops). ``"predicted"``: the midpoints along the path the bisection takes when SN follows
    ``SN = g mu(v)`` with the factor ``g = SN / mu`` of the latest evaluation (1 before any), up to
    ``look_ahead_depth`` iterations, ending at the first point predicted within the tolerance."""
    points: list[float] = []
    if opt.look_ahead == "quarters":
        mid = 0.5 * (lo + hi)
        points = [mid] + ([0.5 * (lo + mid), 0.5 * (mid + hi)] if it < opt.max_iter else [])
    else:
        depth = min(int(opt.look_ahead_depth), int(opt.max_iter) - it + 1)
        points, _ = _predicted_path(current, name, speed, target, opt, lo, hi, _latest_sn_factor(ev), depth)
    requests = [(speed, ExponentialDecay(**dict(current, **{name: x}))) for x in points]
    _prefetch(ev, requests)
    return set(requests)


def _prefetch(ev: Evaluator, requests: list) -> None:
    """Announce ``requests`` (more than one: a batch) to the simulator; the batch's time is simulator time."""
    if len(requests) > 1:
        t0 = time.perf_counter()
        prefetch(ev.simulate, requests)
        ev.sim_wall += time.perf_counter() - t0


def _predicted_path(
    current: dict,
    name: str,
    speed: float,
    target: float,
    opt: StudyOptions,
    lo: float,
    hi: float,
    g: float,
    depth: int,
) -> tuple[list[float], float]:
    """The midpoints (at most ``depth``) the bisection of ``name`` on [lo, hi] evaluates if ``SN = g mu(v)``,
    ending at the first one within the tolerance, and the value the search then keeps (that point, or the one of
    smallest predicted error when none is within the tolerance)."""
    points: list[float] = []
    errs: list[float] = []
    a, b = lo, hi
    for _ in range(depth):
        x = 0.5 * (a + b)
        trial = dict(current, **{name: x})
        err = g * float(ExponentialDecay(**trial).mu_kmh(speed)) / target - 1.0
        points.append(x)
        errs.append(abs(err))
        if abs(err) < opt.tol:
            break
        a, b = _next_interval(name, trial, err, a, b)
    return points, points[min(range(len(points)), key=errs.__getitem__)]


def _announce_stages(
    ev: Evaluator,
    current: dict,
    order: Sequence[tuple[str, float]],
    meas: dict,
    opt: StudyOptions,
    ahead: dict[tuple[float, ExponentialDecay], str],
) -> None:
    """``look_ahead="stages"``, before a search that follows an evaluation: unless its first midpoint was announced
    already, announce the predicted paths (``SN = g mu(v)``, ``g`` of the latest evaluation) of it and of the
    searches after it, each from the value the one before is predicted to keep, as one batch; adds them to
    ``ahead`` (each with its search)."""
    name0, speed0 = order[0]
    lo0, hi0 = (float(x) for x in opt.intervals[name0])
    if (float(speed0), ExponentialDecay(**dict(current, **{name0: 0.5 * (lo0 + hi0)}))) in ahead:
        return
    g = _latest_sn_factor(ev)
    cur = dict(current)
    new: dict[tuple[float, ExponentialDecay], str] = {}
    depth = min(int(opt.look_ahead_depth), int(opt.max_iter))
    for name, speed in order:
        lo, hi = (float(x) for x in opt.intervals[name])
        points, keep = _predicted_path(cur, name, float(speed), meas[float(speed)], opt, lo, hi, g, depth)
        for x in points:
            request = (float(speed), ExponentialDecay(**dict(cur, **{name: x})))
            if request not in ahead:
                new.setdefault(request, name)
        cur[name] = keep
    if len(new) > 1:
        _prefetch(ev, list(new))
        ahead.update(new)


def _latest_sn_factor(ev: Evaluator) -> float:
    """SN / mu(v) of the latest evaluation (1 before the first, or where mu(v) is 0)."""
    if not ev.rows:
        return 1.0
    r = ev.rows[-1]
    mu = float(ExponentialDecay(r["mu_s"], r["mu_k"], r["alpha"]).mu_kmh(r["speed_kmh"]))
    return float(r["sn_sim"]) / mu if mu > 0 else 1.0


class _Speculative:
    """The FE runs announced by the look-ahead that the bisection did not evaluate (withdrawn from the simulator,
    :func:`withdraw`): their count, the steps and wall time (s) of the runs behind them, and the steps run now."""

    def __init__(self):
        self.outcomes: list[FEOutcome] = []

    def withdraw(self, ev: Evaluator, requests) -> None:
        if requests:
            self.outcomes += withdraw(ev.simulate, sorted(requests, key=lambda r: (r[1].mu_s, r[1].mu_k, r[1].alpha)))

    def settings(self) -> dict:
        """``speculative_fe_runs``, ``speculative_fe_steps`` (cost of the runs, cached or not),
        ``speculative_fe_steps_run`` (run in this call), ``speculative_fe_wall_s`` (s, share of the batches)."""
        return {
            "speculative_fe_runs": len(self.outcomes),
            "speculative_fe_steps": int(sum(o.cost_steps for o in self.outcomes)),
            "speculative_fe_steps_run": int(sum(o.n_steps for o in self.outcomes)),
            "speculative_fe_wall_s": float(sum(o.cost_wall_s for o in self.outcomes)),
        }


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
        "look_ahead": opt.look_ahead,
        "look_ahead_depth": int(opt.look_ahead_depth),
    }
