"""FE extension of the model criticism: a viscoelastic slider bulk (hysteresis on macrotexture).

The law-level diagnosis (:func:`skidsim.criticism.diagnose`) names
:class:`skidsim.criticism.extensions.ViscoelasticFE` as the FE change for a within-site shape cause (the
functional form of mu(v), or MPD x speed within sites). This module makes it concrete:

* :data:`DEFAULT_PRONY`: the default Prony series on the slider's shear modulus (g_i relative to the long-term
  shear modulus, tau_i in s); see docs/model-criticism.md "FE extension: viscoelastic slider" for its source.
* :func:`viscoelastic_solver_cfg`: the workflow's ``solver`` section plus the Prony terms (the FE cache key holds
  every solver field, so viscoelastic runs never share cache entries with elastic ones).
* :func:`fe_extension_decision`: whether the workflow runs the per-site viscoelastic recalibrations, from the
  ``diagnosis.fe_extension`` mode (auto | always | never) and ``causes.json``.
* :func:`site_speed_gain` / :func:`campaign_speed_gain`: the held-out-speed gain, per site and over the campaign
  (RMSE of simulated SN against the measured DFT points at the validation speeds, before = elastic calibration,
  after = viscoelastic recalibration; percentile bootstrap over whole sites, seeded). SN and mu dimensionless,
  speeds in km/h.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import ConfigError
from .options import FE_MODES, DiagnosisOptions

#: Default Prony series (dimensionless g_i relative to the long-term shear modulus G_inf; tau_i in s): three
#: Maxwell branches one decade apart, centred on the DFT's texture excitation band (f = v / lambda, 1-10 kHz:
#: 1/(2 pi tau) = 16 kHz, 1.6 kHz, 160 Hz). Loss factor tan(delta) = G''/G' of this series: 0.20 at 1 kHz,
#: 0.15 at 10 kHz; storage modulus G'/G_inf 1.63 at 1 kHz, 2.13 at 10 kHz, G_0/G_inf = 2.5 (the instantaneous
#: modulus sets the explicit time step: dt shrinks by sqrt(2.5) in the rubber). See docs/model-criticism.md.
DEFAULT_PRONY = {k: tuple(v) for k, v in DiagnosisOptions().viscoelastic.items()}
_DEFAULTS = DiagnosisOptions()


def prony_moduli(freq_hz, prony_g: Sequence[float], prony_tau_s: Sequence[float]):
    """Storage and loss shear moduli relative to G_inf of a Prony series at frequency ``freq_hz`` (Hz).

    ``G'/G_inf = 1 + sum g_i w^2 tau_i^2 / (1 + w^2 tau_i^2)``, ``G''/G_inf = sum g_i w tau_i / (1 + w^2 tau_i^2)``,
    ``w = 2 pi f``. Returns ``(storage, loss)`` arrays shaped like ``freq_hz``.
    """
    w = 2 * np.pi * np.asarray(freq_hz, dtype=float)[..., None]
    g = np.asarray(prony_g, dtype=float)
    wt = w * np.asarray(prony_tau_s, dtype=float)
    storage = 1.0 + (g * wt**2 / (1 + wt**2)).sum(-1)
    loss = (g * wt / (1 + wt**2)).sum(-1)
    return storage, loss


def viscoelastic_solver_cfg(solver_cfg: Mapping, prony: Mapping | None = None) -> dict:
    """The workflow ``solver`` section with the Prony terms added to its ``overrides``.

    ``prony``: ``{"prony_g": [...], "prony_tau_s": [...]}`` (config ``diagnosis.viscoelastic``; None: the
    default :data:`DEFAULT_PRONY`). Raises :class:`ConfigError` for unequal lengths, an empty series, g_i < 0
    or tau_i <= 0 s (an empty series would silently be the elastic solver).
    """
    prony = dict(DEFAULT_PRONY if prony is None else prony)
    g = [float(x) for x in prony.get("prony_g") or []]
    tau = [float(x) for x in prony.get("prony_tau_s") or []]
    if not g or len(g) != len(tau):
        raise ConfigError(
            f"config diagnosis.viscoelastic: expected prony_g and prony_tau_s of equal, non-zero "
            f"length, got {len(g)} and {len(tau)}"
        )
    if any(x < 0 for x in g) or any(t <= 0 for t in tau):
        raise ConfigError(f"config diagnosis.viscoelastic: expected g_i >= 0 and tau_i > 0 s, got {g}, {tau}")
    out = dict(solver_cfg)
    overrides = dict(out.get("overrides") or {})
    overrides.update({"prony_g": g, "prony_tau_s": tau})
    out["overrides"] = overrides
    return out


def named_cause(causes: Sequence[Mapping]) -> Mapping | None:
    """The named cause of ``causes.json`` (its first entry, if significant), else None."""
    if not causes:
        return None
    first = causes[0]
    return first if bool(first.get("significant", False)) else None


def is_fe_shape_cause(cause: Mapping | None) -> bool:
    """True for a within-site shape cause the viscoelastic FE addresses: a within-site ``functional_form``, or a
    within-site ``x_speed`` term of MPD or of a macrotexture group holding MPD (hysteresis on macrotexture)."""
    if cause is None or cause.get("level") != "within-site":
        return False
    if cause.get("kind") == "functional_form" or cause.get("variable") == "functional_form":
        return True
    if cause.get("kind") == "x_speed":
        names = [str(cause.get("variable", ""))] + [str(x) for x in cause.get("group") or []]
        return any("mpd" in n.lower() for n in names)
    return False


def fe_extension_decision(mode: str, causes: Sequence[Mapping]) -> tuple[bool, str]:
    """``(apply, reason)``: whether the per-site viscoelastic recalibrations run.

    ``mode``: ``never`` -> not applied; ``always`` -> applied; ``auto`` -> applied when the named cause (first
    entry of causes.json, significant) is a within-site shape cause (:func:`is_fe_shape_cause`).
    """
    if mode not in FE_MODES:
        raise ConfigError(f"config diagnosis.fe_extension: expected one of {FE_MODES}, got {mode!r}")
    if mode == "never":
        return False, "diagnosis.fe_extension is 'never'"
    if mode == "always":
        return True, "diagnosis.fe_extension is 'always'"
    cause = named_cause(causes)
    if cause is None:
        return False, "auto: no significant named cause in causes.json"
    desc = f"{cause.get('level')} {cause.get('kind')} {cause.get('variable')}"
    if is_fe_shape_cause(cause):
        return True, f"auto: named cause is a within-site shape ({desc})"
    return False, f"auto: named cause ({desc}) is not a within-site shape (functional form or MPD x speed)"


def _rmse(res) -> float:
    r = np.asarray(res, dtype=float)
    return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


def site_speed_gain(
    measured: Mapping[float, float],
    sim_before: Mapping[float, float],
    sim_after: Mapping[float, float],
    validation_speeds_kmh: Sequence[float],
) -> dict:
    """Held-out-speed agreement of one site before (elastic) and after (viscoelastic recalibration).

    ``measured``: ``{speed_kmh: mu}`` DFT points; ``sim_before``/``sim_after``: ``{speed_kmh: SN}`` simulated with
    the elastic calibration and with the viscoelastic recalibration. Only validation speeds present in all three
    count. Returns ``{"n", "speeds_kmh", "rmse_before", "rmse_after", "rmse_gain" (before - after; > 0 better),
    "sse_before", "sse_after"}`` (SN units). Raises ValueError when no validation speed is common to the three.
    """

    def lookup(d, v):
        for k, x in d.items():
            if abs(float(k) - v) < 1e-9:
                return float(x)
        return None

    speeds, rb, ra = [], [], []
    for v in sorted(float(x) for x in validation_speeds_kmh):
        m, b, a = lookup(measured, v), lookup(sim_before, v), lookup(sim_after, v)
        if m is None or b is None or a is None or not np.isfinite([m, b, a]).all():
            continue
        speeds.append(v)
        rb.append(b - m)
        ra.append(a - m)
    if not speeds:
        raise ValueError(
            f"no validation speed {list(validation_speeds_kmh)} km/h has a measured point and both simulations"
        )
    rb, ra = np.array(rb), np.array(ra)
    return {
        "n": len(speeds),
        "speeds_kmh": speeds,
        "rmse_before": _rmse(rb),
        "rmse_after": _rmse(ra),
        "rmse_gain": _rmse(rb) - _rmse(ra),
        "sse_before": float((rb**2).sum()),
        "sse_after": float((ra**2).sum()),
    }


def campaign_speed_gain(
    per_site: Mapping[str, Mapping],
    *,
    n_boot: int = _DEFAULTS.n_boot,
    seed: int = _DEFAULTS.seed,
    ci: float = _DEFAULTS.ci,
) -> dict:
    """Campaign-level held-out-speed gain, the shape of gain.json's ``held_out_speeds`` scope.

    ``per_site``: ``{site: site_speed_gain(...)}``. ``rmse_before``/``rmse_after`` pool all points
    (``sqrt(sum SSE / sum n)``), ``rmse_gain = before - after``; ``rmse_gain_ci``: percentile bootstrap interval
    (level ``ci``) of rmse_gain from ``n_boot`` multinomial resamples of whole sites
    (``numpy.random.default_rng(seed)``); ``gain_excludes_zero``: lower bound > 0. SN units.
    """
    sites = sorted(per_site)
    if not sites:
        raise ValueError("campaign_speed_gain: no site")
    sb = np.array([per_site[s]["sse_before"] for s in sites], dtype=float)
    sa = np.array([per_site[s]["sse_after"] for s in sites], dtype=float)
    n = np.array([per_site[s]["n"] for s in sites], dtype=float)
    before, after = float(np.sqrt(sb.sum() / n.sum())), float(np.sqrt(sa.sum() / n.sum()))
    rng = np.random.default_rng(seed)
    w = rng.multinomial(len(sites), np.full(len(sites), 1.0 / len(sites)), size=int(n_boot)).astype(float)
    nb = w @ n
    gains = np.sqrt((w @ sb) / nb) - np.sqrt((w @ sa) / nb)
    lo, hi = np.quantile(gains, [(1 - ci) / 2, 1 - (1 - ci) / 2])
    return {
        "n_sites": len(sites),
        "n_points": int(n.sum()),
        "rmse_before": before,
        "rmse_after": after,
        "rmse_gain": before - after,
        "rmse_gain_ci": [float(lo), float(hi)],
        "ci_level": ci,
        "n_boot": int(n_boot),
        "seed": int(seed),
        "gain_excludes_zero": bool(lo > 0),
    }


def site_fe_gain(
    measured: Mapping[float, float],
    elastic: Mapping[float, float],
    viscoelastic: Mapping[float, float],
    validation_speeds_kmh: Sequence[float],
    recalibration,
) -> dict:
    """One site's entry of fe_gain.json: :func:`site_speed_gain` of the elastic (``elastic``: {speed_kmh: SN}) and
    viscoelastic (``viscoelastic``) simulations against the ``measured`` DFT points, plus the viscoelastic
    recalibration's law (``recalibration``: a :class:`skidsim.calibration.CalibrationResult`), convergence and FE
    run count."""
    g = site_speed_gain(measured, elastic, viscoelastic, validation_speeds_kmh)
    law = recalibration.params
    g["params_viscoelastic"] = {"mu_s": law.mu_s, "mu_k": law.mu_k, "alpha": law.alpha}
    g["converged_viscoelastic"] = bool(recalibration.converged)
    g["n_fe_runs_viscoelastic"] = int(recalibration.n_fe_runs)
    return g


def fe_gain_record(
    mode: str,
    causes: Sequence[Mapping],
    per_site: Mapping[str, Mapping] | None = None,
    *,
    prony: Mapping | None = None,
    validation_speeds_kmh: Sequence[float] = (),
    options: DiagnosisOptions = _DEFAULTS,
) -> dict:
    """The content of fe_gain.json: the decision (:func:`fe_extension_decision`, the named cause of ``causes``)
    and, where the extension applies, the campaign gain over ``per_site`` (:func:`site_fe_gain` per site;
    bootstrap ``options.n_boot``/``seed``/``ci``), the per-site entries, the Prony series (``prony``: prony_g,
    prony_tau_s) and the validation speeds (km/h). Raises ValueError when it applies but ``per_site`` is None."""
    apply, reason = fe_extension_decision(mode, causes)
    out = {
        "applied": bool(apply),
        "reason": reason,
        "mode": mode,
        "named_cause": (
            {k: causes[0].get(k) for k in ("variable", "level", "kind", "p_adjusted", "significant")}
            if causes
            else None
        ),
    }
    if not apply:
        return out
    if per_site is None:
        raise ValueError("fe_gain: the extension applies but the per-site viscoelastic runs are not inputs")
    agg = campaign_speed_gain(per_site, n_boot=int(options.n_boot), seed=int(options.seed), ci=float(options.ci))
    out.update(
        {
            "held_out_speeds": agg,
            "per_site": dict(per_site),
            "prony": {"prony_g": prony["prony_g"], "prony_tau_s": prony["prony_tau_s"]},
            "validation_speeds_kmh": [float(x) for x in validation_speeds_kmh],
        }
    )
    return out
