"""Settings of the embedded default campaign: every generator setting with its default, and the user's config
merged onto them and checked.

The defaults (all in ``docs/synthetic-campaign.md``): study Table 1's section designs (:data:`SECTION_DESIGNS`), the
aggregate components rendered as stones (:data:`COMPONENTS`), the aggregate combinations and the surface structure
of each mix (:data:`GRADATIONS`), and the campaign, surface, scanner, DFT and truth settings (:data:`DEFAULTS`;
``dft`` and ``truth`` are :mod:`skidsim.generators.truth`'s). :func:`resolve_config` merges a config onto them key
by key and rejects what no generator step could use.
"""

from __future__ import annotations

import copy

from ...errors import ConfigError
from .. import truth as _truth

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
