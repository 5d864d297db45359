"""The documented "truth" friction model behind the synthetic campaign's DFT traces.

Nothing in the analysis reads this module's output: it generates the DFT traces of the embedded default
campaign and records, per site, what the pipeline is supposed to find (``results/truth/<site>.json``).
Formulas and sources are in ``docs/synthetic-campaign.md``; the numbers here are its defaults.

The friction of a site at DFT slider speed ``v`` (km/h; slip speed ``s = v / 3.6`` m/s) is composed in this
fixed order (each step's contribution is recorded separately)::

    base(v)        = mu_k + (mu_s - mu_k) * exp(-alpha * s)                  (exponential-decay family)
    temperature    : base(a_T * v) * (1 + level_per_c * (T - T_ref))        (WLF shift of slip speed + level;
                     log10 a_T = size * WLF(T, T_ref), size 1 = the universal constants)
    drainage       : * exp(-k_d * (v - v_ref) / Sp),  Sp = 14.2 + 89.7 MPD   (PIARC/IFI, ASTM E1960; form "ifi")
                     or * max(floor, 1 - k_d * (v^2 - v_ref^2) / Sp^2)         (form "squeeze": partial
                     hydroplaning, the water wedge's load share grows with the dynamic pressure ~ v^2)
    metadata       : * (1 + size * (x - x_ref))                             (e.g. slider wear by test_order)
    section        : + offset[section or mix] * shape(v)                     (unexplained level shift; shape 1, or
                     "low_speed": clip((v_hi - v) / (v_hi - v_lo), 0, 1), a polished aggregate that loses
                     low-speed friction only: a categorical x speed effect)

with the base parameters computed from the generated surface itself (descriptors of this module):

* ``mu_k = mu_k0 + mu_k1 * (1 - exp(-Sdq_micro / sdq_ref))``  (adhesion, microtexture),
* ``mu_s - mu_k = h0 + h1 * MPD``  (hysteresis, macrotexture),
* ``alpha = alpha0 * (mpd_ref / MPD) ** alpha_exp``  s/m (macrotexture controls the speed decay).

The base is exactly the study's exponential-decay family, so with every effect disabled (the null campaign)
the study's FE calibration (SN_sim ~ g * mu) can represent each site; the effects add what it cannot.

Texture descriptors (own, simple; independent of ``skidsim.texture``), computed on the *clean* generated
surface (before scanner speckle, dropouts and quantisation):

* MPD (mm): ISO 13473-1-style on profiles along x (columns): every ``row_step``-th row, dropouts linearly
  interpolated, bin mean to 0.5 mm, one centred segment of ``segment_mm`` (or the whole profile when shorter),
  least-squares slope removed, MSD = mean of the two half-segment peaks minus the segment mean, MPD = mean MSD.
* Micro band: residual of a Gaussian low-pass with cutoff 0.5 mm (ISO 16610-61 weighting,
  sigma = 0.1874 * cutoff); ``micro_sq_mm`` = its RMS, ``micro_sdq`` = its RMS gradient (central differences).
"""

from __future__ import annotations

import copy
import math

import numpy as np
from scipy import ndimage

from ..errors import ConfigError

