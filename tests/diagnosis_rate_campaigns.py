"""Residual-level campaigns for the rates of the model criticism by effect kind (test helper, not a test).

Issue 33, item 4 ("Rates, not anecdotes"): per texture source (``default``, ``chips``, ``spectral``) and effect kind
(:data:`KINDS`) a 36-site campaign (12 sections x 3 sites) whose sites.csv carries realistic decoy columns (section
level: ``aadt``, ``cum_traffic_msa``, ``year_laid``, ``mix``, ``binder``, ``region``, ``aggregate``; site level:
``temperature_c``, ``station_ft``, ``test_order``, ``operator``), of which at most one has an effect. The FE and the
texture stage are replaced as in tests/diagnosis_campaigns.py: DFT points = truth + noise; the simulation is the
per-site exponential-decay law through 20/40/60 km/h (scipy curve_fit, :func:`diagnosis_campaigns.derive_tables`);
the texture model predicts held-out sections like the workflow's ``physics2@dft``: per simulated speed, least
squares of the calibrated curve on ``[1, log(profile_MPD), log(micro_Sq)]``, leave one section out
(:data:`PREDICTION_FEATURES` is handed to the diagnosis as ``DiagnosisInputs.prediction_features``).

Texture sources and friction truths (the friction law of each source is its own, not the study's law alone):

* ``default``: the stand-in texture of tests/diagnosis_campaigns.py (section and site latents of macro and micro
  texture) with a macro rms slope of its own; friction the default generator's truth base
  (:data:`skidsim.generators.truth.TRUTH_DEFAULTS`: ``mu_k = 0.15 + 0.6 (1 - exp(-micro_Sdq / 0.5))``,
  ``mu_s - mu_k = 0.08 + 0.14 MPD``, ``alpha = 0.08 (0.8 / MPD)^0.5`` s/m) times a site factor exp(N(0, 0.02));
* ``chips`` / ``spectral``: the texture of :mod:`skidsim.generators` (clean surfaces rendered by the generator's
  own texture model for its section and site draws, on small scans, :data:`SCAN`), measured by
  :func:`texture_table_of_surface` (27 columns; ``texture_table="workflow"``: every column of the workflow's texture
  table, :func:`workflow_table_of_surface`); friction the generator's own model (``chips``: PIARC/IFI,
  ``spectral``: Rado;
  :mod:`skidsim.generators.friction_models`) with the generator's site random factors on the level and on Sp
  (:data:`skidsim.generators.campaign.COMMON`) but not its section factors: those are a hidden section-level effect
  of their own, so with them a campaign would hide two effects. ``chips+sectionlatent`` /
  ``spectral+sectionlatent`` keep them (:data:`SECTION_LATENT`): a robustness source whose null's right answer is
  ``section (unexplained)``. ``friction_model`` puts another friction-speed model of
  :mod:`skidsim.generators.friction_models` (``piarc``, ``rado``, ``penn_state``) in place of the generator's own,
  with the same random draws and the same level at 20 km/h: the texture of one generator with the friction-speed
  shape of another. The texture tables of a few designs per generator
  (:data:`N_DESIGNS`) are computed once and cached (:func:`generator_texture`); campaign seed ``s`` uses design
  ``s % N_DESIGNS`` and draws everything else (friction random factors, decoys, temperatures, DFT noise) afresh.
  ``n_designs=0`` (:func:`design_of`) gives every seed a texture design of its own, so that a rate counts texture
  designs as well as friction draws (the default source's stand-in texture is drawn per seed either way).

Effect kinds and sizes (``size`` scales each; 1 = the sizes below, chosen near the default campaign's hidden
effects: the seasonal temperature step of the workflow test, sd 0.038 mu; the mix offset -0.05 on 3 of 12
sections; station_ft -0.03 % per ft). The size of an effect is the sd over sites of its mean over 20-70 km/h
(``truth["effect_sd_mu"]``); the two speed-shape kinds are scaled to about 0.037 mu by that measure, like the
others (they were 0.015 and 0.014 mu with the constants 0.03 and 0.08):

* ``none``: no effect;
* ``section_column``: traffic polishing, ``x (1 - 0.015 (cum_traffic_msa - 10))``, cum_traffic_msa a section-level
  number U(2, 18) million standard axles (sd of the factor 7 %);
* ``site_column``: ``x (1 - 0.0003 station_ft)`` (stations 0/100/200 or 0/300/600 ft per section);
* ``temperature``: WLF shift of the slip speed, ``mu(v a_T)``, ``log10 a_T = -8.86 (T - 20) / (101.6 + T - 20)``
  (t_ref 20 deg C, C1 8.86, C2 101.6 K), T = section U(18, 22) + site N(0, 0.7) deg C (in every kind; an effect
  only here). Near 20 deg C these constants shift the speed by 0.087 decades per K, so a few K are a large effect;
* ``texture_speed``: hysteresis growing with speed and the macro rms slope, ``+ 0.075 z (v - 20) / 50``, ``z`` the
  site's ``macro_Sdq`` standardised over the campaign (centred: the campaign-mean hysteresis is the base law's;
  sd of the site means 0.075 x 0.5 = 0.0375 mu);
* ``categorical_speed``: the ``limestone`` sections of ``aggregate`` (3 of 12) polish: ``- 0.21 clip((60 - v) / 40,
  0, 1)`` (-0.21 at 20 km/h, none from 60 km/h; mean over the 5 km/h grid 20-70 km/h 0.21 x 4.5 / 11, on 3 of 12
  sections: sd of the site means 0.037 mu);
* ``texture_measure``: the low-speed level is driven by the microtexture the slider touches,
  ``micro_contact = sqrt(mean(micro^2 1[raw >= q99.5(raw) - 0.5 mm]))`` (the micro band's energy on the aggregate
  tops within 0.5 mm of the highest ones), not by the whole-scan micro Sq; the table holds micro_Sq, not
  micro_contact. ``default``: micro_contact = micro_Sq x (a logistic share of tops that falls with macro Sq).
  The level law is the source's own with micro_contact (rescaled to the campaign mean of micro_Sq) in place of
  micro_Sq;
* ``drainage``: partial hydroplaning through the macrotexture (the squeeze form of
  :func:`skidsim.generators.friction_models.hidden_factor`, as the workflow's drainage campaign),
  ``x max(0.05, 1 - 0.3 (v^2 - 20^2) / Sp^2)`` with the IFI speed constant ``Sp = 14.2 + 89.7 profile_MPD`` (km/h,
  MPD mm): 1 at 20 km/h, a loss growing with speed and faster on shallow texture. The hidden variable is
  profile_MPD, which the table holds: the texture model's ``log(profile_MPD)`` term carries part of the level,
  and the rest is a speed shape the exponential-decay law does not follow (sd of the site means 0.01-0.04 mu,
  median 0.020-0.025 over seeds 0-19 of the three sources; per campaign in ``truth["effect_sd_mu"]``).

Units: speeds km/h, temperatures deg C, MPD and Sq mm, mu dimensionless.
"""

