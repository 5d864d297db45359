"""Plain grid text (.csv/.txt matrices, .xyz point lists) and read_scan dispatch incl. the optional adapter."""

from __future__ import annotations

import json
import sys
import types

import numpy as np
import pytest

from skidsim.errors import ScanFormatError
from skidsim.gridtext import read_grid_text, write_grid_text
from skidsim.scans import check_scan, read_scan, read_with_surfacetopography
from skidsim.surface import Surface
from skidsim.x3p import write_x3p


def surf(rows=7, cols=9, seed=2):
    rng = np.random.default_rng(seed)
    h = rng.normal(0, 1.0, (rows, cols))
    h[rng.random(h.shape) < 0.15] = np.nan
    return Surface(h, dx=0.05, dy=0.1, name="g")


def test_csv_header_spacing_rows_are_y_empty_cells_invalid(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("# LS-40 export\n# dx_mm=0.05 dy_mm=0.1\n# unit: mm\n1.5,2,,4\n5,nan,7,8\n9,10,11,12e-1\n")
    s = read_grid_text(p)
    assert s.shape == (3, 4) and s.dx == 0.05 and s.dy == 0.1
    expected = np.array([[1.5, 2, np.nan, 4], [5, np.nan, 7, 8], [9, 10, 11, 1.2]])
    np.testing.assert_array_equal(s.heights, expected)


def test_csv_sidecar_json_and_unit_conversion(tmp_path):
    p = tmp_path / "side.csv"
    p.write_text("100,200\n300,-400\n")
    (tmp_path / "side.json").write_text(json.dumps({"dx_mm": 0.05, "dy_mm": 0.05, "unit": "um"}))
    s = read_grid_text(p)
    np.testing.assert_allclose(s.heights, [[0.1, 0.2], [0.3, -0.4]])
    # header and sidecar disagree -> error
    p.write_text("# dx_mm=0.1 dy_mm=0.05\n1,2\n3,4\n")
    with pytest.raises(ScanFormatError, match="dx_mm"):
        read_grid_text(p)


def test_txt_whitespace_matrix(tmp_path):
    p = tmp_path / "w.txt"
    p.write_text("# dx_mm=0.5 dy_mm=0.25\n1 2 3\n4  5 nan\n")
    s = read_grid_text(p)
    np.testing.assert_array_equal(s.heights, [[1, 2, 3], [4, 5, np.nan]])
    assert (s.dx, s.dy) == (0.5, 0.25)


@pytest.mark.parametrize("suffix", [".csv", ".txt", ".xyz"])
def test_write_read_roundtrip_exact(tmp_path, suffix):
    s = surf()
    p = tmp_path / f"r{suffix}"
    write_grid_text(p, s)
    r = read_grid_text(p)
    np.testing.assert_array_equal(r.heights, s.heights)
    assert r.dx == pytest.approx(s.dx, rel=1e-12) and r.dy == pytest.approx(s.dy, rel=1e-12)


def test_xyz_any_order_missing_points_and_origin(tmp_path):
    rng = np.random.default_rng(5)
    rows, cols, dx, dy, x0, y0 = 4, 6, 0.05, 0.05, 10.0, -3.0
    z = rng.normal(size=(rows, cols))
    pts = [(x0 + j * dx, y0 + i * dy, float(z[i, j])) for i in range(rows) for j in range(cols)]
    del pts[7]  # (i=1, j=1) absent -> invalid
    order = rng.permutation(len(pts))
    p = tmp_path / "p.xyz"
    p.write_text("# x y z mm\n" + "".join(f"{pts[k][0]!r},{pts[k][1]!r},{pts[k][2]!r}\n" for k in order))
    s = read_grid_text(p)
    expected = z.copy()
    expected[1, 1] = np.nan
    np.testing.assert_array_equal(s.heights, expected)
    assert s.dx == pytest.approx(dx, rel=1e-12) and s.dy == pytest.approx(dy, rel=1e-12)
    assert s.meta["x0_mm"] == pytest.approx(x0) and s.meta["y0_mm"] == pytest.approx(y0)


def test_xyz_irregular_and_duplicate_points(tmp_path):
    p = tmp_path / "irr.xyz"
    p.write_text("0 0 1\n0.05 0 1\n0.1 0 1\n0.13 0 1\n0 0.05 1\n")
    with pytest.raises(ScanFormatError, match="regular grid") as ei:
        read_grid_text(p)
    assert ei.value.column == "x" and ei.value.got == 0.13
    p.write_text("0 0 1\n0.05 0 1\n0 0.05 1\n0.05 0.05 1\n0.05 0.05 2\n")
    with pytest.raises(ScanFormatError, match="one point per grid position"):
        read_grid_text(p)
    p.write_text("0 0 1\n0.05 0 1\n")
    with pytest.raises(ScanFormatError, match="2 distinct y"):
        read_grid_text(p)


def test_matrix_errors_name_row_and_column(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("# dx_mm=0.05 dy_mm=0.05\n1,2,3\n4,5\n")
    with pytest.raises(ScanFormatError) as ei:
        read_grid_text(p)
    assert ei.value.row == 3 and "3 values per row" in str(ei.value)
    p.write_text("# dx_mm=0.05 dy_mm=0.05\n1,2,3\n4,x5,6\n")
    with pytest.raises(ScanFormatError) as ei:
        read_grid_text(p)
    assert (ei.value.row, ei.value.column, ei.value.got) == (3, "2", "x5")
    p.write_text("1,2\n3,4\n")
    with pytest.raises(ScanFormatError, match="dx_mm.*bad.json"):
        read_grid_text(p)
    p.write_text("# dx_mm=-1 dy_mm=0.05\n1,2\n3,4\n")
    with pytest.raises(ScanFormatError, match="positive spacing"):
        read_grid_text(p)
    p.write_text("# dx_mm=1 dy_mm=0.05 unit=inch\n1,2\n3,4\n")
    with pytest.raises(ScanFormatError, match="unit"):
        read_grid_text(p)


def test_read_scan_dispatch_and_check_scan(tmp_path):
    s = surf()
    write_x3p(tmp_path / "a.x3p", s, meta={"Date": "2017-01-15T10:00:00+00:00"})
    write_grid_text(tmp_path / "a.csv", s)
    write_grid_text(tmp_path / "a.xyz", s)
    for name in ("a.x3p", "a.csv", "a.xyz"):
        r = read_scan(tmp_path / name)
        np.testing.assert_allclose(r.heights, s.heights, rtol=1e-15)
        assert check_scan(tmp_path / name, "header") == check_scan(tmp_path / name, "full") == (7, 9)


def test_unknown_suffix_without_surfacetopography_is_a_clear_error(tmp_path):
    p = tmp_path / "scan.sur"
    p.write_bytes(b"\x00\x01")
    with pytest.raises(ScanFormatError, match="pip install SurfaceTopography"):
        read_with_surfacetopography(p, module="skidsim_no_such_module_xyz")
    with pytest.raises(ScanFormatError, match="no such file"):
        read_scan(tmp_path / "absent.sur")


def test_surfacetopography_adapter_transposes_and_converts_units(tmp_path, monkeypatch):
    """A stand-in module with SurfaceTopography's conventions: heights() is (nx, ny), pixel = size / n."""
    nx, ny = 5, 3
    hx = np.arange(nx * ny, dtype=float).reshape(nx, ny)  # value = 3 * ix + iy (um)
    mask = np.zeros_like(hx, dtype=bool)
    mask[4, 0] = True

    class Topo:
        dim = 2
        unit = "µm"
        nb_grid_pts = (nx, ny)
        physical_sizes = (250.0, 300.0)  # um -> dx 50 um, dy 100 um

        def heights(self):
            return np.ma.MaskedArray(hx, mask=mask)

    fake = types.ModuleType("fake_st")
    fake.read_topography = lambda fn: Topo()
    monkeypatch.setitem(sys.modules, "fake_st", fake)
    p = tmp_path / "x.sur"
    p.write_bytes(b"")
    s = read_with_surfacetopography(p, module="fake_st")
    assert s.shape == (ny, nx) and s.dx == pytest.approx(0.05) and s.dy == pytest.approx(0.1)
    assert s.heights[2, 1] == pytest.approx(hx[1, 2] / 1000)  # row = y, col = x
    assert np.isnan(s.heights[0, 4]) and s.invalid_fraction == pytest.approx(1 / 15)