#: Default truth-model settings (the workflow's ``truth:`` config section).
TRUTH_DEFAULTS: dict = {
    "base": {
        "mu_k0": 0.15,  # kinetic friction floor of wet rubber on a micro-smooth surface
        "mu_k1": 0.60,  # adhesion gain from microtexture (saturating)
        "sdq_ref": 0.50,  # micro-band RMS slope (dimensionless) at which adhesion reaches 63 % of mu_k1
        "h0": 0.08,  # hysteresis share mu_s - mu_k at MPD = 0
        "h1": 0.14,  # per mm of MPD
        "alpha0_s_per_m": 0.08,  # decay coefficient at MPD = mpd_ref_mm, s/m
        "mpd_ref_mm": 0.8,
        "alpha_exp": 0.5,
    },
    "effects": {
        "temperature": {
            "enabled": True,
            "size": 1.0,
            "t_ref_c": 15.8,
            "tg_c": -50.0,
            "c1": 8.86,
            "c2_k": 101.6,
            "level_per_c": -0.005,
        },
        "drainage": {
            "enabled": True,
            "size": 0.4,
            "v_ref_kmh": 20.0,
            "sp_a_kmh": 14.2,
            "sp_b_kmh_per_mm": 89.7,
            "form": "ifi",
            "floor": 0.05,
        },
        "metadata": {"enabled": False, "column": "test_order", "size": -0.004, "reference": 1.0},
        "section": {
            "enabled": False,
            "column": "section",
            "offsets": {"E6": 0.05},
            "speed_shape": "level",  # or "low_speed" (SECTION_SHAPES)
            "low_speed_kmh": [20.0, 60.0],  # low_speed: the whole offset up to the first speed, none from the second
        },
    },
}

EFFECT_ORDER = ("temperature", "drainage", "metadata", "section")
#: Drainage forms: "ifi" (exponential in speed, inside what the study's law can absorb over 20-70 km/h) and
#: "squeeze" (quadratic loss, concave in speed; docs/synthetic-campaign.md).
DRAINAGE_FORMS = ("ifi", "squeeze")
#: Speed shapes of the section effect: "level" (the offset at every speed) and "low_speed" (the offset in full up
#: to ``low_speed_kmh[0]``, falling linearly to nothing at ``low_speed_kmh[1]``; :func:`section_shape`).
SECTION_SHAPES = ("level", "low_speed")
REPORT_SPEEDS_KMH = (5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0)


def default_truth_config() -> dict:
    """A fresh copy of :data:`TRUTH_DEFAULTS`."""
    return copy.deepcopy(TRUTH_DEFAULTS)


# ----------------------------------------------------------------------------------------------- descriptors


def mpd_mm(
    heights_mm: np.ndarray, dx_mm: float, *, segment_mm: float = 100.0, row_step: int = 8, bin_mm: float = 0.5
) -> float:
    """Mean profile depth in mm of profiles along x (columns), ISO 13473-1 style (see module docstring).

    Rows ``0, row_step, 2*row_step, ...`` are used; a profile with less than 90 % valid points is skipped.
    Raises ``ValueError`` when no profile is usable.
    """
    h = np.asarray(heights_mm, dtype=float)
    prof = h[:: max(1, int(row_step))]
    nb = max(1, int(round(bin_mm / dx_mm)))
    x = np.arange(prof.shape[1])
    rows = []
    for p in prof:
        ok = np.isfinite(p)
        if ok.mean() < 0.9:
            continue
        if not ok.all():
            p = np.interp(x, x[ok], p[ok])
        rows.append(p)
    if not rows:
        raise ValueError("mpd_mm: no profile with at least 90 % valid points")
    p = np.array(rows)
    nbin = p.shape[1] // nb
    p = p[:, : nbin * nb].reshape(p.shape[0], nbin, nb).mean(axis=2)
    step = nb * dx_mm
    nseg = min(nbin, int(round(segment_mm / step)))
    nseg -= nseg % 2
    if nseg < 4:
        raise ValueError(f"mpd_mm: profile of {nbin * step:g} mm is too short")
    start = (nbin - nseg) // 2
    seg = p[:, start : start + nseg]
    t = np.arange(nseg) - (nseg - 1) / 2.0
    slope = (seg * t).sum(axis=1) / (t * t).sum()
    seg = seg - slope[:, None] * t[None, :]
    half = nseg // 2
    msd = 0.5 * (seg[:, :half].max(axis=1) + seg[:, half:].max(axis=1)) - seg.mean(axis=1)
    return float(msd.mean())