from __future__ import annotations

import json
import zlib
from pathlib import Path

import numpy as np
import pandas as pd
from diagnosis_campaigns import derive_tables, measured_points

KINDS = (
    "none",
    "section_column",
    "site_column",
    "temperature",
    "texture_speed",
    "categorical_speed",
    "texture_measure",
    "drainage",
)
SOURCES = ("default", "chips", "spectral", "chips+sectionlatent", "spectral+sectionlatent")
#: Suffix of a robustness source: the generator's own random section factors on the friction level and on Sp
#: (log-normal, sd ``section_level_sd`` / ``section_sp_sd`` of :data:`skidsim.generators.campaign.COMMON`) are
#: kept. They are a hidden section-level effect that no column and no texture measure carries, so on these sources
#: a second hidden effect sits beside the kind's, and on ``none`` the right answer is ``section (unexplained)``.
#: The plain ``chips`` / ``spectral`` sources have no section factors (one hidden effect per campaign).
SECTION_LATENT = "+sectionlatent"
#: The hidden variable of each kind (None: the texture model / a texture measure the table does not hold).
HIDDEN = {
    "none": None,
    "section_column": "cum_traffic_msa",
    "site_column": "station_ft",
    "temperature": "temperature_c",
    "texture_speed": "macro_Sdq",
    "categorical_speed": "aggregate",
    "texture_measure": None,
    "drainage": "profile_MPD",
}
#: the texture model's columns, as the workflow's physics2@dft records them
PREDICTION_FEATURES = ("log(profile_MPD)", "log(micro_Sq)")
N_SECTIONS, SITES_PER_SECTION = 12, 3
#: small clean scans per generator (rows, cols) at the generator's own spacing
SCAN = {"chips": (640, 640), "spectral": (300, 300)}
N_DESIGNS = 4
#: The measured columns of a generator's texture table (:func:`texture_table_of_surface`).
TABLE_COLUMNS = (
    ["profile_MPD"]
    + [f"{b}_{k}" for b in ("raw", "macro", "micro") for k in ("Sq", "Sa", "Sp", "Sv", "Ssk", "Sku", "Sdq", "Sdr")]
    + ["micro_Sq_top", "micro_Sdq_top"]
)
#: The texture tables of a generator's design (:func:`generator_texture`): the harness's :data:`TABLE_COLUMNS`, or
#: every column of the workflow's texture table.
TABLES = ("harness", "workflow")
#: effect constants (size 1)
POLISH_PER_MSA = 0.015
STATION_PER_FT = 0.0003
WLF = {"t_ref_c": 20.0, "c1": 8.86, "c2_k": 101.6}
TEMP_SECTION_C, TEMP_SITE_SD_K = (18.0, 22.0), 0.7
HYST_MU = 0.075
POLISHED, POLISH_LOW_SPEED_MU = "limestone", 0.21
#: squeeze-form drainage: x max(0.05, 1 - DRAIN_KAPPA (v^2 - 20^2) / Sp^2), Sp = 14.2 + 89.7 profile_MPD (km/h)
DRAIN_KAPPA = 0.3
CONTACT_DEPTH_MM = 0.5


