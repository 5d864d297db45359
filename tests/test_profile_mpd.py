"""MPD of line profiles (skidsim.profiles, skidsim.texture.mpd, `skidsim mpd`): reading text profiles as
profilometers write them, and agreement with captif-slp (the reference implementation) on profiles with the
features of real instruments: dropouts (NaN runs, one at the start), spikes, reference plates at both ends, CRLF
text with a header block."""

import numpy as np
import pytest

from skidsim.cli import main
from skidsim.profiles import ProfileFormatError, read_profile
from skidsim.surface import Surface
from skidsim.texture.mpd import MPDOptions, find_plates, mean_profile_depth, profile_segments, summarise

# captif-slp 0.22 calls DataFrame.set_index(inplace=True), deprecated in pandas 3.1
pytestmark = pytest.mark.filterwarnings("ignore:The inplace keyword:DeprecationWarning")

CAPTIF_HEADER = (
    "Road Name\tCAPTIF\t\nRef Station\t0\t\nStart Pos (m)\t0\t\nEnd Pos (m)\t0\t\n"
    "Direction\tincreasing\t\nWheel Path\tLeft\t\nDate\t11/10/2021\t\nFile No.\t0\t\n"
    "Current Pos\t0.0\t\n*****DATA*****\t\t\nData Point No:\tDistance (mm)\tDepth (mm)\n"
)


def instrument_profile(seed, length_mm=1000.0, dx=0.0375, plates=True):
    """A stationary-laser-profilometer-like run: macrotexture from 30 sinusoids (2-50 mm), sensor noise, a trend,
    dropout runs (one at the start), spikes of 3-8 mm and 0.4-1.1 mm wide, and reference plates (heights ~45 mm)
    at both ends with a dropout run at the first plate edge. Distances and heights rounded to 1 um as instruments
    write them."""
    rng = np.random.default_rng(seed)
    x = np.round(np.arange(int(length_mm / dx)) * dx, 3)
    z = np.zeros(len(x))
    for lam in rng.uniform(2, 50, 30):
        z += rng.normal(0, 0.25 * (lam / 50) ** 0.7) * np.sin(2 * np.pi * x / lam + rng.uniform(0, 6.3))
    z += 0.002 * x - 3.0 + rng.normal(0, 0.02, len(x))
    for _ in range(8):
        i = rng.integers(0, len(x) - 300)
        z[i : i + rng.integers(5, 250)] = np.nan
    z[:20] = np.nan
    for i in rng.integers(100, len(x) - 100, 12):  # spikes 0.4 to 1.1 mm wide: they survive the bin means
        z[i : i + rng.integers(10, 30)] += rng.choice([-1, 1]) * rng.uniform(3, 8)
    if plates:
        z[x < 19.0] = 45 + 0.1 * rng.normal(size=(x < 19).sum())
        z[x > length_mm - 25] = 46 + 0.1 * rng.normal(size=(x > length_mm - 25).sum())
        z[(x > 19.5) & (x < 21)] = np.nan
    return x, np.round(z, 3)


def write_captif(path, x, z):
    body = "".join(
        f"{i + 1}.000\t{xi:.3f}\t{'NaN' if np.isnan(zi) else f'{zi:.3f}'}\n" for i, (xi, zi) in enumerate(zip(x, z))
    )
    path.write_bytes((CAPTIF_HEADER + body).replace("\n", "\r\n").encode())
    return path


@pytest.fixture(scope="module")
def profiles():
    return {(seed, plates): instrument_profile(seed, plates=plates) for seed in range(3) for plates in (True, False)}


# ---------------------------------------------------------------------------------------------- reading text


