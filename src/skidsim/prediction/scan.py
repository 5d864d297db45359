"""The texture pipeline of the workflow on one scan, in one call: :func:`scan_features`.

The same steps, options and library calls as the rules ``despeckle``, ``separate_bands``, ``mpd``,
``texture_parameters`` and ``texture_campaign`` (workflow/rules/texture.smk): read the scan, keep the centred band
of ``crop_y_mm`` rows, despeckle, measure the scan quality, fill invalid points, separate the raw, macro
(0.5-50 mm) and micro bands, compute the areal parameters of each band and the MPD (ISO 13473-1), and lay them out
as one row of the campaign texture table (columns ``<band>_<parameter>``, each in its own unit: mm, %, 1/mm ...).
A model file stores the texture options it was trained with, so a new scan goes through the same pipeline.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from skidsim.scans import read_scan
from skidsim.texture import TextureOptions, despeckle_detail, fill_invalid, mean_profile_depth
from skidsim.texture import separate_bands as _separate_bands
from skidsim.texture.quality import QualityOptions, ScanQuality, breaches, scan_quality
from skidsim.texture.table import band_parameters, campaign_table, texture_table


@dataclass(frozen=True)
class ScanFeatures:
    """The texture row of one scan: ``site`` (the scan's name), ``features`` (``<band>_<parameter>`` -> value in
    the parameter's unit; ``profile_MPD`` in mm), ``quality`` (:class:`ScanQuality`) and ``breaches`` (one line
    per quality limit the scan breaks; empty when it is within them)."""

    site: str
    features: dict
    quality: ScanQuality
    breaches: tuple[str, ...]


def scan_features(path, texture: TextureOptions, quality: QualityOptions, site: str | None = None) -> ScanFeatures:
    """Texture features and quality of the scan at ``path`` (X3P or grid text) with the workflow's texture
    pipeline (module docstring); ``site`` defaults to the file's stem. Raises
    :class:`~skidsim.errors.ScanFormatError` naming the file for an unreadable scan."""
    path = Path(path)
    site = path.stem if site is None else str(site)
    surface = read_scan(path)
    if texture.crop_y_mm:
        surface = surface.crop_y_centred(texture.crop_y_mm)
    res = despeckle_detail(surface, method=texture.despeckle_method, k=texture.despeckle_k, axis=texture.despeckle_axis)
    q = scan_quality(site, surface, res.mask, res.step_mm, res.step_source, quality.min_column_valid_pct)
    clean = fill_invalid(res.surface, method=texture.fill)
    bands = _separate_bands(
        clean, macro=tuple(texture.macro_mm), order=texture.butterworth_order, form=texture.form, fill=texture.fill
    )
    mpd = mean_profile_depth(clean, **texture.mpd_kwargs())
    params = band_parameters(bands, texture)  # as the workflow's texture_parameters
    wide = campaign_table(texture_table(site, params, mpd))
    row = {c: float(v) for c, v in wide.iloc[0].items() if c != "site"}
    return ScanFeatures(site, row, q, tuple(breaches(q, quality)))


def feature_table(scans: list[ScanFeatures], sites: pd.DataFrame | None = None) -> pd.DataFrame:
    """The scans' rows as a texture table indexed by site (columns ``<band>_<parameter>``), joined with the
    ``temperature_c`` (deg C) and ``section`` columns of ``sites`` (a sites.csv table: ``site``, ...) when given."""
    X = pd.DataFrame([s.features for s in scans], index=pd.Index([s.site for s in scans], name="site"))
    if sites is not None:
        meta = sites.assign(site=sites["site"].astype(str)).set_index("site")
        for c in ("section", "temperature_c"):
            if c in meta.columns:
                X[c] = meta[c].reindex(X.index).to_numpy()
    return X
