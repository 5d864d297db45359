"""Campaign contract: the documented example loads unchanged; every contract error is reported, all at once."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from skidsim.campaign import REQUIRED_COLUMNS, load_campaign
from skidsim.errors import CampaignError
from skidsim.surface import Surface
from skidsim.x3p import write_x3p

DOC = Path(__file__).resolve().parents[1] / "docs" / "data-contract.md"
DATE = {"Date": "2017-01-15T10:00:00+00:00"}


def doc_files() -> dict[str, str]:
    """Files of the documented example: each fenced block preceded by ``<!-- example-file: NAME -->``."""
    text = DOC.read_text()
    found = re.findall(r"<!-- example-file: (\S+) -->\s*```[a-z]*\n(.*?)```", text, flags=re.S)
    return dict(found)


def small_scan(seed: int) -> Surface:
    """A 40 x 48 stand-in for the documented 2048 x 2448 LS-40 scan (same type, quantum, layout)."""
    rng = np.random.default_rng(seed)
    h = np.round(rng.normal(0, 1.2, (40, 48)) / 0.01) * 0.01
    h[rng.random(h.shape) < 0.02] = np.nan
    return Surface(h, dx=0.05, dy=0.05)


def build_doc_campaign(root: Path) -> Path:
    files = doc_files()
    for name, body in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(body)
    sites = pd.read_csv(root / "sites.csv", dtype=str)
    for k, rel in enumerate(sites["scan"]):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        write_x3p(root / rel, small_scan(k), dtype="I", z_increment_mm=0.01, meta=DATE)
    return root


@pytest.fixture
def camp(tmp_path) -> Path:
    return build_doc_campaign(tmp_path / "campaign")


def test_doc_example_has_the_promised_pieces():
    files = doc_files()
    assert "sites.csv" in files and any(n.startswith("dft/") for n in files)
    header = files["sites.csv"].splitlines()[0].split(",")
    assert tuple(header[:5]) == REQUIRED_COLUMNS and len(header) == 7  # two metadata columns


def test_doc_example_loads_unchanged(camp):
    c = load_campaign(camp, check_scans="full")
    files = doc_files()
    raw = pd.read_csv(camp / "sites.csv", dtype=str)
    assert c.directory == camp.resolve()
    assert list(c.sites.columns) == list(raw.columns)  # every column, file order
    assert c.metadata_columns == list(raw.columns[5:])
    assert c.site_ids == list(raw["site"])
    for rel, absolute in zip(raw["scan"], c.sites["scan"]):
        assert Path(absolute).is_absolute() and Path(absolute) == (camp / rel).resolve()
    np.testing.assert_array_equal(c.sites["temperature_c"], raw["temperature_c"].astype(float))
    pts = c.dft_points()
    assert list(pts.columns) == ["site", "speed_kmh", "mu"] and len(pts) == 6 * len(raw)
    # independent check: interpolate the documented DFT file by hand with numpy
    site0, dft0 = raw.loc[0, "site"], raw.loc[0, "dft"]
    trace = pd.read_csv(camp / dft0)
    trace = trace.groupby("speed_kmh", as_index=False)["mu"].mean().sort_values("speed_kmh")
    mine = pts[pts.site == site0].set_index("speed_kmh")["mu"]
    for v in (20, 30, 40, 50, 60, 70):
        assert mine[v] == pytest.approx(np.interp(v, trace.speed_kmh, trace.mu), rel=1e-12)
    assert dft0 in files


def test_metadata_types_and_order(camp):
    (camp / "sites.csv").write_text(
        "zone,site,section,scan,dft,temperature_c,aadt\n"
        "north,E1-1,E1,scans/E1-1.x3p,dft/E1-1.csv,15.8,1200\n"
        ",E1-2,E1,scans/E1-2.x3p,dft/E1-2.csv,15.8,\n"
    )
    c = load_campaign(camp, check_scans=False)
    assert c.metadata_columns == ["zone", "aadt"]
    assert list(c.sites.columns)[:2] == ["zone", "site"]
    assert c.sites["aadt"].dtype == float and np.isnan(c.sites["aadt"][1])
    assert list(c.sites["zone"]) == ["north", ""]


def bad_sites(camp: Path, text: str):
    (camp / "sites.csv").write_text(text)
    with pytest.raises(CampaignError) as ei:
        load_campaign(camp)
    return ei.value


HEAD = "site,section,scan,dft,temperature_c,mix,age_months\n"


def row(site="E1-1", section="E1", scan="scans/E1-1.x3p", dft="dft/E1-1.csv", t="15.8"):
    return f"{site},{section},{scan},{dft},{t},HMA,14\n"


@pytest.mark.parametrize(
    "body,line,column,fragment",
    [
        (row(site=""), 2, "site", "a site id"),
        (row(site="E1 1"), 2, "site", "letters, digits"),
        (row(site="_x"), 2, "site", "starting with a letter or digit"),
        (row() + row(), 3, "site", "a unique site id"),
        (row() + row(site="e1-1"), 3, "site", "case-insensitive"),
        ("", 2, None, "at least one site row"),
        (row(section=""), 2, "section", "a section name"),
        (row(scan="scans/none.x3p"), 2, "scan", "an existing scan file"),
        (row(dft="dft/none.csv"), 2, "dft", "an existing dft file"),
        (row(scan=""), 2, "scan", "a path to the scan file"),
        (row(t="warm"), 2, "temperature_c", "a number"),
        (row(t="nan"), 2, "temperature_c", "a finite number"),
        (row(t="61.0F"), 2, "temperature_c", "a number"),
        (row(t="289.1"), 2, "temperature_c", "between -50 and 80"),
        ("E1-1,E1,scans/E1-1.x3p\n", 2, None, "7 fields"),
    ],
)
def test_each_row_error(camp, body, line, column, fragment):
    e = bad_sites(camp, HEAD + body)
    assert len(e.errors) == 1
    inner = e.errors[0]
    assert (inner.row, inner.column) == (line, column) and fragment in str(inner)
    assert str(camp / "sites.csv") in str(inner)
    first = str(e).splitlines()[0]
    assert "1 problem(s)" in first


def test_missing_sites_csv_and_required_columns(tmp_path, camp):
    with pytest.raises(CampaignError, match="sites.csv.*no such file"):
        load_campaign(tmp_path / "empty_dir_that_does_not_exist")
    e = bad_sites(camp, "site,scan,dft,mix\nE1-1,scans/E1-1.x3p,dft/E1-1.csv,HMA\n")
    assert e.errors[0].row == 1 and "missing section, temperature_c" in str(e)
    e = bad_sites(camp, "site,section,scan,dft,temperature_c,site\n")
    assert e.errors[0].column == "site" and "unique column names" in str(e)


def test_corrupt_scan_header_and_full(camp):
    scan = camp / "scans" / "E1-1.x3p"
    scan.write_bytes(b"not a zip at all")
    e = bad_sites(camp, (camp / "sites.csv").read_text())
    assert e.errors[0].column == "scan" and "not a zip" in str(e)
    # flip a data byte: the header check passes (sizes, main.xml checksum); only the full read sees it
    write_x3p(scan, small_scan(0), dtype="D", meta=DATE)
    import zipfile

    with zipfile.ZipFile(scan) as zf:
        m = {n: zf.read(n) for n in zf.namelist()}
    data = bytearray(m["bindata/data.bin"])
    data[8] ^= 0x40
    m["bindata/data.bin"] = bytes(data)
    with zipfile.ZipFile(scan, "w") as zf:
        for n, b in m.items():
            zf.writestr(n, b)
    load_campaign(camp, check_scans="header")
    load_campaign(camp, check_scans=False)
    with pytest.raises(CampaignError, match="MD5ChecksumPointData"):
        load_campaign(camp, check_scans="full")


def test_dft_errors_and_speed_coverage_name_the_file(camp):
    sites = pd.read_csv(camp / "sites.csv", dtype=str)
    d0, d1 = camp / sites.loc[0, "dft"], camp / sites.loc[1, "dft"]
    d0.write_text("speed_kmh,mu\n20,0.5\n30,2.0\n")
    d1.write_text("speed_kmh,mu\n25,0.5\n65,0.4\n")
    with pytest.raises(CampaignError) as ei:
        load_campaign(camp)
    e = ei.value
    assert len(e.errors) == 2
    assert str(d0) in str(e.errors[0]) and "row 3" in str(e.errors[0]) and "between 0 and 1.5" in str(e.errors[0])
    assert str(d1) in str(e.errors[1]) and "25-65 km/h" in str(e.errors[1]) and "20, 70 km/h" in str(e.errors[1])
    # speeds are configurable: 30..60 is covered by the second trace
    d0.write_text("speed_kmh,mu\n20,0.5\n70,0.4\n")
    c = load_campaign(camp, speeds_kmh=(30, 40, 50, 60))
    assert list(c.dft_points().speed_kmh.unique()) == [30.0, 40.0, 50.0, 60.0]


def test_all_errors_collected_in_one_raise(camp):
    shutil.rmtree(camp / "dft")
    text = HEAD + row(site="A", t="x") + row(site="A", section="") + row(site="b c", scan="nope.x3p")
    e = bad_sites(camp, text)
    lines = str(e).splitlines()
    # 3 missing dft files + bad temperature + duplicate id + empty section + bad id + missing scan
    assert len(e.errors) == 8 and len(lines) == 9
    assert lines[0].endswith("got '8 problem(s)' (all listed below; fix them and load again)")
    assert all(ln.startswith("  - ") for ln in lines[1:])


def test_check_scans_argument_validated(camp):
    with pytest.raises(ValueError, match="check_scans"):
        load_campaign(camp, check_scans="quick")
    assert load_campaign(camp, check_scans=True).site_ids