def test_reader_finds_block_after_any_header_and_sniffs_delimiters(tmp_path):
    x = np.arange(8) * 0.25
    z = np.array([0.1, np.nan, -0.2, 0.3, np.nan, np.nan, 0.5, -0.125])
    cells = ["" if np.isnan(v) else f"{v:g}" for v in z]
    cells[4] = "---"  # non-numeric cell: a dropout
    files = {
        "tab_crlf.dat": CAPTIF_HEADER.replace("\n", "\r\n")
        + "".join(f"{i + 1}\t{xi:g}\t{c or 'NaN'}\r\n" for i, (xi, c) in enumerate(zip(x, cells))),
        "comma.csv": '# exported 2026-11-25\n# sensor LS-40\n\n"x_mm","height_mm"\n'
        + "".join(f'"{xi:g}","{c}"\n' for xi, c in zip(x, cells)),
        "semicolon.txt": "Profil;Test\nAbstand [mm];Hoehe [mm]\n"
        + "".join(f"{xi:g};{c}\n".replace(".", ",") for xi, c in zip(x, cells)),
        "spaces.txt": "  profile exported without names\n"
        + "".join(f"  {xi:8.3f}   {c or 'nan'}\n" for xi, c in zip(x, cells)),
    }
    for name, text in files.items():
        p = tmp_path / name
        p.write_bytes(text.encode())
        cols = {"semicolon.txt": ("Abstand", "Hoehe")}.get(name, (None, None))
        prof = read_profile(p, distance_col=cols[0], height_col=cols[1])
        np.testing.assert_allclose(prof.distance_mm, x, err_msg=name)
        np.testing.assert_allclose(prof.height_mm, z, err_msg=name)  # NaN where z is NaN
        assert prof.n_dropouts == 3, name
    prof = read_profile(tmp_path / "tab_crlf.dat")
    assert prof.columns == ("Distance (mm)", "Depth (mm)") and len(prof.header) == 11
    by_index = read_profile(tmp_path / "tab_crlf.dat", distance_col=1, height_col="2")
    np.testing.assert_array_equal(by_index.distance_mm, x)
    p = tmp_path / "first_dropout.csv"  # the block starts at a row holding one number
    p.write_text("Operator;A. N. Other\ndistance;height\n0;\n0,5;1\n1;2\n1,5;NaN\n2;4\n2,5;5\n")
    prof = read_profile(p)
    np.testing.assert_array_equal(prof.distance_mm, [0, 0.5, 1, 1.5, 2, 2.5])
    np.testing.assert_array_equal(np.isnan(prof.height_mm), [True, False, False, True, False, False])


def test_reader_errors_name_file_line_and_expectation(tmp_path):
    p = tmp_path / "nodata.txt"
    p.write_text("Road Name\tCAPTIF\nDate\t11/10/2021\n")
    with pytest.raises(ProfileFormatError, match=r"nodata.txt: expected a numeric block"):
        read_profile(p)
    p = tmp_path / "backwards.csv"
    p.write_text("distance,height\n0,1\n1,2\n2,3\n1.5,4\n3,5\n4,6\n")
    with pytest.raises(
        ProfileFormatError,
        match=r"backwards.csv: line 5, column 'distance': expected distances "
        r"increasing strictly \(previous 2 mm\), got 1.5",
    ):
        read_profile(p)
    p = tmp_path / "baddist.csv"
    p.write_text("distance,height\n0,1\n1,2\n2,3\n3,4\n4,5\nfive,6\n")
    with pytest.raises(ProfileFormatError, match=r"line 7, column 'distance': expected a number.*got 'five'"):
        read_profile(p)
    with pytest.raises(ProfileFormatError, match=r"expected a height column named 'elev'"):
        read_profile(tmp_path / "backwards.csv", height_col="elev")
    p = tmp_path / "three.txt"
    p.write_text("1 2 3\n2 3 4\n3 4 5\n4 5 6\n5 6 7\n")
    with pytest.raises(ProfileFormatError, match=r"expected the distance column by name or 0-based index"):
        read_profile(p)


# ------------------------------------------------------------------------------------- the MPD procedure


def test_plates_found_two_mm_inside_their_edges():
    x = np.arange(0, 300, 0.25)
    z = np.where((x < 20) | (x >= 270.5), 40.0, 0.1 * np.sin(x))
    z[(x >= 20) & (x < 22)] = np.nan  # dropouts after the plate edge keep the plate height for the test
    assert find_plates(x, z) == (22.0 + 2.0, 270.5 - 2.0)
    assert find_plates(x, np.zeros_like(x)) == (None, None)
    segs = profile_segments(z, x, detect_plates=True)
    # 24 .. 268.5 mm, counted from 24 mm: segments (0, 100] and (100, 200] in the trimmed frame; 44.5 mm rest dropped
    np.testing.assert_allclose(segs.start_mm, [24.0, 124.0])
    assert segs.trim_start_mm[0] == 24.0 and segs.trim_end_mm[0] == 268.5


def test_scan_rows_and_profiles_share_one_procedure(profiles):
    x, z = profiles[(0, False)]
    # the same heights on a regular grid (x = j dx) as a one-row surface and as a profile
    dx = 0.0375
    xs = np.arange(len(x)) * dx
    via_scan = mean_profile_depth(Surface(z[None, :], dx, dx), spike_alpha=3.0)
    via_profile = summarise(profile_segments(z, xs))
    assert via_scan.mpd_mm == via_profile.mpd_mm and via_scan.n_segments == via_profile.n_segments == 10
    # a larger spike factor keeps the spikes: the MPD grows
    assert mean_profile_depth(Surface(z[None, :], dx, dx), spike_alpha=20.0).mpd_mm > via_scan.mpd_mm + 0.05


