"""Independent campaigns: design, one site (clean texture -> measures -> friction truth -> scan and DFT trace), and
the files of the data contract (``sites.csv``, ``scans/<site>.x3p``, ``dft/<site>.csv``) plus one truth JSON per
site in a directory beside the campaign.

Nothing here comes from :mod:`skidsim.generators.default`; only the X3P writer (:func:`skidsim.x3p.write_x3p`) and the
texture measures of :mod:`skidsim.texture` are shared, the first being the data contract, the second what the
published relations are written in (MPD, micro Sq).

Determinism: the section's draws come from ``SeedSequence([seed, crc32(generator), crc32(section)])``, a site's
from ``SeedSequence([seed, crc32(generator), crc32(site)])`` (children: texture, scanner, friction, trace), so a
site generated alone has the same bytes as within its campaign.
"""

from __future__ import annotations

import copy
import json
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..atomic import atomic_path, write_text
from ..errors import ConfigError
from ..surface import Surface
from . import chips, friction_models, scanner, spectral

TEXTURES = {"chips": chips, "spectral": spectral}

COMMON = {
    "seed": 20261125,
    "n_sites": 36,
    "n_sections": None,  # None: min(n_sites, max(3, round(n_sites / 3)))
    "shape": [2048, 2448],  # rows (y), cols (x)
    "scanner": {
        "tilt_max": 0.002,
        "tilt_axis": "any",
        "dropout_fraction": 0.005,
        "dropout_radius_mm": [0.2, 0.8],
        "dropout_low_quantile": 0.2,
        "spike_fraction": 0.0005,
        "spike_mm": [3.0, 5.0],
        "z_step_mm": 0.01,
    },
    "friction": {
        "model": "piarc",
        "sq_ref_mm": 0.03,
        "micro_cut_mm": 0.5,
        "section_level_sd": 0.05,
        "site_level_sd": 0.03,  # log-normal factors on the 20 km/h level
        "section_sp_sd": 0.08,
        "site_sp_sd": 0.04,  # log-normal factors on Sp (or PNG)
        "v_peak_kmh": [1.0, 4.0],  # Rado: U(low, high)
        "hidden_effect": None,  # a hidden texture-and-speed effect on the DFT: null | squeeze | drainage
        "hidden_kappa": 0.0,  # its strength (friction_models.hidden_factor), dimensionless
    },
    "site_factor_sd": 0.12,  # log-normal site factors on the section's macro and micro amplitudes
    "dft": {"v_start_kmh": [80.0, 85.0], "v_end_kmh": 5.0, "step_kmh": 0.5, "step_jitter_kmh": 0.05, "noise_mu": 0.01},
    "temperature_c": [8.0, 28.0],  # section's temperature U(low, high); site +- N(0, 0.5); no effect on friction
    "test_date": "2026-06-15",
}

#: The generators: texture model, friction model and the scanner they come with.
GENERATORS = {
    "chips": {
        "texture": "chips",
        "spacing_mm": 0.05,
        "scanner": {"tilt_axis": "y"},
        "friction": {"model": "piarc", "sq_ref_mm": 0.015},
    },
    "spectral": {
        "texture": "spectral",
        "spacing_mm": 0.1,
        "scanner": {"tilt_axis": "any"},
        "friction": {"model": "rado", "sq_ref_mm": 0.015},
    },
}


def _merge(a: dict, b: dict, where: str) -> dict:
    out = copy.deepcopy(a)
    for k, v in (b or {}).items():
        if k not in out:
            raise ConfigError(f"{where}: unknown key {k!r}; expected some of {sorted(out)}")
        out[k] = _merge(out[k], v, f"{where}.{k}") if isinstance(out[k], dict) and isinstance(v, dict) else v
    return out