def generator_of(source: str) -> str:
    """The texture generator of a source (``default``, ``chips``, ``spectral``)."""
    return source.removesuffix(SECTION_LATENT)


def design_of(seed: int, n_designs: int = N_DESIGNS) -> int:
    """The texture design of campaign ``seed``: ``seed % n_designs``; ``n_designs`` 0: the seed itself (a design
    per campaign)."""
    if n_designs < 0:
        raise ValueError(f"n_designs: expected 0 (a design per seed) or a positive count, got {n_designs}")
    return int(seed) if n_designs == 0 else int(seed) % int(n_designs)


def _rng(seed: int, *keys) -> np.random.Generator:
    return np.random.default_rng([int(seed)] + [zlib.crc32(str(k).encode()) for k in keys])


def wlf_log10_shift(t_c, t_ref_c=WLF["t_ref_c"], c1=WLF["c1"], c2_k=WLF["c2_k"]):
    """``log10 a_T = -C1 (T - T_ref) / (C2 + T - T_ref)`` (T deg C, C2 K)."""
    dt = np.asarray(t_c, float) - t_ref_c
    return -c1 * dt / (c2_k + dt)


#: The kinds whose effect acts through a column of sites.csv (:func:`column_effect`).
COLUMN_KINDS = ("section_column", "site_column", "temperature", "categorical_speed")


def drainage_factor(mpd_mm: float, v_kmh, size: float = 1.0) -> np.ndarray:
    """The ``drainage`` kind's multiplier on mu at ``v_kmh`` (km/h) of a site of MPD ``mpd_mm`` (mm):
    ``max(0.05, 1 - size DRAIN_KAPPA (v^2 - 20^2) / Sp^2)``, ``Sp`` the IFI speed constant (km/h)."""
    from skidsim.generators.friction_models import hidden_factor, ifi_speed_constant_kmh

    return hidden_factor("squeeze", size * DRAIN_KAPPA, ifi_speed_constant_kmh(mpd_mm), v_kmh)


def column_effect(kind: str, row, v_kmh, mu_of, size: float = 1.0) -> np.ndarray:
    """The friction (mu) at ``v_kmh`` (km/h) of a site whose friction without the effect is ``mu_of(v_kmh)``, with
    the effect of ``kind`` (:data:`COLUMN_KINDS`, module docstring) read from its sites.csv ``row`` (a mapping):
    traffic polishing by ``cum_traffic_msa``, the station by ``station_ft``, the WLF shift of the slip speed by
    ``temperature_c`` (deg C), the low-speed loss of the ``aggregate`` :data:`POLISHED`; ``size`` scales each."""
    v = np.asarray(v_kmh, float)
    if kind == "temperature":
        return mu_of(v * 10.0 ** (size * wlf_log10_shift(float(row["temperature_c"]))))
    mu = mu_of(v)
    if kind == "section_column":
        return mu * (1.0 - size * POLISH_PER_MSA * (float(row["cum_traffic_msa"]) - 10.0))
    if kind == "site_column":
        return mu * (1.0 - size * STATION_PER_FT * float(row["station_ft"]))
    if kind == "categorical_speed":
        if row["aggregate"] != POLISHED:
            return mu
        return mu - size * POLISH_LOW_SPEED_MU * np.clip((60.0 - v) / 40.0, 0.0, 1.0)
    raise ValueError(f"kind: expected one of {COLUMN_KINDS}, got {kind!r}")


def hide_column_effect(campaign_dir, truth_dir, kind: str, size: float = 1.0) -> None:
    """Hide the effect of ``kind`` (:data:`COLUMN_KINDS`) in a campaign written by
    :func:`skidsim.generators.write_campaign` whose sites.csv already holds the effect's column: each site's DFT
    trace ``dft/<site>.csv`` gains ``column_effect(...) - mu_true`` at its speeds, ``mu_true`` being the
    generator's own friction of the site (:func:`skidsim.generators.campaign.site_mu` of its truth JSON in
    ``truth_dir``), so the trace keeps its noise; rounded to 0.001 as the generator writes it."""
    from skidsim.atomic import write_text
    from skidsim.generators.campaign import site_mu

    camp = Path(campaign_dir)
    for row in pd.read_csv(camp / "sites.csv").to_dict("records"):
        fr = json.loads((Path(truth_dir) / f"{row['site']}.json").read_text())
        dft = pd.read_csv(camp / row["dft"])
        v = dft["speed_kmh"].to_numpy(float)
        mu_true = site_mu(fr, v)
        mu = dft["mu"].to_numpy(float) + column_effect(kind, row, v, lambda u, fr=fr: site_mu(fr, u), size) - mu_true
        lines = ["speed_kmh,mu"] + [f"{a:.2f},{b:.3f}" for a, b in zip(v, mu)]
        write_text(camp / row["dft"], "\n".join(lines) + "\n")


# ---------------------------------------------------------------------------------------------------------------
# texture: the stand-in (default) and the generators' surfaces (chips, spectral)
# ---------------------------------------------------------------------------------------------------------------


