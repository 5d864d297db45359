"""Friction-speed models that users fit to DFT traces, and the published relations that drive them from texture.

Units: speed ``v`` in km/h (the DFT's slip speed), MPD and micro Sq in mm, Sp and v_peak in km/h, PNG in % per
km/h; friction coefficients are dimensionless.

* PIARC / IFI exponential speed model (PIARC 1995; ASTM E1960-07): ``mu(v) = mu20 exp((20 - v) / Sp)``, the
  IFI's ``F(S) = F60 exp((60 - S) / Sp)`` anchored at 20 km/h, with the speed constant ``Sp = 14.2 + 89.7 MPD``.
* Rado's model (Rado 1994, PhD thesis, Penn State): ``mu(v) = mu_peak exp(-(ln(v / v_peak) / C)^2)``, log-normal
  in speed; on a DFT trace (v > v_peak) it falls. ``C`` widens with macrotexture; here it is set so that the
  log-slope at 40 km/h equals the IFI's ``-1 / Sp`` (:func:`rado_shape_from_sp`).
* Penn State model (Leu & Henry 1978; Henry 2000, NCHRP Synthesis 291): ``mu(v) = mu0 exp(-(PNG / 100) v)``;
  the percent normalised gradient PNG falls with macrotexture (Leu & Henry 1978). Form used here:
  ``PNG = 0.94 MPD^-0.84`` (coefficients ours: the power law through the IFI gradient ``100 / Sp`` at MPD 0.5
  and 1.5 mm).
* Low-speed level from microtexture: wet friction needs microtexture to break the water film and grows with it
  towards a plateau (Kummer 1966; Forster 1989). Form used here: ``mu20 = 0.30 + 0.55 (1 - exp(-Sq_micro /
  sq_ref_mm))``, coefficients ours, chosen so that DFT20 spans the typical wet-asphalt range 0.35-0.85.
* Low-speed saturation (:func:`saturate`, ours): the forms above, extrapolated from their slope over 20-60 km/h
  to the end of a spin-down (5 km/h), reach mu 1.3-1.8 on rough, shallow textures (Rado with a peak at 1-4 km/h:
  ``mu_peak`` up to 1.8 ``mu20``), where wet DFT traces stay near or below about 1.2. A site's true friction is
  therefore left as it is up to ``MU_SATURATION_START`` and bent smoothly towards ``MU_CEILING`` above it.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError

MODELS = ("piarc", "rado", "penn_state")
#: Hidden texture-and-speed effects a campaign may carry on top of its friction model (:func:`hidden_factor`).
HIDDEN_EFFECTS = ("squeeze", "drainage", "hysteresis", "contact_micro")
#: Effects that read a texture measure beyond MPD (:data:`HIDDEN_MEASURES`: the measure recorded in the truth's
#: ``hidden`` entry, computed by :func:`skidsim.generators.campaign.hidden_measures` only when the effect is on).
HIDDEN_MEASURES = {"hysteresis": "macro_sdq", "contact_micro": "micro_contact_mm"}
#: ``hysteresis``: the macro rms slope at which the effect is zero (dimensionless; about the campaigns' median at
#: 0.2 mm spacing) and the speed over which the factor grows by ``kappa (Sdq - SDQ_REF)`` (km/h, from 20 km/h).
SDQ_REF = 0.5
HYSTERESIS_SPAN_KMH = 50.0
#: :func:`saturate`: friction up to this value is returned unchanged (dimensionless) ...
MU_SATURATION_START = 1.0
#: ... and above it approaches this ceiling (dimensionless; below the DFT reader's plausible range, mu < 1.5).
MU_CEILING = 1.3


def saturate(mu) -> np.ndarray:
    """Friction ``mu`` (dimensionless) with its implausible low-speed excess bent towards :data:`MU_CEILING`:
    ``mu`` where ``mu <= m0`` (the same floats), ``m0 + w tanh((mu - m0) / w)`` above it, ``m0`` =
    :data:`MU_SATURATION_START`, ``w = MU_CEILING - m0``: continuous with slope 1 at ``m0``, increasing, below
    ``MU_CEILING``. On the generators' spectral campaigns it acts below 15 km/h on all but a few sites
    (docs/synthetic-campaign.md)."""
    mu = np.asarray(mu, float)
    w = MU_CEILING - MU_SATURATION_START
    over = mu > MU_SATURATION_START
    if not over.any():
        return mu
    bent = MU_SATURATION_START + w * np.tanh((mu - MU_SATURATION_START) / w)
    return np.where(over, bent, mu)


def ifi_speed_constant_kmh(mpd_mm: float) -> float:
    """IFI speed constant Sp (km/h) from MPD (mm): ``14.2 + 89.7 MPD`` (ASTM E1960)."""
    return 14.2 + 89.7 * float(mpd_mm)


def penn_state_png(mpd_mm: float) -> float:
    """Percent normalised gradient (% per km/h) from MPD (mm): ``0.94 MPD^-0.84`` (see the module docstring)."""
    return 0.94 * float(mpd_mm) ** -0.84


def level_from_micro(micro_sq_mm: float, sq_ref_mm: float) -> float:
    """Friction level at 20 km/h from the micro Sq (mm): ``0.30 + 0.55 (1 - exp(-Sq / sq_ref_mm))``."""
    return 0.30 + 0.55 * (1.0 - np.exp(-float(micro_sq_mm) / sq_ref_mm))


def rado_shape_from_sp(sp_kmh: float, v_peak_kmh: float, v_match_kmh: float = 40.0) -> float:
    """Rado's shape factor C such that ``d ln mu / dv = -1 / Sp`` at ``v_match_kmh``:
    ``-2 ln(v / v_peak) / (C^2 v) = -1 / Sp``, so ``C = sqrt(2 Sp ln(v / v_peak) / v)``."""
    if not 0 < v_peak_kmh < v_match_kmh:
        raise ConfigError(f"rado: expected 0 < v_peak_kmh < {v_match_kmh}, got {v_peak_kmh}")
    return float(np.sqrt(2.0 * sp_kmh * np.log(v_match_kmh / v_peak_kmh) / v_match_kmh))


def mu_piarc(v_kmh, mu20: float, sp_kmh: float) -> np.ndarray:
    """PIARC/IFI model: ``mu20 exp((20 - v) / Sp)``."""
    return mu20 * np.exp((20.0 - np.asarray(v_kmh, float)) / sp_kmh)


def mu_rado(v_kmh, mu_peak: float, v_peak_kmh: float, c: float) -> np.ndarray:
    """Rado's model: ``mu_peak exp(-(ln(v / v_peak) / C)^2)``."""
    return mu_peak * np.exp(-((np.log(np.asarray(v_kmh, float) / v_peak_kmh) / c) ** 2))


