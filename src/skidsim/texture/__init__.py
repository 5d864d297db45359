"""Texture characterisation: despeckle, band separation, ISO 25178-2 areal parameters, ISO 13473-1 MPD.

Public API (stable names the workflow calls)::

    despeckle(surface, method="mad", k=None, axis=1, replace=None) -> (Surface, n_replaced)
    fill_invalid(surface, method="linear") -> Surface
    separate_bands(surface, macro=(0.5, 50.0), order=2, form="plane", fill="linear", workers=1)
        -> {"raw", "macro", "micro"} Surfaces
    areal_parameters(surface, band, options) -> {name: (value, unit)}
    mean_profile_depth(surface, ...) -> MPDResult
    texture_table / campaign_table / table4_statistics / characterise

Every convention that changes a number is documented in ``docs/texture.md`` and in the module docstrings.
"""

from .despeckle import despeckle
from .filters import fill_invalid, remove_form, separate_bands
from .mpd import MPDResult, mean_profile_depth
from .parameters import GROUPS, UNITS, TextureOptions, areal_parameters
from .table import campaign_table, characterise, table4_statistics, texture_table, write_texture_table

mpd = mean_profile_depth

__all__ = ["despeckle", "fill_invalid", "remove_form", "separate_bands", "MPDResult", "mean_profile_depth", "mpd",
           "GROUPS", "UNITS", "TextureOptions", "areal_parameters", "campaign_table", "characterise",
           "table4_statistics", "texture_table", "write_texture_table"]