def micro_band(heights_mm: np.ndarray, dx_mm: float, dy_mm: float, cutoff_mm: float = 0.5) -> np.ndarray:
    """Micro band (mm): heights minus an ISO 16610-61 Gaussian low-pass with cutoff ``cutoff_mm``.

    Invalid (NaN) points are filled with the surface median before filtering and returned as NaN.
    """
    h = np.asarray(heights_mm, dtype=float)
    bad = ~np.isfinite(h)
    if bad.any():
        h = np.where(bad, np.nanmedian(h), h)
    k = math.sqrt(math.log(2.0) / (2.0 * math.pi**2))  # 0.1874: sigma / cutoff of the Gaussian filter
    low = ndimage.gaussian_filter(h, sigma=(k * cutoff_mm / dy_mm, k * cutoff_mm / dx_mm), mode="reflect")
    r = h - low
    r[bad] = np.nan
    return r


def micro_descriptors(heights_mm: np.ndarray, dx_mm: float, dy_mm: float, cutoff_mm: float = 0.5) -> dict:
    """``micro_sq_mm`` (RMS of the micro band, mm) and ``micro_sdq`` (its RMS gradient, dimensionless)."""
    r = micro_band(heights_mm, dx_mm, dy_mm, cutoff_mm)
    gy, gx = np.gradient(r, dy_mm, dx_mm)
    g2 = gx * gx + gy * gy
    return {"micro_sq_mm": float(np.sqrt(np.nanmean(r * r))), "micro_sdq": float(np.sqrt(np.nanmean(g2)))}


def skewness(heights_mm: np.ndarray) -> float:
    """Ssk of the valid heights (after removing the mean), dimensionless."""
    h = np.asarray(heights_mm, dtype=float)
    h = h[np.isfinite(h)]
    d = h - h.mean()
    d2 = d * d
    return float((d2 * d).mean() / d2.mean() ** 1.5)


def texture_descriptors(heights_mm: np.ndarray, dx_mm: float, dy_mm: float) -> dict:
    """All descriptors the truth model uses: ``mpd_mm``, ``micro_sq_mm``, ``micro_sdq``, ``ssk``."""
    d = {"mpd_mm": mpd_mm(heights_mm, dx_mm)}
    d.update(micro_descriptors(heights_mm, dx_mm, dy_mm))
    d["ssk"] = skewness(heights_mm)
    return d


# ----------------------------------------------------------------------------------------------- the model


def check_truth_config(cfg: dict) -> dict:
    """The truth config merged onto the defaults; unknown keys or effects raise :class:`ConfigError`."""
    out = default_truth_config()
    for key in cfg or {}:
        if key not in out:
            raise ConfigError(f"truth config: unknown key {key!r}; expected one of {sorted(out)}")
    for key, val in (cfg or {}).get("base", {}).items():
        if key not in out["base"]:
            raise ConfigError(f"truth.base: unknown key {key!r}; expected one of {sorted(out['base'])}")
        out["base"][key] = float(val)
    for name, eff in (cfg or {}).get("effects", {}).items():
        if name not in out["effects"]:
            raise ConfigError(f"truth.effects: unknown effect {name!r}; expected one of {list(EFFECT_ORDER)}")
        for key, val in (eff or {}).items():
            if key not in out["effects"][name]:
                raise ConfigError(
                    f"truth.effects.{name}: unknown key {key!r}; expected one of {sorted(out['effects'][name])}"
                )
            out["effects"][name][key] = copy.deepcopy(val)
    form = out["effects"]["drainage"]["form"]
    if form not in DRAINAGE_FORMS:
        raise ConfigError(f"truth.effects.drainage.form: expected one of {list(DRAINAGE_FORMS)}, got {form!r}")
    sec = out["effects"]["section"]
    if sec["speed_shape"] not in SECTION_SHAPES:
        raise ConfigError(
            f"truth.effects.section.speed_shape: expected one of {list(SECTION_SHAPES)}, got {sec['speed_shape']!r}"
        )
    lo_hi = sec["low_speed_kmh"]
    try:
        lo, hi = (float(x) for x in lo_hi)
        ok = 0.0 <= lo < hi
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ConfigError(
            f"truth.effects.section.low_speed_kmh: expected two speeds in km/h, 0 <= first < second, got {lo_hi!r}"
        )
    return out


