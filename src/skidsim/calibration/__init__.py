"""Back-calculation of the exponential-decay friction law from DFT measurements.

Two methods, side by side, both driven by a simulator callback (the workflow wraps :func:`skidsim.solver.simulate`
into one, :func:`site_simulator`)::

    simulate(speed_kmh: float, law: ExponentialDecay) -> FEOutcome

* :func:`calibrate_study` (``study.py``, options :class:`StudyOptions`) -- the study's nested bisection
  (section 6.2): ``mu_k`` at 60 km/h, then ``mu_s`` at 20 km/h, then ``alpha`` at 40 km/h, each search until
  ``|SN_sim - SN_measured| / SN_measured < tol`` (10 %).
* :func:`calibrate_fast` (``joint.py``, options :class:`JointOptions`) -- ours: the three parameters fitted
  jointly to the whole measured curve through a surrogate of the FE, ``SN ~ a + b mu(v + d)``, verified by FE runs
  at the calibration speeds until they agree with the surrogate within ``tol`` (0.01).

The package, one idea per module: ``options`` (the settings of each stage, the study's constants), ``cache`` (the
FE evaluation callback and the per-site cache), ``measured`` (measured DFT values at a speed), ``law_fit`` (fitting
the law without FE), ``brent`` (its bounded Brent step: scipy's algorithm, without importing scipy), ``result``
(:class:`CalibrationResult`), ``study``, ``joint``, ``site`` (one site as the workflow runs it), ``tables``
(validation and the campaign's tables), ``identifiability`` (what a trace determines of the calibrated law,
:func:`assess`; imported on first use, it needs scipy.special).

Conventions that change numbers (also in ``docs/calibration.md``):

* **Units.** Speeds in km/h at the interface, slip speed in m/s inside the law (``v_ms = v_kmh / 3.6``),
  ``alpha`` in s/m. ``SN`` is the ratio tangential / normal force (dimensionless, the same scale as the
  DFT's ``mu``; *not* multiplied by 100).
* **Measured values at a speed.** Linear interpolation of the trace (as ``DftTrace.at``), or local linear
  regression within ``+-window_kmh`` when a window is given. A dict ``{speed_kmh: mu}`` is used as is.
* **Cost accounting.** ``n_fe_runs``, ``n_steps`` and ``fe_wall_s`` of a :class:`CalibrationResult` are the
  method's cost: every evaluation the method asked for, at the cost of the FE run that produced it (also
  when it came from the :class:`FECache`). ``n_steps_run`` / ``n_cache_hits`` say what this run paid.
"""

from skidsim.calibration.cache import FECache, FEOutcome, Simulator, fe_simulator
from skidsim.calibration.joint import alpha_window, calibrate_fast, prior_reference_sites, surrogate_prior
from skidsim.calibration.law_fit import aitken_three_point, box_ls2_many, fit_exponential_decay, invert_law_kmh
from skidsim.calibration.measured import measured_arrays, measured_at, measured_dict
from skidsim.calibration.options import (
    CALIBRATION_SPEEDS_KMH,
    DEFAULT_BOUNDS,
    PARAMS,
    STUDY_ORDER,
    STUDY_START,
    VALIDATION_SPEEDS_KMH,
    IdentifiabilityOptions,
    JointOptions,
    StudyOptions,
)
from skidsim.calibration.result import CalibrationError, CalibrationResult
from skidsim.calibration.site import calibrate_ours_site, measured_points, site_simulator
from skidsim.calibration.study import calibrate_study
from skidsim.calibration.tables import (
    comparison_table,
    figure10_statistics,
    fit_statistics,
    geometric_factors,
    simulate_speeds,
    table2,
    validation_table,
)

#: names of .identifiability imported on first use (PEP 562): the workflow's parse (prior_reference_sites) and the
#: calibrate jobs never need it; the validate_speeds jobs load it after their FE runs, for the identifiability records
_IDENTIFIABILITY_NAMES = (
    "assess",
    "site_record",
    "FLAGS",
    "SurrogateMap",
    "table_row",
    "trace_noise",
    "profile_intervals",
    "curve_combinations",
    "local_uncertainty",
)

__all__ = [
    "FECache",
    "FEOutcome",
    "Simulator",
    "fe_simulator",
    "calibrate_fast",
    "prior_reference_sites",
    "alpha_window",
    "surrogate_prior",
    "aitken_three_point",
    "box_ls2_many",
    "fit_exponential_decay",
    "geometric_factors",
    "invert_law_kmh",
    "measured_arrays",
    "measured_at",
    "measured_dict",
    "CALIBRATION_SPEEDS_KMH",
    "DEFAULT_BOUNDS",
    "PARAMS",
    "STUDY_ORDER",
    "STUDY_START",
    "VALIDATION_SPEEDS_KMH",
    "IdentifiabilityOptions",
    "JointOptions",
    "StudyOptions",
    "CalibrationError",
    "CalibrationResult",
    "calibrate_ours_site",
    "measured_points",
    "site_simulator",
    "calibrate_study",
    "comparison_table",
    "figure10_statistics",
    "fit_statistics",
    "simulate_speeds",
    "table2",
    "validation_table",
    *_IDENTIFIABILITY_NAMES,
]


def __getattr__(name: str):
    if name in _IDENTIFIABILITY_NAMES:
        from skidsim.calibration import identifiability

        return getattr(identifiability, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
