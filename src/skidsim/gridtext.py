"""Plain-text height grids: ``.csv`` / ``.txt`` matrices and ``.xyz`` point lists, heights in mm.

Matrix files (``.csv`` comma-separated; ``.txt`` comma- or whitespace-separated, sniffed from the first data
line): one line per row (y), one value per column (x); row 0 is ``y = 0``. Leading lines starting with ``#``
are the header and carry ``key=value`` (or ``key: value``) tokens:

* ``dx_mm=0.05 dy_mm=0.05``: the grid spacings in mm (column step, row step);
* ``unit=mm`` (optional): the unit of the heights, ``mm`` (default), ``um`` or ``m`` (converted to mm).

Without spacings in the header a sidecar ``<name>.json`` next to the file must give ``{"dx_mm": .., "dy_mm":
..}`` (and optionally ``"unit"``); header and sidecar must agree when both exist. Empty cells and ``nan``
are invalid points (NaN).

``.xyz`` files: three columns ``x y z`` in mm (comma or whitespace separated, ``#`` comment lines ignored),
points of a regular grid in any order. The spacing is inferred (the median gap between distinct coordinates,
else the smallest gap, refined by least squares) and every coordinate must lie within 1 % of a spacing from a grid
line; grid positions without a point, and ``z`` = ``nan``, are invalid. The first grid line is the origin
(``Surface.meta["x0_mm"]``, ``["y0_mm"]``).
"""

from __future__ import annotations

import io
import json
import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from skidsim.atomic import write_bytes
from skidsim.errors import ScanFormatError
from skidsim.surface import Surface

if TYPE_CHECKING:
    import pandas as pd

UNIT_TO_MM = {"mm": 1.0, "um": 1e-3, "µm": 1e-3, "m": 1e3}
_TOKEN = re.compile(r"([A-Za-z_]+)\s*[=:]\s*([^\s,;]+)")
_NA = ["", "nan", "NaN", "NAN"]


def _header(lines: list[str]) -> tuple[dict, int]:
    keys, n = {}, 0
    for line in lines:
        if not line.startswith("#"):
            break
        n += 1
        for k, v in _TOKEN.findall(line):
            keys[k.lower()] = v
    return keys, n


