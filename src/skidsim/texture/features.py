"""ISO 25178-2 feature parameters Spd, Spc, S5p, S5v, S10z, Shv from Wolf-pruned watershed segmentations
(:mod:`skidsim.texture.segmentation`).

Conventions (docs/texture.md):

* Heights are referenced to the mean plane (mean subtracted). Hills are the dales of ``-z``.
* Pruning threshold = ``pruning_pct`` % of a reference height: ``"Sz"`` (ISO 25178-3 / surfalize default,
  5 %), or ``"Sq"``. On strongly negatively skewed pavement Sz is valley-dominated and 5 % of Sz prunes most
  hills; ``"Sq"`` gives a threshold that follows the typical height instead.
* ``exclude_edge`` (default False): drop motifs touching the border (MountainsMap and surfalize default True;
  we keep them by default because the density is divided by the full evaluation area).
* Spd (1/mm^2) = significant hills / evaluation area ``(cols-1) dx (rows-1) dy``.
* S5p (mm) = mean height of the 5 highest significant peaks; S5v (mm) = mean depth of the 5 deepest significant
  pits (fewer if fewer exist); S10z = S5p + S5v.
* Spc (1/mm) = mean over significant peaks of ``-(d2z/dx2 + d2z/dy2)/2`` from a least-squares quadric fitted
  to the ``(2 h + 1)^2`` points around the peak (``h = spc_half_window`` points, default 2): the local fit is the
  S-filter that keeps Spc from following point noise. Peaks closer than ``h`` to the border are skipped.
* Shv (mm^3) = mean over significant hills of the volume above the hill's base (its lowest saddle to another
  hill), ``sum(max(z - base, 0)) dx dy`` over the hill.
"""

from __future__ import annotations

import numpy as np

from .segmentation import Segmentation, deepest_motifs, segment

PRUNING_REFERENCES = ("Sz", "Sq")
PRUNING_PCT = 5.0  # % of the reference height: the default of every function here and of TextureOptions


def pruning_threshold(
    zc: np.ndarray, pruning_pct: float, reference: str, sz: float | None = None, sq: float | None = None
) -> float:
    """Pruning height in mm: ``pruning_pct`` % of Sz or Sq of the mean-subtracted heights ``zc``; ``sz``
    (``zc.max() - zc.min()``) or ``sq`` (``sqrt(mean(zc * zc))``) when the caller has it."""
    if reference not in PRUNING_REFERENCES:
        raise ValueError(f"pruning reference must be one of {PRUNING_REFERENCES}, got {reference!r}")
    if reference == "Sz":
        ref = float(zc.max() - zc.min()) if sz is None else sz
    else:
        ref = float(np.sqrt(np.mean(zc * zc))) if sq is None else sq
    return pruning_pct / 100.0 * ref


def peak_curvature(zc: np.ndarray, flat_index: np.ndarray, dx: float, dy: float, half: int = 2) -> np.ndarray:
    """``-(z_xx + z_yy)/2`` (1/mm) at the given points from a local least-squares quadric on a
    ``(2 half + 1)^2`` window; points closer than ``half`` to the border are skipped."""
    rows, cols = zc.shape
    r, c = np.divmod(np.asarray(flat_index, dtype=np.int64), cols)
    ok = (r >= half) & (r < rows - half) & (c >= half) & (c < cols - half)
    r, c = r[ok], c[ok]
    if r.size == 0:
        return np.empty(0)
    oy, ox = np.mgrid[-half : half + 1, -half : half + 1]
    x = (ox * dx).ravel()
    y = (oy * dy).ravel()
    design = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)
    pinv = np.linalg.pinv(design)  # (6, w^2)
    win = zc[r[:, None] + oy.ravel()[None, :], c[:, None] + ox.ravel()[None, :]]  # (n, w^2)
    coef = win @ pinv.T
    return -(coef[:, 3] + coef[:, 5])