def texture_table_of_surface(clean: np.ndarray, dx_mm: float, micro_cut_mm: float = 0.5) -> tuple[dict, dict]:
    """(table row, hidden measures) of one clean height map (mm): profile_MPD (mm; the generator's
    :func:`~skidsim.generators.campaign.texture_measures`), and per band raw / macro / micro (form removed,
    Butterworth bands at ``max(micro_cut_mm, 5 dx)`` and 50 mm) Sq, Sa, Sp, Sv (mm), Ssk, Sku, Sdq, Sdr (%), and
    the micro band's contact-zone micro_Sq_top (mm) and micro_Sdq_top (:mod:`skidsim.texture.contact`).
    Hidden: the generator's micro_sq_mm (what its friction law reads) and micro_contact (mm, module docstring)."""
    from skidsim.texture import TextureOptions
    from skidsim.texture.contact import contact_parameters
    from skidsim.texture.height import height_parameters
    from skidsim.texture.hybrid import sdq, sdr

    meas, bands = _measures_and_bands(clean, dx_mm, micro_cut_mm)
    row = {"profile_MPD": meas["mpd_mm"]}
    for band in ("raw", "macro", "micro"):
        z = bands[band].heights
        hp = height_parameters(z)
        for k in ("Sq", "Sa", "Sp", "Sv", "Ssk", "Sku"):
            row[f"{band}_{k}"] = hp[k]
        row[f"{band}_Sdq"] = sdq(z, dx_mm, dx_mm)
        row[f"{band}_Sdr"] = sdr(z, dx_mm, dx_mm)
    raw, micro = bands["raw"].heights, bands["micro"].heights
    for k, v in contact_parameters(raw, micro, dx_mm, dx_mm, TextureOptions().contact_top_pct).items():
        row[f"micro_{k}"] = v
    return row, _hidden_measures(meas, raw, micro)


def _measures_and_bands(clean: np.ndarray, dx_mm: float, micro_cut_mm: float) -> tuple[dict, dict]:
    """The generator's own measures of a clean height map (mm; :func:`~skidsim.generators.campaign.texture_measures`)
    and its raw / macro / micro bands (form removed, Butterworth at ``max(micro_cut_mm, 5 dx)`` and 50 mm)."""
    from skidsim.generators.campaign import texture_measures
    from skidsim.surface import Surface
    from skidsim.texture.filters import separate_bands

    cut = max(micro_cut_mm, 5 * dx_mm)
    bands = separate_bands(Surface(clean, dx_mm, dx_mm, name="clean"), macro=(cut, 50.0))
    return texture_measures(clean, dx_mm, micro_cut_mm), bands


def _hidden_measures(meas: dict, raw: np.ndarray, micro: np.ndarray) -> dict:
    """The measures a campaign's friction reads and its table does not hold: the generator's micro_sq_mm, and the
    micro band's energy on the tops within :data:`CONTACT_DEPTH_MM` of the highest ones (mm, module docstring)."""
    top = raw >= np.quantile(raw, 0.995) - CONTACT_DEPTH_MM
    return {
        "micro_sq_mm": meas["micro_sq_mm"],
        "micro_contact": float(np.sqrt(np.mean(micro**2 * top))),
        "contact_share": float(top.mean()),
    }


def workflow_table_of_surface(clean: np.ndarray, dx_mm: float, micro_cut_mm: float = 0.5) -> tuple[dict, dict]:
    """(table row, hidden measures) of one clean height map (mm), the row the workflow's texture table holds: every
    areal parameter of the raw, macro and micro bands (:func:`skidsim.texture.parameters.areal_parameters`,
    ``TextureOptions()`` defaults, as the ``texture_parameters`` rule computes them; columns ``<band>_<name>``) and
    the cross-band contact-zone parameters (``micro_Sq_top``, ``micro_Sdq_top``), with profile_MPD (mm) as
    :func:`texture_table_of_surface` gives it; the bands and the hidden measures as there (Butterworth at
    ``max(micro_cut_mm, 5 dx)`` and 50 mm)."""
    from skidsim.texture import TextureOptions
    from skidsim.texture.parameters import areal_parameters, cross_band_parameters

    opt = TextureOptions()
    meas, bands = _measures_and_bands(clean, dx_mm, micro_cut_mm)
    row = {"profile_MPD": meas["mpd_mm"]}
    for band in ("raw", "macro", "micro"):
        row.update({f"{band}_{k}": v for k, (v, _) in areal_parameters(bands[band], band, opt).items()})
    for band, values in cross_band_parameters(bands, opt).items():
        row.update({f"{band}_{k}": v for k, (v, _) in values.items()})
    return row, _hidden_measures(meas, bands["raw"].heights, bands["micro"].heights)