def generator_config(name: str, overrides: dict | None = None) -> dict:
    """Full settings of generator ``name`` (``chips`` or ``spectral``) with ``overrides`` merged in (nested keys;
    texture keys under ``"texture_params"``). Unknown keys raise :class:`ConfigError`."""
    if name not in GENERATORS:
        raise ConfigError(f"generator: expected one of {', '.join(GENERATORS)}, got {name!r}")
    g = GENERATORS[name]
    base = _merge(COMMON, {"scanner": g["scanner"], "friction": g["friction"]}, name)
    base.update(
        {
            "generator": name,
            "texture": g["texture"],
            "spacing_mm": g["spacing_mm"],
            "texture_params": copy.deepcopy(TEXTURES[g["texture"]].DEFAULTS),
        }
    )
    cfg = _merge(base, overrides or {}, name)
    if cfg["friction"]["model"] not in friction_models.MODELS:
        raise ConfigError(
            f"{name}.friction.model: expected one of {', '.join(friction_models.MODELS)}, "
            f"got {cfg['friction']['model']!r}"
        )
    if cfg["n_sites"] < 1:
        raise ConfigError(f"{name}.n_sites: expected at least 1 site, got {cfg['n_sites']}")
    f = cfg["friction"]
    if f["hidden_effect"] is not None and f["hidden_effect"] not in friction_models.HIDDEN_EFFECTS:
        raise ConfigError(
            f"{name}.friction.hidden_effect: expected null or one of "
            f"{', '.join(friction_models.HIDDEN_EFFECTS)}, got {f['hidden_effect']!r}"
        )
    if not (isinstance(f["hidden_kappa"], (int, float)) and f["hidden_kappa"] >= 0):
        raise ConfigError(f"{name}.friction.hidden_kappa: expected a number >= 0, got {f['hidden_kappa']!r}")
    return cfg


def _crc(text: str) -> int:
    return zlib.crc32(text.encode())


def _seq(cfg: dict, key: str) -> np.random.SeedSequence:
    return np.random.SeedSequence([int(cfg["seed"]), _crc(cfg["generator"]), _crc(key)])


def design_campaign(cfg: dict) -> pd.DataFrame:
    """Sites and sections: site, section, temperature_c (deg C) and the section's draws (columns ``sec_*``)."""
    n = int(cfg["n_sites"])
    n_sec = cfg["n_sections"] or min(n, max(3, int(round(n / 3))))
    if not 1 <= n_sec <= n:
        raise ConfigError(f"{cfg['generator']}.n_sections: expected 1..{n} (n_sites), got {n_sec}")
    tex = TEXTURES[cfg["texture"]]
    rows = []
    for k, members in enumerate(np.array_split(np.arange(n), n_sec)):
        sec = f"S{k + 1:02d}"
        s_tex, s_fric, s_temp = (np.random.default_rng(s) for s in _seq(cfg, sec).spawn(3))
        draws = tex.section_draws(s_tex, cfg["texture_params"])
        f = cfg["friction"]
        level = float(np.exp(s_fric.normal(0.0, f["section_level_sd"])))
        sp = float(np.exp(s_fric.normal(0.0, f["section_sp_sd"])))
        t_sec = float(s_temp.uniform(*cfg["temperature_c"]))
        for j, _ in enumerate(members):
            rows.append(
                {
                    "site": f"{sec}-{j + 1}",
                    "section": sec,
                    "temperature_c": round(t_sec + float(s_temp.normal(0.0, 0.5)), 1),
                    **{f"sec_{k2}": v for k2, v in draws.items()},
                    "sec_level_factor": level,
                    "sec_sp_factor": sp,
                }
            )
    return pd.DataFrame(rows)


@dataclass
class SiteData:
    """One site: ``surface`` (the scan, heights mm with NaN dropouts), ``clean`` (heights mm before the scanner),
    ``dft`` (speed_kmh, mu in spin-down order) and ``truth`` (JSON-serialisable)."""

    surface: Surface
    clean: np.ndarray
    dft: pd.DataFrame
    truth: dict


