"""The FE pavement strip: a strip of the scan cut, smoothed, resampled and levelled into the rigid
:class:`~.heightfield.Heightfield`, and the ``mesh:`` options that set it (:class:`MeshOptions`).

The study (Section 3, Fig. 7) cut a 114.3 x 40 mm strip of the LS-40 scan, smoothed it "before meshing" and
meshed it at 0.5 mm as a rigid 114.3 x 40 x 8 mm body. :func:`pavement_strip` does the same, with every
choice explicit (see ``docs/reconstruction.md``):

1. **Position** (scan coordinates, mm; point ``(i, j)`` of the scan at ``x = j dx, y = i dy``): the strip's
   nodes span ``[x0, x0 + length] x [y0, y0 + width]``. Default: centred on the scan.
2. **Smoothing**: ISO 16610-61 Gaussian low-pass applied on the scan grid, cutoff wavelength ``smoothing``
   (mm; default ``"nyquist"`` = 2 x resolution, the shortest wavelength the FE grid can carry). It plays the
   role of the study's unspecified surface smoothing: it removes the sub-grid content that would alias into
   the 0.5 mm grid and the sharp angles that make contact normals jump.
3. **Resampling** by exact area averaging: each FE node gets the mean of the scan over the
   ``hx x hy`` box centred on it, the scan being piecewise constant on its pixels (pixel ``j`` covers
   ``[(j - 1/2) dx, (j + 1/2) dx]``). When the box is an integer number of pixels aligned with pixel edges
   this is exactly the block mean. Boxes of edge nodes are clipped to the scanned area.
   The node spacing is ``length / round(length / resolution)`` (0.49913 mm for 114.3 mm at 0.5 mm) so that
   the strip is exactly ``length`` long.
4. **Levelling** (default on): the least-squares mean plane of the resampled strip is removed, so ``z = 0``
   is the strip's mean plane and the surface has no tilt along the sliding direction. The solver places
   the slider relative to :attr:`Heightfield.max_height_m`.
5. **Units**: the :class:`Heightfield` is SI (metres), in the FE frame: node ``(i, j)`` at
   ``x = origin_x + j dx_m``, ``y = origin_y + i dy_m``, origin ``(0, 0)`` at the strip's first node
   (x = sliding direction). The scan position is kept in ``meta``.
6. **Solid**: the heightfield on top of a flat bottom at ``z_bottom_m = min(z) - base_depth`` (8 mm by
   default), so the solid is at least ``base_depth`` thick under the deepest valley.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, InputError
from ..options import section_items
from ..surface import Surface
from .heightfield import Heightfield
from .resample import _gaussian_reflect, gaussian_sigma_mm, remove_mean_plane, resample_area

#: the study's strip length (mm): the DFT slider's path, ``mesh.length_mm`` by default
STUDY_STRIP_LENGTH_MM = 114.3


@dataclass(frozen=True)
class MeshOptions:
    """The FE pavement strip and its exports (config keys under ``mesh:``).

    length_mm, width_mm: strip size in mm along x (the sliding direction) and y (the study's 114.3 x 40;
    ``length_mm="auto"``: see :func:`strip_length_mm`); x0_mm, y0_mm: strip origin on the scan in mm (None:
    centred); resolution_mm: node spacing of the rigid pavement in mm (area-averaged); smoothing: Gaussian cutoff
    in mm applied before resampling, ``"nyquist"`` (2 x resolution_mm) or None; base_depth_mm: solid below the
    lowest point in mm; gmsh_layers: hexahedral layers through the pavement of the gmsh .msh; inp_speed_kmh:
    sliding speed in km/h written into the dynamic CalculiX/ABAQUS decks.
    """

    length_mm: float | str = STUDY_STRIP_LENGTH_MM
    width_mm: float = 40.0
    x0_mm: float | None = None
    y0_mm: float | None = None
    resolution_mm: float = 0.5
    smoothing: float | str | None = "nyquist"
    base_depth_mm: float = 8.0
    gmsh_layers: int = 4
    inp_speed_kmh: float = 20.0

    def __post_init__(self) -> None:
        def bad(key, expected):
            raise ConfigError(f"mesh.{key}: expected {expected}, got {getattr(self, key)!r}")

        def positive(v):
            return isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0

        if not (self.length_mm == "auto" or positive(self.length_mm)):
            bad("length_mm", "a length > 0 mm or 'auto'")
        for key in ("width_mm", "resolution_mm", "base_depth_mm", "inp_speed_kmh"):
            if not positive(getattr(self, key)):
                bad(key, "a number > 0")
        for key in ("x0_mm", "y0_mm"):
            v = getattr(self, key)
            if v is not None and not (isinstance(v, (int, float)) and v >= 0):
                bad(key, "null (centred) or a coordinate >= 0 mm")
        if not (self.smoothing in ("nyquist", None) or positive(self.smoothing)):
            bad("smoothing", "'nyquist', null or a cutoff > 0 mm")
        if not (isinstance(self.gmsh_layers, int) and self.gmsh_layers >= 1):
            bad("gmsh_layers", "an integer >= 1")

    @classmethod
    def from_dict(cls, d: dict | None) -> MeshOptions:
        """From the ``mesh:`` config block; an unknown key raises :class:`ConfigError`."""
        d = section_items(cls, d, "mesh")
        return cls(**d)

    def strip_kwargs(self) -> dict:
        """Keyword arguments of :func:`pavement_strip` (the strip geometry, resolution and smoothing)."""
        return dict(
            length_mm=self.length_mm,
            width_mm=self.width_mm,
            x0_mm=self.x0_mm,
            y0_mm=self.y0_mm,
            resolution_mm=self.resolution_mm,
            smoothing=self.smoothing,
            base_depth_mm=self.base_depth_mm,
        )


def strip_length_mm(surface: Surface, length_mm: float | str, x0_mm: float | None = None) -> float:
    """The strip length in mm: ``length_mm`` itself, or for ``"auto"`` the scan's length along x from ``x0_mm``
    (the whole scan when None) up to the study's 114.3 mm."""
    if isinstance(length_mm, str):
        if length_mm != "auto":
            raise InputError(
                surface.name or "<surface>", "a strip length in mm or 'auto'", column="length_mm", got=length_mm
            )
        return min(STUDY_STRIP_LENGTH_MM, surface.width_mm - (x0_mm or 0.0))
    return float(length_mm)