def generator_texture(generator: str, design: int, cache_dir=None, shape=None, table: str = "harness") -> pd.DataFrame:
    """Texture of design ``design`` of ``generator`` (36 sites, 12 sections): the generator's section draws
    (:func:`skidsim.generators.design_campaign`, seed ``20261125 + design``) and its clean surfaces (the site's
    texture stream, as :func:`skidsim.generators.generate_site` draws it) on ``shape`` (default :data:`SCAN`).
    Columns: site, section, the table and the hidden measures prefixed ``hidden_``. ``table``: ``harness``, the
    :data:`TABLE_COLUMNS` (:func:`texture_table_of_surface`), or ``workflow``, every column the workflow's texture
    table holds (:func:`workflow_table_of_surface`; about 120, 4-5x the computing time). Cached as CSV in
    ``cache_dir`` when given (the workflow table under a name of its own)."""
    from skidsim.generators import campaign as gc

    if table not in TABLES:
        raise ValueError(f"table: expected one of {TABLES}, got {table!r}")
    shape = tuple(shape or SCAN[generator])
    path = None
    if cache_dir is not None:
        suffix = "" if table == "harness" else f"_{table}"
        path = Path(cache_dir) / f"{generator}_{design}_{shape[0]}x{shape[1]}{suffix}.csv"
        if path.exists():
            cached = pd.read_csv(path)
            if set(TABLE_COLUMNS) <= set(cached.columns):  # a cache of an older table is computed again
                return cached
    cfg = gc.generator_config(
        generator,
        {"seed": 20261125 + int(design), "n_sites": 36, "n_sections": N_SECTIONS, "shape": list(shape)},
    )
    dx = float(cfg["spacing_mm"])
    of_surface = texture_table_of_surface if table == "harness" else workflow_table_of_surface
    rows = []
    for _, r in gc.design_campaign(cfg).iterrows():
        site = str(r["site"])
        s_tex = np.random.default_rng(gc._seq(cfg, site).spawn(4)[0])
        sec = {k[4:]: float(r[k]) for k in r.keys() if k.startswith("sec_") and "factor" not in k}
        sd = cfg["site_factor_sd"]
        site_f = {k: float(np.exp(s_tex.normal(0, sd))) for k in ("protrusion_factor", "macro_factor", "micro_factor")}
        clean, _ = gc.TEXTURES[cfg["texture"]].render(s_tex, shape, dx, sec, site_f, cfg["texture_params"])
        row, hidden = of_surface(clean, dx, cfg["friction"]["micro_cut_mm"])
        rows.append(
            {"site": site, "section": str(r["section"]), **row, **{f"hidden_{k}": v for k, v in hidden.items()}}
        )
    df = pd.DataFrame(rows)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        df.to_csv(tmp, index=False)
        tmp.replace(path)
    return df


def default_texture(seed: int) -> pd.DataFrame:
    """The stand-in texture (tests/diagnosis_campaigns.py's latents and columns, renamed to the workflow's
    texture table names) plus macro_Sdq (its own wavelength latent) and the hidden contact microtexture."""
    rng = _rng(seed, "default-texture")
    n = N_SECTIONS * SITES_PER_SECTION
    sec_idx = np.repeat(np.arange(N_SECTIONS), SITES_PER_SECTION)
    sec = [f"S{k + 1:02d}" for k in range(N_SECTIONS)]
    macro = 0.8 * rng.normal(size=N_SECTIONS)[sec_idx] + 0.6 * rng.normal(size=n)
    micro = 0.8 * rng.normal(size=N_SECTIONS)[sec_idx] + 0.6 * rng.normal(size=n)
    wave = 0.8 * rng.normal(size=N_SECTIONS)[sec_idx] + 0.6 * rng.normal(size=n)  # macro wavelength (slope)
    mpd = np.clip(0.8 + 0.22 * macro, 0.25, None)
    macro_sq = 0.55 * mpd + 0.02 * rng.normal(size=n)
    df = pd.DataFrame(
        {
            "site": [f"{sec[k]}-{j + 1}" for k in range(N_SECTIONS) for j in range(SITES_PER_SECTION)],
            "section": np.repeat(sec, SITES_PER_SECTION),
            "profile_MPD": mpd,
            "macro_Sq": macro_sq,
            "macro_Sa": 0.42 * mpd + 0.02 * rng.normal(size=n),
            "macro_Sdr": 8.0 + 3.0 * macro + 0.4 * rng.normal(size=n),
            "macro_Sdq": 0.30 + 0.05 * macro + 0.06 * wave + 0.01 * rng.normal(size=n),
            "macro_Ssk": -0.5 + 0.3 * rng.normal(size=n),
            "macro_Sku": 3.2 + 0.4 * rng.normal(size=n),
            "macro_Str": 0.6 + 0.1 * rng.normal(size=n),
            "micro_Sq": 0.030 + 0.005 * micro + 0.0008 * rng.normal(size=n),
            "micro_Sdq": 0.40 + 0.06 * micro + 0.01 * rng.normal(size=n),
            "micro_Ssk": -0.2 + 0.3 * rng.normal(size=n),
            "micro_Str": 0.7 + 0.1 * rng.normal(size=n),
        }
    )
    zq = (macro_sq - macro_sq.mean()) / macro_sq.std()
    share = 1.0 + 0.3 * np.tanh(-zq)  # deeper texture: fewer tops in contact
    df["hidden_micro_sq_mm"] = df["micro_Sq"]
    df["hidden_micro_contact"] = df["micro_Sq"] * share / share.mean()
    return df


# ---------------------------------------------------------------------------------------------------------------
# the campaign
# ---------------------------------------------------------------------------------------------------------------


