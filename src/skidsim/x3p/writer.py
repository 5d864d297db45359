"""X3P writer (:func:`write_x3p`): a deterministic archive (fixed entry times), heights quantised to integer codes
or written as floats (:mod:`skidsim.x3p`)."""

from __future__ import annotations

import hashlib
import zipfile
from datetime import UTC, datetime
from decimal import Decimal
from xml.etree import ElementTree

import numpy as np

from skidsim.atomic import atomic_path
from skidsim.surface import Surface

from .format import (
    CHECKSUM_FILE,
    DATA_BIN,
    DTYPES,
    MAIN_XML,
    NAMESPACE,
    PROBING_TYPES,
    RECORD2_KEYS,
    VALID_BIN,
    XSI_NAMESPACE,
    _mm_to_m_text,
)

_ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # fixed zip entry time: identical inputs give identical bytes


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
