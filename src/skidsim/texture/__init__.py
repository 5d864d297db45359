"""Texture characterisation: despeckle, band separation, ISO 25178-2 areal parameters, ISO 13473-1 MPD.

Public API (stable names the workflow calls)::

    despeckle(surface, method="local", k=None, axis=1, replace=None) -> (Surface, n_replaced)
    despeckle_detail(surface, ...) -> DespeckleResult (surface, mask of replaced points, height step)
    fill_invalid(surface, method="linear") -> Surface
    separate_bands(surface, macro=(0.5, 50.0), order=2, form="plane", fill="linear", workers=1)
        -> {"raw", "macro", "micro"} Surfaces
    areal_parameters(surface, band, options) -> {name: (value, unit)}
    cross_band_parameters(bands, options) -> {band: {name: (value, unit)}}  (contact zone: micro on the tops)
    band_parameters(bands, options) -> {band: {name: (value, unit)}}  (both, every band: the workflow's set)
    mean_profile_depth(surface, ...) -> MPDResult
    texture_table / campaign_table / table4_statistics / characterise

Every convention that changes a number is documented in ``docs/texture.md`` and in the module docstrings.
"""

from .despeckle import despeckle, despeckle_detail
from .filters import fill_invalid, remove_form, separate_bands
from .mpd import MPDResult, mean_profile_depth
from .parameters import GROUPS, UNITS, TextureOptions, areal_parameters, cross_band_parameters

mpd = mean_profile_depth

#: names of .table (pandas) imported on first use (PEP 562): a step that only despeckles, filters or computes
#: the MPD then starts without pandas (about 0.4 s of the start-up of each of the 4 x 36 per-site jobs)
_TABLE_NAMES = (
    "band_parameters",
    "campaign_table",
    "characterise",
    "table4_statistics",
    "texture_table",
    "write_texture_table",
)


__all__ = [
    "despeckle",
    "despeckle_detail",
    "fill_invalid",
    "remove_form",
    "separate_bands",
    "MPDResult",
    "mean_profile_depth",
    "mpd",
    "GROUPS",
    "UNITS",
    "cross_band_parameters",
    "TextureOptions",
    "areal_parameters",
    *_TABLE_NAMES,
]


def __getattr__(name: str):
    if name in _TABLE_NAMES:
        from . import table

        return getattr(table, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
