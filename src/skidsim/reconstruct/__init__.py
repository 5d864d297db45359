"""Pavement reconstruction: a scan strip turned into the rigid FE heightfield of the DFT model.

The study (Section 3, Fig. 7) cut a 114.3 x 40 mm strip of the LS-40 scan, smoothed it "before meshing" and
meshed it at 0.5 mm as a rigid 114.3 x 40 x 8 mm body. :func:`pavement_strip` does the same, with every
choice explicit (see ``docs/reconstruction.md``).

One module per idea:

* :mod:`.heightfield`: :class:`Heightfield`, the rigid surface in SI units (C1 interpolation, persistence);
* :mod:`.resample`: the scan-grid operations of the strip: the ISO 16610-61 Gaussian
  (:func:`gaussian_sigma_mm`), exact area averaging (:func:`area_weights`, :func:`resample_area`) and the mean
  plane (:func:`remove_mean_plane`);
* :mod:`.strip`: :class:`MeshOptions` (the ``mesh:`` config) and :func:`pavement_strip`, whose numbered
  conventions (position, smoothing, resampling, levelling, units, solid) are that module's docstring.
"""

from .heightfield import Heightfield
from .resample import ISO_GAUSS_ALPHA, area_weights, gaussian_sigma_mm, remove_mean_plane, resample_area
from .strip import STUDY_STRIP_LENGTH_MM, MeshOptions, pavement_strip, strip_length_mm

__all__ = [
    "ISO_GAUSS_ALPHA",
    "STUDY_STRIP_LENGTH_MM",
    "Heightfield",
    "MeshOptions",
    "area_weights",
    "gaussian_sigma_mm",
    "pavement_strip",
    "remove_mean_plane",
    "resample_area",
    "strip_length_mm",
]
