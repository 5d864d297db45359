"""Despeckling (the study's "limiting filter") per profile frame, and robust variants.

A *profile frame* is one scan line: by default one row of the scan (a line along x), i.e. the statistics are
taken along ``axis=1``. Three rules (``docs/texture.md`` has the comparison figure):

* ``"study"``, literal as the study writes it: per frame the first quartile Q1 and third quartile Q3; a value
  above ``k * Q3`` is set to Q3, a value below ``k * Q1`` is set to Q1 (k = 1.5). The fences scale with the
  *value* of the quartiles, not with their spread, so the rule depends on where zero is: on heights that cross
  zero or sit far from it (range data), it replaces large shares of genuine points or none at all.
* ``"tukey"``: Tukey fences ``Q1 - k IQR`` and ``Q3 + k IQR`` (k = 1.5); invariant to offsets and scale of the
  heights, but on negatively skewed pavement profiles the lower fence cuts into genuine deep voids.
* ``"mad"`` (default): fences ``median -+ k * 1.4826 * MAD`` (k = 3.5: the Iglewicz-Hoaglin modified z-score,
  about 3.5 standard deviations for normal heights); offset and scale invariant, and wide enough to leave the
  voids of a skewed profile alone (docs/texture.md, figure texture-despeckle.png).

Replacement: ``"study"`` replaces by Q1/Q3 as written; ``"tukey"`` and ``"mad"`` by default mark the outliers
invalid and re-interpolate them linearly along the frame (``replace="interpolate"``), so a spike does not
become a plateau at the fence; ``replace="clip"`` sets them to the fence, ``replace="quartile"`` to Q1/Q3.
Quartiles use NumPy's default (linear) definition and ignore invalid points; invalid points stay invalid.
"""

from __future__ import annotations

import numpy as np

from skidsim.surface import Surface

from .filters import _interp_rows

METHODS = ("tukey", "study", "mad")
REPLACE = ("interpolate", "clip", "quartile")
_DEFAULT_K = {"study": 1.5, "tukey": 1.5, "mad": 3.5}
_MAD_SCALE = 1.4826


def despeckle_fences(heights: np.ndarray, method: str = "mad", k: float | None = None,
                     axis: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame ``(low_fence, high_fence, low_replacement, high_replacement)`` (mm), shaped to broadcast
    against ``heights`` along ``axis``. Replacements are the quartiles Q1, Q3."""
    if method not in METHODS:
        raise ValueError(f"despeckle: method must be one of {METHODS}, got {method!r}")
    k = _DEFAULT_K[method] if k is None else float(k)
    if not k > 0:
        raise ValueError(f"despeckle: k must be > 0, got {k}")
    has_nan = np.isnan(heights).any()
    pct = np.nanpercentile if has_nan else np.percentile
    q1, med, q3 = pct(heights, [25.0, 50.0, 75.0], axis=axis, keepdims=True)  # one partition pass
    if method == "study":
        lo, hi = k * q1, k * q3
    elif method == "tukey":
        iqr = q3 - q1
        lo, hi = q1 - k * iqr, q3 + k * iqr
    else:
        med_fn = np.nanmedian if has_nan else np.median
        mad = med_fn(np.abs(heights - med), axis=axis, keepdims=True)
        lo, hi = med - k * _MAD_SCALE * mad, med + k * _MAD_SCALE * mad
    return lo, hi, q1, q3


def despeckle(surface: Surface, method: str = "mad", k: float | None = None, axis: int = 1,
              replace: str | None = None) -> tuple[Surface, int]:
    """Despeckle every profile frame; returns ``(new Surface, number of replaced points)``.

    Parameters
    ----------
    surface:
        Heights in mm, NaN = invalid (left invalid).
    method:
        ``"mad"`` (default), ``"tukey"`` or ``"study"`` (literal limiting filter); see the module docstring.
    k:
        Fence factor; default 1.5 for ``study`` and ``tukey``, 3.5 for ``mad``.
    axis:
        Axis along which a frame runs: 1 = rows are frames (lines along x, default), 0 = columns.
    replace:
        ``"interpolate"`` (default for tukey/mad), ``"quartile"`` (default for study: above -> Q3,
        below -> Q1), or ``"clip"`` (to the fence).
    """
    if axis not in (0, 1):
        raise ValueError(f"despeckle: axis must be 0 or 1, got {axis!r}")
    replace = ("quartile" if method == "study" else "interpolate") if replace is None else replace
    if replace not in REPLACE:
        raise ValueError(f"despeckle: replace must be one of {REPLACE}, got {replace!r}")
    h = surface.heights
    lo, hi, q1, q3 = despeckle_fences(h, method, k, axis)
    with np.errstate(invalid="ignore"):
        high = h > hi
        low = h < lo
    n = int(high.sum() + low.sum())
    if n == 0:
        return surface, 0
    out = np.array(h, dtype=np.float64)
    if replace == "quartile":
        np.copyto(out, np.broadcast_to(q3, h.shape), where=high)
        np.copyto(out, np.broadcast_to(q1, h.shape), where=low)
    elif replace == "clip":
        np.copyto(out, np.broadcast_to(hi, h.shape), where=high)
        np.copyto(out, np.broadcast_to(lo, h.shape), where=low)
    else:
        was_nan = np.isnan(out)
        out[high | low] = np.nan
        view = out if axis == 1 else out.T
        _interp_rows(view, "linear")
        out[was_nan] = np.nan
    return surface.with_heights(out), n
