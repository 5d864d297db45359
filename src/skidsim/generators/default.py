"""The embedded default campaign: a deterministic synthetic LTPP SPS-10-like field campaign.

When the user gives no campaign, the workflow designs the campaign (:func:`design_campaign`, cheap), generates
each site (:func:`generate_site`: an LS-40-like texture scan and a DFT spin-down trace from the documented truth
model of :mod:`skidsim.generators.truth`), writes it (:func:`write_site`) and writes
``sites.csv`` (:func:`write_sites_csv`).
The rest of the pipeline treats the result exactly like measured data. See ``docs/synthetic-campaign.md``.

Conventions that change numbers (all in ``docs/synthetic-campaign.md``):

* Heights in mm, ``z = 0`` is the roller plane (the compacted top of the coarse stones); heights below are
  negative. Columns run along x (2448 points), rows along y, spacing ``spacing_mm`` both ways.
* Surface = max(stone caps, mastic): stones are superellipsoid caps (plan exponent 2-4: rounded to
  rounded-polyhedral; vertical exponent 2-3.5: flat-topped), sizes drawn log-uniformly within each gradation
  component's size range until the component's share of the surface area is reached, placed largest first by
  random sequential placement on a 0.25 mm occupancy grid. A stone's top sits at
  ``min(0, -D_p + f * d) - |N(0, sigma_top)|`` (d its size, f its protrusion share): large stones reach the
  roller plane, small grains sit in the mortar. The mastic (mortar) lies at ``-D_p`` plus a smooth field and
  surface voids (depth up to ``D_v``). ``D_p = protrusion_ratio * d_c`` and ``D_v = void_depth_ratio * d_c``
  with ``d_c`` the area-weighted mean size of the drawn coarse (>= 4.75 mm) stones: larger stones, deeper
  texture. Each site draws a lognormal texture-depth factor (``site_depth_sd``) on D_p and D_v and a lognormal
  factor (``site_void_sd``) on the void fraction.
* Microtexture: one self-affine Gaussian field (PSD ~ (q_r^2 + q^2)^-(1+H)), scaled so that its band below
  0.5 mm wavelength has RMS 1, times a per-point amplitude: the site's aggregate micro Sq times the stone's
  component factor on stones, ``mastic_micro_factor`` of it on mastic.
* Scanner: a small random plane tilt, dropouts (NaN clusters placed preferentially in the lowest 20 % of
  heights, exact configured fraction), speckle (isolated spikes of random sign, exact configured fraction of
  the valid points), then quantisation to ``z_quantum_mm``.
* Random streams: every site draws from ``numpy.random.SeedSequence([seed, crc32(site id)])`` (children for
  layout, micro field, scanner, trace), so one site generated alone is identical to the same site in a full
  campaign. The design draws from ``SeedSequence([seed, 0x5D5])``.
"""

from __future__ import annotations

import copy
import json
import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import fft as sfft
from scipy import ndimage

from ..atomic import atomic_path, write_text
from ..errors import ConfigError
from ..surface import Surface
from . import truth as _truth

# ------------------------------------------------------------------------------------------------ defaults

#: Study Table 1 (LTPP SPS-10, Oklahoma US-66): binder, mix, aggregate combination per section.
SECTION_DESIGNS: dict = {
    "E1": {
        "section_type": "experimental",
        "binder": "PG 70-28",
        "mix": "HMA",
        "comment": "HMA with RAP + RAS",
        "aggregate_combination": 1,
    },
    "E2": {
        "section_type": "experimental",
        "binder": "PG 70-28",
        "mix": "WMA foaming",
        "comment": "WMA foaming with RAP + RAS",
        "aggregate_combination": 1,
    },
    "E3": {
        "section_type": "experimental",
        "binder": "PG 70-28",
        "mix": "WMA chemical",
        "comment": "WMA chemical with RAP + RAS",
        "aggregate_combination": 1,
    },
    "E4": {
        "section_type": "experimental",
        "binder": "PG 64-22",
        "mix": "WMA chemical",
        "comment": "WMA chemical with RAP + RAS",
        "aggregate_combination": 1,
    },
    "E5": {
        "section_type": "experimental",
        "binder": "PG 58-28",
        "mix": "WMA chemical",
        "comment": "WMA chemical with RAP + RAS",
        "aggregate_combination": 1,
    },
    "E6": {
        "section_type": "experimental",
        "binder": "PG 70-28",
        "mix": "WMA stone mix",
        "comment": "WMA stone mix with mineral filler",
        "aggregate_combination": 2,
    },
    **{
        f"C{i}": {
            "section_type": "control",
            "binder": "PG 70-28",
            "mix": "HMA",
            "comment": "HMA with RAP",
            "aggregate_combination": 3,
        }
        for i in range(1, 7)
    },
}