def test_segment_length_and_dropout_limit_options(profiles):
    x, z = profiles[(1, False)]
    long = profile_segments(z, x, segment_mm=200.0)
    assert len(long.msd_mm) == 5 and np.all(np.diff(long.start_mm) == 200.0)
    strict = profile_segments(z, x, max_dropout_pct=0.5)
    loose = profile_segments(z, x, max_dropout_pct=100.0)
    assert strict.valid.sum() < loose.valid.sum()
    np.testing.assert_array_equal(strict.valid, (strict.dropout_pct <= 0.5) & (strict.spike_pct <= 5.0))
    np.testing.assert_array_equal(loose.valid, loose.spike_pct <= 5.0)


# ----------------------------------------------------------------------------------- captif-slp agreement


def _captif(x, z, **kw):
    captif_slp = pytest.importorskip("captif_slp")
    import pandas as pd

    reading = captif_slp.Reading.from_trace(pd.DataFrame({"distance_mm": x, "relative_height_mm": z}), **kw)
    return reading.mpd(), reading.msd()


@pytest.mark.peer
@pytest.mark.parametrize("plates", [True, False])
def test_agrees_with_captif_slp(profiles, plates):
    for seed in range(3):
        x, z = profiles[(seed, plates)]
        ref, ref_seg = _captif(x, z, detect_plates=plates)
        segs = profile_segments(z, x, detect_plates=plates)
        ours = summarise(segs)
        assert ours.mpd_mm == pytest.approx(ref["mpd"], rel=5e-3)  # the bound
        assert ours.sd_mm == pytest.approx(ref["stdev"], rel=5e-3)
        assert ours.n_segments == len(ref_seg) and ours.n_segments - ours.n_invalid_segments == ref["valid_segments"]
        # segment by segment, to the 1e-6 mm rounding both apply
        np.testing.assert_allclose(segs.msd_mm, [s["msd"] for s in ref_seg], atol=2e-6)
        np.testing.assert_array_equal(segs.valid, [s["valid"] for s in ref_seg])
        assert (~segs.valid).any() or seed != 0  # the fixture does exercise invalid segments


@pytest.mark.peer
def test_cli_agrees_with_captif_slp_reading_its_own_file_format(profiles, tmp_path, capsys):
    captif_slp = pytest.importorskip("captif_slp")
    x, z = profiles[(2, True)]
    path = write_captif(tmp_path / "run.dat", x, z)
    ref = captif_slp.Reading.from_file(path, detect_plates=True, parallel=False).mpd()
    out_csv = tmp_path / "segments.csv"
    assert main(["mpd", str(path), "--detect-plates", "-o", str(out_csv)]) == 0
    line = capsys.readouterr().out.splitlines()[0]
    n_invalid = 9 - int(ref["valid_segments"])
    assert line.startswith(
        f"MPD {ref['mpd']:.4f} mm, SD {ref['stdev']:.4f} mm, {int(ref['valid_segments'])} valid "
        f"segments, {n_invalid} invalid segment"
    )
    import pandas as pd

    seg = pd.read_csv(out_csv)
    assert list(seg.columns) == ["segment", "start_mm", "end_mm", "msd_mm", "dropout_pct", "spike_pct", "valid"]
    assert seg["msd_mm"][seg["valid"]].mean() == pytest.approx(ref["mpd"], rel=1e-5)


def test_cli_short_profile_reports_not_available(tmp_path, capsys, caplog):
    p = tmp_path / "short.csv"
    p.write_text("distance_mm,height_mm\n" + "".join(f"{i * 0.5},{np.sin(i):.3f}\n" for i in range(160)))
    assert main(["mpd", str(p)]) == 0
    assert capsys.readouterr().out.startswith("MPD n/a mm, SD n/a mm, 0 valid segments, 0 invalid segments")
    assert "MPD not available" in caplog.text
    assert main(["mpd", str(p), "--segment-mm", "-5"]) == 2
    assert "segment_mm: expected a positive number" in capsys.readouterr().err


def test_options_are_checked():
    with pytest.raises(Exception, match="lowpass_mm"):
        MPDOptions(lowpass_mm=0.8)