def site_design(seed: int, site, section, temperature_section_c: tuple = TEMP_SECTION_C) -> pd.DataFrame:
    """sites.csv of a campaign: identifiers and the decoy columns (every kind has the same columns); the sections'
    temperatures U(``temperature_section_c``) deg C."""
    rng = _rng(seed, "sites")
    secs = list(dict.fromkeys(section))
    k = len(secs)
    sec_of = np.array([secs.index(s) for s in section])
    n = len(site)

    def per_section(values):
        return np.asarray(values)[sec_of]

    stations = np.array([(0, 100, 200), (0, 300, 600)])[rng.integers(0, 2, size=k)]
    pos = np.concatenate([np.arange((sec_of == j).sum()) for j in range(k)])
    t_sec = rng.uniform(*temperature_section_c, size=k)
    return pd.DataFrame(
        {
            "site": list(site),
            "section": list(section),
            "temperature_c": np.round(per_section(t_sec) + rng.normal(0.0, TEMP_SITE_SD_K, n), 1),
            "station_ft": stations[sec_of, np.minimum(pos, 2)],
            "test_order": rng.permutation(n) + 1,
            "operator": rng.choice(["JD", "KL", "MP"], size=n),
            "aadt": per_section(np.round(rng.lognormal(np.log(8000), 0.6, size=k), -1)),
            "cum_traffic_msa": per_section(np.round(rng.uniform(2.0, 18.0, size=k), 2)),
            "year_laid": per_section(rng.integers(2005, 2024, size=k)),
            "mix": per_section(rng.permutation(np.resize(["SMA", "DGA", "OGFC"], k))),
            "binder": per_section(rng.permutation(np.resize(["PG64-22", "PG76-22"], k))),
            "region": per_section(np.repeat(["north", "central", "south"], int(np.ceil(k / 3)))[:k]),
            "aggregate": per_section(rng.permutation(np.resize(["granite", "basalt", "gritstone", POLISHED], k))),
        }
    )


def _base_law(
    source: str,
    tex: pd.DataFrame,
    rng: np.random.Generator,
    micro_driver: np.ndarray,
    friction_model: str | None = None,
):
    """A function ``mu(i, v)`` of the source's friction law with its random factors; ``micro_driver``: the micro
    Sq (mm) the level law reads (the whole-scan one, or the contact one of the texture-measure kind);
    ``friction_model``: chips and spectral only, one of :data:`skidsim.generators.friction_models.MODELS` in place
    of the generator's own (None: its own), with the same random draws."""
    from skidsim.generators import campaign as gc
    from skidsim.generators import friction_models as fm

    n = len(tex)
    if source == "default":
        if friction_model is not None:
            raise ValueError(f"friction_model: the default source has a law of its own, got {friction_model!r}")
        sdq_micro = tex["micro_Sdq"].to_numpy(float) * micro_driver / tex["hidden_micro_sq_mm"].to_numpy(float)
        mpd = tex["profile_MPD"].to_numpy(float)
        mu_k = (0.15 + 0.60 * (1.0 - np.exp(-sdq_micro / 0.5))) * np.exp(rng.normal(0.0, 0.02, n))
        mu_s = mu_k + 0.08 + 0.14 * mpd
        alpha = 0.08 * (0.8 / mpd) ** 0.5

        def mu(i, v):
            return mu_k[i] + (mu_s[i] - mu_k[i]) * np.exp(-alpha[i] * np.asarray(v, float) / 3.6)

        return mu
    gen = generator_of(source)
    cfg = gc.generator_config(gen)
    f = cfg["friction"]
    if friction_model is not None:  # an unknown model: fm.model_parameters' ConfigError
        f = {**f, "model": friction_model}
    if not source.endswith(SECTION_LATENT):  # one hidden effect per campaign: no random section factors
        f = {**f, "section_level_sd": 0.0, "section_sp_sd": 0.0}
    secs = list(dict.fromkeys(tex["section"]))
    sec_of = np.array([secs.index(s) for s in tex["section"]])
    sec_level = np.exp(rng.normal(0.0, f["section_level_sd"], len(secs)))[sec_of]
    sec_sp = np.exp(rng.normal(0.0, f["section_sp_sd"], len(secs)))[sec_of]
    site_level = np.exp(rng.normal(0.0, f["site_level_sd"], n))
    site_sp = np.exp(rng.normal(0.0, f["site_sp_sd"], n))
    v_peak = rng.uniform(*f["v_peak_kmh"], size=n)
    mpd = tex["profile_MPD"].to_numpy(float)
    params = []
    for i in range(n):
        mu20 = fm.level_from_micro(micro_driver[i], f["sq_ref_mm"]) * sec_level[i] * site_level[i]
        params.append(
            fm.model_parameters(f["model"], mu20, mpd[i], sp_factor=sec_sp[i] * site_sp[i], v_peak_kmh=v_peak[i])
        )

    def mu(i, v):
        return fm.evaluate(f["model"], params[i], np.asarray(v, float))

    return mu