#: Aggregate components: size range (mm, the part rendered as individual stones), plan exponent range,
#: vertical exponent range, micro-amplitude factor (relative to the site's aggregate micro Sq), aspect range.
COMPONENTS: dict = {
    "chips_5_8": {
        "size_mm": [4.75, 15.9],
        "plan_exponent": [2.5, 4.0],
        "vertical_exponent": [2.5, 3.5],
        "aspect": [0.55, 0.95],
        "micro_factor": 1.0,
    },
    "screens": {
        "size_mm": [2.36, 6.3],
        "plan_exponent": [2.5, 4.0],
        "vertical_exponent": [2.0, 3.0],
        "aspect": [0.55, 0.95],
        "micro_factor": 1.0,
    },
    "stone_sand": {
        "size_mm": [1.0, 4.75],
        "plan_exponent": [2.2, 3.5],
        "vertical_exponent": [2.0, 3.0],
        "aspect": [0.6, 1.0],
        "micro_factor": 0.9,
    },
    "sand": {
        "size_mm": [1.0, 2.36],
        "plan_exponent": [2.0, 2.4],
        "vertical_exponent": [2.0, 2.2],
        "aspect": [0.7, 1.0],
        "micro_factor": 0.6,
    },
    "rap": {
        "size_mm": [2.36, 12.5],
        "plan_exponent": [2.0, 3.0],
        "vertical_exponent": [2.0, 2.5],
        "aspect": [0.6, 1.0],
        "micro_factor": 0.5,
    },
    "ras": {
        "size_mm": [1.5, 6.0],
        "plan_exponent": [2.5, 4.0],
        "vertical_exponent": [4.0, 6.0],
        "aspect": [0.4, 0.8],
        "micro_factor": 0.8,
    },
}

#: Study Table 1 aggregate combinations (mass %; components finer than the rendered sizes are mastic) and
#: the surface structure of each mix (area share of rendered stones per mass %, mortar and void depths).
GRADATIONS: dict = {
    "1": {
        "fractions": {"chips_5_8": 38, "stone_sand": 35, "sand": 12, "rap": 12, "ras": 3},
        "protrusion_ratio": 0.10,
        "void_fraction": 0.20,
        "void_depth_ratio": 0.18,
    },
    "2": {
        "fractions": {"chips_5_8": 90, "mineral_filler": 10},
        "protrusion_ratio": 0.22,
        "void_fraction": 0.30,
        "void_depth_ratio": 0.26,
    },
    "3": {
        "fractions": {"chips_5_8": 34, "screens": 13, "stone_sand": 30, "sand": 13, "rap": 10},
        "protrusion_ratio": 0.10,
        "void_fraction": 0.20,
        "void_depth_ratio": 0.18,
    },
}

DEFAULTS: dict = {
    "seed": 20170117,
    "sections": ["E1", "E2", "E3", "E4", "E5", "E6", "C1", "C2", "C3", "C4", "C5", "C6"],
    "sites_per_section": 3,
    "station_interval_ft": {"experimental": 100, "control": 300},
    "visit_order": "shuffled",  # "shuffled" (seeded order of sections) or "listed"
    "test_date": "2017-01-17",
    "start_time": "09:00",
    "minutes_per_site": 10.0,
    "minutes_between_sections": 8.0,
    "temperature_range_c": [11.8, 18.9],  # pavement surface temperature, rescaled to exactly this range
    "temperature_peak_time": "14:30",
    "temperature_site_sd_c": 0.8,
    "section_designs": SECTION_DESIGNS,
    "components": COMPONENTS,
    "gradations": GRADATIONS,
    "shape": [2048, 2448],  # rows (y) x cols (x)
    "spacing_mm": 0.05,
    "z_quantum_mm": 0.01,
    "stone_area_factor": 1.15,  # rendered stone area per unit mass share (overlap allowance)
    "min_stone_mm": 1.0,  # smaller particles are part of the mastic
    "top_sd_mm": 0.12,  # scatter of coarse-stone tops below the roller plane
    "protrusion_share": [0.25, 0.5],  # share of a small grain's size standing above the mortar
    "site_depth_sd": 0.32,  # lognormal sd of the site's texture-depth factor on D_p, D_v
    "site_void_sd": 0.4,  # lognormal sd of the site's factor on the void fraction (max 0.6)
    "edge_round_mm": 0.15,  # Gaussian rounding (sigma) of the macro shape before the microtexture
    "mastic_sd_mm": 0.06,  # smooth mortar undulation
    "mastic_corr_mm": 3.0,
    "void_corr_mm": 1.6,
    "micro_hurst": 0.75,
    "micro_rolloff_mm": 1.0,  # wavelength of the self-affine roll-off
    "micro_sq_mm": [0.016, 0.032],  # aggregate micro Sq (band < 0.5 mm), drawn per site
    "mastic_micro_factor": 0.35,
    "tilt_max_percent": 0.2,
    "speckle_fraction": 0.0005,
    "speckle_height_mm": [0.5, 4.0],
    "dropout_fraction": 0.005,
    "dropout_radius_mm": [0.1, 0.5],
    "dft": _truth.DFT_DEFAULTS,
    "truth": _truth.TRUTH_DEFAULTS,
}