def wlf_log10_shift(
    temperature_c: float, t_ref_c: float, tg_c: float = -50.0, c1: float = 8.86, c2_k: float = 101.6
) -> float:
    """log10 a_T of the WLF equation re-referenced to ``t_ref_c`` (deg C).

    WLF with the universal constants holds about ``T_s = Tg + 50 K``:
    ``log10 a_{T/Ts} = -C1 (T - Ts) / (C2 + T - Ts)``; re-referenced: ``log10 a_T = log a_{T/Ts} - log a_{Tref/Ts}``.
    a_T > 1 below ``t_ref_c`` (the rubber responds as if sliding faster).
    """
    ts = tg_c + 50.0

    def la(t):
        if c2_k + t - ts <= 0:
            raise ConfigError(f"truth.effects.temperature: WLF undefined at {t} deg C (C2 + T - Ts <= 0)")
        return -c1 * (t - ts) / (c2_k + t - ts)

    return float(la(temperature_c) - la(t_ref_c))


def base_parameters(descriptors: dict, base_cfg: dict) -> dict:
    """mu_s, mu_k, alpha (s/m) of the base curve and its two terms from the texture descriptors."""
    b = base_cfg
    adhesion = b["mu_k0"] + b["mu_k1"] * (1.0 - math.exp(-descriptors["micro_sdq"] / b["sdq_ref"]))
    hysteresis = b["h0"] + b["h1"] * descriptors["mpd_mm"]
    alpha = b["alpha0_s_per_m"] * (b["mpd_ref_mm"] / max(descriptors["mpd_mm"], 0.05)) ** b["alpha_exp"]
    return {
        "mu_s": adhesion + hysteresis,
        "mu_k": adhesion,
        "alpha_s_per_m": alpha,
        "terms": {"adhesion_mu_k": adhesion, "hysteresis_mu_s_minus_mu_k": hysteresis},
    }


def site_truth(descriptors: dict, row: dict, truth_cfg: dict | None = None) -> dict:
    """The site's true friction model (JSON-serialisable): base parameters and each effect's parameters.

    ``row`` is the site's design row (needs ``temperature_c`` and the columns the enabled effects name).
    Evaluate it with :func:`mu_true`.
    """
    cfg = check_truth_config(truth_cfg or {})
    base = base_parameters(descriptors, cfg["base"])
    eff_cfg = cfg["effects"]
    effects: dict = {}
    t = eff_cfg["temperature"]
    temp_c = float(row["temperature_c"])
    log_at = float(t["size"]) * wlf_log10_shift(temp_c, t["t_ref_c"], t["tg_c"], t["c1"], t["c2_k"])
    effects["temperature"] = {
        "enabled": bool(t["enabled"]),
        "temperature_c": temp_c,
        "log10_a_T": log_at,
        "a_T": 10.0**log_at,
        "level_factor": 1.0 + t["level_per_c"] * (temp_c - t["t_ref_c"]),
        "config": t,
    }
    d = eff_cfg["drainage"]
    sp = d["sp_a_kmh"] + d["sp_b_kmh_per_mm"] * descriptors["mpd_mm"]
    effects["drainage"] = {
        "enabled": bool(d["enabled"]),
        "sp_kmh": sp,
        "size": float(d["size"]),
        "v_ref_kmh": float(d["v_ref_kmh"]),
        "form": str(d.get("form", "ifi")),
        "floor": float(d.get("floor", 0.05)),
        "config": d,
    }
    m = eff_cfg["metadata"]
    if m["enabled"]:
        if m["column"] not in row:
            raise ConfigError(f"truth.effects.metadata: column {m['column']!r} is not in the site design")
        x = float(row[m["column"]])
        factor = 1.0 + float(m["size"]) * (x - float(m["reference"]))
    else:
        x, factor = None, 1.0
    effects["metadata"] = {
        "enabled": bool(m["enabled"]),
        "column": m["column"],
        "value": x,
        "factor": factor,
        "config": m,
    }
    s = eff_cfg["section"]
    if s["enabled"]:
        if s["column"] not in row:
            raise ConfigError(f"truth.effects.section: column {s['column']!r} is not in the site design")
        key = str(row[s["column"]])
        offset = float((s["offsets"] or {}).get(key, 0.0))
    else:
        key, offset = None, 0.0
    effects["section"] = {
        "enabled": bool(s["enabled"]),
        "column": s["column"],
        "value": key,
        "offset_mu": offset,
        "speed_shape": str(s["speed_shape"]),
        "low_speed_kmh": [float(x) for x in s["low_speed_kmh"]],
        "config": s,
    }
    truth = {"model": "skidsim.generators.truth/1", "descriptors": dict(descriptors), "base": base, "effects": effects}
    v = np.array(REPORT_SPEEDS_KMH)
    steps = mu_steps(v, truth)
    truth["curve"] = {"speeds_kmh": v.tolist(), **{k: np.round(val, 6).tolist() for k, val in steps.items()}}
    return _plain(truth)