def generate(
    source: str,
    kind: str,
    seed: int,
    *,
    size: float = 1.0,
    cache_dir=None,
    noise_mu: float | None = None,
    trace_step_kmh: float = 4.0,
    texture: pd.DataFrame | None = None,
    n_designs: int = N_DESIGNS,
    texture_table: str = "harness",
    trace_from_kmh: float = 20.0,
    temperature_section_c: tuple = TEMP_SECTION_C,
    friction_model: str | None = None,
):
    """Return (sites, measured, texture, truth) of one campaign: sites.csv columns, DFT points (site, speed_kmh,
    mu, kind), the texture table (site + numeric columns; the hidden measures are not in it) and the truth dict
    (kind, variable, effect_sd_mu: sd over sites of the effect's mean over 20-70 km/h,
    effect_sd_beyond_texture_model_mu: the same of the part the prediction model's texture terms cannot carry
    (:func:`beyond_texture_model`), effect_rms_mu: RMS of the
    effect over sites and 20-70 km/h about its campaign mean per speed). ``texture``: a precomputed
    :func:`generator_texture` table (else design :func:`design_of` (``seed``, ``n_designs``) is computed or read
    from ``cache_dir``; ``texture_table``: which table, :data:`TABLES`). ``trace_from_kmh``: the DFT trace's lowest
    speed (km/h; 20 by default: no trace point below 20 km/h; :func:`diagnosis_campaigns.measured_points`);
    ``temperature_section_c``: the range (deg C) of the sections' temperatures (:func:`site_design`);
    ``friction_model``: chips and spectral only, a friction-speed model of
    :data:`skidsim.generators.friction_models.MODELS` in place of the generator's own (:func:`_base_law`)."""
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {KINDS}, got {kind!r}")
    if source not in SOURCES:
        raise ValueError(f"source: expected one of {SOURCES}, got {source!r}")
    if texture is None:
        gen = generator_of(source)
        design = design_of(seed, n_designs)
        texture = (
            default_texture(seed)
            if gen == "default"
            else generator_texture(gen, design, cache_dir, table=texture_table)
        )
    tex = texture.reset_index(drop=True)
    n = len(tex)
    sites = site_design(seed, tex["site"], tex["section"], tuple(temperature_section_c))
    rng = _rng(seed, source, "friction")
    micro = tex["hidden_micro_sq_mm"].to_numpy(float)
    if kind == "texture_measure":
        contact = tex["hidden_micro_contact"].to_numpy(float)
        contact = contact * micro.mean() / contact.mean()
        driver = micro + size * (contact - micro)
    else:
        driver = micro
    base = _base_law(source, tex, rng, driver, friction_model)
    plain = (
        _base_law(source, tex, _rng(seed, source, "friction"), micro, friction_model)
        if kind == "texture_measure"
        else base
    )
    rows = sites.to_dict("records")
    mpd = tex["profile_MPD"].to_numpy(float)
    sdq = tex["macro_Sdq"].to_numpy(float)
    z_sdq = (sdq - sdq.mean()) / sdq.std()

    def truth_mu(i, v):
        v = np.asarray(v, float)
        if kind in COLUMN_KINDS:
            return column_effect(kind, rows[i], v, lambda u: base(i, u), size)
        mu = base(i, v)
        if kind == "texture_speed":
            mu = mu + size * HYST_MU * z_sdq[i] * (v - 20.0) / 50.0
        elif kind == "drainage":
            mu = mu * drainage_factor(mpd[i], v, size)
        return mu

    noise = noise_mu if noise_mu is not None else (0.005 if source == "default" else 0.007)  # mu per DFT point
    rng_n = _rng(seed, source, kind, "noise")
    site = tex["site"].astype(str).tolist()
    measured = measured_points(site, truth_mu, noise, trace_step_kmh, rng_n, trace_from_kmh)
    grid = np.arange(20.0, 70.0 + 1e-9, 5.0)
    eff = np.array([truth_mu(i, grid) - plain(i, grid) for i in range(n)]) if kind != "none" else np.zeros((n, 1))
    table = tex[[c for c in tex.columns if c != "section" and not c.startswith("hidden_")]].copy()
    num = table.columns.drop("site")
    table[num] = table[num].fillna(table[num].mean())  # Ssk, Sku of a scan without a chip: the campaign mean
    truth = {
        "source": source,
        "kind": kind,
        "variable": HIDDEN[kind],
        "size": size,
        "friction_model": friction_model or "",
        "effect_sd_mu": float(eff.mean(axis=1).std()),
        "effect_rms_mu": float(np.sqrt(((eff - eff.mean(axis=0)) ** 2).mean())),
        "effect_sd_beyond_texture_model_mu": beyond_texture_model(eff, table),
        "corr_contact_micro": float(np.corrcoef(tex["hidden_micro_contact"], micro)[0, 1]),
    }
    return sites, measured, table, truth


