"""The areal surface: a height map on a regular grid, the one data type every texture step passes on.

Conventions (they change numbers; see ``docs/data-contract.md``):

* ``heights`` is a float64 array of shape ``(rows, cols)`` in **millimetres**; ``NaN`` marks an invalid
  (dropout) point.
* Columns run along **x** (the sliding direction of the FE model, the scan's long axis: 2448 points for an
  LS-40 scan), rows along **y**. ``dx`` is the spacing between columns in mm, ``dy`` between rows in mm.
* Point ``(i, j)`` sits at ``x = j * dx``, ``y = i * dy`` (origin at the first point, not at a pixel corner).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


@dataclass(frozen=True)
class Surface:
    """A height map in mm on a regular grid.

    Attributes
    ----------
    heights:
        ``(rows, cols)`` float64 heights in mm, ``NaN`` where the instrument returned no valid point.
    dx:
        Spacing between columns (x direction) in mm.
    dy:
        Spacing between rows (y direction) in mm.
    name:
        Free-text identifier (site id, file name), for messages.
    meta:
        Free metadata read from or written to file formats (instrument, date, ...).
    """

    heights: np.ndarray
    dx: float
    dy: float
    name: str = ""
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        h = np.asarray(self.heights)
        if h.ndim != 2:
            raise ValueError(f"Surface {self.name!r}: heights must be 2-D (rows, cols), got shape {h.shape}")
        if not (np.isfinite(self.dx) and self.dx > 0 and np.isfinite(self.dy) and self.dy > 0):
            raise ValueError(f"Surface {self.name!r}: spacings dx, dy must be positive mm, got {self.dx}, {self.dy}")
        if h.dtype != np.float64:
            object.__setattr__(self, "heights", h.astype(np.float64))

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)``."""
        return self.heights.shape  # type: ignore[return-value]

    @property
    def width_mm(self) -> float:
        """Extent along x in mm, ``(cols - 1) * dx``."""
        return (self.shape[1] - 1) * self.dx

    @property
    def height_mm(self) -> float:
        """Extent along y in mm, ``(rows - 1) * dy``."""
        return (self.shape[0] - 1) * self.dy

    @property
    def valid(self) -> np.ndarray:
        """Boolean mask of valid (finite) points."""
        return np.isfinite(self.heights)

    @property
    def invalid_fraction(self) -> float:
        """Share of invalid points, 0..1."""
        return float(1.0 - self.valid.mean())

    def x_mm(self) -> np.ndarray:
        """Column coordinates in mm."""
        return np.arange(self.shape[1]) * self.dx

    def y_mm(self) -> np.ndarray:
        """Row coordinates in mm."""
        return np.arange(self.shape[0]) * self.dy

    def with_heights(self, heights: np.ndarray, **changes) -> Surface:
        """A copy with new heights (same grid) and optional other field changes."""
        return replace(self, heights=np.asarray(heights, dtype=np.float64), **changes)

    def crop(self, rows: slice, cols: slice) -> Surface:
        """A sub-surface (view copied) by row and column slices."""
        return self.with_heights(np.array(self.heights[rows, cols]))

    def crop_y_centred(self, extent_mm: float) -> Surface:
        """The centred band of rows spanning at most ``extent_mm`` (mm) along y; all columns kept.

        ``round(extent_mm / dy) + 1`` rows (capped at the scan), starting at ``(rows - n) // 2``; the band keeps
        the row spacing, so its y extent is ``(n - 1) * dy``. Used by the quick configuration (texture option
        ``crop_y_mm``) to work on part of each scan.
        """
        if not (np.isfinite(extent_mm) and extent_mm > 0):
            raise ValueError(f"Surface {self.name!r}: crop extent must be a positive number of mm, got {extent_mm}")
        n = min(self.shape[0], int(round(extent_mm / self.dy)) + 1)
        r0 = (self.shape[0] - n) // 2
        return self.crop(slice(r0, r0 + n), slice(None))
