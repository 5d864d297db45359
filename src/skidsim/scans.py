"""One entry point for scan files: :func:`read_scan` dispatches on the file suffix.

* ``.x3p`` -> :func:`skidsim.x3p.read_x3p` (ISO 25178-72; metres in the file, mm in the Surface);
* ``.csv``, ``.txt``, ``.xyz`` -> :func:`skidsim.gridtext.read_grid_text`;
* any other suffix -> the optional SurfaceTopography adapter (``pip install SurfaceTopography``, the
  ``formats`` extra), imported lazily. SurfaceTopography arrays are ``(nx, ny)`` = (x, y): they are
  transposed to the Surface layout ``(rows = y, cols = x)``; its unit (m, mm, um/µm, nm) is converted to mm.

Between workflow rules, named surfaces travel in one ``.npz`` (:func:`save_surfaces` / :func:`load_surfaces`:
heights in mm, float64, with their spacings in mm).
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from skidsim.atomic import atomic_path
from skidsim.errors import ScanFormatError
from skidsim.gridtext import read_grid_text
from skidsim.surface import Surface
from skidsim.x3p import read_x3p, read_x3p_header

TEXT_SUFFIXES = (".csv", ".txt", ".xyz")
NATIVE_SUFFIXES = (".x3p",) + TEXT_SUFFIXES
UNIT_TO_MM = {"m": 1e3, "mm": 1.0, "um": 1e-3, "µm": 1e-3, "μm": 1e-3, "nm": 1e-6}


def read_scan(path) -> Surface:
    """Read any supported scan file into a :class:`Surface` (heights mm, NaN invalid, rows = y, cols = x).

    Raises :class:`ScanFormatError` naming the file for a missing file, a corrupt file, or an unknown suffix
    when SurfaceTopography is not installed.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".x3p":
        return read_x3p(path)
    if suffix in TEXT_SUFFIXES:
        return read_grid_text(path)
    if not path.is_file():
        raise ScanFormatError(path, "an existing scan file", got="no such file")
    return read_with_surfacetopography(path)


def check_scan(path, level: str = "header") -> tuple[int, int]:
    """Check a scan file and return its ``(rows, cols)``; :class:`ScanFormatError` when it cannot be read.

    ``level="header"``: for X3P open the archive and check the main.xml checksum, the header and the data
    sizes without decoding the heights (:func:`skidsim.x3p.read_x3p_header`); other formats are read in full
    (text grids have no separate header). ``level="full"``: read every file completely (X3P: also the MD5 of
    data.bin).
    """
    if level not in ("header", "full"):
        raise ValueError(f"level must be 'header' or 'full', got {level!r}")
    path = Path(path)
    if level == "header" and path.suffix.lower() == ".x3p":
        return read_x3p_header(path).shape
    return read_scan(path).shape


def read_with_surfacetopography(path, module: str = "SurfaceTopography") -> Surface:
    """Read an instrument format through SurfaceTopography (optional dependency, imported here, lazily).

    ``module`` is the import name (tests substitute a stand-in). 2-D uniform topographies only.
    """
    path = Path(path)
    try:
        st = importlib.import_module(module)
    except ImportError:
        raise ScanFormatError(
            path,
            f"a file of a native format ({', '.join(NATIVE_SUFFIXES)})",
            got=path.suffix or "no suffix",
            hint="other instrument formats need the optional package SurfaceTopography: "
            "pip install SurfaceTopography (extra 'formats')",
        ) from None
    try:
        topo = st.read_topography(str(path))
    except Exception as exc:  # the reader raises many types for files it cannot read
        raise ScanFormatError(path, "a file SurfaceTopography can read", got=f"{type(exc).__name__}: {exc}") from None
    if getattr(topo, "dim", 2) != 2:
        raise ScanFormatError(path, "an areal (2-D) topography", got=f"dim {topo.dim}")
    unit = getattr(topo, "unit", None)
    if unit not in UNIT_TO_MM:
        raise ScanFormatError(path, f"a length unit among {sorted(UNIT_TO_MM)}", column="unit", got=unit)
    scale = UNIT_TO_MM[unit]
    h = topo.heights()  # (nx, ny)
    if isinstance(h, np.ma.MaskedArray):
        h = h.astype(np.float64).filled(np.nan)
    h = np.asarray(h, dtype=np.float64).T * scale  # -> (ny, nx) = (rows, cols)
    nx, ny = topo.nb_grid_pts
    sx, sy = topo.physical_sizes
    return Surface(
        np.ascontiguousarray(h),
        dx=sx / nx * scale,
        dy=sy / ny * scale,
        name=path.stem,
        meta={"source_format": "SurfaceTopography", "source_unit": unit},
    )


def save_surfaces(path: str | Path, surfaces: dict[str, Surface]) -> None:
    """Store named surfaces (heights in mm, float64) with their spacings (mm) in one ``.npz``, atomically."""
    arrays = {}
    for name, s in surfaces.items():
        arrays[f"{name}__heights_mm"] = s.heights
        arrays[f"{name}__spacing_mm"] = np.array([s.dx, s.dy])
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)


def load_surfaces(path: str | Path, names: Sequence[str] | None = None) -> dict[str, Surface]:
    """Inverse of :func:`save_surfaces`: ``{name: Surface}`` (heights mm, spacings mm); ``names``: only these
    (each array of the file is read on access, so the others cost nothing), a missing one raises KeyError."""
    out = {}
    with np.load(path) as z:
        stored = sorted({k.split("__")[0] for k in z.files})
        if names is not None:
            missing = [n for n in names if n not in stored]
            if missing:
                raise KeyError(f"{path}: no surface {', '.join(map(repr, missing))} (stored: {', '.join(stored)})")
        for n in stored if names is None else names:
            dx, dy = z[f"{n}__spacing_mm"]
            out[n] = Surface(z[f"{n}__heights_mm"], float(dx), float(dy), name=n)
    return out