def beyond_texture_model(eff: np.ndarray, table: pd.DataFrame) -> float:
    """sd over sites (mu) of the mean over 20-70 km/h of the part of the effect ``eff`` (sites x speeds) that the
    prediction model's texture terms cannot carry: per speed, the residual of the least squares of the effect on
    ``[1, log(profile_MPD), log(micro_Sq)]`` over all sites. The model behind ``sn_pred`` is trained on calibrated
    curves that hold the effect, so it learns this projection (up to its held-out-section error), and only the
    rest reaches the between-site residual. An effect of a texture measure correlated with the model's terms
    (chips: macro_Sdq, R^2 0.88 on log MPD and log micro Sq) is mostly predicted, not missed."""
    if not np.any(eff):
        return 0.0
    logs = [np.log(table[c].to_numpy(float)) for c in ("profile_MPD", "micro_Sq")]
    X = np.c_[np.ones(len(table)), logs[0], logs[1]]
    rest = eff - X @ np.linalg.lstsq(X, eff, rcond=None)[0]
    return float(rest.mean(axis=1).std())


def physics2_predictions(simulated: pd.DataFrame, sites: pd.DataFrame, texture: pd.DataFrame) -> pd.DataFrame:
    """Held-out predictions like the workflow's ``physics2@dft``: per simulated speed, leave-one-section-out
    least squares of the calibrated SN on ``[1, log(profile_MPD), log(micro_Sq)]``."""
    site = sites["site"].astype(str).tolist()
    sec = sites["section"].astype(str).to_numpy()
    t = texture.set_index(texture["site"].astype(str)).loc[site]
    X = np.c_[np.ones(len(site)), np.log(t["profile_MPD"].to_numpy(float)), np.log(t["micro_Sq"].to_numpy(float))]
    Y = simulated.pivot(index="site", columns="speed_kmh", values="sn").loc[site]
    speeds = Y.columns.to_numpy(float)
    Y = Y.to_numpy(float)
    pred = np.empty_like(Y)
    for s in np.unique(sec):
        te, tr = sec == s, sec != s
        beta = np.linalg.lstsq(X[tr], Y[tr], rcond=None)[0]
        pred[te] = X[te] @ beta
    return pd.DataFrame(
        [(site[i], float(v), float(pred[i, j])) for i in range(len(site)) for j, v in enumerate(speeds)],
        columns=["site", "speed_kmh", "sn_pred"],
    )


def make_rate_campaign(source: str, kind: str, seed: int, **kw):
    """(tables, truth): the diagnosis inputs of one campaign (sites, measured, simulated, predicted, texture,
    prediction_features) and its truth. Keywords: :func:`generate`."""
    sites, measured, tex, truth = generate(source, kind, seed, **kw)
    t = derive_tables(sites, measured, tex)
    t["predicted"] = physics2_predictions(t["simulated"], sites, tex)
    t["prediction_features"] = PREDICTION_FEATURES
    return t, truth


def rate_inputs(t: dict):
    """The :class:`skidsim.criticism.DiagnosisInputs` of the tables ``t`` of :func:`make_rate_campaign` (the
    physics2-like prediction model and its texture features)."""
    from skidsim.criticism import DiagnosisInputs

    return DiagnosisInputs(
        t["sites"],
        t["measured"],
        t["simulated"],
        t["predicted"],
        t["texture"],
        prediction_model="physics2-like",
        prediction_features=t["prediction_features"],
    )


def screen_rate_campaign(t: dict, options):
    """The screening of ``skidsim.criticism.diagnose`` on the tables ``t`` of :func:`make_rate_campaign`, without
    the extension and its gain: residuals, the texture model's scores with the prediction features as lead, then
    ``screen_candidates`` under the :class:`~skidsim.criticism.DiagnosisOptions` ``options``. Returns the causes."""
    from skidsim import criticism as cr
    from skidsim.criticism.adjustment import texture_model_scores

    res = cr.build_residuals(t["sites"], t["measured"], t["simulated"], t["predicted"])
    lead = t["prediction_features"]
    pcs, _ = texture_model_scores(res, t["sites"], t["texture"], options.speed_bin_kmh, cr.DEFAULT_EXCLUDE, lead=lead)
    return cr.screen_candidates(res, t["sites"], t["texture"], options, texture_pc_scores=pcs, texture_lead=lead)


def describe_kinds() -> str:
    """The kinds and their sizes, as JSON (for the benchmark's output)."""
    return json.dumps(
        {
            "section_column": f"x (1 - {POLISH_PER_MSA} (cum_traffic_msa - 10)), msa U(2, 18) per section",
            "site_column": f"x (1 - {STATION_PER_FT} station_ft)",
            "temperature": f"mu(v a_T), WLF t_ref {WLF['t_ref_c']} C1 {WLF['c1']} C2 {WLF['c2_k']}; "
            f"T section U{TEMP_SECTION_C} + site N(0, {TEMP_SITE_SD_K})",
            "texture_speed": f"+ {HYST_MU} z(macro_Sdq) (v - 20) / 50",
            "categorical_speed": f"- {POLISH_LOW_SPEED_MU} clip((60 - v) / 40, 0, 1) on aggregate == {POLISHED}",
            "texture_measure": f"level from micro Sq within {CONTACT_DEPTH_MM} mm of the tops (not in the table)",
            "drainage": f"x max(0.05, 1 - {DRAIN_KAPPA} (v^2 - 400) / Sp^2), Sp = 14.2 + 89.7 profile_MPD",
        }
    )