METADATA_COLUMNS = (
    "section_type",
    "mix",
    "comment",
    "binder",
    "aggregate_combination",
    "station_ft",
    "test_order",
    "test_time",
    "test_date",
)


def default_config() -> dict:
    """Every generator setting with its default; ``truth`` holds the truth model's settings (a fresh copy)."""
    return copy.deepcopy(DEFAULTS)


def resolve_config(cfg: dict | None) -> dict:
    """Defaults merged with ``cfg`` (dicts merge key by key). Accepts the flat form (generator keys plus
    ``truth``) or the workflow form ``{"synthetic": {...}, "truth": {...}}``. Unknown top-level keys raise."""
    cfg = dict(cfg or {})
    if "synthetic" in cfg:
        flat = dict(cfg["synthetic"] or {})
        if "truth" in cfg:
            flat["truth"] = cfg["truth"]
        cfg = flat
    unknown = sorted(set(cfg) - set(DEFAULTS))
    if unknown:
        raise ConfigError(f"synthetic config: unknown key(s) {unknown}; expected some of {sorted(DEFAULTS)}")
    out = _merged(default_config(), cfg)
    for sec in out["sections"]:
        if sec not in out["section_designs"]:
            raise ConfigError(f"synthetic.sections: section {sec!r} has no entry in synthetic.section_designs")
        comb = str(out["section_designs"][sec]["aggregate_combination"])
        if comb not in out["gradations"]:
            raise ConfigError(
                f"synthetic.section_designs.{sec}.aggregate_combination: {comb!r} is not in "
                f"synthetic.gradations {sorted(out['gradations'])}"
            )
    if int(out["sites_per_section"]) < 1:
        raise ConfigError("synthetic.sites_per_section: expected an integer >= 1")
    shape = out["shape"]
    if len(shape) != 2 or min(int(shape[0]), int(shape[1])) < 16:
        raise ConfigError(f"synthetic.shape: expected [rows, cols] each >= 16, got {shape!r}")
    _truth.check_truth_config(out["truth"])  # unknown truth keys fail early (at design time)
    unknown = sorted(set(out["dft"]) - set(_truth.DFT_DEFAULTS))
    if unknown:
        raise ConfigError(f"synthetic.dft: unknown key(s) {unknown}; expected some of {sorted(_truth.DFT_DEFAULTS)}")
    for key, top in (("dropout_fraction", 0.5), ("speckle_fraction", 0.05)):
        if not 0.0 <= float(out[key]) <= top:
            raise ConfigError(f"synthetic.{key}: expected a share between 0 and {top}, got {out[key]!r}")
    if not float(out["spacing_mm"]) > 0 or not float(out["z_quantum_mm"]) >= 0:
        raise ConfigError("synthetic.spacing_mm must be > 0 mm and synthetic.z_quantum_mm >= 0 mm")
    if out["visit_order"] not in ("shuffled", "listed"):
        raise ConfigError(f"synthetic.visit_order: expected 'shuffled' or 'listed', got {out['visit_order']!r}")
    lo, hi = out["temperature_range_c"]
    if not lo <= hi:
        raise ConfigError("synthetic.temperature_range_c: expected [low, high] with low <= high")
    return out


def _merged(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merged(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


# ------------------------------------------------------------------------------------------------ design


def _minutes(hhmm: str) -> float:
    h, m = str(hhmm).split(":")
    return 60.0 * int(h) + float(m)


def design_campaign(cfg: dict | None = None) -> pd.DataFrame:
    """The site table of the campaign (no surfaces): one row per site, deterministic from ``cfg['seed']``.

    Columns: ``site`` (``<section>-<k>``), ``section``, ``temperature_c`` (pavement surface temperature, deg C)
    and metadata: ``section_type``, ``mix``, ``comment``, ``binder``, ``aggregate_combination`` (study Table 1),
    ``station_ft`` (from the section start: 100-ft intervals, 300-ft on control sections), ``test_order``
    (1..n, the day's order), ``test_time`` (HH:MM), ``test_date``.

    Temperatures follow a diurnal cycle over the test times (peak at ``temperature_peak_time``) plus a per-site
    sun/shade scatter, then are rescaled linearly onto ``temperature_range_c`` (study: 11.8-18.9 deg C).
    """
    c = resolve_config(cfg)
    rng = np.random.default_rng(np.random.SeedSequence([int(c["seed"]), 0x5D5]))
    sections = list(c["sections"])
    order = list(rng.permutation(len(sections))) if c["visit_order"] == "shuffled" else list(range(len(sections)))
    n_per = int(c["sites_per_section"])
    rows = []
    t = _minutes(c["start_time"])
    k = 0
    for oi, si in enumerate(order):
        sec = sections[si]
        d = c["section_designs"][sec]
        if oi > 0:
            t += float(c["minutes_between_sections"])
        interval = (
            float(c["station_interval_ft"][d["section_type"]])
            if isinstance(c["station_interval_ft"], dict)
            else float(c["station_interval_ft"])
        )
        for j in range(n_per):
            k += 1
            rows.append(
                {
                    "site": f"{sec}-{j + 1}",
                    "section": sec,
                    "section_type": d["section_type"],
                    "mix": d["mix"],
                    "comment": d["comment"],
                    "binder": d["binder"],
                    "aggregate_combination": int(d["aggregate_combination"]),
                    "station_ft": int(round(j * interval)),
                    "test_order": k,
                    "_t": t,
                }
            )
            t += float(c["minutes_per_site"])
    df = pd.DataFrame(rows)
    tpk = _minutes(c["temperature_peak_time"])
    diurnal = np.cos(2.0 * np.pi * (df["_t"].to_numpy() - tpk) / (24 * 60.0))
    raw = diurnal + rng.normal(0.0, float(c["temperature_site_sd_c"]) / 3.5, len(df))
    lo, hi = (float(x) for x in c["temperature_range_c"])
    span = raw.max() - raw.min()
    scaled = lo + (raw - raw.min()) / span * (hi - lo) if span > 0 else np.full(len(df), 0.5 * (lo + hi))
    df["temperature_c"] = np.round(scaled, 1)
    df["test_time"] = [f"{int(m // 60):02d}:{int(m % 60):02d}" for m in df["_t"]]
    df["test_date"] = str(c["test_date"])
    df = df.drop(columns="_t")
    # table order: the listed section order, sites by station (test_order keeps the day's order)
    df["_s"] = df["section"].map({s: i for i, s in enumerate(sections)})
    df = df.sort_values(["_s", "station_ft"], kind="stable").drop(columns="_s").reset_index(drop=True)
    cols = ["site", "section", "temperature_c", *METADATA_COLUMNS]
    return df[cols]


# ------------------------------------------------------------------------------------------------ surfaces


@dataclass
class SiteData:
    """One generated site: the LS-40-like scan, the DFT trace and the ground truth.

    ``surface`` heights in mm (NaN dropouts, quantised); ``dft`` DataFrame ``speed_kmh`` (km/h, high to low,
    the spin-down order), ``mu``; ``truth`` JSON-serialisable dict (see :mod:`skidsim.generators.truth`).
    ``clean`` is the noise-free surface before scanner artefacts (not written by :func:`write_site`).
    """

    surface: Surface
    dft: pd.DataFrame
    truth: dict
    clean: Surface | None = field(default=None, repr=False)


def _site_seed(seed: int, site: str) -> np.random.SeedSequence:
    return np.random.SeedSequence([int(seed), zlib.crc32(str(site).encode("utf-8"))])


def _smooth_field(rng: np.random.Generator, shape, dx_mm: float, corr_mm: float) -> np.ndarray:
    """Unit-variance Gaussian random field with Gaussian correlation of length ``corr_mm``.

    Drawn on a coarse grid (spacing corr_mm / 4, at least dx) and interpolated bilinearly (cheap)."""
    f = max(1, int(corr_mm / 4.0 / dx_mm))
    cs = (shape[0] // f + 3, shape[1] // f + 3)
    g = ndimage.gaussian_filter(rng.standard_normal(cs), sigma=corr_mm / (f * dx_mm) / 2.0, mode="wrap")
    g /= g.std()
    if f == 1:
        return g[: shape[0], : shape[1]]
    yi = np.arange(shape[0]) / f
    xi = np.arange(shape[1]) / f
    y0 = yi.astype(int)
    x0 = xi.astype(int)
    wy = (yi - y0)[:, None]
    wx = (xi - x0)[None, :]
    t = g[y0] * (1.0 - wy) + g[y0 + 1] * wy  # rows first (cheap), then columns
    out = t[:, x0]
    out *= 1.0 - wx
    out += t[:, x0 + 1] * wx
    return out


def micro_field(
    rng: np.random.Generator, shape, dx_mm: float, hurst: float, rolloff_mm: float, band_mm: float = 0.5
) -> np.ndarray:
    """Self-affine Gaussian field, PSD ~ (q_r^2 + q^2)^-(1 + H), whose band of wavelengths below ``band_mm``
    has expected RMS 1 (mm after scaling by the caller's amplitude)."""
    ny, nx = shape
    qy = 2 * np.pi * sfft.fftfreq(ny, d=dx_mm)[:, None]
    qx = 2 * np.pi * sfft.rfftfreq(nx, d=dx_mm)[None, :]
    q2 = qy * qy + qx * qx
    qr = 2 * np.pi / rolloff_mm
    psd = (qr * qr + q2) ** (-(1.0 + hurst))
    psd[0, 0] = 0.0
    # real-FFT half plane: columns 1..(nx-1)/2 stand for two conjugate coefficients
    weight = np.full(qx.shape, 2.0)
    weight[0, 0] = 1.0
    if nx % 2 == 0:
        weight[0, -1] = 1.0
    band = q2 > (2 * np.pi / band_mm) ** 2
    band_var = float((psd * weight * band).sum()) / (nx * ny)
    amp = np.sqrt(psd / band_var)
    noise = sfft.rfft2(rng.standard_normal(shape))
    return sfft.irfft2(noise * amp, s=shape)


def _draw_stones(rng, c: dict, comb: dict, width_mm: float, height_mm: float, margin_mm: float):
    """Stone list (largest first): size d (mm), component name, shape parameters."""
    area = (width_mm + 2 * margin_mm) * (height_mm + 2 * margin_mm)
    stones = []
    for name, mass in comb["fractions"].items():
        if name not in c["components"]:
            continue  # fines (mineral filler, ...) are part of the mastic
        comp = c["components"][name]
        lo, hi = (float(x) for x in comp["size_mm"])
        lo = max(lo, float(c["min_stone_mm"]))
        if lo >= hi:
            continue
        target = area * float(c["stone_area_factor"]) * float(mass) / 100.0
        acc = 0.0
        while acc < target:
            d = math.exp(rng.uniform(math.log(lo), math.log(hi)))
            aspect = rng.uniform(*comp["aspect"])
            acc += math.pi / 4 * d * d * aspect
            stones.append((d, name, aspect))
    stones.sort(key=lambda s: -s[0])
    return stones


def _stone_cap(u, v, a: float, b: float, n_pl: float, m_v: float, base: float, thick: float, t0: float, t1: float):
    """A stone's plan outline and cap on its patch: ``(inside, z)``.

    ``u``, ``v`` (mm): the patch's points in the stone's axes; ``a``, ``b`` (mm): its half axes; the outline is the
    superellipse ``rho = |u / a|^n_pl + |v / b|^n_pl < 1``; ``z`` (mm), at the ``inside`` points in raster order,
    is ``base + t0 u + t1 v + thick (1 - rho^(m_v / n_pl))^(1 / m_v)``. The powers are taken only in the box
    ``|u / a| < 1``, ``|v / b| < 1``, which holds the outline (outside it one term alone is >= 1); every point
    gets the same arithmetic as over the whole patch (tests/test_synthetic.py compares the two bit for bit)."""
    ua, vb = np.abs(u * (1.0 / a)), np.abs(v * (1.0 / b))
    box = (ua < 1.0) & (vb < 1.0)
    rho = ua[box] ** n_pl + vb[box] ** n_pl
    in_box = rho < 1.0
    inside = np.zeros_like(box)
    inside[box] = in_box
    w = 1.0 - np.minimum(rho[in_box], 1.0) ** (m_v / n_pl)  # 1 - rho^m
    z = base + t0 * u[inside] + t1 * v[inside] + thick * w ** (1.0 / m_v)
    return inside, z


def _render(rng, c: dict, comb: dict, shape, dx: float, depth_factor: float):
    """Clean height map (mm), per-point micro amplitude factor, and structural numbers."""
    ny, nx = shape
    W, H = nx * dx, ny * dx
    dmax = max(float(c["components"][n]["size_mm"][1]) for n in comb["fractions"] if n in c["components"])
    margin = 0.6 * dmax
    stones = _draw_stones(rng, c, comb, W, H, margin)
    coarse = [(d, a) for d, _, a in stones if d >= 4.75]
    d_c = (sum(d * d * a * d for d, a in coarse) / sum(d * d * a for d, a in coarse)) if coarse else 3.0
    D_p = float(comb["protrusion_ratio"]) * d_c * depth_factor
    D_v = float(comb["void_depth_ratio"]) * d_c * depth_factor
    # occupancy grid (0.25 mm) for random sequential placement
    cell = 0.25
    occ = np.zeros((int((H + 2 * margin) / cell) + 2, int((W + 2 * margin) / cell) + 2), dtype=bool)
    top = np.full(shape, -np.inf)
    label = np.zeros(shape, dtype=np.int32)
    micro_of = [float(c["mastic_micro_factor"])]
    ps_lo, ps_hi = (float(x) for x in c["protrusion_share"])
    n_placed = 0
    ns = len(stones)
    U = rng.random((ns, 18))  # all per-stone draws at once: 6 placement tries (x, y), shape, top, micro
    N = rng.standard_normal((ns, 3))
    top_sd = float(c["top_sd_mm"])
    disks: dict = {}
    for k, (d, name, aspect) in enumerate(stones):
        comp = c["components"][name]
        a = d / 2.0
        b = a * aspect
        rr = max(1, int(0.45 * b / cell))
        for t in range(6):
            cx = -margin + U[k, 2 * t] * (W + 2 * margin)
            cy = -margin + U[k, 2 * t + 1] * (H + 2 * margin)
            gi, gj = int((cy + margin) / cell), int((cx + margin) / cell)
            sub = occ[max(0, gi - rr) : gi + rr + 1, max(0, gj - rr) : gj + rr + 1]
            if np.count_nonzero(sub) / sub.size < 0.35:  # sub.mean(): the same count over the same size
                break
        else:
            continue
        if rr not in disks:
            yy, xx = np.ogrid[-rr : rr + 1, -rr : rr + 1]
            disks[rr] = (yy * yy + xx * xx) <= rr * rr
        s_i0, s_j0 = max(0, gi - rr), max(0, gj - rr)
        sub = occ[s_i0 : gi + rr + 1, s_j0 : gj + rr + 1]
        di, dj = s_i0 - (gi - rr), s_j0 - (gj - rr)
        sub |= disks[rr][di : di + sub.shape[0], dj : dj + sub.shape[1]]
        n_placed += 1
        theta = np.pi * U[k, 12]
        pe, ve = comp["plan_exponent"], comp["vertical_exponent"]
        n_pl = pe[0] + (pe[1] - pe[0]) * U[k, 13]
        m_v = ve[0] + (ve[1] - ve[0]) * U[k, 14]
        thick = a * (0.45 + 0.3 * U[k, 15])
        ztop = min(0.0, -D_p + (ps_lo + (ps_hi - ps_lo) * U[k, 16]) * d) - abs(top_sd * N[k, 0])
        t0, t1 = 0.06 * N[k, 1], 0.06 * N[k, 2]
        R = 1.2 * a
        j0, j1 = max(0, int((cx - R) / dx)), min(nx, int((cx + R) / dx) + 2)
        i0, i1 = max(0, int((cy - R) / dx)), min(ny, int((cy + R) / dx) + 2)
        if j0 >= j1 or i0 >= i1:
            continue
        X = np.arange(j0, j1) * dx - cx
        Y = (np.arange(i0, i1) * dx - cy)[:, None]
        ct, st = math.cos(theta), math.sin(theta)
        u = X * ct + Y * st
        v = Y * ct - X * st
        inside, z = _stone_cap(u, v, a, b, n_pl, m_v, ztop - thick, thick, t0, t1)
        patch = top[i0:i1, j0:j1]
        up = np.zeros_like(inside)
        up[inside] = z > patch[inside]
        patch[up] = z[up[inside]]
        label[i0:i1, j0:j1][up] = len(micro_of)
        micro_of.append(float(comp["micro_factor"]) * (0.8 + 0.4 * U[k, 17]))
    # mastic: mortar level, smooth undulation, surface voids
    mastic = -D_p + float(c["mastic_sd_mm"]) * _smooth_field(rng, shape, dx, float(c["mastic_corr_mm"]))
    g = _smooth_field(rng, shape, dx, float(c["void_corr_mm"]))
    q = float(comb["void_fraction"])
    thr = float(np.quantile(g[::8, ::8], 1.0 - q)) if q > 0 else np.inf
    # the power only where the void term is not 0 (0 ** 0.7 is 0: the other points keep their mortar level)
    void = np.clip((g - thr) / 0.6, 0.0, 1.0)
    deep = void > 0.0
    mastic[deep] -= D_v * void[deep] ** 0.7
    on_mastic = mastic >= top
    heights = np.where(on_mastic, mastic, top)
    er = float(c["edge_round_mm"]) / dx
    if er > 0:  # binder films and wear round the stone edges and the void rims
        heights = ndimage.gaussian_filter(heights, er, mode="nearest", truncate=3.0)
    label[on_mastic] = 0
    amp = np.asarray(micro_of)[label]
    info = {
        "coarse_size_mm": d_c,
        "mortar_depth_mm": D_p,
        "void_depth_mm": D_v,
        "stones_placed": n_placed,
        "stone_area_fraction": float(1.0 - on_mastic.mean()),
    }
    return heights, amp, info


def _scanner(rng, heights: np.ndarray, c: dict, dx: float) -> np.ndarray:
    """Tilt, dropouts, speckle, quantisation (see module docstring)."""
    ny, nx = heights.shape
    h = heights.copy()
    slope = rng.uniform(0.0, float(c["tilt_max_percent"])) / 100.0
    phi = rng.uniform(0, 2 * np.pi)
    h += slope * (math.cos(phi) * np.arange(nx)[None, :] * dx + math.sin(phi) * np.arange(ny)[:, None] * dx)
    n = h.size
    # dropouts: clusters, preferably in the lowest 20 % (occlusion in voids)
    target = int(round(float(c["dropout_fraction"]) * n))
    if target > 0:
        flat = heights.ravel()
        low_thr = np.quantile(flat[:: max(1, n // 20000)], 0.2)
        mask = np.zeros(n, dtype=bool)
        count = 0
        rlo, rhi = (float(x) for x in c["dropout_radius_mm"])
        last = None
        while count < target:
            k = int(rng.integers(n))
            if flat[k] > low_thr and rng.random() < 0.75:
                continue
            ci, cj = divmod(k, nx)
            ra = rng.uniform(rlo, rhi) / dx
            rb = ra * rng.uniform(0.5, 1.0)
            th = rng.uniform(0, np.pi)
            R = int(math.ceil(ra)) + 1
            i0, i1, j0, j1 = max(0, ci - R), min(ny, ci + R + 1), max(0, cj - R), min(nx, cj + R + 1)
            Y, X = np.mgrid[i0:i1, j0:j1]
            uu = (X - cj) * math.cos(th) + (Y - ci) * math.sin(th)
            vv = -(X - cj) * math.sin(th) + (Y - ci) * math.cos(th)
            inside = (uu / ra) ** 2 + (vv / rb) ** 2 <= 1.0
            idx = Y[inside] * nx + X[inside]
            new = idx[~mask[idx]]
            if new.size == 0:
                continue
            mask[new] = True
            count += new.size
            last = new
        if count > target and last is not None:
            new = last
            ii, jj = np.divmod(new, nx)
            ci_, cj_ = ii.mean(), jj.mean()
            far = np.argsort(-((ii - ci_) ** 2 + (jj - cj_) ** 2), kind="stable")[: count - target]
            mask[new[far]] = False
        h.ravel()[mask] = np.nan
    # speckle: isolated spikes on valid points
    n_sp = int(round(float(c["speckle_fraction"]) * n))
    if n_sp > 0:
        valid_idx = np.flatnonzero(np.isfinite(h.ravel()))
        pick = rng.choice(valid_idx.size, size=n_sp, replace=False) if valid_idx.size < 4 * n_sp else None
        if pick is None:
            chosen = np.unique(rng.integers(0, valid_idx.size, size=int(n_sp * 1.2) + 16))
            while chosen.size < n_sp:
                chosen = np.unique(np.concatenate([chosen, rng.integers(0, valid_idx.size, size=n_sp)]))
            chosen = rng.permutation(chosen)[:n_sp]
        else:
            chosen = pick
        lo, hi = (float(x) for x in c["speckle_height_mm"])
        spikes = rng.uniform(lo, hi, n_sp) * rng.choice([-1.0, 1.0], n_sp)
        h.ravel()[valid_idx[chosen]] += spikes
    qz = float(c["z_quantum_mm"])
    if qz > 0:
        h = np.rint(h / qz) * qz
    return h


def synthesize_surface(row, cfg: dict | None = None):
    """The clean surface of a site (no scanner artefacts) and structural info; see :func:`generate_site`.

    Returns ``(heights_mm, info)``; ``info`` holds the site's drawn structure (mm) and its micro Sq.
    """
    c = resolve_config(cfg)
    row = dict(row)
    site = str(row["site"])
    comb_key = str(row.get("aggregate_combination", c["section_designs"][str(row["section"])]["aggregate_combination"]))
    if comb_key not in c["gradations"]:
        raise ConfigError(f"synthetic.gradations: no aggregate combination {comb_key!r} (site {site})")
    comb = c["gradations"][comb_key]
    ss = _site_seed(c["seed"], site).spawn(4)
    rng_layout = np.random.default_rng(ss[0])
    rng_micro = np.random.default_rng(ss[1])
    shape = (int(c["shape"][0]), int(c["shape"][1]))
    dx = float(c["spacing_mm"])
    depth_factor = float(np.exp(rng_layout.normal(0.0, float(c["site_depth_sd"]))))
    sq_agg = float(rng_layout.uniform(*c["micro_sq_mm"]))
    void_factor = float(np.exp(rng_layout.normal(0.0, float(c["site_void_sd"]))))
    comb = dict(comb, void_fraction=float(np.clip(float(comb["void_fraction"]) * void_factor, 0.0, 0.6)))
    heights, amp, info = _render(rng_layout, c, comb, shape, dx, depth_factor)
    heights += sq_agg * amp * micro_field(rng_micro, shape, dx, float(c["micro_hurst"]), float(c["micro_rolloff_mm"]))
    info.update(
        site_depth_factor=depth_factor,
        aggregate_micro_sq_mm=sq_agg,
        aggregate_combination=comb_key,
        void_fraction=comb["void_fraction"],
    )
    return heights, info


def generate_site(row, cfg: dict | None = None) -> SiteData:
    """Generate one site from its design row (:func:`design_campaign`) and the config.

    Deterministic per site: every draw comes from ``SeedSequence([seed, crc32(site)])``, so generating one site
    alone gives identical arrays to generating it within the campaign.
    """
    c = resolve_config(cfg)
    row = dict(row)
    site = str(row["site"])
    if "temperature_c" not in row:
        raise ConfigError(f"generate_site: design row of site {site!r} lacks 'temperature_c'")
    heights, info = synthesize_surface(row, c)
    ss = _site_seed(c["seed"], site).spawn(4)
    dx = float(c["spacing_mm"])
    desc = _truth.texture_descriptors(heights, dx, dx)
    tr = _truth.site_truth(desc, row, c["truth"])
    speeds, mu_meas, mu_tr = _truth.spin_down_trace(tr, c["dft"], np.random.default_rng(ss[3]))
    tr["site"] = site
    tr["seed"] = [int(c["seed"]), zlib.crc32(site.encode("utf-8"))]
    tr["surface"] = _truth._plain(info)
    tr["dft_true"] = {"speeds_kmh": speeds.tolist(), "mu": np.round(mu_tr, 6).tolist()}
    resid = mu_meas / mu_tr - 1.0
    tr["dft_noise"] = {"cv_configured": float(c["dft"]["noise_cv"]), "cv_realised": float(resid.std())}
    scan = _scanner(np.random.default_rng(ss[2]), heights, c, dx)
    meta = {
        "Date": f"{row.get('test_date', c['test_date'])}T{row.get('test_time', '12:00')}:00+00:00",
        "Creator": "skidsim.generators.default",
        "InstrumentManufacturer": "skidsim (simulated)",
        "InstrumentModel": "LS-40-like synthetic scanner",
        "ProbingSystemType": "NonContacting",
        "Comment": f"synthetic site {site}, seed {c['seed']}",
        "z_quantum_mm": float(c["z_quantum_mm"]),
    }
    surface = Surface(scan, dx, dx, name=site, meta=meta)
    clean = Surface(heights, dx, dx, name=f"{site} (clean)")
    dft = pd.DataFrame({"speed_kmh": speeds, "mu": mu_meas})
    return SiteData(surface=surface, dft=dft, truth=tr, clean=clean)


# ------------------------------------------------------------------------------------------------ writing


def write_site(site_data: SiteData, scan_path, dft_path, truth_path) -> None:
    """Write the scan (X3P, int16/int32 codes with 0.01 mm increment), the DFT CSV (``speed_kmh,mu``, spin-down
    order) and the truth JSON; each file is written to a temporary name and renamed."""
    from ..x3p import write_x3p

    for p in (scan_path, dft_path, truth_path):
        Path(p).parent.mkdir(parents=True, exist_ok=True)
    s = site_data.surface
    zq = float(s.meta.get("z_quantum_mm", 0.01)) if s.meta else 0.01
    hv = s.heights[np.isfinite(s.heights)]
    span = float(np.abs(hv).max()) / zq if hv.size else 0.0
    dtype = "I" if span < 32000 else "L"
    write_x3p(scan_path, s, dtype=dtype, z_increment_mm=zq)
    lines = ["speed_kmh,mu"] + [f"{v:.10g},{m:.10g}" for v, m in zip(site_data.dft["speed_kmh"], site_data.dft["mu"])]
    write_text(dft_path, "\n".join(lines) + "\n")
    write_text(truth_path, json.dumps(site_data.truth, indent=1, sort_keys=True) + "\n")


def write_sites_csv(design_df: pd.DataFrame, campaign_dir, path) -> None:
    """Write ``sites.csv``: site, section, scan (``scans/<site>.x3p``), dft (``dft/<site>.csv``), temperature_c,
    then the metadata columns. ``campaign_dir`` is the directory the relative paths refer to (files need not
    exist yet); ``path`` the output file (normally ``<campaign_dir>/sites.csv``)."""
    df = design_df.copy()
    for col in ("site", "section", "temperature_c"):
        if col not in df.columns:
            raise ConfigError(f"write_sites_csv: design table lacks column {col!r}")
    df["scan"] = [f"scans/{s}.x3p" for s in df["site"]]
    df["dft"] = [f"dft/{s}.csv" for s in df["site"]]
    first = ["site", "section", "scan", "dft", "temperature_c"]
    df = df[first + [c for c in df.columns if c not in first]]
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)
