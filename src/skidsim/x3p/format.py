"""What the reader and the writer of X3P share: the archive's member names, the data types, the namespaces and
the conversion of lengths between the file's metres and our millimetres (:mod:`skidsim.x3p`)."""

from __future__ import annotations

from decimal import Decimal
from xml.etree import ElementTree

import numpy as np

from skidsim.errors import ScanFormatError

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


def strip_namespaces(root: ElementTree.Element) -> None:
    for el in root.iter():
        if isinstance(el.tag, str) and "}" in el.tag:
            el.tag = el.tag.split("}", 1)[1]
