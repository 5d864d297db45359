"""Line profiles as laser profilometers write them: plain text, a header block of any length, delimited columns.

Format accepted (docs/texture.md, "MPD of profiles"):

* UTF-8 (with or without BOM) or, when the file is not valid UTF-8, Latin-1 (so ``µm`` in a column name is read
  either way); LF or CRLF line ends. The block is sought in the first :data:`HEAD_LINES` lines (the whole file
  when they hold none); the rest of a long file is parsed by NumPy's C reader, cell by cell when that fails.
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
* Units: a unit stated in a column name is used: in brackets at the end (``Distance (m)``, ``Height [um]``,
  ``z (µm)``) or as a suffix after ``_`` or a space (``Distance_m``, ``height_mm``, ``x um``); the units are those
  of :data:`UNITS_MM` (m, cm, mm, um / µm / micron, nm, km, in, ft). ``distance_unit`` / ``height_unit``
  (``--distance-unit`` / ``--height-unit``) give the unit of a column whose name states none; one that contradicts
  the name is an error. Without either, mm. Every value is converted to mm.
* Plausibility, after conversion (an error names the column and the unit used): the median distance step must be
  0.005-10 mm (:data:`STEP_RANGE_MM`: distances in m read as mm give steps of um, in um read as mm steps of
  metres); the valid heights must span at least 0.01 mm between their 1st and 99th percentiles
  (:data:`MIN_HEIGHT_RANGE_MM`: heights in m read as mm, or one height everywhere) and their median step between
  neighbours must be at most 5 mm (:data:`MAX_MEDIAN_HEIGHT_STEP_MM`: heights in um read as mm).
* A height cell that is empty, ``NaN`` or not a number is a dropout. A distance cell must be a number and
  distances must increase strictly: otherwise :class:`~skidsim.errors.ProfileFormatError` names the file, the
  line, the column, what was expected and what was found.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

DELIMITERS = ("\t", ";", ",", None)  # None: runs of whitespace

#: length units a column name or an option may state -> mm per unit
UNITS_MM = {
    "km": 1e6,
    "m": 1e3,
    "cm": 10.0,
    "mm": 1.0,
    "um": 1e-3,
    "µm": 1e-3,  # micro sign
    "μm": 1e-3,  # Greek mu
    "micron": 1e-3,
    "microns": 1e-3,
    "micrometre": 1e-3,
    "micrometer": 1e-3,
    "micrometres": 1e-3,
    "micrometers": 1e-3,
    "nm": 1e-6,
    "in": 25.4,
    "inch": 25.4,
    "ft": 304.8,
}
#: units a name may state as a suffix (``distance_m``); the others only in brackets (``Depth (in)``)
_SUFFIX_UNITS = ("km", "m", "cm", "mm", "um", "µm", "μm", "nm", "microns")
#: lines read to find the numeric block; a longer header makes the reader read the whole file as text
HEAD_LINES = 5000
#: plausible median distance step (mm) of a texture profile: below, distances are in m or km; above, in um
STEP_RANGE_MM = (0.005, 10.0)
#: smallest spread (mm, 1st to 99th percentile) of the valid heights of a pavement profile (heights in m: um)
MIN_HEIGHT_RANGE_MM = 0.01
#: largest median height step (mm) between neighbouring samples of a texture profile (heights in um: 1000 x)
MAX_MEDIAN_HEIGHT_STEP_MM = 5.0
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
    ``columns``: the names (or indices) of the two columns used; ``header``: the lines above the numeric block;
    ``units``: the units the file's numbers were read in (distance, height; keys of :data:`UNITS_MM`) and
    ``unit_sources``: where each came from (``"column name"``, ``"option"`` or ``"default"``)."""

    distance_mm: np.ndarray
    height_mm: np.ndarray
    path: str
    columns: tuple[str, str]
    header: tuple[str, ...]
    units: tuple[str, str] = ("mm", "mm")
    unit_sources: tuple[str, str] = ("default", "default")

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