def texture_measures(clean: np.ndarray, dx_mm: float, micro_cut_mm: float) -> dict:
    """MPD (mm, ISO 13473-1 by :func:`skidsim.texture.mean_profile_depth`, profiles along x; one segment of the
    profile length when shorter than 100 mm) and the micro band's Sq (mm, wavelengths below
    ``max(micro_cut_mm, 5 dx)`` after :func:`skidsim.texture.separate_bands`) of a clean height map."""
    from ..texture import mean_profile_depth, separate_bands

    s = Surface(clean, dx_mm, dx_mm, name="clean")
    length = clean.shape[1] * dx_mm
    seg = 100.0 if length >= 100.0 else float(np.floor((length - dx_mm) / 0.5) * 0.5)
    mpd = mean_profile_depth(s, segment_mm=seg).mpd_mm
    cut = max(micro_cut_mm, 5 * dx_mm)
    micro = separate_bands(s, macro=(cut, 50.0))["micro"].heights
    return {
        "mpd_mm": float(mpd),
        "micro_sq_mm": float(np.std(micro)),
        "micro_cut_mm": cut,
        "mpd_segment_mm": seg,
        "sq_mm": float(np.std(clean)),
    }


def hidden_measures(clean: np.ndarray, dx_mm: float, micro_cut_mm: float, effect: str | None) -> dict:
    """The texture measure a hidden effect reads (:data:`friction_models.HIDDEN_MEASURES`; {} for the others, so
    that campaigns without such an effect keep their bytes), on the clean height map (mm):

    * ``macro_sdq`` (``hysteresis``): rms slope (dimensionless, :func:`skidsim.texture.hybrid.sdq`) of the macro
      band (wavelengths ``max(micro_cut_mm, 5 dx)`` to 50 mm, :func:`skidsim.texture.separate_bands`);
    * ``micro_contact_mm`` (``contact_micro``): the micro band's rms over the scan counting only the points
      within 0.5 mm of the tops (raw height >= its 99.5th percentile - 0.5 mm), ``sqrt(mean(micro^2 1[top]))``:
      the microtexture the slider touches; also ``contact_share`` (the share of those points)."""
    if effect not in friction_models.HIDDEN_MEASURES:
        return {}
    from ..texture import separate_bands
    from ..texture.hybrid import sdq

    cut = max(micro_cut_mm, 5 * dx_mm)
    bands = separate_bands(Surface(clean, dx_mm, dx_mm, name="clean"), macro=(cut, 50.0))
    if effect == "hysteresis":
        return {"macro_sdq": float(sdq(bands["macro"].heights, dx_mm, dx_mm))}
    raw, micro = bands["raw"].heights, bands["micro"].heights
    top = raw >= np.quantile(raw, 0.995) - 0.5
    return {"micro_contact_mm": float(np.sqrt(np.mean(micro**2 * top))), "contact_share": float(top.mean())}


def spin_down(rng: np.random.Generator, c: dict) -> np.ndarray:
    """DFT speeds (km/h) from U(v_start) down to the last one >= v_end, steps ``step_kmh`` +- N(0, jitter)."""
    v = [float(rng.uniform(*c["v_start_kmh"]))]
    while True:
        nxt = v[-1] - c["step_kmh"] - float(rng.normal(0.0, c["step_jitter_kmh"]))
        if nxt < c["v_end_kmh"]:
            return np.array(v)
        v.append(nxt)


