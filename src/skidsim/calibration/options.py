"""The settings of each calibration stage: one frozen dataclass per config section, and the study's constants.

* :class:`StudyOptions` -- ``calibration.study`` (the study's nested bisection, :func:`calibrate_study`);
* :class:`JointOptions` -- ``calibration.ours`` (our joint surrogate fit, :func:`calibrate_fast`);
* :class:`IdentifiabilityOptions` -- ``calibration.identifiability`` (the per-site quality record, :func:`assess`).

Field names are the config keys; the defaults are the values of ``config/config.yaml``, so a config section that
leaves a key out means the same as the library default. ``from_config(section)`` builds the options from the config
mapping (None or {}: the defaults) and raises :class:`~skidsim.errors.ConfigError` naming the section for an
unknown key or a bad value. Fields without a config key (e.g. ``JointOptions.g_prior``) are library settings that
tests and benchmarks set directly.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from skidsim.errors import ConfigError
from skidsim.options import section_items

#: The law's parameters in the order of every (mu_s, mu_k, alpha) tuple.
PARAMS: tuple[str, str, str] = ("mu_s", "mu_k", "alpha")
#: Parameter bounds (mu_s, mu_k, alpha[s/m]) of the study (section 6.2).
DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {"mu_s": (0.0, 0.85), "mu_k": (0.0, 0.7), "alpha": (0.0, 1.0)}
#: Start values (mu_s, mu_k, alpha[s/m]) of the study's mesh study.
STUDY_START: tuple[float, float, float] = (0.4, 0.35, 0.6)
#: Calibration speeds (km/h) and validation speeds (km/h) of the study.
CALIBRATION_SPEEDS_KMH: tuple[float, ...] = (20.0, 40.0, 60.0)
VALIDATION_SPEEDS_KMH: tuple[float, ...] = (30.0, 50.0, 70.0)
#: The study's search order: (parameter, speed km/h).
STUDY_ORDER: tuple[tuple[str, float], ...] = (("mu_k", 60.0), ("mu_s", 20.0), ("alpha", 40.0))


def _positive(name: str, value: Any) -> None:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0):
        raise ConfigError(f"{name}: expected a positive number, got {value!r}")


def _interval(name: str, value: Any) -> tuple[float, float]:
    """A (lo, hi) pair of finite numbers with lo <= hi, as given (the values are recorded with the result)."""
    try:
        lo, hi = value
        ok = math.isfinite(float(lo)) and math.isfinite(float(hi)) and float(lo) <= float(hi)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{name}: expected a pair [lo, hi] of numbers, got {value!r}") from exc
    if isinstance(lo, bool) or isinstance(hi, bool) or not ok:
        raise ConfigError(f"{name}: expected finite numbers lo <= hi, got {value!r}")
    return lo, hi


def _bounds(name: str, value: Mapping | None) -> dict[str, tuple[float, float]]:
    """Per-parameter intervals: the given ones over :data:`DEFAULT_BOUNDS` (mu_s, mu_k dimensionless, alpha s/m)."""
    if value is None:
        return dict(DEFAULT_BOUNDS)
    if not isinstance(value, Mapping):
        raise ConfigError(f"{name}: expected a mapping {{mu_s, mu_k, alpha: [lo, hi]}}, got {value!r}")
    unknown = sorted(str(k) for k in value if k not in PARAMS)
    if unknown:
        raise ConfigError(f"{name}: unknown parameter(s) {unknown}; known: {list(PARAMS)}")
    return {p: _interval(f"{name}.{p}", value[p]) if p in value else DEFAULT_BOUNDS[p] for p in PARAMS}


@dataclass(frozen=True)
class StudyOptions:
    """The study's nested bisection (config ``calibration.study``; :func:`calibrate_study`).

    start: (mu_s, mu_k, alpha[s/m]) held for the parameters not yet searched (config: a mapping mu_s, mu_k, alpha).
    intervals: search interval per parameter (mu_s, mu_k dimensionless, alpha in s/m).
    tol: relative error ``|SN_sim - SN_measured| / SN_measured`` below which a search stops (strict <).
    max_iter: FE evaluations per parameter search.
    on_max_iter: ``"flag"`` (keep the best evaluated value, converged=False, go on) or ``"raise"``
        (:class:`CalibrationError`).
    window_kmh: None (linear interpolation of a trace) or the half-width, km/h, of the local regression line
        (:func:`measured_at`).
    look_ahead: FE runs of later iterations announced with each one, for a simulator that batches them
        (:func:`~skidsim.calibration.cache.prefetch`); the evaluations, decisions and result are those of the
        sequential bisection bit for bit, only the CPU time and the unused runs (``speculative_fe_*`` in the
        result's settings) differ. ``"none"``: one run per iteration; ``"quarters"``: the midpoint with both
        quarter points (one is the next midpoint); ``"predicted"``: the midpoints of the next
        ``look_ahead_depth`` iterations along the path predicted by ``SN = g mu(v)`` (docs/calibration.md);
        ``"stages"``: ``"predicted"``, and at the start of each later search the predicted paths of it and of the
        searches after it (from the values the earlier ones are predicted to keep) announced as one batch.
    look_ahead_depth: iterations announced at once per search by ``look_ahead="predicted"`` / ``"stages"`` (1: none).
    """

    start: tuple[float, float, float] = STUDY_START
    intervals: Mapping[str, tuple[float, float]] = field(default_factory=lambda: dict(DEFAULT_BOUNDS))
    tol: float = 0.10
    max_iter: int = 8
    on_max_iter: str = "flag"
    window_kmh: float | None = None
    look_ahead: str = "stages"
    look_ahead_depth: int = 8

    def __post_init__(self):
        where = "calibration.study"
        if not (isinstance(self.start, (tuple, list)) and len(self.start) == 3):
            raise ConfigError(f"{where}.start: expected (mu_s, mu_k, alpha), got {self.start!r}")
        object.__setattr__(self, "start", tuple(self.start))
        object.__setattr__(self, "intervals", _bounds(f"{where}.intervals", self.intervals))
        for p, (lo, hi) in self.intervals.items():
            if not hi > lo:
                raise ConfigError(f"{where}.intervals.{p}: expected lo < hi, got {[lo, hi]}")
        _positive(f"{where}.tol", self.tol)
        if isinstance(self.max_iter, bool) or int(self.max_iter) != self.max_iter or self.max_iter < 1:
            raise ConfigError(f"{where}.max_iter: expected an integer >= 1, got {self.max_iter!r}")
        if self.on_max_iter not in ("flag", "raise"):
            raise ConfigError(f"{where}.on_max_iter: expected 'flag' or 'raise', got {self.on_max_iter!r}")
        if self.window_kmh is not None:
            _positive(f"{where}.window_kmh", self.window_kmh)
        if self.look_ahead not in ("none", "quarters", "predicted", "stages"):
            raise ConfigError(
                f"{where}.look_ahead: expected 'none', 'quarters', 'predicted' or 'stages', got {self.look_ahead!r}"
            )
        d = self.look_ahead_depth
        if isinstance(d, bool) or not isinstance(d, int) or d < 1:
            raise ConfigError(f"{where}.look_ahead_depth: expected an integer >= 1, got {d!r}")

    @classmethod
    def from_config(cls, section: Mapping | None) -> StudyOptions:
        """From the ``calibration.study`` mapping; ``start`` may be a mapping {mu_s, mu_k, alpha} (the config form,
        missing names keep :data:`STUDY_START`) or a 3-sequence; missing intervals keep :data:`DEFAULT_BOUNDS`."""
        cfg = section_items(cls, section, "calibration.study")
        start = cfg.get("start")
        if isinstance(start, Mapping):
            unknown = sorted(str(k) for k in start if k not in PARAMS)
            if unknown:
                raise ConfigError(f"calibration.study.start: unknown parameter(s) {unknown}; known: {list(PARAMS)}")
            cfg["start"] = tuple(start.get(p, s) for p, s in zip(PARAMS, STUDY_START))
        return cls(**cfg)


@dataclass(frozen=True)
class JointOptions:
    """Our joint surrogate calibration (config ``calibration.ours``; :func:`calibrate_fast`).

    tol: SN; converged when every FE verification run is within ``tol`` of the surrogate.
    max_fe_runs: FE evaluation budget (pilot included); when the next batch would exceed it the best verified law
        is kept (smallest RMSE vs measured at the calibration speeds), converged=False.
    fit_range_kmh: (lo, hi) km/h of the trace points fitted; None: the calibration speed range.
    model: how FE runs correct the surrogate: ``"slip"`` (``SN = g mu(v + d)``, slip-speed offsets d) or
        ``"ratio"`` (``SN = a + b mu(v)``).
    prior_sites: reference sites calibrated without a prior whose median surrogate starts every other site's fit
        (the workflow's :func:`prior_reference_sites`; 0: each site on its own, with a pilot run).
    fit_on: ``"trace"`` (every measured point within ``fit_range_kmh``) or ``"speeds"`` (the measured values at
        the calibration speeds).
    bounds: per-parameter bounds of the fit (mu_s, mu_k dimensionless, alpha s/m); None: :data:`DEFAULT_BOUNDS`.
    g_prior: start value of the geometric factor ``b`` (SN / mu, dimensionless).
    pilot_speed_kmh: ``"fastest"`` (the highest calibration speed), a speed in km/h, or None (no pilot run).
    secant_min_dmu: ``model="ratio"``: smallest change of mu between two runs at a speed for the secant update.
    window_kmh: None or the half-width, km/h, of the local regression of the measured values (:func:`measured_at`).
    alpha_step_factor: trust region of the refit between FE batches: after a batch, the next law's alpha (s/m)
        stays within ``[alpha_prev / f, alpha_prev * f + alpha_step_floor_s_per_m]`` of the law just verified
        when the free refit's alpha falls outside that window and the best law inside it fits the data (under
        the surrogate) at most ``alpha_step_max_cost`` worse; None: no limit. It keeps the calibration on one
        branch of the mu_k / alpha trade-off, where the FE's response to the law was measured, as long as the
        data cannot tell the branches apart (docs/calibration.md, "Trust region").
    alpha_step_floor_s_per_m: s/m added to the window's upper end, so that a flat law (alpha near 0) can move.
    alpha_step_max_cost: mu; the largest increase of the fit's RMSE on the fitted points that the trust region
        may cost (larger: the data want the far law, and the refit goes there).
    correction_relaxation: share (0 < r <= 1) of the way the second and later corrections of the surrogate move
        its factors ``b`` and slip offsets ``d`` towards what the latest FE batch implies (``model="slip"``); the
        first correction, which moves the campaign prior to the site, is always whole. 1: each correction follows
        the latest batch alone. Below 1 it is an under-relaxed fixed-point iteration: where the FE's response
        differs between the laws tried (coarse texture), whole steps chase the latest batch and oscillate
        (docs/calibration.md, "Relaxed corrections and the FE budget").
    relaxation_on_reversal: True (the default): the corrections stay whole while the FE's miss of the surrogate
        keeps its sign and at least halves from one batch to the next at every calibration speed, and are relaxed
        by ``correction_relaxation`` from the first batch where it does not on (for good: a reversal is the
        oscillation the relaxation damps; a miss that keeps its sign and halves is the monotone approach that half
        steps slow down; 13 % fewer FE steps on a 36-site chips campaign, the same on spectral and the default
        campaign, docs/calibration.md). False: every correction from the second on is relaxed.
    fit_gain_tol: mu, or None. A batch within ``tol`` converges only when one more batch would not improve the
        RMSE vs measured at the calibration speeds by more than this (predicted by the surrogate corrected on that
        batch: its refit law against the batch's verified RMSE); otherwise the surrogate is corrected and another
        batch runs (budget permitting). None: ``tol`` alone decides.
    reach_mu_s_max: the upper bound of mu_s (dimensionless) where the ``bounds``' own one costs the fit: before the
        first FE batch, the surrogate's law is fitted to the measured points with ``bounds`` and with mu_s up to
        this; when the second fit's RMSE is lower by more than ``reach_min_gain_mu`` (mu), the site is calibrated
        with the wider mu_s interval (``settings["reach"]`` records both fits and the choice). Curves whose zero-
        speed extrapolation lies above the study's 0.85 (PIARC/IFI and Rado curves of rough surfaces) are then
        fitted instead of tilted; elsewhere the study's interval stays. None (the default): ``bounds`` alone. Off by
        default: on chips campaigns it raises the fit but costs 9-27 % more FE steps and does not change how often
        model criticism names the simulation's speed shape on them (docs/calibration.md, "The law's reach").
    reach_min_gain_mu: mu; the least RMSE gain of the wider mu_s interval that makes a site use it.
    """

    tol: float = 0.01
    max_fe_runs: int = 24
    fit_range_kmh: tuple[float, float] | None = None
    model: str = "slip"
    prior_sites: int = 3
    fit_on: str = "trace"
    bounds: Mapping[str, tuple[float, float]] | None = None
    g_prior: float = 1.0
    pilot_speed_kmh: float | str | None = "fastest"
    secant_min_dmu: float = 0.01
    window_kmh: float | None = None
    alpha_step_factor: float | None = 2.0
    alpha_step_floor_s_per_m: float = 0.02
    alpha_step_max_cost: float = 0.005
    correction_relaxation: float = 0.5
    relaxation_on_reversal: bool = True
    fit_gain_tol: float | None = 0.004
    reach_mu_s_max: float | None = None
    reach_min_gain_mu: float = 0.002

    def __post_init__(self):
        where = "calibration.ours"
        _positive(f"{where}.tol", self.tol)
        if isinstance(self.max_fe_runs, bool) or int(self.max_fe_runs) != self.max_fe_runs or self.max_fe_runs < 1:
            raise ConfigError(f"{where}.max_fe_runs: expected an integer >= 1, got {self.max_fe_runs!r}")
        if self.fit_range_kmh is not None:
            object.__setattr__(self, "fit_range_kmh", _interval(f"{where}.fit_range_kmh", self.fit_range_kmh))
        if self.model not in ("slip", "ratio"):
            raise ConfigError(f"{where}.model: expected 'slip' or 'ratio', got {self.model!r}")
        if isinstance(self.prior_sites, bool) or int(self.prior_sites) != self.prior_sites or self.prior_sites < 0:
            raise ConfigError(f"{where}.prior_sites: expected an integer >= 0, got {self.prior_sites!r}")
        if self.fit_on not in ("trace", "speeds"):
            raise ConfigError(f"{where}.fit_on: expected 'trace' or 'speeds', got {self.fit_on!r}")
        if self.bounds is not None:
            object.__setattr__(self, "bounds", _bounds(f"{where}.bounds", self.bounds))
        _positive(f"{where}.g_prior", self.g_prior)
        if self.reach_mu_s_max is not None:
            _positive(f"{where}.reach_mu_s_max", self.reach_mu_s_max)
        _positive(f"{where}.reach_min_gain_mu", self.reach_min_gain_mu)
        if self.pilot_speed_kmh is not None and self.pilot_speed_kmh != "fastest":
            _positive(f"{where}.pilot_speed_kmh", self.pilot_speed_kmh)
        _positive(f"{where}.secant_min_dmu", self.secant_min_dmu)
        if self.window_kmh is not None:
            _positive(f"{where}.window_kmh", self.window_kmh)
        if self.alpha_step_factor is not None and not (
            isinstance(self.alpha_step_factor, (int, float)) and self.alpha_step_factor > 1
        ):
            got = self.alpha_step_factor
            raise ConfigError(f"{where}.alpha_step_factor: expected a number > 1 or null, got {got!r}")
        _positive(f"{where}.alpha_step_floor_s_per_m", self.alpha_step_floor_s_per_m)
        _positive(f"{where}.alpha_step_max_cost", self.alpha_step_max_cost)
        r = self.correction_relaxation
        if isinstance(r, bool) or not isinstance(r, (int, float)) or not 0 < r <= 1:
            raise ConfigError(f"{where}.correction_relaxation: expected a number in (0, 1], got {r!r}")
        if not isinstance(self.relaxation_on_reversal, bool):
            got = self.relaxation_on_reversal
            raise ConfigError(f"{where}.relaxation_on_reversal: expected true or false, got {got!r}")
        if self.fit_gain_tol is not None:
            _positive(f"{where}.fit_gain_tol", self.fit_gain_tol)

    @classmethod
    def from_config(cls, section: Mapping | None) -> JointOptions:
        """From the ``calibration.ours`` mapping (None or {}: the defaults)."""
        return cls(**section_items(cls, section, "calibration.ours"))


@dataclass(frozen=True)
class IdentifiabilityOptions:
    """Thresholds of the per-site quality and identifiability record (config ``calibration.identifiability``).

    noise_window_kmh: half-width, km/h, of the local quadratic smooth the trace noise is measured around.
    noise_min_points: fewest trace points in the analysis range for a noise estimate (fewer: sigma is NaN and
        the flags that need it are not decided).
    fit_noise_factor: ``fit_beyond_noise`` when the FE RMSE vs measured (calibration or validation speeds)
        exceeds this many sigma.
    outside_law_factor: ``outside_law`` when the RMSE of the law family's best fit to the trace points (wide
        bounds ``wide_mu_max``, ``wide_alpha_max_s_per_m``, through the calibration's FE mapping) exceeds this
        many sigma.
    at_bound_rel_tol: a parameter within this fraction of its bound width of a bound is ``at_bound``.
    fe_miss_max: SN; ``fe_not_smooth`` when |SN_FE - SN_surrogate| exceeds it in a verification run after the
        surrogate was corrected at least once (iteration >= 2; the surrogate as its latest correction would be
        as a whole step, history ``sn_pred_whole``) and the law had moved by at most ``fe_smooth_step_max``, or
        at a validation speed.
    fe_smooth_step_max: mu; the largest change of the law (max over the batch's speeds of |mu_new - mu_old|
        from the batch the surrogate was corrected on) after which a miss counts as roughness of the FE's
        response. Misses after larger steps grow with the step (a response slope the surrogate does not have)
        and are reported (``miss_per_step_median``), not flagged.
    identified_rel_halfwidth: a parameter or an eigen-direction is identified when its 95 % half-width is at
        most this fraction of the bound width.
    identified_halfwidth_mu: a curve combination (mu units) is identified when its 95 % half-width is at most this.
    profile_points: grid points per parameter of the profile likelihood over the calibration bounds.
    alpha_grid_points: alpha grid (over its bounds) the other parameters are profiled on.
    confidence: level of the profile intervals and half-widths (0.95).
    wide_mu_max, wide_alpha_max_s_per_m: the law family's reach for ``outside_law`` (mu in [0, wide_mu_max],
        alpha in [0, wide_alpha_max_s_per_m] s/m).
    """

    noise_window_kmh: float = 15.0
    noise_min_points: int = 12
    fit_noise_factor: float = 2.0
    outside_law_factor: float = 1.5
    at_bound_rel_tol: float = 0.01
    fe_miss_max: float = 0.03
    fe_smooth_step_max: float = 0.03
    identified_rel_halfwidth: float = 0.05
    identified_halfwidth_mu: float = 0.02
    profile_points: int = 121
    alpha_grid_points: int = 801
    confidence: float = 0.95
    wide_mu_max: float = 2.0
    wide_alpha_max_s_per_m: float = 10.0

    def __post_init__(self):
        pos = (
            "noise_window_kmh",
            "fit_noise_factor",
            "outside_law_factor",
            "fe_miss_max",
            "fe_smooth_step_max",
            "identified_rel_halfwidth",
            "identified_halfwidth_mu",
            "wide_mu_max",
            "wide_alpha_max_s_per_m",
        )
        for name in pos:
            _positive(f"calibration.identifiability.{name}", getattr(self, name))
        if not (0 <= self.at_bound_rel_tol < 0.5):
            raise ConfigError(
                f"calibration.identifiability.at_bound_rel_tol: expected 0 <= x < 0.5, got {self.at_bound_rel_tol!r}"
            )
        if not (0 < self.confidence < 1):
            raise ConfigError(f"calibration.identifiability.confidence: expected 0 < x < 1, got {self.confidence!r}")
        for name, lo in (("noise_min_points", 5), ("profile_points", 11), ("alpha_grid_points", 51)):
            if int(getattr(self, name)) < lo:
                raise ConfigError(
                    f"calibration.identifiability.{name}: expected an integer >= {lo}, got {getattr(self, name)!r}"
                )

    @classmethod
    def from_config(cls, section: Mapping | None) -> IdentifiabilityOptions:
        """From the ``calibration.identifiability`` mapping (None or {}: the defaults)."""
        return cls(**section_items(cls, section, "calibration.identifiability"))
