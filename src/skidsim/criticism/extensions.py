"""Physical and generic extensions of the study's friction model, fitted at the friction-law level.

The study's model is ``SN_sim(v) = g * mu(v)`` with the exponential-decay law
``mu(s) = mu_k + (mu_s - mu_k) exp(-alpha s)`` (slip speed ``s`` in m/s, ``alpha`` in s/m, ``g`` the site's
geometric factor from the FE, ~1). Every extension below is a documented formula that modifies that curve;
none needs the FE except :class:`ViscoelasticFE`, a flag the workflow acts on
(:mod:`skidsim.criticism.fe_extension`).
See ``docs/model-criticism.md`` for the formulas, sources and conventions.

* :class:`TemperatureShift` -- time-temperature superposition (Williams, Landel & Ferry 1955; Grosch 1963):
  ``mu(v, T) = b_T mu_ref(a_T v)`` with a linearised vertical shift ``b_T = 1 + k_T (T - T_anchor)`` (Ferry 1980),
  ``log10 a_T = -C1 (T - T_r) / (C2 + T - T_r)`` with the universal constants
  ``C1 = 8.86``, ``C2 = 101.6 K``. The fitted parameter is the reference temperature ``T_r`` (deg C), which sets
  the sensitivity ``d log10 a_T / dT``. Temperatures are centred: a site at the anchor temperature (mean of the
  training sites) is unchanged, i.e. the effective slip speed is ``s * a_T(T_i) / a_T(T_anchor)``.
* :class:`DrainageIFI` -- macrotexture-controlled drainage, PIARC / International Friction Index (ASTM E1960):
  ``F(S) = F60 exp((60 - S) / Sp)``, ``Sp = a + b MPD`` (km/h, MPD in mm, a = 14.2, b = 89.7). The extension
  multiplies the curve by ``exp(-kappa (v - v_ref) / Sp_i)`` (within a site, law refitted) or, for predictions of
  a texture model that already carries the level and the campaign-average drainage, by
  ``m_i(v) / mean_site(m_i)``, ``m_i(v) = exp(-kappa v (1/Sp_i - mean_train(1/Sp)))`` (shape only).
  ``kappa`` (dimensionless, 1 = IFI) is fitted. ``form="squeeze"`` replaces the exponential by the
  partial-hydroplaning (squeeze-film) loss ``max(floor, 1 - kappa v^2 / Sp^2)``, concave in speed, which
  the exponential-decay law cannot absorb; ``form="auto"`` (default) fits both on the training data and keeps the
  one with the smaller training error.
* :class:`CovariateTerm` -- a generic linear term in a named covariate when no physical model fits: on the level
  (``+ b0 + b1 z_i``) or on the speed slope (``+ (c1 + b1 z_i)(v - v_mean,i)``); categoricals by group.
* :class:`SharedShape` -- a residual shape shared by all sites (the functional form of mu(v) is wrong): an additive
  speed profile ``h(v)``, the mean training residual, linearly interpolated in speed.
* :class:`ViscoelasticFE` -- hook for viscoelastic rubber in the FE (Prony series; hysteresis on macrotexture,
  Persson 2001, Klueppel & Heinrich 2000). Not fitted here: :mod:`skidsim.criticism.fe_extension` and the workflow's
  ``fe_gain`` rule recalibrate with the Prony series and measure the gain.

:func:`apply_extension` chooses the extension of a named cause (:class:`ExtendedModel`). All curve functions are
vectorised NumPy; every random draw elsewhere takes an explicit seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, InputError
from ..friction import KMH_PER_MS
from .causes import Cause
from .covariates import DEFAULT_EXCLUDE, find_mpd_column, names_temperature, site_covariates

#: Universal WLF constants (Williams, Landel & Ferry 1955).
WLF_C1 = 8.86
WLF_C2_K = 101.6
#: Curve forms of :class:`DrainageIFI` ("auto" chooses between them on training data).
DRAINAGE_FORMS = ("ifi", "squeeze")
#: IFI speed constant coefficients, Sp = a + b * MPD (km/h, MPD in mm), ASTM E1960.
IFI_SP_A_KMH = 14.2
IFI_SP_B_KMH_PER_MM = 89.7


# ----------------------------------------------------------------------------------------------------------------
# closed-form pieces
# ----------------------------------------------------------------------------------------------------------------


def wlf_log10_shift(temperature_c, t_ref_c: float, c1: float = WLF_C1, c2_k: float = WLF_C2_K):
    """log10 a_T of the WLF equation; temperatures in deg C (differences in K). Raises if T - T_r <= -C2."""
    dt = np.asarray(temperature_c, dtype=float) - float(t_ref_c)
    if np.any(c2_k + dt <= 0):
        raise ConfigError(f"WLF undefined: C2 + T - T_r <= 0 for T_r = {t_ref_c} deg C, C2 = {c2_k} K")
    return -c1 * dt / (c2_k + dt)


def ifi_speed_constant_kmh(mpd_mm, a_kmh: float = IFI_SP_A_KMH, b_kmh_per_mm: float = IFI_SP_B_KMH_PER_MM):
    """IFI speed constant Sp (km/h) from the mean profile depth MPD (mm): Sp = a + b MPD."""
    return a_kmh + b_kmh_per_mm * np.asarray(mpd_mm, dtype=float)


def exp_curve(speed_kmh, b, c, alpha_s_per_m):
    """``b + c exp(-alpha s)`` with s = speed/3.6 (m/s); broadcasts. For ``b = g mu_k``, ``c = g (mu_s - mu_k)``
    this is the study's simulated skid number ``g mu(v)``."""
    s = np.asarray(speed_kmh, dtype=float) / KMH_PER_MS
    return np.asarray(b) + np.asarray(c) * np.exp(-np.asarray(alpha_s_per_m) * s)