def _spacing(path: Path, keys: dict) -> tuple[float, float, float]:
    """(dx_mm, dy_mm, height scale to mm) from the header and/or the sidecar json."""
    sidecar = path.with_suffix(".json")
    side = {}
    if sidecar.is_file():
        try:
            side = json.loads(sidecar.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ScanFormatError(sidecar, 'JSON {"dx_mm": .., "dy_mm": ..}', got=str(exc)) from None
        if not isinstance(side, dict):
            raise ScanFormatError(sidecar, 'a JSON object {"dx_mm": .., "dy_mm": ..}', got=type(side).__name__)
    out = []
    for key in ("dx_mm", "dy_mm"):
        val = None
        if key in keys:
            try:
                val = float(keys[key])
            except ValueError:
                raise ScanFormatError(path, "a number of mm", column=key, got=keys[key]) from None
        if key in side:
            try:
                sval = float(side[key])
            except (TypeError, ValueError):
                raise ScanFormatError(sidecar, "a number of mm", column=key, got=side[key]) from None
            if val is not None and not np.isclose(val, sval, rtol=1e-9, atol=0):
                raise ScanFormatError(
                    path, f"{key} in the header equal to the sidecar {sidecar.name}", column=key, got=f"{val} vs {sval}"
                )
            val = sval
        if val is None:
            raise ScanFormatError(
                path, f"{key} in a '# dx_mm=.. dy_mm=..' header line or in {sidecar.name}", column=key, got="missing"
            )
        if not (np.isfinite(val) and val > 0):
            raise ScanFormatError(path, "a positive spacing in mm", column=key, got=val)
        out.append(val)
    unit = str(side.get("unit", keys.get("unit", "mm")))
    if unit not in UNIT_TO_MM:
        raise ScanFormatError(path, f"a height unit among {sorted(UNIT_TO_MM)}", column="unit", got=unit)
    return out[0], out[1], UNIT_TO_MM[unit]


def _bad_cell(path, df: pd.DataFrame, first_row: int, expected="a number or an empty cell") -> None:
    """Raise for the first cell that is not numeric (row = file line number, column = 1-based index)."""
    import pandas as pd  # imported on use: most workflow steps never need it

    for j in range(df.shape[1]):
        col = df.iloc[:, j]
        if not pd.api.types.is_numeric_dtype(col):
            num = pd.to_numeric(col, errors="coerce")
            bad = np.flatnonzero(num.isna().to_numpy() & ~col.isna().to_numpy())
            if bad.size:
                i = int(bad[0])
                raise ScanFormatError(path, expected, row=first_row + i, column=str(j + 1), got=col.iloc[i])


def _read_matrix(path: Path, text: str) -> Surface:
    import pandas as pd  # imported on use: most workflow steps never need it

    lines = text.splitlines()
    keys, n_head = _header(lines)
    dx, dy, scale = _spacing(path, keys)
    body = lines[n_head:]
    while body and not body[-1].strip():
        body.pop()
    if not body:
        raise ScanFormatError(path, "at least one row of heights after the header", got="no data")
    first = body[0]
    delim = "," if ("," in first or path.suffix.lower() == ".csv") else None
    if delim == ",":
        counts = np.fromiter((ln.count(",") for ln in body), dtype=np.int64, count=len(body))
    else:
        counts = np.fromiter((len(ln.split()) for ln in body), dtype=np.int64, count=len(body))
    bad = np.flatnonzero(counts != counts[0])
    if bad.size:
        i = int(bad[0])
        nf = counts + (1 if delim == "," else 0)
        raise ScanFormatError(
            path, f"{nf[0]} values per row as in row {n_head + 1}", row=n_head + i + 1, got=f"{nf[i]} values"
        )
    buf = io.StringIO("\n".join(body))
    if delim == ",":
        df = pd.read_csv(buf, header=None, na_values=_NA, keep_default_na=False, skip_blank_lines=False)
    else:
        df = pd.read_csv(buf, header=None, sep=r"\s+", na_values=_NA, keep_default_na=False)
    _bad_cell(path, df, n_head + 1)
    h = df.to_numpy(dtype=np.float64)
    if scale != 1.0:
        h = h * scale
    return Surface(h, dx=dx, dy=dy, name=path.stem, meta={"x0_mm": 0.0, "y0_mm": 0.0})


def _grid_index(path, coord: np.ndarray, axis: str) -> tuple[np.ndarray, float, float]:
    """Integer grid index of each coordinate, spacing (mm) and origin (mm); error if irregular."""
    c0, c1 = float(coord.min()), float(coord.max())
    if c1 == c0:
        raise ScanFormatError(
            path, f"at least 2 distinct {axis} coordinates (a 2-D grid)", column=axis, got=f"all {axis} = {c0}"
        )
    u = np.unique(coord)
    gaps = np.diff(u)
    gaps = gaps[gaps > 1e-9 * max(abs(c0), abs(c1), c1 - c0)]
    first_error = None
    # the typical (median) gap first; the smallest gap when columns are missing in between
    for step in (float(np.median(gaps)), float(gaps.min())):
        try:
            return _fit_axis(path, coord, axis, step, c0)
        except ScanFormatError as exc:
            first_error = first_error or exc
    raise first_error


def _fit_axis(path, coord, axis, step, c0):
    idx = _grid_indices(path, coord, axis, step, c0)
    step = float(np.dot(idx, coord - c0) / np.dot(idx, idx))  # least-squares step through the origin c0
    idx = _grid_indices(path, coord, axis, step, c0)
    return idx.astype(np.int64), step, c0


def _grid_indices(path, coord, axis, step, c0) -> np.ndarray:
    """Grid index (float) of each coordinate for grid ``c0 + i * step``; error if one is off by > 1 % of a step."""
    idx = np.rint((coord - c0) / step)
    resid = np.abs(coord - c0 - idx * step)
    worst = int(np.argmax(resid))
    if resid[worst] > 0.01 * step:
        raise ScanFormatError(
            path,
            f"{axis} coordinates on a regular grid of step {step:g} mm (within 1 %)",
            column=axis,
            got=float(coord[worst]),
            hint=f"data point {worst + 1} is off the grid",
        )
    return idx


def _read_xyz(path: Path, text: str) -> Surface:
    import pandas as pd  # imported on use: most workflow steps never need it

    lines = text.splitlines()
    body_start = 0
    while body_start < len(lines) and (lines[body_start].startswith("#") or not lines[body_start].strip()):
        body_start += 1
    body = list(lines[body_start:])
    while body and not body[-1].strip():
        body.pop()
    if not body:
        raise ScanFormatError(path, "x y z lines (mm)", got="no data")
    delim = "," if "," in body[0] else None
    buf = io.StringIO("\n".join(body))
    kw = dict(header=None, na_values=_NA, keep_default_na=False, comment="#")
    try:
        df = pd.read_csv(buf, sep="," if delim else r"\s+", **kw)
    except pd.errors.ParserError as exc:
        raise ScanFormatError(path, "3 columns x y z on every line", got=str(exc).strip()) from None
    if df.shape[1] != 3:
        raise ScanFormatError(path, "3 columns x y z (mm)", got=f"{df.shape[1]} columns")
    _bad_cell(path, df, body_start + 1)
    arr = df.to_numpy(dtype=np.float64)
    x, y, z = arr[:, 0], arr[:, 1], arr[:, 2]
    for name, c in (("x", x), ("y", y)):
        if not np.all(np.isfinite(c)):
            i = int(np.flatnonzero(~np.isfinite(c))[0])
            raise ScanFormatError(
                path, f"a finite {name} coordinate (mm)", column=name, got=c[i], hint=f"data point {i + 1}"
            )
    j, dx, x0 = _grid_index(path, x, "x")
    i, dy, y0 = _grid_index(path, y, "y")
    rows, cols = int(i.max()) + 1, int(j.max()) + 1
    flat = i * cols + j
    counts = np.bincount(flat, minlength=rows * cols)
    if counts.max() > 1:
        k = int(np.flatnonzero(counts[flat] > 1)[0])
        raise ScanFormatError(
            path, "at most one point per grid position", got=f"duplicate x={x[k]} y={y[k]}", hint=f"data point {k + 1}"
        )
    h = np.full(rows * cols, np.nan)
    h[flat] = z
    return Surface(h.reshape(rows, cols), dx=dx, dy=dy, name=path.stem, meta={"x0_mm": x0, "y0_mm": y0})


def read_grid_text(path) -> Surface:
    """Read a ``.csv``/``.txt`` height matrix or an ``.xyz`` point list (mm) into a :class:`Surface`.

    Raises :class:`ScanFormatError` naming the file, the row (file line number) and the column for: a missing
    file, missing or non-positive spacing, header/sidecar disagreement, rows of unequal length, non-numeric
    cells, irregular or duplicate ``.xyz`` points.
    """
    path = Path(path)
    if not path.is_file():
        raise ScanFormatError(path, "an existing grid text file", got="no such file")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ScanFormatError(path, "a UTF-8 text file", got="binary data") from None
    suffix = path.suffix.lower()
    if suffix == ".xyz":
        return _read_xyz(path, text)
    if suffix in (".csv", ".txt"):
        return _read_matrix(path, text)
    raise ScanFormatError(path, "a .csv, .txt or .xyz file", got=suffix)


def write_grid_text(path, surface: Surface) -> None:
    """Write ``surface`` as text, atomically: ``.csv``/``.txt`` matrix with a ``# dx_mm= dy_mm=`` and
    ``# unit=mm`` header (invalid points as empty cells), or ``.xyz`` ``x y z`` lines (mm, invalid as ``nan``,
    coordinates ``x0_mm + j*dx``). Values are written with Python's shortest round-trip repr.
    """
    import pandas as pd  # imported on use: most workflow steps never need it

    path = Path(path)
    suffix = path.suffix.lower()
    h = np.asarray(surface.heights, dtype=np.float64)
    if suffix in (".csv", ".txt"):
        head = f"# dx_mm={surface.dx!r} dy_mm={surface.dy!r}\n# unit=mm\n"
        body = pd.DataFrame(h).to_csv(header=False, index=False, na_rep="", lineterminator="\n")
        payload = (head + body).encode("utf-8")
    elif suffix == ".xyz":
        x0 = float(surface.meta.get("x0_mm", 0.0))
        y0 = float(surface.meta.get("y0_mm", 0.0))
        yy, xx = np.meshgrid(y0 + surface.y_mm(), x0 + surface.x_mm(), indexing="ij")
        df = pd.DataFrame({"x": xx.ravel(), "y": yy.ravel(), "z": h.ravel()})
        payload = (
            "# x y z in mm\n" + df.to_csv(sep=" ", header=False, index=False, na_rep="nan", lineterminator="\n")
        ).encode("utf-8")
    else:
        raise ValueError(f"{path}: grid text suffix must be .csv, .txt or .xyz, got {suffix!r}")
    write_bytes(path, payload)
