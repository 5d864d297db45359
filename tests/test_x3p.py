"""X3P reader/writer: round trips, the byte layout of the archive, checksums, and every format error."""

from __future__ import annotations

import hashlib
import re
import zipfile

import numpy as np
import pytest

from skidsim.errors import ScanFormatError
from skidsim.surface import Surface
from skidsim.x3p import read_x3p, read_x3p_header, write_x3p

DATE = {"Date": "2017-01-15T10:00:00+00:00"}


def scan(rows=12, cols=17, seed=1, quantum_mm=None, invalid=0.1):
    """A small LS-40-like scan: heights in mm, ~10 % invalid points, optionally quantised k * quantum."""
    rng = np.random.default_rng(seed)
    h = rng.normal(0.0, 1.5, (rows, cols))
    if quantum_mm is not None:
        h = np.round(h / quantum_mm) * quantum_mm
    h[rng.random(h.shape) < invalid] = np.nan
    h[0, 0] = np.nan  # first point invalid: exercises bit 0 of valid.bin
    return Surface(h, dx=0.05, dy=0.05, name="s")


def members(path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as zf:
        return {n: zf.read(n) for n in zf.namelist()}


def rezip(path, out, replace=None, drop=()):
    """Copy an X3P archive, replacing or dropping members (no checksum fix-up unless asked)."""
    m = members(path)
    m.update(replace or {})
    with zipfile.ZipFile(out, "w") as zf:
        for n, b in m.items():
            if n not in drop:
                zf.writestr(n, b)
    return out


def with_xml(path, out, edit):
    """Copy with main.xml edited by ``edit(str) -> str`` and md5checksum.hex recomputed (a valid archive)."""
    xml = edit(members(path)["main.xml"].decode())
    b = xml.encode()
    return rezip(path, out, {"main.xml": b, "md5checksum.hex": f"{hashlib.md5(b).hexdigest()} *main.xml\n".encode()})


# ---------------------------------------------------------------- round trips


def test_roundtrip_D_within_one_ulp_and_nan_mask(tmp_path):
    s = scan()
    p = tmp_path / "a.x3p"
    write_x3p(p, s, dtype="D", meta=DATE)
    r = read_x3p(p)
    assert r.shape == s.shape and r.dx == 0.05 and r.dy == 0.05
    np.testing.assert_array_equal(np.isnan(r.heights), np.isnan(s.heights))
    v = s.valid
    np.testing.assert_allclose(r.heights[v], s.heights[v], rtol=2.3e-16, atol=0)
    assert r.meta["x3p_dtype"] == "D" and r.meta["Date"] == DATE["Date"]


def test_roundtrip_F_float32_precision(tmp_path):
    s = scan()
    p = tmp_path / "f.x3p"
    write_x3p(p, s, dtype="F")
    r = read_x3p(p)
    v = s.valid
    np.testing.assert_array_equal(r.valid, v)
    err = np.abs(r.heights[v] - s.heights[v])
    assert np.all(err <= 1.2e-7 * np.abs(s.heights[v]) + 1e-12)
    assert err.max() > 0  # really float32, not float64 in disguise


@pytest.mark.parametrize("dtype", ["I", "L"])
def test_roundtrip_integer_types_exact_at_ls40_quantum(tmp_path, dtype):
    s = scan(quantum_mm=0.01)
    p = tmp_path / f"{dtype}.x3p"
    write_x3p(p, s, dtype=dtype, z_increment_mm=0.01)
    r = read_x3p(p)
    np.testing.assert_array_equal(r.heights, s.heights)  # bit-exact, NaN where invalid
    assert r.meta["z_increment_mm"] == 0.01 and r.meta["x3p_dtype"] == dtype
    m = members(p)
    assert "bindata/valid.bin" in m
    # codes are heights / 0.01 mm, invalid points stored as code 0
    codes = np.frombuffer(m["bindata/data.bin"], dtype={"I": "<i2", "L": "<i4"}[dtype]).reshape(s.shape)
    np.testing.assert_array_equal(codes[s.valid], np.rint(s.heights[s.valid] / 0.01).astype(int))
    assert np.all(codes[~s.valid] == 0)


@pytest.mark.parametrize("dtype", ["I", "L"])
def test_integer_auto_increment_error_below_half_step(tmp_path, dtype):
    s = scan(seed=3)
    p = tmp_path / "auto.x3p"
    write_x3p(p, s, dtype=dtype)
    r = read_x3p(p)
    inc = r.meta["z_increment_mm"]
    span = np.nanmax(s.heights) - np.nanmin(s.heights)
    assert span / {"I": 65534, "L": 2**32 - 2}[dtype] <= inc <= 1.02 * span / {"I": 65532, "L": 2**32 - 4}[dtype]
    err = np.nanmax(np.abs(r.heights - s.heights))
    assert err <= 0.5 * inc * (1 + 1e-9)
    np.testing.assert_array_equal(r.valid, s.valid)


def test_integer_offset_used_when_range_exceeds_int16(tmp_path):
    s = Surface(np.array([[500.0, 500.01, np.nan], [500.02, 499.99, 500.0]]), 0.05, 0.05)
    p = tmp_path / "off.x3p"
    write_x3p(p, s, dtype="I", z_increment_mm=0.01)  # 500 mm / 0.01 mm = 50000 codes > 32767
    r = read_x3p(p)
    np.testing.assert_allclose(r.heights, s.heights, atol=1e-9)
    assert r.meta["z_offset_mm"] != 0.0
    with pytest.raises(ValueError, match="do not fit"):
        write_x3p(p, Surface(np.array([[0.0, 700.0]]), 0.05, 0.05), dtype="I", z_increment_mm=0.01)


# ---------------------------------------------------------------- archive layout (independent decoding)


def test_archive_layout_metres_x_fastest_and_checksum_of_main_xml(tmp_path):
    h = np.arange(6, dtype=float).reshape(2, 3) * 0.25  # rows = y (2), cols = x (3)
    p = tmp_path / "lay.x3p"
    write_x3p(p, Surface(h, dx=0.05, dy=0.1), dtype="D", meta=DATE)
    m = members(p)
    xml = m["main.xml"].decode()
    assert re.search(r"<SizeX>3</SizeX>", xml) and re.search(r"<SizeY>2</SizeY>", xml)
    assert "<Increment>0.00005</Increment>" in xml and "<Increment>0.0001</Increment>" in xml  # metres
    raw = np.frombuffer(m["bindata/data.bin"], dtype="<f8")
    np.testing.assert_allclose(raw, h.ravel() / 1000.0, rtol=1e-15)  # x fastest, metres
    stated = m["md5checksum.hex"].decode()
    assert stated == hashlib.md5(m["main.xml"]).hexdigest() + " *main.xml\n"
    assert stated.split()[0] != hashlib.md5(m["bindata/data.bin"]).hexdigest()
    assert hashlib.md5(m["bindata/data.bin"]).hexdigest() in xml  # MD5ChecksumPointData


def test_valid_bin_bit_order_lsb_first_one_is_valid(tmp_path):
    h = np.ones((3, 5))
    h[0, 0] = h[0, 3] = h[1, 4] = h[2, 4] = np.nan  # flat indices 0, 3, 9, 14
    p = tmp_path / "v.x3p"
    write_x3p(p, Surface(h, 0.05, 0.05), dtype="L", z_increment_mm=0.01)
    vb = members(p)["bindata/valid.bin"]
    bits = np.ones(16, dtype=int)
    bits[[0, 3, 9, 14, 15]] = 0  # bit 15 is padding beyond 15 points
    expected = bytes([sum(int(b) << k for k, b in enumerate(bits[i : i + 8])) for i in (0, 8)])
    assert vb == expected == bytes([0b11110110, 0b00111101])


def test_deterministic_bytes_given_date(tmp_path):
    s = scan()
    write_x3p(tmp_path / "1.x3p", s, meta=DATE)
    write_x3p(tmp_path / "2.x3p", s, meta=DATE)
    assert (tmp_path / "1.x3p").read_bytes() == (tmp_path / "2.x3p").read_bytes()
    assert sorted(q.name for q in tmp_path.iterdir()) == ["1.x3p", "2.x3p"]  # no temp files left


def test_record2_metadata_roundtrip(tmp_path):
    meta = {
        **DATE,
        "InstrumentManufacturer": "HyMIT",
        "InstrumentModel": "LS-40",
        "ProbingSystemType": "NonContacting",
        "Comment": "site E1-1",
    }
    p = tmp_path / "m.x3p"
    write_x3p(p, scan(), meta=meta)
    r = read_x3p(p)
    for k, v in meta.items():
        assert r.meta[k] == v
    with pytest.raises(ValueError, match="ProbingSystemType"):
        write_x3p(p, scan(), meta={"ProbingSystemType": "laser"})


# ---------------------------------------------------------------- hand-written file (spec reading)

HAND_XML = """<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2">
 <Record1><Revision>ISO5436 - 2000</Revision><FeatureType>SUR</FeatureType>
  <Axes>
   <CX><AxisType>I</AxisType><DataType>D</DataType><Increment>2.5E-5</Increment><Offset>0.0</Offset></CX>
   <CY><AxisType>I</AxisType><DataType>D</DataType><Increment>5.0e-5</Increment><Offset>0.0</Offset></CY>
   <CZ><AxisType>A</AxisType><DataType>L</DataType>{zscale}</CZ>
  </Axes></Record1>
 <Record3><MatrixDimension><SizeX>4</SizeX><SizeY>2</SizeY><SizeZ>1</SizeZ></MatrixDimension>
  <DataLink><PointDataLink>bindata/data.bin</PointDataLink>{valid}</DataLink></Record3>
 <Record4><ChecksumFile>md5checksum.hex</ChecksumFile></Record4>
</p:ISO5436_2>
"""


def hand_file(path, zscale, valid_bits=None):
    codes = np.array([[0, 1, 2, 3], [-4, 5, 6, 1000]], dtype="<i4")
    valid = "" if valid_bits is None else "<ValidPointsLink>bindata/valid.bin</ValidPointsLink>"
    xml = HAND_XML.format(zscale=zscale, valid=valid).encode()
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("main.xml", xml)
        zf.writestr("bindata/data.bin", codes.tobytes())
        if valid_bits is not None:
            zf.writestr("bindata/valid.bin", bytes([valid_bits]))
        zf.writestr("md5checksum.hex", hashlib.md5(xml).hexdigest().upper() + "  main.xml")
    return codes


def test_hand_written_integer_file_with_increment_offset_and_valid_bits(tmp_path):
    p = tmp_path / "hand.x3p"
    codes = hand_file(p, "<Increment>1E-6</Increment><Offset>0.001</Offset>", valid_bits=0b01111110)
    r = read_x3p(p)
    expected = codes * 0.001 + 1.0  # 1 um steps, 1 mm offset
    expected[0, 0] = expected[1, 3] = np.nan  # bits 0 and 7 cleared
    np.testing.assert_allclose(r.heights, expected, rtol=1e-14)
    np.testing.assert_array_equal(np.isnan(r.heights), np.isnan(expected))
    assert r.dx == 0.025 and r.dy == 0.05


def test_integer_file_without_valid_bin_or_z_scale_is_all_valid_metres(tmp_path):
    p = tmp_path / "hand2.x3p"
    codes = hand_file(p, "")
    r = read_x3p(p)
    np.testing.assert_allclose(r.heights, codes * 1000.0)  # raw values are metres
    assert r.invalid_fraction == 0.0


# ---------------------------------------------------------------- errors


def make(tmp_path, dtype="D"):
    p = tmp_path / "good.x3p"
    write_x3p(p, scan(), dtype=dtype, z_increment_mm=0.01 if dtype in "IL" else None, meta=DATE)
    return p


def test_bad_main_xml_checksum_surfacetopography_style(tmp_path):
    p = make(tmp_path)
    data_md5 = hashlib.md5(members(p)["bindata/data.bin"]).hexdigest()
    bad = rezip(p, tmp_path / "bad.x3p", {"md5checksum.hex": f"{data_md5} *main.xml\n".encode()})
    for reader in (read_x3p, read_x3p_header):
        with pytest.raises(ScanFormatError, match=r"bad\.x3p.*MD5 of main\.xml") as ei:
            reader(bad)
        assert ei.value.got == data_md5


def test_missing_checksum_file(tmp_path):
    bad = rezip(make(tmp_path), tmp_path / "nock.x3p", drop=("md5checksum.hex",))
    with pytest.raises(ScanFormatError, match="md5checksum.hex"):
        read_x3p_header(bad)


@pytest.mark.parametrize("dtype", ["D", "I"])
def test_truncated_data(tmp_path, dtype):
    p = make(tmp_path, dtype)
    data = members(p)["bindata/data.bin"]
    bad = rezip(p, tmp_path / "trunc.x3p", {"bindata/data.bin": data[:-7]})
    with pytest.raises(ScanFormatError, match=r"trunc\.x3p.*data\.bin of \d+ bytes") as ei:
        read_x3p_header(bad)
    assert ei.value.got == f"{len(data) - 7} bytes"


def test_corrupt_point_data_md5_detected_on_full_read_only(tmp_path):
    p = make(tmp_path)
    data = bytearray(members(p)["bindata/data.bin"])
    data[100] ^= 0xFF
    bad = rezip(p, tmp_path / "flip.x3p", {"bindata/data.bin": bytes(data)})
    assert read_x3p_header(bad).shape == (12, 17)  # sizes fine
    with pytest.raises(ScanFormatError, match="MD5ChecksumPointData"):
        read_x3p(bad)


def test_not_a_zip_and_missing_main_xml_and_missing_file(tmp_path):
    q = tmp_path / "plain.x3p"
    q.write_text("x y z\n")
    with pytest.raises(ScanFormatError, match=r"plain\.x3p.*not a zip"):
        read_x3p(q)
    nomain = rezip(make(tmp_path), tmp_path / "nomain.x3p", drop=("main.xml",))
    with pytest.raises(ScanFormatError, match=r"nomain\.x3p.*main\.xml"):
        read_x3p(nomain)
    with pytest.raises(ScanFormatError, match="no such file"):
        read_x3p(tmp_path / "absent.x3p")


@pytest.mark.parametrize(
    "old,new,match",
    [
        ("<FeatureType>SUR</FeatureType>", "<FeatureType>PRF</FeatureType>", "FeatureType SUR"),
        ("<CX>\n        <AxisType>I</AxisType>", "<CX>\n        <AxisType>A</AxisType>", "AxisType I"),
        (
            "<DataType>D</DataType>\n        <Increment>1",
            "<DataType>Q</DataType>\n        <Increment>1",
            "DataType one of",
        ),
        ("<SizeZ>1</SizeZ>", "<SizeZ>2</SizeZ>", "SizeZ 1"),
    ],
)
def test_unsupported_header_features(tmp_path, old, new, match):
    p = make(tmp_path)
    bad = with_xml(p, tmp_path / "feat.x3p", lambda x: x.replace(old, new, 1) if old in x else pytest.fail(old))
    with pytest.raises(ScanFormatError, match=match) as ei:
        read_x3p_header(bad)
    assert "feat.x3p" in str(ei.value)


def test_wrong_data_type_for_data_size(tmp_path):
    """main.xml says F (4 bytes) but data.bin holds D (8 bytes): a size mismatch, named as such."""
    p = make(tmp_path)
    bad = with_xml(
        p,
        tmp_path / "dt.x3p",
        lambda x: x.replace(
            "<DataType>D</DataType>\n        <Increment>1", "<DataType>F</DataType>\n        <Increment>1"
        ),
    )
    with pytest.raises(ScanFormatError, match="type F"):
        read_x3p_header(bad)


def test_writer_argument_errors(tmp_path):
    with pytest.raises(ValueError, match="dtype"):
        write_x3p(tmp_path / "x.x3p", scan(), dtype="Q")
    with pytest.raises(ValueError, match="integer types"):
        write_x3p(tmp_path / "x.x3p", scan(), dtype="D", z_increment_mm=0.01)


# ---------------------------------------------------------------- peer: surfalize (test-only, GPL)


@pytest.mark.peer
@pytest.mark.parametrize("dtype", ["I", "L", "F", "D"])
def test_surfalize_reads_our_files(tmp_path, dtype):
    surfalize = pytest.importorskip("surfalize")
    s = scan(quantum_mm=0.01)
    p = tmp_path / f"peer{dtype}.x3p"
    write_x3p(p, s, dtype=dtype, z_increment_mm=0.01 if dtype in "IL" else None)
    peer = surfalize.Surface.load(p)
    np.testing.assert_allclose(peer.data / 1000.0, s.heights, rtol=1e-6, atol=1e-9)  # um -> mm, NaN equal
    assert peer.step_x == pytest.approx(50.0) and peer.step_y == pytest.approx(50.0)


@pytest.mark.peer
@pytest.mark.filterwarnings("ignore:The surface has different pixel size")
def test_we_read_surfalize_files(tmp_path):
    surfalize = pytest.importorskip("surfalize")
    s = scan()
    peer = surfalize.Surface(s.heights * 1000.0, 50.0, 25.0)  # um
    p = tmp_path / "from_peer.x3p"
    peer.save(p)
    r = read_x3p(p)
    assert r.dx == pytest.approx(0.05) and r.dy == pytest.approx(0.025)
    np.testing.assert_allclose(r.heights, s.heights, rtol=1e-14)


@pytest.mark.peer
def test_we_read_surfacetopography_files_md5_of_data_bin(tmp_path):
    """SurfaceTopography writes ``<MD5 OF data.bin, upper case> *bindata/data.bin`` into md5checksum.hex."""
    st = pytest.importorskip("SurfaceTopography")
    s = scan(rows=9, cols=14, invalid=0.0)
    p = tmp_path / "from_st.x3p"
    # SurfaceTopography arrays are (nx, ny): the transpose of (rows, cols); lengths in m
    st.Topography(s.heights.T * 1e-3, physical_sizes=(14 * 5e-5, 9 * 5e-5), unit="m").to_x3p(p)
    stated = members(p)["md5checksum.hex"].decode()
    assert stated.split() == [hashlib.md5(members(p)["bindata/data.bin"]).hexdigest().upper(), "*bindata/data.bin"]
    r = read_x3p(p)
    assert r.shape == (9, 14) and r.dx == pytest.approx(0.05) and r.dy == pytest.approx(0.05)
    np.testing.assert_allclose(r.heights, s.heights, rtol=1e-12, atol=1e-15)
    hdr = read_x3p_header(p)
    assert (hdr.size_x, hdr.size_y, hdr.dtype) == (14, 9, "D")


@pytest.mark.parametrize(
    "content, ok",
    [
        ("{xml_md5} *main.xml\n", True),  # openGPS library / md5sum binary mode
        ("{XML_MD5}  main.xml\r\n", True),  # md5sum text mode, upper case, CRLF
        ("{xml_md5}", True),  # bare digest of main.xml
        ("{bin_md5}", True),  # bare digest of the point data
        ("{BIN_MD5} *bindata/data.bin\n", True),  # SurfaceTopography
        ("{bin_md5} *main.xml\n", False),  # names main.xml, holds the data's digest
        ("{xml_md5} *bindata/data.bin\n", False),  # names the data, holds main.xml's digest
        ("{xml_md5} *bindata/other.bin\n", False),  # names a member that is not there
        ("0123456789abcdef0123456789abcdef\n", False),
    ],
)
def test_checksum_conventions_of_real_writers(tmp_path, content, ok):
    p = make(tmp_path)
    m = members(p)
    xml_md5, bin_md5 = hashlib.md5(m["main.xml"]).hexdigest(), hashlib.md5(m["bindata/data.bin"]).hexdigest()
    text = content.format(xml_md5=xml_md5, XML_MD5=xml_md5.upper(), bin_md5=bin_md5, BIN_MD5=bin_md5.upper())
    q = rezip(p, tmp_path / "conv.x3p", {"md5checksum.hex": text.encode()})
    if ok:
        np.testing.assert_array_equal(np.isnan(read_x3p(q).heights), np.isnan(scan().heights))
    else:
        with pytest.raises(ScanFormatError, match=r"conv\.x3p: expected md5checksum\.hex (holding|naming)"):
            read_x3p_header(q)


def test_datalist_text_points(tmp_path):
    """Points stored as text in main.xml (Record3/DataList) instead of data.bin; empty Datum = invalid."""
    xml = HAND_XML.replace("<DataType>L</DataType>{zscale}", "<DataType>D</DataType>")
    xml = xml.replace("<SizeX>4</SizeX><SizeY>2</SizeY>", "<SizeX>3</SizeX><SizeY>1</SizeY>")
    xml = xml.replace(
        "<DataLink><PointDataLink>bindata/data.bin</PointDataLink>{valid}</DataLink>",
        "<DataList><Datum>1e-3</Datum><Datum></Datum><Datum>-2.5e-4</Datum></DataList>",
    ).encode()
    p = tmp_path / "list.x3p"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("main.xml", xml)
        zf.writestr("md5checksum.hex", hashlib.md5(xml).hexdigest() + " *main.xml\n")
    r = read_x3p(p)
    np.testing.assert_array_equal(r.heights, [[1.0, np.nan, -0.25]])
