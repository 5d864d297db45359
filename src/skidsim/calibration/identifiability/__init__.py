"""What a DFT trace determines of the exponential-decay law, per site.

A back-calculation (:mod:`skidsim.calibration`) returns one law ``mu(s) = mu_k + (mu_s - mu_k) exp(-alpha s)``
per site. This module says how far to trust it, from what the calibration already produced (the trace, the
calibrated law with the surrogate state it was fitted under, the FE verification runs and the FE runs at the
calibration and validation speeds); it runs no FE.

Units: speeds ``v`` in km/h, slip speed ``s = v / 3.6`` in m/s inside the law, ``alpha`` in s/m; ``mu`` and SN
dimensionless (DFT scale, not x100).

The FE mapping. Our calibration models the FE as ``SN(v) = a(v) + b(v) mu(v + d(v))`` (:func:`calibrate_fast`;
``a, b, d`` per calibration speed, linear in between, constant beyond; ``d`` in km/h). The data are fitted *through
that mapping*; this module uses the calibration's final mapping (:class:`SurrogateMap`; the identity for the study's
bisection, which has none), so the law is judged on the scale the calibration fitted it.

Per site (:func:`assess`, module :mod:`.assess`):

* **noise** (:func:`trace_noise`): the scatter of the trace around a local quadratic smooth (every point, the
  points within ``+-noise_window_kmh``), ``sigma^2 = RSS / (n - 2 tr H + tr H'H)`` (H the smoother's hat
  matrix), and the lag-one autocorrelation ``rho1`` of those residuals. Noise slower than the window counts
  as curve: on correlated noise ``sigma`` is a lower bound.
* **fit**: RMSE of the FE at the calibration and at the validation speeds against the measured curve
  (linear interpolation of the trace, as the calibration uses it), in units of ``sigma``.
* **flags** with reasons: ``not_converged``; ``at_bound`` (which parameter, which bound, and whether the
  bound costs fit); ``outside_law`` (the best law of the family, with wide bounds, through the mapping, cannot
  fit the trace points within ``outside_law_factor * sigma``); ``fe_not_smooth`` (the FE missed the surrogate by
  more than ``fe_miss_max`` in a verification run after the surrogate had been corrected and the law had changed
  by at most ``fe_smooth_step_max`` (mu), measured against the surrogate as that correction would be as a whole
  step, or at the validation speeds); ``fit_beyond_noise``
  (FE RMSE at calibration or validation speeds above ``fit_noise_factor * sigma``).
* **uncertainty**: the Jacobian ``J`` of the fitted curve (the points the calibration fitted) with respect to
  ``(mu_s, mu_k, alpha)`` at the calibrated law, the Gauss-Newton covariance ``sigma_eff^2 (J'J)^-1`` with
  ``sigma_eff^2 = max(sigma^2, s_resid^2) (1 + rho) / (1 - rho)`` (``s_resid``: the residual scatter of the law
  family's best fit within the wide bounds, larger than ``sigma`` when the curve is outside the law or the noise is
  correlated; ``rho``: the lag-one autocorrelation of those residuals in speed order, clipped to [0, 0.9], the
  AR(1) variance inflation; a calibration bound that costs fit is reported as ``bound_cost_rmse``, not taken as
  noise), standard errors, the eigen-decomposition of ``J'J`` in parameters
  scaled by their bound widths (identified directions: 95 % half-width <= ``identified_rel_halfwidth`` of the
  range), profile-likelihood intervals (``(SSE_profile - SSE_min) / sigma_eff^2 <= chi2_1(0.95)`` over the
  calibration bounds; an interval that reaches a bound is open there, "not bounded within the bounds"), and
  three curve combinations of the law over the calibration window, all in mu: the level at the window's middle,
  the slope times the half-span and half the curvature times the half-span squared (identified when their 95 %
  half-width <= ``identified_halfwidth_mu``).

One module per idea: :mod:`.mapping` (the FE mapping), :mod:`.noise`, :mod:`.fit` (the law family's and the FE's
fit), :mod:`.smoothness` (where the FE missed the corrected surrogate), :mod:`.flags`, :mod:`.profile` (profile
likelihood), :mod:`.uncertainty` (Gauss-Newton, curve combinations), :mod:`.records` (statement, table row) and
:mod:`.assess` (the per-site record).
"""

from skidsim.calibration.identifiability.assess import assess, site_record
from skidsim.calibration.identifiability.flags import FLAGS
from skidsim.calibration.identifiability.mapping import SurrogateMap, sse_of
from skidsim.calibration.identifiability.noise import trace_noise
from skidsim.calibration.identifiability.profile import profile_intervals
from skidsim.calibration.identifiability.records import table_row
from skidsim.calibration.identifiability.uncertainty import curve_combinations, local_uncertainty
from skidsim.calibration.options import IdentifiabilityOptions

__all__ = [
    "FLAGS",
    "IdentifiabilityOptions",
    "SurrogateMap",
    "assess",
    "curve_combinations",
    "local_uncertainty",
    "profile_intervals",
    "site_record",
    "sse_of",
    "table_row",
    "trace_noise",
]