def fit_exp_curves(speed_kmh, y, *, alpha_bounds=(1e-4, 3.0), n_grid: int = 240):
    """Least-squares fit of ``y ~ b + c exp(-alpha s)`` per row, vectorised over rows (sites).

    ``speed_kmh``, ``y``: arrays (n_rows, n_points) (NaN = missing point; at least 3 per row). Variable
    projection: for each alpha (s/m) on a geometric grid over ``alpha_bounds`` the linear pair (b, c) has a closed
    form; the best grid alpha is refined by a second, 40x finer grid around it (relative alpha resolution
    ~1e-3). With three points the fit interpolates them (Aitken's closed form when speeds are equally spaced).
    Returns ``(b, c, alpha)`` arrays (n_rows,).
    """
    v = np.atleast_2d(np.asarray(speed_kmh, dtype=float))
    y = np.atleast_2d(np.asarray(y, dtype=float))
    if v.shape != y.shape:
        v = np.broadcast_to(v, y.shape)
    w = np.isfinite(y) & np.isfinite(v)
    if np.any(w.sum(axis=1) < 3):
        raise InputError(
            None,
            "at least 3 finite (speed_kmh, mu) points per site to fit the exponential law",
            got=int(w.sum(axis=1).min()),
        )
    s = np.where(w, v, 0.0) / KMH_PER_MS
    yy = np.where(w, y, 0.0)
    lo, hi = np.log(alpha_bounds[0]), np.log(alpha_bounds[1])

    def sse_for(alphas):  # alphas (n_rows, G)
        e = np.exp(-alphas[:, :, None] * s[:, None, :]) * w[:, None, :]  # (n, G, J)
        n = w.sum(axis=1)[:, None]
        se = e.sum(-1)
        see = (e * e).sum(-1)
        sy = yy.sum(-1)[:, None]
        sey = (e * yy[:, None, :]).sum(-1)
        det = n * see - se * se
        det = np.where(np.abs(det) < 1e-300, np.nan, det)
        c = (n * sey - se * sy) / det
        b = (sy - c * se) / n
        r = (b[..., None] + c[..., None] * e - yy[:, None, :]) * w[:, None, :]
        return (r * r).sum(-1), b, c

    grid = np.exp(np.linspace(lo, hi, n_grid))[None, :].repeat(y.shape[0], 0)
    sse, _, _ = sse_for(grid)
    k = np.nanargmin(np.where(np.isfinite(sse), sse, np.inf), axis=1)
    step = (hi - lo) / (n_grid - 1)
    centre = np.log(grid[np.arange(len(k)), k])
    fine = np.exp(np.clip(centre[:, None] + np.linspace(-step, step, 81)[None, :], lo, hi))
    sse2, b2, c2 = sse_for(fine)
    k2 = np.nanargmin(np.where(np.isfinite(sse2), sse2, np.inf), axis=1)
    idx = np.arange(len(k2))
    return b2[idx, k2], c2[idx, k2], fine[idx, k2]


