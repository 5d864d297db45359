"""Line profiles as laser profilometers write them: plain text, a header block of any length, delimited columns.

Format accepted (docs/texture.md, "MPD of profiles"):

* Any text encoding that is ASCII-compatible (UTF-8, Latin-1); LF or CRLF line ends.
* A header block of any length (free text, key/value lines), then the **numeric block**: it is found at the first
  line with >= 2 numbers followed by 4 lines of as many fields, each holding a number, and extends upwards over
  rows of as many fields whose distance cell is a number (a first row with a dropout). The non-empty line just
  above it, if it has as many fields and is not numeric, names the columns.
* Delimiter sniffed on the numeric block: tab, semicolon, comma, or whitespace (runs of spaces), preferred in that
  order when several fit from the same line. With a delimiter other than the comma, a decimal comma (``0,125``) is
  read as a decimal point.
* Cells may be quoted (``"0.5"``). Columns chosen by name (case-insensitive, a name equal to or starting with the
  one given) or by 0-based index.
  Without a choice: the columns named like a distance (``distance``, ``dist``, ``position``, ``x``) and a height
  (``height``, ``depth``, ``z``, ``elevation``, ``profile``); with no names, a two-column file is (distance,
  height).
* Distance and height in mm. A height cell that is empty, ``NaN`` or not a number is a dropout. A distance cell
  must be a number and distances must increase strictly: otherwise :class:`~skidsim.errors.ProfileFormatError`
  names the file, the line, the column, what was expected and what was found.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

DELIMITERS = ("\t", ";", ",", None)  # None: runs of whitespace
_DISTANCE_NAMES = ("distance", "dist", "position", "pos", "x")
_HEIGHT_NAMES = ("height", "depth", "z", "elevation", "profile", "relative_height", "h")
_UNIT = re.compile(r"\s*[\(\[].*?[\)\]]\s*$")


class ProfileFormatError(InputError):
    """A profile text file that cannot be read: no numeric block, bad column, bad distance. The message reads
    ``<file>: line <n>, column '<name>': expected ..., got ...`` (line numbers from 1)."""


def _error(
    path, expected: str, *, line: int | None = None, column: str | None = None, got: object = None
) -> ProfileFormatError:
    where = [f"line {line}"] if line is not None else []
    where += [f"column '{column}'"] if column is not None else []
    return ProfileFormatError(
        f"{path}: {', '.join(where)}" if where else path,
        expected,
        got=got.item() if isinstance(got, np.generic) else got,
    )


@dataclass(frozen=True)
class Profile:
    """One line profile: ``distance_mm`` (strictly increasing) and ``height_mm`` (NaN: dropout), from ``path``;
    ``columns``: the names (or indices) of the two columns used; ``header``: the lines above the numeric block."""

    distance_mm: np.ndarray
    height_mm: np.ndarray
    path: str
    columns: tuple[str, str]
    header: tuple[str, ...]

    @property
    def n_dropouts(self) -> int:
        """Number of samples without a valid height."""
        return int(np.isnan(self.height_mm).sum())


def _split(line: str, delim: str | None) -> list[str]:
    return [c.strip().strip('"').strip() for c in (line.split() if delim is None else line.split(delim))]


def _number(cell: str, delim: str | None = None) -> float | None:
    if delim != "," and "," in cell:
        cell = cell.replace(",", ".", 1) if cell.count(",") == 1 and "." not in cell else cell
    try:
        v = float(cell)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def _numeric(fields: list[str], delim: str | None) -> bool:
    return len(fields) >= 2 and sum(_number(c, delim) is not None for c in fields) >= 2


def _block_core(lines: list[str], delim: str | None) -> tuple[int, int] | None:
    """First line with >= 2 numbers followed by 4 lines of as many fields each holding a number (dropout rows
    hold one): ``(line index, field count)`` or None."""
    idx = [i for i, ln in enumerate(lines) if ln.strip()]
    for pos, i in enumerate(idx):
        f = _split(lines[i], delim)
        if not _numeric(f, delim):
            continue
        run = [_split(lines[j], delim) for j in idx[pos + 1 : pos + 5]]
        if all(len(r) == len(f) and any(_number(c, delim) is not None for c in r) for r in run):
            return i, len(f)
    return None


def _walk_back(lines: list[str], core: int, delim: str | None, n_fields: int, col: int) -> int:
    """Extend the block upwards over rows of as many fields whose column ``col`` is a number."""
    start = core
    for i in range(core - 1, -1, -1):
        if not lines[i].strip():
            continue
        f = _split(lines[i], delim)
        if len(f) != n_fields or _number(f[col], delim) is None:
            break
        start = i
    return start


def _names(lines: list[str], start: int, delim: str | None, n_fields: int) -> list[str] | None:
    above = [ln for ln in lines[:start] if ln.strip()]
    if not above:
        return None
    f = _split(above[-1], delim)
    if len(f) != n_fields or _numeric(f, delim):
        return None
    return f


def _clean(name: str) -> str:
    return _UNIT.sub("", name).strip().strip(":").strip().lower()


def _pick(
    spec: str | int | None, names: list[str] | None, n_fields: int, defaults: tuple[str, ...], role: str, path: str
) -> int:
    if spec is not None and (isinstance(spec, int) or str(spec).lstrip("-").isdigit()):
        i = int(spec)
        if not 0 <= i < n_fields:
            raise _error(path, f"a {role} column index in 0..{n_fields - 1}", got=i)
        return i
    if spec is not None:
        if not names:
            raise _error(
                path,
                f"a header line naming the columns (to find {role} column {spec!r}); "
                "or give the column's 0-based index",
                got="no column names",
            )
        want = str(spec).strip().lower()
        for i, n in enumerate(names):
            if n.lower() == want or _clean(n) == want:
                return i
        for i, n in enumerate(names):
            if n.lower().startswith(want):
                return i
        raise _error(path, f"a {role} column named {spec!r}", got=names)
    if names:
        clean = [_clean(n) for n in names]
        for d in defaults:
            for i, n in enumerate(clean):
                if n == d or n.startswith((d + " ", d + "_")):
                    return i
    if n_fields == 2:
        return 0 if role == "distance" else 1
    raise _error(
        path, f"the {role} column by name or 0-based index (--{role}-col)", got=names or f"{n_fields} unnamed columns"
    )


def read_profile(
    path: str | Path, *, distance_col: str | int | None = None, height_col: str | int | None = None
) -> Profile:
    """Read a text profile (module docstring). Raises :class:`ProfileFormatError` on a file without a numeric
    block, an unknown column, a non-numeric distance or distances that do not increase."""
    path = Path(path)
    text = path.read_bytes().decode("utf-8", errors="replace").lstrip("\ufeff")
    lines = text.splitlines()
    found = None
    for delim in DELIMITERS:
        hit = _block_core(lines, delim)
        if hit is not None and (found is None or hit[0] < found[1][0]):
            found = (delim, hit)
    if found is None:
        raise _error(
            path,
            "a numeric block: lines of >= 2 delimited fields (tab, ';', ',' or spaces), at least two of them numbers",
            got=f"{len(lines)} lines without one",
        )
    delim, (core, n_fields) = found
    names = _names(lines, core, delim, n_fields)
    di = _pick(distance_col, names, n_fields, _DISTANCE_NAMES, "distance", str(path))
    start = _walk_back(lines, core, delim, n_fields, di)
    if start < core:
        names = _names(lines, start, delim, n_fields)
    hi = _pick(height_col, names, n_fields, _HEIGHT_NAMES, "height", str(path))
    if di == hi:
        raise _error(path, "two different columns for distance and height", got=f"column {di} twice")
    dname = names[di] if names else str(di)
    hname = names[hi] if names else str(hi)
    dist, height = [], []
    for i in range(start, len(lines)):
        if not lines[i].strip():
            continue
        f = _split(lines[i], delim)
        d = _number(f[di], delim) if di < len(f) else None
        if d is None:
            raise _error(
                path,
                "a number (distance in mm)",
                line=i + 1,
                column=dname,
                got=f[di] if di < len(f) else "(missing cell)",
            )
        h = _number(f[hi], delim) if hi < len(f) else None
        dist.append(d)
        height.append(np.nan if h is None else h)
    x = np.asarray(dist)
    bad = np.flatnonzero(np.diff(x) <= 0)
    if bad.size:
        k = bad[0] + 1
        line_no = [i for i in range(start, len(lines)) if lines[i].strip()][k] + 1
        raise _error(
            path, f"distances increasing strictly (previous {x[k - 1]:g} mm)", line=line_no, column=dname, got=x[k]
        )
    return Profile(
        distance_mm=x, height_mm=np.asarray(height), path=str(path), columns=(dname, hname), header=tuple(lines[:start])
    )