def _site_friction(rng: np.random.Generator, row, meas: dict, f: dict, extra: dict | None = None) -> dict:
    """The friction truth of one site: model parameters from the texture measures (mm) through the published
    relations, with the section's (``row``) and the site's random factors; ``extra``: the measures of a hidden
    effect that reads more than MPD (:func:`hidden_measures`), recorded in the ``hidden`` entry."""
    base_level = friction_models.level_from_micro(meas["micro_sq_mm"], f["sq_ref_mm"])
    site_level = float(np.exp(rng.normal(0.0, f["site_level_sd"])))
    site_sp = float(np.exp(rng.normal(0.0, f["site_sp_sd"])))
    v_peak = float(rng.uniform(*f["v_peak_kmh"]))
    mu20 = base_level * float(row["sec_level_factor"]) * site_level
    sp_factor = float(row["sec_sp_factor"]) * site_sp
    params = friction_models.model_parameters(f["model"], mu20, meas["mpd_mm"], sp_factor=sp_factor, v_peak_kmh=v_peak)
    hidden = {
        "effect": f["hidden_effect"],
        "kappa": float(f["hidden_kappa"]),
        "sp_kmh": friction_models.ifi_speed_constant_kmh(meas["mpd_mm"]) * sp_factor,
    }
    if extra:
        hidden.update(extra)
        if f["hidden_effect"] == "contact_micro":
            hidden.update(micro_sq_mm=float(meas["micro_sq_mm"]), sq_ref_mm=float(f["sq_ref_mm"]))
    return {
        "friction_model": f["model"],
        "parameters": params,
        "level_from_micro": base_level,
        "section_level_factor": float(row["sec_level_factor"]),
        "site_level_factor": site_level,
        "section_sp_factor": float(row["sec_sp_factor"]),
        "site_sp_factor": site_sp,
        "mu20": mu20,
        "hidden": hidden,
    }


def site_mu(fr: dict, v_kmh) -> np.ndarray:
    """The true friction of a site at ``v_kmh`` (km/h): its model (``fr`` as :func:`generate_site` records it in
    the truth) times the hidden effect's factor (:func:`friction_models.hidden_factor`; 1 without one), saturated
    above mu 1.0 (:func:`friction_models.saturate`: only the lowest speeds of the rough sites reach it)."""
    mu = friction_models.evaluate(fr["friction_model"], fr["parameters"], v_kmh)
    h = fr.get("hidden") or {}
    if h.get("effect") is not None:
        keys = ("macro_sdq", "micro_contact_mm", "micro_sq_mm", "sq_ref_mm")
        mu = mu * friction_models.hidden_factor(
            h["effect"], h["kappa"], h["sp_kmh"], v_kmh, **{k: h[k] for k in keys if k in h}
        )
    return friction_models.saturate(mu)


def _trace(rng: np.random.Generator, fr: dict, c: dict) -> pd.DataFrame:
    """The DFT trace (speed_kmh, mu; spin-down order) of the friction truth ``fr`` with settings ``c``."""
    speeds = spin_down(rng, c)
    mu_true = site_mu(fr, speeds)
    mu = np.round(mu_true + rng.normal(0.0, c["noise_mu"], speeds.size), 3)
    return pd.DataFrame({"speed_kmh": np.round(speeds, 2), "mu": mu})


