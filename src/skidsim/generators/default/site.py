"""One default-campaign site: generated from its design row and written as the campaign's files.

:func:`generate_site` takes the site's clean surface (:mod:`.surface`), measures it, derives the site's friction
truth and DFT spin-down trace (:mod:`skidsim.generators.truth`, from the site's fourth random stream) and passes the
surface through the scanner; :func:`write_site` writes the scan (X3P), the DFT CSV and the truth JSON,
:func:`write_sites_csv` the campaign's ``sites.csv``.
"""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ...atomic import atomic_path, write_text
from ...errors import ConfigError
from ...surface import Surface
from .. import truth as _truth
from .config import resolve_config
from .surface import _scanner, _site_seed, synthesize_surface


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


def generate_site(row, cfg: dict | None = None) -> SiteData:
    """Generate one site from its design row (:func:`.design.design_campaign`) and the config.

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
    from ...x3p import write_x3p

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