# ----------------------------------------------------------------------------------------------------------------
# extensions
# ----------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TemperatureShift:
    """WLF time-temperature shift of the slip speed, effective speed ``v a_T(T_i) / a_T(T_anchor)``, and a vertical
    (amplitude) shift ``b_T = 1 + level_per_c (T_i - T_anchor)``: ``mu(v, T) = b_T mu_ref(v a_T / a_T(T_anchor))``.

    ``c1`` (-), ``c2_k`` (K) are the universal WLF constants; ``t_ref_c`` (deg C) the reference temperature
    (fitted by :func:`skidsim.criticism.recalibration.recalibrate` within ``t_ref_bounds_c``); ``level_per_c`` (1/K) the
    vertical shift slope, fitted within ``level_bounds_per_c`` when ``fit_level`` (else held at its value; 0 =
    the pure WLF speed shift); ``column`` the temperature
    column (deg C) of sites.csv. ``decay_column``: a texture column (mm, the MPD) whose log10 the reference decay
    constant of the measured curves follows across sites besides temperature
    (:func:`skidsim.criticism.wlf.wlf_from_curves`: the IFI speed constant Sp = 14.2 + 89.7 MPD km/h
    makes the decay of friction with speed a property of the macrotexture too); None: one reference decay
    constant for the campaign. ``texture_pcs >= 0`` (cause found by the texture-adjusted test): between sites the
    shift is evaluated at ``T_anchor + T~_i``, ``T~`` the part of T that the first ``texture_pcs`` texture
    principal components do not predict (fitted on the training sites), since the texture model already carries
    the texture-predictable part. Source: Williams, Landel & Ferry (1955) J. Am. Chem. Soc. 77, 3701; Grosch (1963)
    Proc. R. Soc. A 274, 21 (rubber friction master curves); Ferry (1980) Viscoelastic Properties of Polymers,
    3rd ed., Wiley, ch. 11 (vertical shift factor b_T).
    """

    column: str = "temperature_c"
    c1: float = WLF_C1
    c2_k: float = WLF_C2_K
    t_ref_c: float = -30.0
    level_per_c: float = 0.0
    fit_level: bool = True
    level_bounds_per_c: tuple[float, float] = (-0.05, 0.05)
    physical: bool = True
    texture_pcs: int = -1
    decay_column: str | None = None

    def vertical_factor(self, temperature_c, anchor_c: float, level_per_c: float | None = None):
        """Vertical shift factor ``b_T = 1 + level_per_c (T - T_anchor)`` (dimensionless; level_per_c in 1/K),
        the linearised amplitude shift of time-temperature superposition (Ferry 1980, ch. 11)."""
        k = self.level_per_c if level_per_c is None else level_per_c
        return 1.0 + k * (np.asarray(temperature_c, dtype=float) - float(anchor_c))

    def speed_factor(self, temperature_c, anchor_c: float, t_ref_c: float | None = None):
        """``a_T(T) / a_T(T_anchor)`` (dimensionless) for temperatures in deg C."""
        tr = self.t_ref_c if t_ref_c is None else t_ref_c
        return 10.0 ** (
            wlf_log10_shift(temperature_c, tr, self.c1, self.c2_k) - wlf_log10_shift(anchor_c, tr, self.c1, self.c2_k)
        )

    def t_ref_bounds_c(self, temperatures_c) -> tuple[float, float]:
        """Search interval for T_r (deg C): from 'no effect' (T_max - 400) up to 5 K inside the WLF pole."""
        t = np.asarray(temperatures_c, dtype=float)
        return float(np.nanmax(t) - 400.0), float(np.nanmin(t) + self.c2_k - 5.0)


