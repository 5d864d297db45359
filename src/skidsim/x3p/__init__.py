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
    strip_namespaces,
)
from .reader import X3PHeader, read_x3p, read_x3p_header
from .writer import write_x3p

__all__ = [
    "CHECKSUM_FILE",
    "DATA_BIN",
    "DTYPES",
    "MAIN_XML",
    "NAMESPACE",
    "PROBING_TYPES",
    "RECORD2_KEYS",
    "VALID_BIN",
    "XSI_NAMESPACE",
    "X3PHeader",
    "read_x3p",
    "read_x3p_header",
    "strip_namespaces",
    "write_x3p",
]
