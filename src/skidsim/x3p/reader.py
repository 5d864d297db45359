"""X3P reader: the header (:class:`X3PHeader`, :func:`read_x3p_header`) and the heights (:func:`read_x3p`), with
the checks of the archive, the checksum and the point data (:mod:`skidsim.x3p`)."""

from __future__ import annotations

import hashlib
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from skidsim.surface import Surface

from .format import (
    CHECKSUM_FILE,
    DATA_BIN,
    DTYPES,
    MAIN_XML,
    _err,
    _m_to_mm,
    strip_namespaces,
)


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
    strip_namespaces(root)

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
    strip_namespaces(root)
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