def pavement_strip(
    surface: Surface,
    length_mm: float | str = MeshOptions.length_mm,
    width_mm: float = MeshOptions.width_mm,
    x0_mm: float | None = MeshOptions.x0_mm,
    y0_mm: float | None = MeshOptions.y0_mm,
    resolution_mm: float = MeshOptions.resolution_mm,
    smoothing: float | str | None = MeshOptions.smoothing,
    base_depth_mm: float = MeshOptions.base_depth_mm,
    level: bool = True,
) -> Heightfield:
    """Cut, smooth, resample and level a strip of ``surface`` into the FE :class:`Heightfield` (SI).

    Parameters
    ----------
    surface:
        Despeckled, gap-filled scan (heights mm, no NaN inside the strip and its smoothing margin).
    length_mm, width_mm:
        Strip size along x (sliding direction) and y, mm (study: 114.3 x 40). ``length_mm="auto"``: the scan's
        length (from ``x0_mm``, or all of it) up to 114.3 mm, so a scan a little shorter than the study's strip
        still gives a pavement (:func:`strip_length_mm`); the solver then shortens the slide to fit.
    x0_mm, y0_mm:
        Scan coordinates (mm, ``x = j dx``) of the strip's first node; ``None`` centres the strip.
    resolution_mm:
        Target node spacing (mm); the actual spacing is ``length / round(length / resolution)``.
    smoothing:
        ISO 16610-61 Gaussian cutoff wavelength in mm applied to the scan before resampling;
        ``"nyquist"`` (default) = ``2 * resolution_mm``; ``None`` or 0 = no smoothing.
    base_depth_mm:
        Thickness (mm) of solid under the lowest point: ``z_bottom = min(z) - base_depth``.
    level:
        Remove the least-squares mean plane of the strip (z = 0 is its mean plane). If False, heights keep
        the scan's datum.
    """
    where = surface.name or "<surface>"
    length_mm = strip_length_mm(surface, length_mm, x0_mm)
    for nm, v in (
        ("length_mm", length_mm),
        ("width_mm", width_mm),
        ("resolution_mm", resolution_mm),
        ("base_depth_mm", base_depth_mm),
    ):
        if not (np.isfinite(v) and v > 0):
            raise InputError(where, "a positive length in mm", column=nm, got=v)
    nx_cells = max(1, int(round(length_mm / resolution_mm)))
    ny_cells = max(1, int(round(width_mm / resolution_mm)))
    hx = length_mm / nx_cells
    hy = width_mm / ny_cells
    W, H = surface.width_mm, surface.height_mm
    if x0_mm is None:
        x0_mm = 0.5 * (W - length_mm)
    if y0_mm is None:
        y0_mm = 0.5 * (H - width_mm)
    tol = 1e-9 * max(W, H, 1.0)
    if x0_mm < -tol or x0_mm + length_mm > W + tol:
        hint = (
            f"the scan is {length_mm - W:.4g} mm shorter than the {length_mm:g} mm strip: give a longer scan, "
            "or length_mm='auto' for a strip of the scan's length"
            if length_mm > W + tol
            else None
        )
        raise InputError(
            where,
            f"a strip x range inside the scan's [0, {W:.4g}] mm",
            column="x0_mm",
            got=(round(x0_mm, 6), round(x0_mm + length_mm, 6)),
            hint=hint,
        )
    if y0_mm < -tol or y0_mm + width_mm > H + tol:
        raise InputError(
            where, f"a strip y range inside the scan's [0, {H:.4g}] mm", column="y0_mm", got=(y0_mm, y0_mm + width_mm)
        )
    if isinstance(smoothing, str):
        if smoothing != "nyquist":
            raise InputError(where, "smoothing 'nyquist', a cutoff in mm, or None", column="smoothing", got=smoothing)
        cutoff_mm = 2.0 * resolution_mm
    else:
        cutoff_mm = float(smoothing) if smoothing else 0.0
        if cutoff_mm < 0 or not np.isfinite(cutoff_mm):
            raise InputError(where, "a non-negative smoothing cutoff in mm", column="smoothing", got=smoothing)
    xn = x0_mm + hx * np.arange(nx_cells + 1)
    yn = y0_mm + hy * np.arange(ny_cells + 1)
    dx, dy = surface.dx, surface.dy
    sig = gaussian_sigma_mm(cutoff_mm) if cutoff_mm > 0 else 0.0
    # Source window: node boxes plus the Gaussian's 4-sigma support, within the scan.
    mx, my = 0.5 * hx + 4.0 * sig + dx, 0.5 * hy + 4.0 * sig + dy
    j0 = max(0, int(math.floor((xn[0] - mx) / dx)))
    j1 = min(surface.shape[1], int(math.ceil((xn[-1] + mx) / dx)) + 1)
    i0 = max(0, int(math.floor((yn[0] - my) / dy)))
    i1 = min(surface.shape[0], int(math.ceil((yn[-1] + my) / dy)) + 1)
    win = surface.heights[i0:i1, j0:j1]
    bad = ~np.isfinite(win)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise InputError(
            where,
            "finite heights in the strip (gap-fill the scan first)",
            column="heights",
            got=f"{int(bad.sum())} NaN, first at row {i0 + r}, col {j0 + c}",
        )
    if sig > 0:
        win = _gaussian_reflect(win, (sig / dy, sig / dx), truncate=4.0)
    z_mm = resample_area(win, dx, dy, xn - j0 * dx, yn - i0 * dy, hx, hy)
    xl = hx * np.arange(nx_cells + 1)
    yl = hy * np.arange(ny_cells + 1)
    plane = np.zeros(3)
    if level:
        z_mm, plane = remove_mean_plane(z_mm, xl, yl)
    z_m = z_mm * 1e-3
    meta = {
        "source": surface.name,
        "x0_mm": float(x0_mm),
        "y0_mm": float(y0_mm),
        "length_mm": float(length_mm),
        "width_mm": float(width_mm),
        "resolution_mm": float(resolution_mm),
        "dx_mm": hx,
        "dy_mm": hy,
        "smoothing_cutoff_mm": cutoff_mm,
        "smoothing_sigma_mm": sig,
        "smoothing_kernel": "ISO 16610-61 Gaussian",
        "resampling": "area average",
        "levelled": bool(level),
        "removed_plane_mm": {"a_mm": float(plane[0]), "b_mm_per_mm": float(plane[1]), "c_mm_per_mm": float(plane[2])},
        "base_depth_mm": float(base_depth_mm),
    }
    return Heightfield(
        z_m, hx * 1e-3, hy * 1e-3, (0.0, 0.0), float(z_m.min()) - base_depth_mm * 1e-3, surface.name, meta
    )