def mu_steps(speed_kmh, truth: dict) -> dict:
    """The curve after each step of the composition: ``base``, then ``temperature``, ``drainage``, ``metadata``,
    ``section`` (cumulative; a disabled effect repeats the previous step) and ``total`` (= last)."""
    v = np.asarray(speed_kmh, dtype=float)
    b = truth["base"]
    e = truth["effects"]
    s = v / 3.6
    out = {"base": b["mu_k"] + (b["mu_s"] - b["mu_k"]) * np.exp(-b["alpha_s_per_m"] * s)}
    cur = out["base"]
    if e["temperature"]["enabled"]:
        cur = (b["mu_k"] + (b["mu_s"] - b["mu_k"]) * np.exp(-b["alpha_s_per_m"] * e["temperature"]["a_T"] * s)) * e[
            "temperature"
        ]["level_factor"]
    out["temperature"] = cur
    if e["drainage"]["enabled"]:
        cur = cur * drainage_factor(v, e["drainage"])
    out["drainage"] = cur
    if e["metadata"]["enabled"]:
        cur = cur * e["metadata"]["factor"]
    out["metadata"] = cur
    if e["section"]["enabled"]:
        cur = cur + e["section"]["offset_mu"] * section_shape(v, e["section"])
    out["section"] = cur
    out["total"] = cur
    return out


def section_shape(speed_kmh, section: dict):
    """The share (dimensionless) of the section offset at DFT speed(s) in km/h: 1.0 for the ``level`` shape (a
    truth recorded before the shape existed has none), ``clip((v_hi - v) / (v_hi - v_lo), 0, 1)`` for
    ``low_speed`` with ``(v_lo, v_hi)`` = ``low_speed_kmh``."""
    if section.get("speed_shape", "level") == "level":
        return 1.0
    lo, hi = (float(x) for x in section["low_speed_kmh"])
    return np.clip((hi - np.asarray(speed_kmh, dtype=float)) / (hi - lo), 0.0, 1.0)


def drainage_factor(speed_kmh, drainage: dict) -> np.ndarray:
    """The drainage multiplier (dimensionless) at DFT speed(s) in km/h, 1 at ``v_ref_kmh``.

    ``"ifi"``: ``exp(-size (v - v_ref) / Sp)`` (PIARC / IFI). ``"squeeze"``: ``max(floor, 1 - size (v^2 - v_ref^2)
    / Sp^2)``, partial hydroplaning: the share of the slider load carried by the water wedge grows with the
    hydrodynamic pressure ~ rho v^2 / 2 (Horne & Joyner 1965; Moore 1975, squeeze-film), and drainage through the
    macrotexture raises the speed scale (the IFI speed constant Sp = a + b MPD stands in for it)."""
    v = np.asarray(speed_kmh, dtype=float)
    sp, k, v0 = drainage["sp_kmh"], drainage["size"], drainage["v_ref_kmh"]
    if drainage.get("form", "ifi") == "squeeze":
        return np.maximum(drainage.get("floor", 0.05), 1.0 - k * (v * v - v0 * v0) / (sp * sp))
    return np.exp(-k * (v - v0) / sp)