def generate_site(row, cfg: dict) -> SiteData:
    """Generate one site of :func:`design_campaign` (a row: Series or dict)."""
    site = str(row["site"])
    dx = float(cfg["spacing_mm"])
    shape = tuple(int(n) for n in cfg["shape"])
    s_tex, s_scan, s_fric, s_trace = (np.random.default_rng(s) for s in _seq(cfg, site).spawn(4))
    sec = {k[4:]: float(row[k]) for k in row.keys() if k.startswith("sec_") and "factor" not in k}
    sd = cfg["site_factor_sd"]
    site_f = {k: float(np.exp(s_tex.normal(0, sd))) for k in ("protrusion_factor", "macro_factor", "micro_factor")}
    clean, layout = TEXTURES[cfg["texture"]].render(s_tex, shape, dx, sec, site_f, cfg["texture_params"])
    heights, scan_info = scanner.scan(clean, s_scan, dx, cfg["scanner"])
    meas = texture_measures(clean, dx, cfg["friction"]["micro_cut_mm"])
    extra = hidden_measures(clean, dx, cfg["friction"]["micro_cut_mm"], cfg["friction"]["hidden_effect"])
    fr = _site_friction(s_fric, row, meas, cfg["friction"], extra)
    dft = _trace(s_trace, fr, cfg["dft"])
    grid = np.arange(5.0, 85.0, 5.0)
    curve = site_mu(fr, grid)
    truth = {
        "site": site,
        "section": str(row["section"]),
        "generator": cfg["generator"],
        "texture_model": cfg["texture"],
        **fr,
        "texture_measures": meas,
        "section_texture": sec,
        "site_texture_factors": site_f,
        "layout": layout,
        "scanner": scan_info,
        "spacing_mm": dx,
        "shape": list(shape),
        "noise_mu": cfg["dft"]["noise_mu"],
        "curve": {"speed_kmh": grid.tolist(), "mu": curve.tolist()},
        "temperature_c": float(row["temperature_c"]),
        "seed": int(cfg["seed"]),
    }
    meta = {
        "Date": f"{cfg['test_date']}T12:00:00+00:00",
        "Creator": f"skidsim.generators.{cfg['generator']}",
        "InstrumentModel": f"independent generator {cfg['generator']}",
    }
    return SiteData(surface=Surface(heights, dx, dx, name=site, meta=meta), clean=clean, dft=dft, truth=truth)


def write_site(data: SiteData, scan_path, dft_path, truth_path, z_step_mm: float = 0.01) -> None:
    """Scan as X3P (integer codes of ``z_step_mm``), DFT CSV ``speed_kmh,mu`` in spin-down order, truth JSON."""
    from ..x3p import write_x3p

    for p in (scan_path, dft_path, truth_path):
        Path(p).parent.mkdir(parents=True, exist_ok=True)
    hv = data.surface.heights[np.isfinite(data.surface.heights)]
    dtype = "I" if (hv.size == 0 or float(np.abs(hv).max()) / z_step_mm < 32000) else "L"
    write_x3p(scan_path, data.surface, dtype=dtype, z_increment_mm=z_step_mm, meta=data.surface.meta)
    lines = ["speed_kmh,mu"] + [f"{v:.2f},{m:.3f}" for v, m in zip(data.dft["speed_kmh"], data.dft["mu"])]
    write_text(dft_path, "\n".join(lines) + "\n")
    write_text(truth_path, json.dumps(data.truth, indent=1, sort_keys=True) + "\n")


def write_campaign(
    out_dir, generator: str, overrides: dict | None = None, truth_dir=None, progress=None
) -> pd.DataFrame:
    """Generate and write a whole campaign into ``out_dir`` (sites.csv, scans/, dft/) and the truth JSONs into
    ``truth_dir`` (default ``<out_dir>-truth`` beside it). Returns the design table."""
    cfg = generator_config(generator, overrides)
    out = Path(out_dir)
    truth_dir = Path(truth_dir) if truth_dir else out.parent / (out.name + "-truth")
    design = design_campaign(cfg)
    for n, (_, row) in enumerate(design.iterrows(), 1):
        data = generate_site(row, cfg)
        write_site(
            data,
            out / "scans" / f"{row['site']}.x3p",
            out / "dft" / f"{row['site']}.csv",
            truth_dir / f"{row['site']}.json",
            cfg["scanner"]["z_step_mm"],
        )
        if progress is not None:
            progress(n)
    sites = pd.DataFrame(
        {
            "site": design["site"],
            "section": design["section"],
            "scan": [f"scans/{s}.x3p" for s in design["site"]],
            "dft": [f"dft/{s}.csv" for s in design["site"]],
            "temperature_c": design["temperature_c"],
        }
    )
    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(out / "sites.csv") as tmp:
        sites.to_csv(tmp, index=False)
    write_text(truth_dir / "generator.json", json.dumps(cfg, indent=1, sort_keys=True) + "\n")
    return design
