"""X3P (ISO 25178-72, formerly ISO 5436-2 / openGPS) reader and writer for areal surfaces.

An X3P file is a zip archive with

* ``main.xml``: the header (Record1 axes, Record2 instrument metadata, Record3 matrix size and data links,
  Record4 name of the checksum file);
* ``bindata/data.bin``: the heights, little-endian, **x fastest** (a C-order ``(rows=y, cols=x)`` array, the
  layout of :class:`skidsim.surface.Surface`);
* ``bindata/valid.bin`` (optional): one bit per point, least-significant bit first, 1 = valid. It is the only
  way to mark invalid points for the integer types; float types use NaN;
* ``md5checksum.hex``: ``"<md5> *<member>"`` as ``md5sum`` writes it. The openGPS library and surfalize (and this
  writer) store the MD5 of main.xml (``"<md5> *main.xml"``); SurfaceTopography stores the MD5 of the point data
  (``"<MD5 IN UPPER CASE> *bindata/data.bin"``). The reader checks the member the file names (hex case ignored);
  a bare ``<md5>`` must match main.xml or bindata/data.bin. Only a checksum that matches none is an error.

Conventions that change numbers (see ``docs/data-contract.md``):

* All lengths in the file are in **metres** (increments, offsets, heights); :class:`Surface` is in **mm**.
  Increments and offsets are converted through :class:`decimal.Decimal`, so an increment written as 0.01 mm
  reads back as exactly ``0.01`` mm.
* Stored value ``v`` of axis CZ means height ``v * Increment + Offset`` (Increment 1, Offset 0 when absent).
  Data types: ``I`` int16, ``L`` int32, ``F`` float32, ``D`` float64.
* Float heights are converted m -> mm by one multiplication by 1000 (write: one division), so a ``D`` round
  trip is exact to 1 ulp, not bit-exact. Integer heights read as ``k * inc_mm + offset_mm``: a surface whose
  heights are ``k * 0.01`` mm round-trips bit-exactly with ``z_increment_mm=0.01`` (offset 0 when it fits).
* Only the matrix (grid) form of feature type ``SUR`` with incremental X/Y axes and SizeZ = 1 is supported.
"""

from __future__ import annotations

import hashlib
import zipfile
from dataclasses import dataclass, field
from datetime import UTC, datetime
from decimal import Decimal
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from skidsim.atomic import atomic_path
from skidsim.errors import ScanFormatError
from skidsim.surface import Surface

DTYPES = {"I": np.dtype("<i2"), "L": np.dtype("<i4"), "F": np.dtype("<f4"), "D": np.dtype("<f8")}
"""X3P data type code -> little-endian numpy dtype."""

NAMESPACE = "http://www.opengps.eu/2008/ISO5436_2"
XSI_NAMESPACE = "http://www.w3.org/2001/XMLSchema-instance"
MAIN_XML = "main.xml"
DATA_BIN = "bindata/data.bin"
VALID_BIN = "bindata/valid.bin"
CHECKSUM_FILE = "md5checksum.hex"
PROBING_TYPES = ("Contacting", "NonContacting", "Software")
RECORD2_KEYS = (
    "Date",
    "Creator",
    "InstrumentManufacturer",
    "InstrumentModel",
    "InstrumentSerial",
    "InstrumentVersion",
    "CalibrationDate",
    "ProbingSystemType",
    "ProbingSystemIdentification",
    "Comment",
)
"""Keys of ``Surface.meta`` / ``meta`` that map to Record2 (flattened element names)."""

_ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # fixed zip entry time: identical inputs give identical bytes