def mu_true(speed_kmh, truth: dict) -> np.ndarray:
    """The noise-free true friction coefficient at DFT speed(s) in km/h."""
    return mu_steps(speed_kmh, truth)["total"]


def contributions(speed_kmh, truth: dict) -> dict:
    """Each effect's additive contribution to mu (step minus previous step) at the given speeds (km/h)."""
    st = mu_steps(speed_kmh, truth)
    prev = st["base"]
    out = {}
    for name in EFFECT_ORDER:
        out[name] = st[name] - prev
        prev = st[name]
    return out


# ----------------------------------------------------------------------------------------------- DFT trace

DFT_DEFAULTS: dict = {
    "speed_start_kmh": [80.0, 86.0],  # spin-down start speed, drawn uniformly per site
    "speed_end_kmh": 5.0,  # last sample at or above this speed
    "step_kmh_at_mu_0_5": 0.8,  # speed drop between samples when mu = 0.5 (drop is proportional to mu)
    "noise_cv": 0.03,  # total multiplicative noise, coefficient of variation
    "noise_ar1": 0.7,  # lag-one correlation of the correlated part
    "noise_white_share": 0.3,  # share of the variance that is white
    "mu_decimals": 3,
    "speed_decimals": 2,
}


def default_dft_config() -> dict:
    return copy.deepcopy(DFT_DEFAULTS)


def spin_down_trace(truth: dict, dft_cfg: dict | None, rng: np.random.Generator):
    """A DFT spin-down trace of the true curve: ``(speeds_kmh, mu_measured, mu_true)``, high to low speed.

    Sampling at a fixed time step: the disk loses speed in proportion to the friction torque,
    ``v[k+1] = v[k] - step_kmh_at_mu_0_5 * mu_true(v[k]) / 0.5``. Noise is multiplicative,
    ``mu = mu_true * (1 + cv * e)``, ``e = sqrt(1 - w) * AR1(phi) + sqrt(w) * white``, unit variance.
    """
    c = {**DFT_DEFAULTS, **(dft_cfg or {})}
    lo, hi = c["speed_start_kmh"]
    v = float(rng.uniform(lo, hi))
    speeds = []
    while v >= c["speed_end_kmh"]:
        speeds.append(v)
        mu = float(mu_true(v, truth))
        v -= c["step_kmh_at_mu_0_5"] * max(mu, 0.05) / 0.5
        if len(speeds) > 100000:
            raise ConfigError("synthetic.dft: step_kmh_at_mu_0_5 too small (more than 100000 samples)")
    sp = np.round(np.array(speeds), int(c["speed_decimals"]))
    truth_mu = mu_true(sp, truth)
    n = sp.size
    phi = float(c["noise_ar1"])
    w = float(c["noise_white_share"])
    innov = rng.standard_normal(n)
    ar = np.empty(n)
    ar[0] = innov[0]
    for k in range(1, n):
        ar[k] = phi * ar[k - 1] + math.sqrt(1.0 - phi * phi) * innov[k]
    e = math.sqrt(1.0 - w) * ar + math.sqrt(w) * rng.standard_normal(n)
    measured = np.round(truth_mu * (1.0 + c["noise_cv"] * e), int(c["mu_decimals"]))
    return sp, measured, truth_mu


def _plain(obj):
    """Convert numpy scalars/arrays inside nested dicts/lists to plain Python for JSON."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj
