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


# ------------------------------------------------------------------------- profiles at 1 mm, units, long runs


def thin_to_mm(x, z, step=1.0):
    """A profile as a road profiler at ``step`` mm delivers it: the sample at or just after each multiple of
    ``step`` (point sampling, as a coarser instrument), distances written as the multiples."""
    grid = np.arange(0.0, x[-1], step)
    idx = np.searchsorted(x, grid)
    return grid, z[idx]


def road_profile(seed, length_mm=20_000.0, dx=1.0):
    """A long-run profile at ``dx`` mm: macrotexture from 40 sinusoids (2-50 mm), a longitudinal unevenness of
    metres (a 5 mm, 3 m wave: the reason for the evaluation-length high-pass), sensor noise, dropout runs and a
    few spikes; heights rounded to 1 um."""
    rng = np.random.default_rng(seed)
    x = np.arange(int(length_mm / dx)) * dx
    z = np.zeros(len(x))
    for lam in rng.uniform(2, 50, 40):
        z += rng.normal(0, 0.25 * (lam / 50) ** 0.7) * np.sin(2 * np.pi * x / lam + rng.uniform(0, 6.3))
    z += 5.0 * np.sin(2 * np.pi * x / 3000.0) + rng.normal(0, 0.02, len(x))
    for _ in range(int(length_mm / 400)):
        i = rng.integers(0, len(x) - 40)
        z[i : i + rng.integers(2, 40)] = np.nan
    for i in rng.integers(0, len(x) - 3, int(length_mm / 500)):
        z[i : i + 2] += rng.choice([-1, 1]) * rng.uniform(4, 8)
    return x, np.round(z, 3)


@pytest.mark.peer
@pytest.mark.parametrize("plates", [True, False])
def test_one_mm_profiles_agree_with_captif_slp(profiles, plates):
    """The CAPTIF-like runs thinned to 1 mm (ISO 13473-1's coarsest spacing): evaluated at 1 mm, segment by
    segment as captif-slp with target_sample_spacing_mm=1.0 (the issue's bound 0.5 %; measured: identical)."""
    worst = 0.0
    for seed in range(3):
        x, z = thin_to_mm(*profiles[(seed, plates)])
        segs = profile_segments(z, x, detect_plates=plates)
        assert segs.spacing_mm == 1.0
        ref, ref_seg = _captif(x, z, detect_plates=plates, target_sample_spacing_mm=1.0)
        assert len(segs.msd_mm) == len(ref_seg) >= 9
        ref_msd = np.array([s["msd"] for s in ref_seg])
        worst = max(worst, float(np.max(np.abs(segs.msd_mm / ref_msd - 1))))
        np.testing.assert_allclose(segs.msd_mm, ref_msd, rtol=5e-3)
        np.testing.assert_array_equal(segs.valid, [s["valid"] for s in ref_seg])
        ours = summarise(segs)
        assert ours.mpd_mm == pytest.approx(ref["mpd"], rel=5e-3)
        # the same run at 0.0375 mm: thinning to 1 mm moves the MPD by a few %, not by a factor
        native = summarise(profile_segments(*profiles[(seed, plates)][::-1], detect_plates=plates))
        assert ours.mpd_mm == pytest.approx(native.mpd_mm, rel=0.15)
    assert worst < 1e-6


@pytest.mark.peer
@pytest.mark.parametrize("evaluation_length_m", [None, 5.0, 20.0])
def test_twenty_metre_profile_at_1mm_agrees_with_captif_slp(evaluation_length_m):
    x, z = road_profile(7)
    segs = profile_segments(z, x, evaluation_length_m=evaluation_length_m)
    ref, ref_seg = _captif(x, z, target_sample_spacing_mm=1.0, evaluation_length_m=evaluation_length_m)
    assert len(segs.msd_mm) == len(ref_seg) == 200
    np.testing.assert_allclose(segs.msd_mm, [s["msd"] for s in ref_seg], rtol=5e-3, atol=2e-6)
    np.testing.assert_array_equal(segs.valid, [s["valid"] for s in ref_seg])
    assert (~segs.valid).any() and segs.valid.sum() > 150  # dropout runs and spikes do invalidate some
    if evaluation_length_m is None:
        assert summarise(segs).mpd_mm == pytest.approx(ref["mpd"], rel=5e-3)
        return
    from skidsim.texture.mpd import evaluation_lengths

    np.testing.assert_array_equal(segs.evaluation_end_m, [s["evaluation_length_position_m"] for s in ref_seg])
    per = evaluation_lengths(segs)
    ref = ref if hasattr(ref, "columns") else __import__("pandas").DataFrame([ref])
    assert list(per["end_m"]) == list(ref["distance_m"]) == list(np.arange(1, len(ref) + 1) * evaluation_length_m)
    np.testing.assert_allclose(per["mpd_mm"], ref["mpd"], rtol=5e-3)
    np.testing.assert_allclose(per["sd_mm"], ref["stdev"], rtol=5e-3)
    np.testing.assert_array_equal(per["n_valid"], ref["valid_segments"])
    np.testing.assert_array_equal(per["is_valid"], ref["is_valid"])
    # the high-pass removes the 3 m unevenness that the per-segment slope removal would otherwise have to
    spot = summarise(profile_segments(z, x)).mpd_mm
    assert per["mpd_mm"].mean() == pytest.approx(spot, rel=0.1)


def test_spacing_rules_and_errors():
    from skidsim.texture.mpd import SpacingError, resampled_spacing_mm

    assert resampled_spacing_mm(np.arange(100) * 0.05) == 0.5
    assert resampled_spacing_mm(np.arange(100) * 0.8) == 0.8  # its own spacing
    assert resampled_spacing_mm(np.arange(100) * 1.01) == 1.0  # within 2 % of 1 mm
    assert resampled_spacing_mm(np.arange(100) * 0.05, 1.0) == 1.0  # an option coarser than the profile
    with pytest.raises(SpacingError, match=r"expected a mean distance step of at most 1 mm.*got mean step 1.25 mm"):
        resampled_spacing_mm(np.arange(100) * 1.25)
    with pytest.raises(SpacingError, match=r"resample_mm 0.5 mm\) no finer than the profile's mean distance step"):
        resampled_spacing_mm(np.arange(100) * 1.0, 0.5)
    with pytest.raises(Exception, match=r"resample_mm: expected null or a spacing in \(0, 1\] mm"):
        MPDOptions(resample_mm=2.0)
    # a 1 mm profile evaluated at 1 mm: a 2.4 mm low-pass still lies above its 2 mm Nyquist wavelength
    x = np.arange(0, 300.0, 1.0)
    z = 0.8 * np.cos(2 * np.pi * x / 20.0)
    segs = profile_segments(z, x)
    assert segs.spacing_mm == 1.0 and len(segs.msd_mm) == 3
    # the standard's steps on the ideal samples of the middle segment (100, 200]: zero-phase low-pass gain |H|^2
    # of the filter designed for 1 mm at the cosine's frequency, least-squares line removed, half-segment peaks
    from scipy import signal

    _, h = signal.sosfreqz(signal.butter(2, (1 / 2.4) / 0.5, output="sos"), worN=[2 * np.pi * 1.0 / 20.0])
    seq = abs(h[0]) ** 2 * z[101:201]
    seq = seq - np.polyval(np.polyfit(x[101:201], seq, 1), x[101:201])
    expected = 0.5 * (seq[:50].max() + seq[50:].max()) - seq.mean()
    # (the 0.5 mm filter applied to 1 mm samples cuts at 4.8 mm: its gain at 20 mm is 0.2 % lower)
    assert segs.msd_mm[1] == pytest.approx(expected, rel=1e-4)


def test_cli_one_mm_real_format_and_units(tmp_path, capsys):
    """`skidsim mpd` on a CAPTIF-format run thinned to 1 mm gives an MPD (it printed n/a before), the same with
    distances in m stated by the column name, and refuses what it cannot read as a texture profile."""
    x, z = thin_to_mm(*instrument_profile(4, length_mm=1914.0, plates=False))
    path = write_captif(tmp_path / "run_1mm.dat", x, z)
    assert main(["mpd", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    ref = summarise(profile_segments(z, x))
    n_valid = ref.n_segments - ref.n_invalid_segments
    assert ref.n_segments == 19 and out[0].startswith(
        f"MPD {ref.mpd_mm:.4f} mm, SD {ref.sd_mm:.4f} mm, {n_valid} valid"
    )
    assert "resampled at 1 mm" in out[1] and "in mm (column name), mm (column name)" in out[1]
    variants = {
        "Distance (m)": x / 1000,
        "Distance_m": x / 1000,
        "distance [mm]": x,
        "position um": x * 1000,
        "Distance (µm)": x * 1000,
    }
    for name, values in variants.items():
        p = tmp_path / "units.csv"
        p.write_text(f"{name},Height (mm)\n" + "".join(f"{a:.6f},{b:.3f}\n" for a, b in zip(values, z)))
        prof = read_profile(p)
        np.testing.assert_allclose(prof.distance_mm, x, atol=1e-6, err_msg=name)
        assert main(["mpd", str(p)]) == 0, name
        assert capsys.readouterr().out.startswith(f"MPD {ref.mpd_mm:.4f} mm"), name
    # heights in um stated by the name; an unnamed unit given by the option
    p = tmp_path / "um.csv"
    p.write_text("x_mm;z_um\n" + "".join(f"{a:g};{b * 1000:.0f}\n" for a, b in zip(x, z)))
    np.testing.assert_allclose(read_profile(p).height_mm, z, atol=1e-9)
    p = tmp_path / "plain.csv"
    p.write_text("distance,height\n" + "".join(f"{a / 1000:.3f},{b:.3f}\n" for a, b in zip(x, z)))
    assert main(["mpd", str(p), "--distance-unit", "m"]) == 0
    assert capsys.readouterr().out.startswith(f"MPD {ref.mpd_mm:.4f} mm")
    # never a silent different number: metres read as mm, an option against the name, > 1 mm spacing
    assert main(["mpd", str(p)]) == 2
    err = capsys.readouterr().err
    assert "plain.csv: column 'distance': expected a median distance step of 0.005 to 10 mm" in err
    assert "distances read in mm (default)" in err and "got '0.001 mm'" in err
    q = tmp_path / "named.csv"
    q.write_text("Distance_m,height\n" + "".join(f"{a / 1000:.3f},{b:.3f}\n" for a, b in zip(x, z)))
    with pytest.raises(ProfileFormatError, match=r"column 'Distance_m': expected the distance unit its name states"):
        read_profile(q, distance_unit="mm")
    p = tmp_path / "coarse.csv"
    p.write_text("distance,height\n" + "".join(f"{2 * a:g},{b:.3f}\n" for a, b in zip(x, z)))
    assert main(["mpd", str(p)]) == 2
    err = capsys.readouterr().err
    assert "coarse.csv: column 'distance': expected a mean distance step of at most 1 mm" in err
    assert "got 'mean step 2 mm'" in err


def test_reader_refuses_heights_that_are_not_a_texture_profile(tmp_path):
    x, z = thin_to_mm(*instrument_profile(5, length_mm=400.0, plates=False))
    cases = {
        "flat": (np.full_like(z, 1.25), r"column 'height': expected heights spanning at least 0.01 mm"),
        "metres": (z / 1000, r"column 'height': expected heights spanning at least 0.01 mm"),
        "micrometres": (z * 1000, r"column 'height': expected a median height step .* at most 5 mm"),
    }
    for name, (h, msg) in cases.items():
        p = tmp_path / f"{name}.csv"
        p.write_text("distance,height\n" + "".join(f"{a:g},{b:.6f}\n" for a, b in zip(x, h)))
        with pytest.raises(ProfileFormatError, match=msg):
            read_profile(p)
    p = tmp_path / "metres.csv"
    np.testing.assert_allclose(read_profile(p, height_unit="m").height_mm, z, atol=1e-6)


@pytest.mark.slow
def test_one_kilometre_at_1mm_in_seconds_with_bounded_memory(tmp_path):
    """A 1 km long run at 1 mm (10^6 samples), distances in m as network profilers write them: read and
    evaluated in seconds; the memory the two steps allocate is bounded by ~150 bytes per sample."""
    import time
    import tracemalloc

    x, z = road_profile(11, length_mm=1_000_000.0)
    p = tmp_path / "network_1km.csv"
    with open(p, "w") as fh:
        fh.write("Chainage (m),Height (mm)\n")
        fh.write("\n".join(f"{a / 1000:.3f},{'NaN' if b != b else f'{b:.3f}'}" for a, b in zip(x, z)))
    t0 = time.process_time()
    prof = read_profile(p)
    segs = profile_segments(prof.height_mm, prof.distance_mm, evaluation_length_m=20.0)
    cpu_s = time.process_time() - t0
    tracemalloc.start()  # a second run under tracemalloc (which slows it about four times)
    profile_segments(read_profile(p).height_mm, prof.distance_mm, evaluation_length_m=20.0)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert len(prof.distance_mm) == 1_000_000 and prof.units == ("m", "mm")
    assert len(segs.msd_mm) == 10_000 and segs.spacing_mm == 1.0
    assert cpu_s < 15.0, cpu_s  # measured 2026-11-28: 1.9 s CPU on the shared 2-core machine
    assert peak < 150 * 1_000_000, peak  # measured: 76 MB
    assert np.isfinite(segs.evaluation_end_m).all() and len(np.unique(segs.evaluation_end_m)) == 50


@pytest.mark.peer
def test_real_captif_profile_thinned_to_1mm(capsys):
    """116 mm of a real CAPTIF run (captif-slp's test data, 0.0375 mm) thinned to 1 mm, with its dropouts and
    steep chip edges: `skidsim mpd` evaluates it at 1 mm (it printed MPD n/a before) and every segment agrees with
    captif-slp at target_sample_spacing_mm=1.0 (measured 2026-11-28: identical, MSD 2.540600 mm)."""
    from pathlib import Path

    path = Path(__file__).parent / "data" / "captif_station0_1mm.csv"
    prof = read_profile(path)
    assert prof.columns == ("Distance (mm)", "Depth (mm)") and prof.n_dropouts == 4 and len(prof.distance_mm) == 116
    segs = profile_segments(prof.height_mm, prof.distance_mm)
    _, ref_seg = _captif(prof.distance_mm, prof.height_mm, target_sample_spacing_mm=1.0)
    assert segs.spacing_mm == 1.0 and len(segs.msd_mm) == len(ref_seg) == 1
    assert segs.msd_mm[0] == pytest.approx(ref_seg[0]["msd"], rel=5e-3)
    assert segs.msd_mm[0] == pytest.approx(2.540600, abs=1e-6) and segs.valid[0] == ref_seg[0]["valid"]
    assert segs.spike_pct[0] == pytest.approx(100 * 2 / 101) and segs.dropout_pct[0] == pytest.approx(100 * 4 / 101)
    assert main(["mpd", str(path)]) == 0
    assert capsys.readouterr().out.startswith("MPD 2.5406 mm, SD n/a mm, 1 valid segment, 0 invalid segments")


def test_long_files_read_the_same_by_numpy_and_cell_by_cell(tmp_path):
    """Files longer than the head the reader sniffs (HEAD_LINES) go to NumPy's parser; a decimal comma sends them
    cell by cell; both give the same numbers, and a bad cell deep in the file is named by its line."""
    from skidsim.profiles import HEAD_LINES

    n = HEAD_LINES + 3000
    x = np.round(np.arange(n) * 0.05, 3)
    z = np.round(np.sin(x), 3)
    z[[10, 6000]] = np.nan
    dot = tmp_path / "dot.csv"
    dot.write_text("distance;height\n" + "".join(f"{a:.3f};{'NaN' if b != b else f'{b:.3f}'}\n" for a, b in zip(x, z)))
    comma = tmp_path / "comma.csv"
    comma.write_text(dot.read_text().replace(".", ","))
    for p in (dot, comma):
        prof = read_profile(p)
        np.testing.assert_array_equal(prof.distance_mm, x)
        np.testing.assert_array_equal(prof.height_mm, z)  # NaN where z is NaN
    lines = dot.read_text().splitlines()
    lines[HEAD_LINES + 500] = "five;0.1"
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(ProfileFormatError, match=rf"bad.csv: line {HEAD_LINES + 501}, column 'distance': .*'five'"):
        read_profile(bad)


def test_units_in_latin1_and_utf8_names(tmp_path):
    """A German export in Latin-1 (micro sign as byte 0xB5, decimal commas) and the same in UTF-8 with the Greek
    mu: distances in m and heights in um, both converted to mm."""
    x = np.arange(300) * 0.5
    z = np.round(0.8 * np.sin(2 * np.pi * x / 12.0), 3)
    body = "".join(f"{a / 1000:.4f};{b * 1000:.0f}\n".replace(".", ",") for a, b in zip(x, z))
    latin = tmp_path / "latin1.txt"
    latin.write_bytes(("Messung;Strecke 3\nAbstand (m);Höhe (µm)\n" + body).encode("latin-1"))
    greek = tmp_path / "greek.txt"
    greek.write_text("Abstand [m];z (\u03bcm)\n" + body, encoding="utf-8")
    for p in (latin, greek):
        prof = read_profile(p, distance_col="Abstand", height_col=1)
        assert prof.units == ("m", "µm" if p is latin else "\u03bcm"), p.name
        np.testing.assert_allclose(prof.distance_mm, x, atol=1e-9)
        np.testing.assert_allclose(prof.height_mm, z, atol=1e-9)


def test_cli_evaluation_lengths_of_a_network_run(tmp_path, capsys):
    from skidsim.texture.mpd import evaluation_lengths

    x, z = road_profile(3)
    p = tmp_path / "run_20m.csv"
    p.write_text("Distance_m,Height_mm\n" + "".join(f"{a / 1000:.3f},{b:.3f}\n" for a, b in zip(x, z)))
    out_csv = tmp_path / "segments.csv"
    assert main(["mpd", str(p), "--evaluation-length-m", "5", "-o", str(out_csv)]) == 0
    lines = capsys.readouterr().out.splitlines()
    per = evaluation_lengths(profile_segments(z, x, evaluation_length_m=5.0))
    shown = [ln for ln in lines if ln.startswith("  evaluation length to ")]
    assert len(shown) == 4 == len(per)
    for ln, r in zip(shown, per.itertuples()):
        assert ln.startswith(f"  evaluation length to {r.end_m:g} m: MPD {r.mpd_mm:.4f} mm, SD {r.sd_mm:.4f} mm")
    import pandas as pd

    seg = pd.read_csv(out_csv)
    assert list(seg["evaluation_end_m"].unique()) == [5.0, 10.0, 15.0, 20.0]