def _find_block(lines: list[str]) -> tuple[str | None, tuple[int, int]] | None:
    """The numeric block's core: the first line with >= 2 numbers followed by 4 non-empty lines of as many fields
    each holding a number (dropout rows hold one), for the first delimiter of :data:`DELIMITERS` that gives one at
    that line: ``(delimiter, (line index, field count))`` or None. Reads only as far as the block's start."""
    nonempty = (i for i, ln in enumerate(lines) if ln.strip())
    window = list(itertools.islice(nonempty, 5))
    while window:
        i = window[0]
        for delim in DELIMITERS:
            f = _split(lines[i], delim)
            if not _numeric(f, delim):
                continue
            run = [_split(lines[j], delim) for j in window[1:]]
            if all(len(r) == len(f) and any(_number(c, delim) is not None for c in r) for r in run):
                return delim, (i, len(f))
        window.pop(0)
        nxt = next(nonempty, None)
        if nxt is not None:
            window.append(nxt)
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


_BRACKET = re.compile(r"[\(\[]\s*([^\)\]]*?)\s*[\)\]]\s*:?\s*$")


def _norm_unit(text: str) -> str | None:
    u = text.strip().lower()
    return u if u in UNITS_MM else None


def column_unit(name: str) -> str | None:
    """The length unit a column name states (a key of :data:`UNITS_MM`), or None: in brackets at the end
    (``Distance (m)``, ``Height [um]``) or as a suffix after ``_`` or a space (``Distance_m``, ``height mm``)."""
    n = str(name).strip().strip(":").strip()
    m = _BRACKET.search(n)
    if m:
        return _norm_unit(m.group(1))
    parts = re.split(r"[_\s]+", n)
    if len(parts) > 1:
        u = _norm_unit(parts[-1])
        if u in _SUFFIX_UNITS:
            return u
    return None


def _resolve_unit(path, column: str, named: str | None, option: str | None, role: str) -> tuple[str, str]:
    """(unit, source) of one column: the name's unit, the option's, or mm; an option contradicting the name or
    an unknown option raises."""
    if option is not None:
        opt = _norm_unit(option)
        if opt is None:
            raise _error(path, f"a {role} unit, one of {', '.join(UNITS_MM)}", got=option)
        if named is not None and UNITS_MM[named] != UNITS_MM[opt]:
            raise _error(
                path,
                f"the {role} unit its name states ({named}), or no --{role}-unit",
                column=column,
                got=f"--{role}-unit {option}",
            )
        return opt, "option"
    if named is not None:
        return named, "column name"
    return "mm", "default"


def _check_plausible(path, x: np.ndarray, z: np.ndarray, names: tuple[str, str], units, sources) -> None:
    """The plausibility rules of the module docstring, on values already in mm."""
    how = [f"read in {u} ({'the column name' if s == 'column name' else s})" for u, s in zip(units, sources)]
    hint = "state the unit in the column name, e.g. 'Distance (m)', or with --{}-unit"
    if len(x) > 1:
        step = float(np.median(np.diff(x)))
        lo, hi = STEP_RANGE_MM
        if not lo <= step <= hi:
            raise _error(
                path,
                f"a median distance step of {lo:g} to {hi:g} mm, as texture profilers sample "
                f"(distances {how[0]}; {hint.format('distance')})",
                column=names[0],
                got=f"{step:.3g} mm",
            )
    ok = z[np.isfinite(z)]
    if ok.size == 0:
        raise _error(path, "at least one valid height", column=names[1], got="no number in the column")
    if ok.size < 2:
        return
    p1, p99 = np.percentile(ok, [1, 99])
    if p99 - p1 < MIN_HEIGHT_RANGE_MM:
        raise _error(
            path,
            f"heights spanning at least {MIN_HEIGHT_RANGE_MM:g} mm between their 1st and 99th percentiles, as a "
            f"pavement profile does (heights {how[1]}; one height everywhere or heights in m; "
            f"{hint.format('height')})",
            column=names[1],
            got=f"{p99 - p1:.3g} mm",
        )
    dz = np.abs(np.diff(z))
    dz = dz[np.isfinite(dz)]
    if dz.size and float(np.median(dz)) > MAX_MEDIAN_HEIGHT_STEP_MM:
        raise _error(
            path,
            f"a median height step between neighbouring samples of at most {MAX_MEDIAN_HEIGHT_STEP_MM:g} mm, as a "
            f"texture profile has (heights {how[1]}; heights in um read as mm are 1000 times too large; "
            f"{hint.format('height')})",
            column=names[1],
            got=f"{float(np.median(dz)):.3g} mm",
        )


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


def _encoding(path: Path) -> str:
    """``utf-8-sig`` when the first MB of the file is UTF-8 (a character cut at its end allowed), else ``latin-1``."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 20)
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as e:
        if e.start < len(head) - 3:
            return "latin-1"
    return "utf-8-sig"


def _all_lines(path: Path) -> list[str]:
    return path.read_text(encoding=_encoding(path), errors="replace").lstrip("\ufeff").splitlines()


def _fast_block(rows, delim: str | None, di: int, hi: int):
    """The numeric block (``rows``: its lines, or the open file at its first line) parsed by NumPy's C reader
    (long runs: 10^6 lines in about a second), or None when it does not parse as plain numbers (decimal commas,
    non-numeric cells, missing cells, non-finite distances): then :func:`_slow_block` reads it cell by cell and
    names the first bad cell."""
    try:
        a = np.loadtxt(rows, delimiter=delim, usecols=(di, hi), ndmin=2, comments=None, quotechar='"', dtype=np.float64)
    except ValueError:
        return None
    x, z = a[:, 0].copy(), a[:, 1].copy()
    if not np.isfinite(x).all():
        return None
    z[~np.isfinite(z)] = np.nan
    return x, z


def _slow_block(lines: list[str], start: int, delim: str | None, di: int, hi: int, path, dname: str):
    """The numeric block cell by cell (decimal commas, dropout cells of any text); a distance that is not a number
    raises naming the line and the column."""
    dist, height = [], []
    for i in range(start, len(lines)):
        if not lines[i].strip():
            continue
        f = _split(lines[i], delim)
        d = _number(f[di], delim) if di < len(f) else None
        if d is None:
            raise _error(
                path,
                "a number (distance)",
                line=i + 1,
                column=dname,
                got=f[di] if di < len(f) else "(missing cell)",
            )
        h = _number(f[hi], delim) if hi < len(f) else None
        dist.append(d)
        height.append(np.nan if h is None else h)
    return np.asarray(dist, dtype=np.float64), np.asarray(height, dtype=np.float64)


def read_profile(
    path: str | Path,
    *,
    distance_col: str | int | None = None,
    height_col: str | int | None = None,
    distance_unit: str | None = None,
    height_unit: str | None = None,
) -> Profile:
    """Read a text profile (module docstring), distances and heights converted to mm. Raises
    :class:`ProfileFormatError` on a file without a numeric block, an unknown column, a non-numeric distance,
    distances that do not increase, a unit option that contradicts the column name, or values implausible for a
    texture profile in the unit used."""
    path = Path(path)
    encoding = _encoding(path)
    with open(path, encoding=encoding, errors="replace", newline=None) as fh:
        lines = [ln.rstrip("\n") for ln in itertools.islice(fh, HEAD_LINES)]
    whole = len(lines) < HEAD_LINES
    found = _find_block(lines)
    if not whole and (found is None or found[1][0] > HEAD_LINES - 20):
        lines, whole = _all_lines(path), True  # a header longer than the head read: look again in the whole file
        found = _find_block(lines)
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
    du, dsrc = _resolve_unit(path, dname, column_unit(dname) if names else None, distance_unit, "distance")
    hu, hsrc = _resolve_unit(path, hname, column_unit(hname) if names else None, height_unit, "height")
    header = tuple(lines[:start])
    if whole:
        fast = _fast_block(lines[start:], delim, di, hi)
    else:  # long runs: NumPy reads the rest of the file itself, no list of lines is built
        with open(path, encoding=encoding, errors="replace", newline=None) as fh:
            for _ in range(start):
                next(fh)
            fast = _fast_block(fh, delim, di, hi)
    if fast is None and not whole:
        lines, whole = _all_lines(path), True
    x, z = fast if fast is not None else _slow_block(lines, start, delim, di, hi, path, dname)
    bad = np.flatnonzero(np.diff(x) <= 0)
    if bad.size:
        k = bad[0] + 1
        if not whole:
            lines = _all_lines(path)
        line_no = [i for i in range(start, len(lines)) if lines[i].strip()][k] + 1
        raise _error(
            path, f"distances increasing strictly (previous {x[k - 1]:g} {du})", line=line_no, column=dname, got=x[k]
        )
    x = x * UNITS_MM[du] if du != "mm" else x
    z = z * UNITS_MM[hu] if hu != "mm" else z
    _check_plausible(path, x, z, (dname, hname), (du, hu), (dsrc, hsrc))
    return Profile(
        distance_mm=x,
        height_mm=z,
        path=str(path),
        columns=(dname, hname),
        header=header,
        units=(du, hu),
        unit_sources=(dsrc, hsrc),
    )