@dataclass(frozen=True)
class DrainageIFI:
    """Macrotexture drainage: multiplier ``exp(-kappa (v - v_ref) / Sp)``, ``Sp = a + b MPD`` (km/h, mm).

    ``kappa`` (dimensionless) scales the IFI exponent (1 = PIARC/IFI); ``v_ref_kmh`` = 60 km/h as in the IFI.
    ``mpd_column`` names the MPD (mm) column of the texture table or sites.csv. Source: Wambold et al. (1995)
    PIARC international experiment; ASTM E1960 (IFI): F(S) = F60 exp((60 - S)/Sp), Sp = 14.2 + 89.7 MPD.
    """

    mpd_column: str = "mpd_mm"
    a_kmh: float = IFI_SP_A_KMH
    b_kmh_per_mm: float = IFI_SP_B_KMH_PER_MM
    v_ref_kmh: float = 60.0
    kappa: float = 1.0
    kappa_bounds: tuple[float, float] = (0.0, 5.0)
    form: str = "auto"
    floor: float = 0.05
    physical: bool = True

    def __post_init__(self):
        if self.form not in DRAINAGE_FORMS + ("auto",):
            raise ConfigError(f"DrainageIFI.form: expected one of {list(DRAINAGE_FORMS) + ['auto']}, got {self.form!r}")

    def inverse_speed_constant(self, mpd_mm):
        """1 / Sp in h/km."""
        return 1.0 / ifi_speed_constant_kmh(mpd_mm, self.a_kmh, self.b_kmh_per_mm)

    def multiplier(self, speed_kmh, inv_sp_h_per_km, kappa: float | None = None, form: str | None = None):
        """The drainage multiplier (dimensionless); broadcasts speed (km/h) against 1/Sp (h/km).

        ``"ifi"``: ``exp(-kappa (v - v_ref) / Sp)``; ``"squeeze"``: ``max(floor, 1 - kappa v^2 / Sp^2)`` (no loss at
        standstill; ``v_ref`` does not enter) (``form=None`` uses the extension's form; ``"auto"`` has none and
        raises)."""
        k = self.kappa if kappa is None else kappa
        f = self.form if form is None else form
        v = np.asarray(speed_kmh, dtype=float)
        inv = np.asarray(inv_sp_h_per_km, dtype=float)
        if f == "ifi":
            return np.exp(-k * (v - self.v_ref_kmh) * inv)
        if f == "squeeze":
            return np.maximum(self.floor, 1.0 - k * v * v * inv * inv)
        raise ConfigError(f"DrainageIFI.multiplier: form {f!r} is not a curve; expected one of {list(DRAINAGE_FORMS)}")


@dataclass(frozen=True)
class CovariateTerm:
    """Generic linear term in a named covariate: ``on="level"`` adds ``b0 + b1 z_i``; ``on="slope"`` adds
    ``(c1 + b1 z_i)(v - v_mean,i)`` with ``v_mean,i`` the mean of site i's evaluated speeds (km/h), for numeric z
    a pure shape term that leaves the site's mean level alone. Numeric z is centred on the training mean; a categorical
    covariate enters through group means (level), or with ``on="slope"`` through each group's residual level and
    speed slope ``c_g0 + c_g1 (v - v_mean,i)`` (a group whose friction changes with speed, a polished aggregate
    that loses low-speed friction, changes its mean too), fitted on the training sites; a level unseen in training
    gets the training-wide value. ``texture_pcs >= 0`` (a cause found by the texture-adjusted
    test, numeric z, between sites): a texture refit, not a residual term. The texture model has already taken part
    of such an effect into its texture coefficients, so the prediction's site level (``on="level"``) or speed
    slope (``on="slope"``) is replaced by that of the linear model ``[1, PC_1..k, z]`` fitted on the training
    sites' measured site means (slopes), k = ``texture_pcs`` leading texture principal components; the texture
    model's speed profile is kept (``skidsim.criticism.recalibration.refit_correction``)."""

    name: str
    on: str = "level"
    physical: bool = False
    texture_pcs: int = -1

    def __post_init__(self):
        if self.on not in ("level", "slope"):
            raise ConfigError(f"CovariateTerm.on must be 'level' or 'slope', got {self.on!r}")


@dataclass(frozen=True)
class TextureModelTerm:
    """The richer texture model of a texture-model cause (:mod:`skidsim.criticism.texture_candidate`): between
    sites the prediction is corrected by a linear model on the member's design ``Z`` (its 3 columns, e.g.
    ``[z, z^2, z^3]`` of a texture axis, each standardised over the sites), least squares on the training sites'
    residual rows: ``on="level"`` (a ``main`` cause) ``after = before + b0 + Z_i b``; ``on="slope"`` (an ``x_speed``
    cause, the speed shape) ``after = before + (b0 + Z_i b)(v - v_mean,i)`` (km/h; v_mean,i the mean of site i's
    evaluated speeds), which leaves the site's mean level alone, as :class:`CovariateTerm` does. Within a site
    (held-out speeds) it changes nothing: the texture model does not enter the calibrated simulation. ``sites`` and
    ``design`` (one row of 3 values per site) hold the design, ``name`` the cause's variable, ``words`` what it
    means."""

    name: str
    sites: tuple = ()
    design: tuple = ()
    words: str = ""
    physical: bool = False
    on: str = "level"

    def __post_init__(self):
        if self.on not in ("level", "slope"):
            raise ConfigError(f"TextureModelTerm.on must be 'level' or 'slope', got {self.on!r}")

    def design_of(self, sites) -> np.ndarray:
        """The design rows (len(sites), q) of ``sites``."""
        pos = {s: k for k, s in enumerate(self.sites)}
        missing = [s for s in sites if s not in pos]
        if missing:
            raise InputError("texture table", "texture values of every held-out site", column="site", got=missing[:5])
        return np.asarray([self.design[pos[s]] for s in sites], dtype=float)