def mu_penn_state(v_kmh, mu0: float, png_pct_per_kmh: float) -> np.ndarray:
    """Penn State model: ``mu0 exp(-(PNG / 100) v)``."""
    return mu0 * np.exp(-png_pct_per_kmh / 100.0 * np.asarray(v_kmh, float))


def model_parameters(
    model: str, mu20: float, mpd_mm: float, *, sp_factor: float = 1.0, v_peak_kmh: float = 2.0
) -> dict:
    """Parameters of ``model`` whose curve passes through ``mu20`` at 20 km/h, with the speed dependence from
    MPD (mm) through the published relation, scaled by ``sp_factor`` (a section/site random effect on the
    speed constant; 1 = the relation itself)."""
    sp = ifi_speed_constant_kmh(mpd_mm) * sp_factor
    if model == "piarc":
        return {"mu20": float(mu20), "sp_kmh": float(sp)}
    if model == "rado":
        c = rado_shape_from_sp(sp, v_peak_kmh)
        peak = mu20 / float(np.exp(-((np.log(20.0 / v_peak_kmh) / c) ** 2)))
        return {"mu_peak": float(peak), "v_peak_kmh": float(v_peak_kmh), "c": c, "sp_kmh": float(sp)}
    if model == "penn_state":
        png = penn_state_png(mpd_mm) / sp_factor
        return {"mu0": float(mu20 * np.exp(png / 100.0 * 20.0)), "png_pct_per_kmh": float(png)}
    raise ConfigError(f"friction model: expected one of {', '.join(MODELS)}, got {model!r}")