def feature_parameters(
    zc: np.ndarray,
    dx: float,
    dy: float,
    *,
    pruning_pct: float = PRUNING_PCT,
    pruning_reference: str = PRUNING_REFERENCES[0],
    exclude_edge: bool = False,
    spc_half_window: int = 2,
    hills: Segmentation | None = None,
    dales: Segmentation | None = None,
    sz: float | None = None,
) -> dict[str, float]:
    """Spc (1/mm), S10z S5p S5v (mm), Spd (1/mm^2), Shv (mm^3) of mean-subtracted heights ``zc`` (mm). ``sz``:
    ``zc.max() - zc.min()`` when the caller has it (:func:`pruning_threshold`)."""
    t = pruning_threshold(zc, pruning_pct, pruning_reference, sz=sz)
    if hills is None:
        hills = segment(-zc, t, dx, dy, keep_peaks=dales is None)
    if dales is None and exclude_edge:
        dales = segment(zc, t, dx, dy, measure=False, bases=False)  # S5v: its critical points and edge flags
    area = (zc.shape[1] - 1) * dx * (zc.shape[0] - 1) * dy
    hk = hills.select(exclude_edge)
    curv = peak_curvature(zc, hills.critical_index[hk], dx, dy, spc_half_window)
    return {
        "Spc": float(np.mean(curv)) if curv.size else np.nan,
        **_ten_point(zc, t, hills, dales, exclude_edge),
        "Spd": float(hk.sum()) / area,
        "Shv": float(np.mean(hills.volume_mm3[hk])) if hk.any() else np.nan,
    }


def ten_point_height(
    zc: np.ndarray,
    dx: float,
    dy: float,
    *,
    pruning_pct: float = PRUNING_PCT,
    pruning_reference: str = PRUNING_REFERENCES[0],
    exclude_edge: bool = False,
    sz: float | None = None,
) -> dict[str, float]:
    """S10z, S5p, S5v (mm) of mean-subtracted heights ``zc`` (mm) alone: the values of :func:`feature_parameters`,
    without the passes over the points for the hills' areas and volumes, nor the peaks' curvature."""
    t = pruning_threshold(zc, pruning_pct, pruning_reference, sz=sz)
    hills = segment(-zc, t, dx, dy, keep_peaks=not exclude_edge, measure=False, bases=False)
    dales = segment(zc, t, dx, dy, measure=False, bases=False) if exclude_edge else None
    return _ten_point(zc, t, hills, dales, exclude_edge)


def _ten_point(zc, t, hills: Segmentation, dales: Segmentation | None, exclude_edge: bool) -> dict[str, float]:
    """S10z = S5p + S5v (mm): the 5 highest significant peaks of ``hills`` and the 5 deepest significant pits (of
    ``dales``, or without it :func:`deepest_motifs` from the peaks of ``-zc``)."""
    peaks = -hills.critical[hills.select(exclude_edge)]  # heights, descending (critical ascending in -z)
    if dales is None:  # S5v reads the 5 deepest significant pits only: no whole segmentation of the dales
        pits = deepest_motifs(zc, t, 5, sinks=hills.peaks)  # the peaks of -zc: the sinks of zc
    else:
        pits = dales.critical[dales.select(exclude_edge)]  # ascending: deepest first
    s5p = float(np.mean(peaks[:5])) if peaks.size else np.nan
    s5v = float(-np.mean(pits[:5])) if pits.size else np.nan
    return {"S10z": s5p + s5v, "S5p": s5p, "S5v": s5v}


def motif_parameters(
    zc: np.ndarray,
    dx: float,
    dy: float,
    *,
    pruning_pct: float = PRUNING_PCT,
    pruning_reference: str = PRUNING_REFERENCES[0],
    exclude_edge: bool = False,
    hills: Segmentation | None = None,
    sz: float | None = None,
) -> dict[str, float]:
    """Our motif parameters (MountainsMap's are not public; no equivalence claimed).

    Motifs = the significant hills of the Wolf-pruned watershed segmentation with threshold
    ``motif_threshold`` = ``pruning_pct`` % of the reference height (mm). Per motif: area (mm^2), volume above
    its base (mm^3), height = peak - base (mm). Returns motif_count, motif_threshold (mm), motif_mean_volume
    (mm^3), motif_mean_height_surface_ratio (mean of height / area, mm/mm^2), motif_mean_area (mm^2). ``sz``:
    ``zc.max() - zc.min()`` when the caller has it (:func:`pruning_threshold`).
    """
    t = pruning_threshold(zc, pruning_pct, pruning_reference, sz=sz)
    if hills is None or hills.threshold_mm != t:
        hills = segment(-zc, t, dx, dy)
    k = hills.select(exclude_edge)
    height = hills.base[k] - hills.critical[k]
    area = hills.area_mm2[k]
    n = int(k.sum())
    return {
        "motif_count": float(n),
        "motif_threshold": t,
        "motif_mean_volume": float(np.mean(hills.volume_mm3[k])) if n else np.nan,
        "motif_mean_height_surface_ratio": float(np.mean(height / area)) if n else np.nan,
        "motif_mean_area": float(np.mean(area)) if n else np.nan,
    }