@dataclass(frozen=True)
class X3PHeader:
    """What ``main.xml`` says, checked against the archive (sizes, checksum) without decoding the heights.

    Lengths in mm (converted from the file's metres).
    """

    path: str
    size_x: int  # columns (x)
    size_y: int  # rows (y)
    dtype: str  # I, L, F or D
    dx_mm: float
    dy_mm: float
    z_increment_mm: float  # 1000 * CZ Increment (1000.0 when absent: raw values are metres)
    z_offset_mm: float
    x_offset_mm: float
    y_offset_mm: float
    point_data_link: str | None  # None when the points are stored as an XML DataList
    valid_points_link: str | None
    point_data_md5: str | None
    record2: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` = ``(SizeY, SizeX)``."""
        return (self.size_y, self.size_x)


def _err(path, expected, got=None, hint=None, column=None) -> ScanFormatError:
    return ScanFormatError(path, expected, got=got, hint=hint, column=column)


def _m_to_mm(text: str, path, what: str) -> float:
    try:
        return float(Decimal(text.strip()) * 1000)
    except Exception:  # decimal.InvalidOperation and friends
        raise _err(path, f"a number (metres) in {what}", got=text) from None


def _mm_to_m_text(value_mm: float) -> str:
    """Shortest decimal text of ``value_mm / 1000`` exact in decimal (no binary rounding)."""
    d = Decimal(repr(float(value_mm))) / 1000
    text = format(d.normalize(), "f") if d != 0 else "0"
    return text


def _strip_namespaces(root: ElementTree.Element) -> None:
    for el in root.iter():
        if isinstance(el.tag, str) and "}" in el.tag:
            el.tag = el.tag.split("}", 1)[1]


def _text(parent, tag, path, required=True, what=None):
    el = parent.find(tag) if parent is not None else None
    if el is None or el.text is None or not el.text.strip():
        if required:
            raise _err(path, f"element {what or tag} in main.xml")
        return None
    return el.text.strip()


def _flatten(element, prefix="") -> dict:
    out = {}
    for child in element:
        key = prefix + child.tag
        if len(child):
            out.update(_flatten(child, key))
        elif child.text and child.text.strip():
            out[key] = child.text.strip()
    return out


def _open_zip(path) -> zipfile.ZipFile:
    p = Path(path)
    if not p.is_file():
        raise _err(p, "an existing X3P file", got="no such file")
    try:
        return zipfile.ZipFile(p)
    except zipfile.BadZipFile:
        raise _err(p, "an X3P file (a zip archive with main.xml)", got="not a zip archive") from None


def _check_checksum(zf: zipfile.ZipFile, checksum_name: str, xml_bytes: bytes, path) -> None:
    """Verify the checksum file as its writer meant it (module docstring): ``<md5> *<member>`` (md5sum's binary
    mode; ``<md5>  <member>`` text mode) checks the member it names; a bare ``<md5>`` must match main.xml or the
    point data. Hex case is ignored. Raises when the named member is missing or no candidate matches."""
    text = zf.read(checksum_name).decode("ascii", "replace").strip()
    parts = text.split(None, 1)
    if not parts:
        raise _err(path, f"{checksum_name} holding an MD5 (of main.xml)", got="empty file")
    stated = parts[0].lower()
    named = parts[1].strip().lstrip("*").strip() if len(parts) > 1 else ""
    if named:
        if named not in zf.namelist():
            raise _err(path, f"{checksum_name} naming a member of the archive", got=named)
        candidates = {named: xml_bytes if named == MAIN_XML else zf.read(named)}
    else:
        candidates = {MAIN_XML: xml_bytes}
        if DATA_BIN in zf.namelist():
            candidates[DATA_BIN] = zf.read(DATA_BIN)
    actual = {name: hashlib.md5(data).hexdigest() for name, data in candidates.items()}
    if stated not in actual.values():
        want = " or ".join(f"the MD5 of {n} ({h})" for n, h in actual.items())
        raise _err(path, f"{checksum_name} holding {want}", got=parts[0], hint="a corrupt or altered archive")


def _parse_header(zf: zipfile.ZipFile, path) -> X3PHeader:
    names = set(zf.namelist())
    if MAIN_XML not in names:
        raise _err(path, "an X3P archive containing main.xml", got=f"members {sorted(names)[:5]}")
    xml_bytes = zf.read(MAIN_XML)
    try:
        root = ElementTree.fromstring(xml_bytes)
    except ElementTree.ParseError as exc:
        raise _err(path, "well-formed XML in main.xml", got=str(exc)) from None
    _strip_namespaces(root)

    # Record4: the checksum file (mandatory in ISO 25178-72); which member it covers: _check_checksum
    checksum_name = _text(root.find("Record4"), "ChecksumFile", path, required=False) or CHECKSUM_FILE
    if checksum_name not in names:
        raise _err(path, f"checksum file {checksum_name} holding the MD5 of main.xml", got="missing")
    _check_checksum(zf, checksum_name, xml_bytes, path)

    record1 = root.find("Record1")
    if record1 is None:
        raise _err(path, "element Record1 in main.xml")
    feature = _text(record1, "FeatureType", path, what="Record1/FeatureType")
    if feature != "SUR":
        raise _err(path, "FeatureType SUR (an areal surface)", got=feature, column="Record1/FeatureType")
    axes = record1.find("Axes")
    if axes is None:
        raise _err(path, "element Record1/Axes in main.xml")
    lateral = {}
    for name in ("CX", "CY"):
        ax = axes.find(name)
        if ax is None:
            raise _err(path, f"element Record1/Axes/{name} in main.xml")
        axis_type = _text(ax, "AxisType", path, what=f"{name}/AxisType")
        if axis_type != "I":
            raise _err(
                path,
                "AxisType I (incremental, a regular grid)",
                got=axis_type,
                column=f"Record1/Axes/{name}/AxisType",
                hint="absolute lateral axes are not supported",
            )
        inc = _m_to_mm(_text(ax, "Increment", path, what=f"{name}/Increment"), path, f"{name}/Increment")
        if not (np.isfinite(inc) and inc > 0):
            raise _err(path, "a positive increment", got=inc, column=f"Record1/Axes/{name}/Increment")
        off_text = _text(ax, "Offset", path, required=False)
        lateral[name] = (inc, 0.0 if off_text is None else _m_to_mm(off_text, path, f"{name}/Offset"))
    cz = axes.find("CZ")
    if cz is None:
        raise _err(path, "element Record1/Axes/CZ in main.xml")
    z_type = _text(cz, "AxisType", path, what="CZ/AxisType")
    if z_type != "A":
        raise _err(path, "AxisType A (absolute) for CZ", got=z_type, column="Record1/Axes/CZ/AxisType")
    dtype = _text(cz, "DataType", path, what="CZ/DataType")
    if dtype not in DTYPES:
        raise _err(
            path,
            "DataType one of I (int16), L (int32), F (float32), D (float64)",
            got=dtype,
            column="Record1/Axes/CZ/DataType",
        )
    z_inc_text = _text(cz, "Increment", path, required=False)
    z_off_text = _text(cz, "Offset", path, required=False)
    z_inc = 1000.0 if z_inc_text is None else _m_to_mm(z_inc_text, path, "CZ/Increment")
    z_off = 0.0 if z_off_text is None else _m_to_mm(z_off_text, path, "CZ/Offset")

    record3 = root.find("Record3")
    if record3 is None:
        raise _err(path, "element Record3 in main.xml")
    dims = record3.find("MatrixDimension")
    if dims is None:
        raise _err(path, "Record3/MatrixDimension (the grid form)", hint="point lists are not supported")
    sizes = []
    for tag in ("SizeX", "SizeY", "SizeZ"):
        t = _text(dims, tag, path, what=f"MatrixDimension/{tag}")
        try:
            n = int(t)
        except ValueError:
            raise _err(path, "a positive integer", got=t, column=f"Record3/MatrixDimension/{tag}") from None
        if n < 1:
            raise _err(path, "a positive integer", got=t, column=f"Record3/MatrixDimension/{tag}")
        sizes.append(n)
    if sizes[2] != 1:
        raise _err(path, "SizeZ 1 (a single layer)", got=sizes[2], column="Record3/MatrixDimension/SizeZ")
    link = record3.find("DataLink")
    point_link = valid_link = data_md5 = None
    if link is not None:
        point_link = _text(link, "PointDataLink", path, what="DataLink/PointDataLink")
        valid_link = _text(link, "ValidPointsLink", path, required=False)
        data_md5 = _text(link, "MD5ChecksumPointData", path, required=False)
    elif record3.find("DataList") is None:
        raise _err(path, "Record3/DataLink or Record3/DataList in main.xml")

    n = sizes[0] * sizes[1]
    if point_link is not None:
        if point_link not in names:
            raise _err(path, f"point data member {point_link}", got="missing from the archive")
        size = zf.getinfo(point_link).file_size
        expected = n * DTYPES[dtype].itemsize
        if size != expected:
            raise _err(
                path,
                f"{point_link} of {expected} bytes (SizeX {sizes[0]} x SizeY {sizes[1]} x "
                f"{DTYPES[dtype].itemsize} bytes of type {dtype})",
                got=f"{size} bytes",
                hint="truncated or mismatched data",
            )
    if valid_link is not None:
        if valid_link not in names:
            raise _err(path, f"valid points member {valid_link}", got="missing from the archive")
        size = zf.getinfo(valid_link).file_size
        if size != (n + 7) // 8:
            raise _err(path, f"{valid_link} of {(n + 7) // 8} bytes (one bit per point)", got=f"{size} bytes")
    record2 = root.find("Record2")
    return X3PHeader(
        path=str(path),
        size_x=sizes[0],
        size_y=sizes[1],
        dtype=dtype,
        dx_mm=lateral["CX"][0],
        dy_mm=lateral["CY"][0],
        z_increment_mm=z_inc,
        z_offset_mm=z_off,
        x_offset_mm=lateral["CX"][1],
        y_offset_mm=lateral["CY"][1],
        point_data_link=point_link,
        valid_points_link=valid_link,
        point_data_md5=data_md5,
        record2={} if record2 is None else _flatten(record2),
    )


def read_x3p_header(path) -> X3PHeader:
    """Open an X3P archive and check it without decoding the heights.

    Checks: a zip archive, ``main.xml`` present and well-formed, the checksum file holds the MD5 of the member it
    names (main.xml; bindata/data.bin as SurfaceTopography writes), feature type SUR, incremental X/Y axes,
    absolute Z axis with type I/L/F/D, ``data.bin`` and ``valid.bin`` sizes match SizeX * SizeY. The optional
    MD5 that main.xml states for data.bin is **not** checked here (:func:`read_x3p` checks it). Raises
    :class:`ScanFormatError` naming the file and what was expected.
    """
    with _open_zip(path) as zf:
        return _parse_header(zf, path)


def read_x3p(path) -> Surface:
    """Read an X3P file into a :class:`Surface` (heights in mm, NaN invalid, rows = y, cols = x).

    Everything :func:`read_x3p_header` checks, plus the MD5 of data.bin when main.xml states it
    (``DataLink/MD5ChecksumPointData``, case-insensitive). Invalid points: NaN/inf for F and D, cleared bits of
    valid.bin for every type; integer files without valid.bin are all valid. ``Surface.meta`` holds the
    flattened Record2 (``Date``, ``InstrumentManufacturer``, ...) and ``x3p_dtype``, ``z_increment_mm``,
    ``z_offset_mm``, ``x0_mm``, ``y0_mm``.
    """
    path = Path(path)
    with _open_zip(path) as zf:
        hdr = _parse_header(zf, path)
        n = hdr.size_x * hdr.size_y
        dt = DTYPES[hdr.dtype]
        if hdr.point_data_link is not None:
            raw_bytes = zf.read(hdr.point_data_link)
            if hdr.point_data_md5 is not None:
                actual = hashlib.md5(raw_bytes).hexdigest()
                if actual != hdr.point_data_md5.lower():
                    raise _err(
                        path,
                        f"{hdr.point_data_link} with the MD5 stated in main.xml ({hdr.point_data_md5.lower()})",
                        got=actual,
                        column="Record3/DataLink/MD5ChecksumPointData",
                        hint="corrupt point data",
                    )
            raw = np.frombuffer(raw_bytes, dtype=dt)
        else:
            raw = _read_datalist(zf, path, n)
        valid = None
        if hdr.valid_points_link is not None:
            bits = np.frombuffer(zf.read(hdr.valid_points_link), dtype=np.uint8)
            valid = np.unpackbits(bits, count=n, bitorder="little").astype(bool)
    heights = raw.astype(np.float64)
    if hdr.dtype in ("F", "D") and hdr.z_increment_mm == 1000.0 and hdr.z_offset_mm == 0.0:
        heights *= 1000.0  # metres -> mm, one multiplication
    else:
        heights *= hdr.z_increment_mm
        if hdr.z_offset_mm != 0.0:
            heights += hdr.z_offset_mm
    heights[~np.isfinite(heights)] = np.nan
    if valid is not None:
        heights[~valid] = np.nan
    meta = dict(hdr.record2)
    meta.update(
        x3p_dtype=hdr.dtype,
        z_increment_mm=hdr.z_increment_mm,
        z_offset_mm=hdr.z_offset_mm,
        x0_mm=hdr.x_offset_mm,
        y0_mm=hdr.y_offset_mm,
    )
    return Surface(heights.reshape(hdr.size_y, hdr.size_x), dx=hdr.dx_mm, dy=hdr.dy_mm, name=path.stem, meta=meta)


def _read_datalist(zf, path, n) -> np.ndarray:
    root = ElementTree.fromstring(zf.read(MAIN_XML))
    _strip_namespaces(root)
    datums = root.findall("Record3/DataList/Datum")
    if len(datums) != n:
        raise _err(path, f"{n} Datum elements in Record3/DataList", got=len(datums))
    out = np.empty(n)
    for i, d in enumerate(datums):
        t = (d.text or "").strip()
        try:
            out[i] = float(t) if t else np.nan
        except ValueError:
            raise _err(path, "a number in every Datum", got=t, column=f"Record3/DataList/Datum[{i}]") from None
    return out


def _sub(parent, tag, text=None):
    el = ElementTree.SubElement(parent, tag)
    if text is not None:
        el.text = str(text)
    return el


def _main_xml(hdr: dict, record2: dict) -> bytes:
    root = ElementTree.Element(
        "p:ISO5436_2",
        {
            "xmlns:p": NAMESPACE,
            "xmlns:xsi": XSI_NAMESPACE,
            "xsi:schemaLocation": f"{NAMESPACE} {NAMESPACE}/ISO5436_2_XML.xsd",
        },
    )
    r1 = _sub(root, "Record1")
    _sub(r1, "Revision", "ISO5436 - 2000")
    _sub(r1, "FeatureType", "SUR")
    axes = _sub(r1, "Axes")
    for name, inc in (("CX", hdr["dx_mm"]), ("CY", hdr["dy_mm"])):
        ax = _sub(axes, name)
        _sub(ax, "AxisType", "I")
        _sub(ax, "DataType", "D")
        _sub(ax, "Increment", _mm_to_m_text(inc))
        _sub(ax, "Offset", _mm_to_m_text(hdr[f"{name[1].lower()}0_mm"]))
    cz = _sub(axes, "CZ")
    _sub(cz, "AxisType", "A")
    _sub(cz, "DataType", hdr["dtype"])
    _sub(cz, "Increment", hdr["z_inc_text"])
    _sub(cz, "Offset", hdr["z_off_text"])
    r2 = _sub(root, "Record2")
    _sub(r2, "Date", record2["Date"])
    if "Creator" in record2:
        _sub(r2, "Creator", record2["Creator"])
    ins = _sub(r2, "Instrument")
    for key in ("Manufacturer", "Model", "Serial", "Version"):
        _sub(ins, key, record2.get("Instrument" + key, "unknown"))
    _sub(r2, "CalibrationDate", record2.get("CalibrationDate", record2["Date"]))
    probe = _sub(r2, "ProbingSystem")
    _sub(probe, "Type", record2.get("ProbingSystemType", "Software"))
    _sub(probe, "Identification", record2.get("ProbingSystemIdentification", "unknown"))
    _sub(r2, "Comment", record2.get("Comment", "written by skidsim"))
    r3 = _sub(root, "Record3")
    dims = _sub(r3, "MatrixDimension")
    _sub(dims, "SizeX", hdr["nx"])
    _sub(dims, "SizeY", hdr["ny"])
    _sub(dims, "SizeZ", 1)
    link = _sub(r3, "DataLink")
    _sub(link, "PointDataLink", DATA_BIN)
    _sub(link, "MD5ChecksumPointData", hdr["data_md5"])
    if hdr["valid_md5"] is not None:
        _sub(link, "ValidPointsLink", VALID_BIN)
        _sub(link, "MD5ChecksumValidPoints", hdr["valid_md5"])
    r4 = _sub(root, "Record4")
    _sub(r4, "ChecksumFile", CHECKSUM_FILE)
    ElementTree.indent(root, space="  ")
    text = '<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n' + ElementTree.tostring(root, "unicode")
    return (text + "\n").encode("utf-8")


def _quantise(h_mm: np.ndarray, valid: np.ndarray, dtype: str, z_increment_mm, path):
    """Integer codes, increment text (m) and offset text (m) for the integer types."""
    info = np.iinfo(DTYPES[dtype])
    lo_code, hi_code = info.min + 1, info.max - 1
    hv = h_mm[valid]
    hmin, hmax = (float(hv.min()), float(hv.max())) if hv.size else (0.0, 0.0)
    if z_increment_mm is None:
        # spread the valid range over the code range; quantisation error <= increment / 2
        # (3 significant digits, rounded up so that the range still fits)
        span = hmax - hmin
        inc = span / (hi_code - lo_code) if span > 0 else 1e-6
        unit = 10.0 ** (np.floor(np.log10(inc)) - 2)
        inc = float(f"{np.ceil(inc / unit * (1 - 1e-12)) * unit:.3g}")
    else:
        inc = float(z_increment_mm)
        if not (np.isfinite(inc) and inc > 0):
            raise ValueError(f"{path}: z_increment_mm must be a positive number of mm, got {z_increment_mm!r}")
    inc_text = _mm_to_m_text(inc)
    inc_mm = float(Decimal(inc_text) * 1000)  # what a reader will use
    # offset 0 when the range fits (exact round trip of k * inc), else a multiple of inc at mid-range
    k0 = 0
    if hv.size and (round(hmin / inc_mm) < lo_code or round(hmax / inc_mm) > hi_code):
        k0 = int(round(0.5 * (hmin + hmax) / inc_mm))
    off_text = _mm_to_m_text(k0 * inc_mm) if k0 else "0"
    off_mm = float(Decimal(off_text) * 1000)
    codes = np.zeros(h_mm.shape, dtype=np.float64)
    np.subtract(h_mm, off_mm, out=codes, where=valid)
    codes /= inc_mm
    np.rint(codes, out=codes)
    codes[~valid] = 0
    if hv.size and (codes.min() < info.min or codes.max() > info.max):
        raise ValueError(
            f"{path}: heights {hmin:g}..{hmax:g} mm do not fit type {dtype} with increment "
            f"{inc_mm:g} mm; use a larger z_increment_mm or dtype 'L'/'D'"
        )
    return codes.astype(DTYPES[dtype]), inc_text, off_text


def write_x3p(
    path,
    surface: Surface,
    dtype: str = "D",
    z_increment_mm: float | None = None,
    meta: dict | None = None,
    compresslevel: int | None = None,
) -> None:
    """Write ``surface`` (heights mm) as an ISO 25178-72 X3P file (metres inside), atomically.

    Parameters
    ----------
    dtype:
        ``"D"`` float64, ``"F"`` float32 (heights rounded to float32 metres), ``"I"`` int16 or ``"L"`` int32
        (quantised: ``code = rint((h - offset) / z_increment)``, invalid points in ``bindata/valid.bin``).
    z_increment_mm:
        Height step of the integer types in mm (e.g. 0.01 for an LS-40). ``None``: the valid height range is
        spread over the code range (quantisation error at most half a step). Not allowed for F/D.
    meta:
        Record2 entries (keys :data:`RECORD2_KEYS`); overrides ``surface.meta``. ``Date`` defaults to the
        current UTC time; pass it to make the output byte-reproducible (zip entry times are fixed).
    compresslevel:
        ``None`` (default) stores the members uncompressed (fast: ~0.2 s for a 2048 x 2448 scan); 1-9 deflates
        them (level 1: ~30 % of the size for float64, 70 % for int16, but ~4x slower to write).

    ``md5checksum.hex`` holds the MD5 of main.xml; main.xml states the MD5 of data.bin (and of valid.bin).
    """
    dtype = str(dtype).upper()
    if dtype not in DTYPES:
        raise ValueError(f"{path}: dtype must be one of I, L, F, D, got {dtype!r}")
    if z_increment_mm is not None and dtype in ("F", "D"):
        raise ValueError(f"{path}: z_increment_mm applies to the integer types I and L only, not {dtype!r}")
    h = np.ascontiguousarray(surface.heights, dtype=np.float64)
    valid = np.isfinite(h)
    valid_bytes = None
    if dtype in ("F", "D"):
        data = (h / 1000.0).astype(DTYPES[dtype])  # mm -> m; NaN stays NaN
        z_inc_text, z_off_text = "1", "0"
    else:
        data, z_inc_text, z_off_text = _quantise(h, valid, dtype, z_increment_mm, path)
        valid_bytes = np.packbits(valid.ravel(), bitorder="little").tobytes()
    data_bytes = data.tobytes()
    record2 = {k: str(v) for k, v in {**(surface.meta or {}), **(meta or {})}.items() if k in RECORD2_KEYS}
    record2.setdefault("Date", datetime.now(UTC).replace(microsecond=0).isoformat())
    if record2.get("ProbingSystemType", "Software") not in PROBING_TYPES:
        raise ValueError(
            f"{path}: meta ProbingSystemType must be one of {PROBING_TYPES}, got {record2['ProbingSystemType']!r}"
        )
    hdr = dict(
        nx=h.shape[1],
        ny=h.shape[0],
        dx_mm=surface.dx,
        dy_mm=surface.dy,
        dtype=dtype,
        x0_mm=float((surface.meta or {}).get("x0_mm", 0.0)),
        y0_mm=float((surface.meta or {}).get("y0_mm", 0.0)),
        z_inc_text=z_inc_text,
        z_off_text=z_off_text,
        data_md5=hashlib.md5(data_bytes).hexdigest(),
        valid_md5=None if valid_bytes is None else hashlib.md5(valid_bytes).hexdigest(),
    )
    xml = _main_xml(hdr, record2)
    members = [(MAIN_XML, xml), (DATA_BIN, data_bytes)]
    if valid_bytes is not None:
        members.append((VALID_BIN, valid_bytes))
    members.append((CHECKSUM_FILE, f"{hashlib.md5(xml).hexdigest()} *{MAIN_XML}\n".encode("ascii")))

    def _write(fh):
        with zipfile.ZipFile(fh, "w") as zf:
            for name, payload in members:
                info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
                if compresslevel is None:
                    info.compress_type = zipfile.ZIP_STORED
                    zf.writestr(info, payload)
                else:
                    info.compress_type = zipfile.ZIP_DEFLATED
                    zf.writestr(info, payload, compresslevel=compresslevel)

    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        _write(fh)