def evaluate(model: str, params: dict, v_kmh) -> np.ndarray:
    """mu at ``v_kmh`` of ``model`` with ``params`` (as :func:`model_parameters` returns them)."""
    if model == "piarc":
        return mu_piarc(v_kmh, params["mu20"], params["sp_kmh"])
    if model == "rado":
        return mu_rado(v_kmh, params["mu_peak"], params["v_peak_kmh"], params["c"])
    if model == "penn_state":
        return mu_penn_state(v_kmh, params["mu0"], params["png_pct_per_kmh"])
    raise ConfigError(f"friction model: expected one of {', '.join(MODELS)}, got {model!r}")


def hidden_factor(
    effect: str | None,
    kappa: float,
    sp_kmh: float,
    v_kmh,
    *,
    macro_sdq: float | None = None,
    micro_contact_mm: float | None = None,
    micro_sq_mm: float | None = None,
    sq_ref_mm: float | None = None,
) -> np.ndarray:
    """Multiplier on mu of a hidden effect that rides on texture (through the site's speed constant ``sp_kmh``,
    km/h, from MPD, or a texture measure the workflow's texture model does not use) and speed ``v_kmh`` (km/h):

    * ``"squeeze"`` (partial hydroplaning: the water film squeezed out of the contact in less time at speed,
      more so on shallow texture): ``max(0.05, 1 - kappa (v^2 - 20^2) / Sp^2)``; 1 at 20 km/h;
    * ``"drainage"`` (an extra exponential loss, faster on shallow texture): ``exp(-kappa (v - 20) / Sp)``;
      1 at 20 km/h;
    * ``"hysteresis"`` (texture x speed: the rubber's hysteresis on the macrotexture grows with the excitation
      frequency, i.e. with speed, and with the texture's rms slope): ``max(0.05, 1 + kappa (Sdq - SDQ_REF) (v -
      20) / HYSTERESIS_SPAN_KMH)``, ``Sdq`` = ``macro_sdq`` (the macro band's rms slope, dimensionless); 1 at
      20 km/h;
    * ``"contact_micro"`` (a texture measure the table does not hold: the level is set by the microtexture on the
      aggregate tops the slider touches, not by the whole-scan micro Sq): ``L(kappa micro_contact_mm) /
      L(micro_sq_mm)`` at every speed, ``L`` = :func:`level_from_micro` with ``sq_ref_mm`` (kappa rescales the
      contact measure to the micro Sq's scale);
    * ``None``: 1 (no effect).

    ``kappa`` dimensionless, >= 0."""
    v = np.asarray(v_kmh, float)
    if effect is None or kappa == 0.0:
        return np.ones_like(v)
    if effect == "squeeze":
        return np.maximum(0.05, 1.0 - kappa * (v * v - 400.0) / sp_kmh**2)
    if effect == "drainage":
        return np.exp(-kappa * (v - 20.0) / sp_kmh)
    if effect == "hysteresis":
        if macro_sdq is None:
            raise ConfigError("friction hidden_effect hysteresis: needs the site's macro_sdq")
        return np.maximum(0.05, 1.0 + kappa * (float(macro_sdq) - SDQ_REF) * (v - 20.0) / HYSTERESIS_SPAN_KMH)
    if effect == "contact_micro":
        if micro_contact_mm is None or micro_sq_mm is None or sq_ref_mm is None:
            raise ConfigError("friction hidden_effect contact_micro: needs micro_contact_mm, micro_sq_mm, sq_ref_mm")
        ratio = level_from_micro(kappa * float(micro_contact_mm), sq_ref_mm) / level_from_micro(micro_sq_mm, sq_ref_mm)
        return np.full_like(v, ratio)
    raise ConfigError(f"friction hidden_effect: expected null or one of {', '.join(HIDDEN_EFFECTS)}, got {effect!r}")