@dataclass(frozen=True)
class SharedShape:
    """A residual speed profile shared by all sites (wrong functional form of mu(v)): additive ``h(v)``, the mean
    training residual per speed bin (``speed_bin_kmh``), linearly interpolated in speed (km/h)."""

    speed_bin_kmh: float = 10.0
    physical: bool = False


@dataclass(frozen=True)
class ViscoelasticFE:
    """Hook for viscoelastic rubber in the FE solver (Prony series relaxation, hysteresis on macrotexture;
    Persson 2001 J. Chem. Phys. 115, 3840; Klueppel & Heinrich 2000 Rubber Chem. Technol. 73, 578).

    Not fitted here: the workflow maps :attr:`solver_flags` onto the solver's Prony option
    (``skidsim.solver`` ``SolverConfig.prony_g`` / ``prony_tau_s``, owned by the solver) and re-runs calibration.
    The law-level diagnosis reports it as the recommended FE change when the residual shape is shared by all sites
    or tied to macrotexture."""

    solver_flags: dict = field(default_factory=lambda: {"viscoelastic": True})
    physical: bool = True


# ----------------------------------------------------------------------------------------------------------------
# the extension of a named cause
# ----------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ExtendedModel:
    """The extension chosen for a named cause: ``extension`` (physical where one applies), ``fallback`` (generic
    term, also evaluated), ``fe_hook`` (solver flags for an FE-level extension, not evaluated here)."""

    cause: Cause
    extension: object
    fallback: object | None = None
    fe_hook: ViscoelasticFE | None = None


def apply_extension(
    cause: Cause,
    sites,
    texture_wide=None,
    *,
    speed_bin_kmh: float = 10.0,
    exclude=DEFAULT_EXCLUDE,
    texture_design: TextureModelTerm | None = None,
) -> ExtendedModel:
    """Choose the extension for a named cause.

    temperature (name contains 'temp') -> :class:`TemperatureShift`; MPD, or a macrotexture cause whose correlated
    group holds the MPD column, interacting with speed -> :class:`DrainageIFI`; functional form ->
    :class:`SharedShape` plus the :class:`ViscoelasticFE` hook; anything else -> :class:`CovariateTerm` (on the
    level for ``main``, on the speed slope for ``x_speed``); the texture model (a texture-model cause) ->
    ``texture_design``, its :class:`TextureModelTerm`. Physical extensions carry the generic term as
    ``fallback``.
    """
    if cause.kind == "functional_form":
        return ExtendedModel(cause, SharedShape(speed_bin_kmh=speed_bin_kmh), None, ViscoelasticFE())
    if cause.source == "texture_model":
        if texture_design is None:
            raise InputError("texture table", f"the design of the texture-model cause {cause.variable}")
        return ExtendedModel(cause, texture_design, None)
    pcs = cause.texture_pcs_cv if cause.dtype == "numeric" else -1
    generic = CovariateTerm(cause.variable, on="level" if cause.kind == "main" else "slope", texture_pcs=pcs)
    name = cause.variable.lower()
    cov, _ = site_covariates(sites, texture_wide, exclude=exclude)
    mpd = find_mpd_column(cov)
    if names_temperature(cause.variable, cause.dtype):
        return ExtendedModel(cause, TemperatureShift(column=cause.variable, texture_pcs=pcs, decay_column=mpd), generic)
    if mpd is not None and cause.kind == "x_speed" and (cause.variable == mpd or mpd in cause.group or "macro" in name):
        return ExtendedModel(cause, DrainageIFI(mpd_column=mpd), generic, ViscoelasticFE())
    return ExtendedModel(cause, generic, None)
