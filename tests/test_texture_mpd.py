"""MPD per ISO 13473-1:2019 on profiles with known answers."""

import numpy as np
import pytest
from scipy import signal

from skidsim.surface import Surface
from skidsim.texture import mean_profile_depth


def sine_scan(rows=6, cols=2448, dx=0.05, amp=0.8, lam=10.0):
    x = np.arange(cols) * dx
    # bin k = ceil(x / 0.5 mm) holds x in (0.5 (k - 1), 0.5 k]: its centre is 0.5 k - 0.225 mm; crests at bin
    # centres, the first 5 mm from the start (away from filter transients)
    z = amp * np.cos(2 * np.pi * (x - 0.275 - 5.0) / lam)
    return np.tile(z, (rows, 1)), x


def expected_msd(amp, lam, dx=0.05, lowpass=True):
    """The standard's steps applied analytically to the ideal resampled cosine: bin mean (Dirichlet factor),
    zero-phase low-pass (|H|^2 at the cosine's frequency), least-squares slope removal, half-segment peaks."""
    m = int(round(0.5 / dx))
    binmean = np.sin(np.pi * m * dx / lam) / (m * np.sin(np.pi * dx / lam))
    gain = 1.0
    if lowpass:
        sos = signal.butter(2, (1 / 2.4) / 1.0, output="sos")  # 0.5 mm spacing: Nyquist 1 / mm
        _, h = signal.sosfreqz(sos, worN=[2 * np.pi * 0.5 / lam])
        gain = abs(h[0]) ** 2
    k = np.arange(200)
    seq = amp * binmean * gain * np.cos(2 * np.pi * (k * 0.5 - 5.0) / lam)
    seq = seq - np.polyval(np.polyfit(k, seq, 1), k)
    return 0.5 * (seq[:100].max() + seq[100:].max()) - seq.mean()


def test_mpd_of_sinusoid_matches_analytic():
    z, _ = sine_scan()
    res = mean_profile_depth(Surface(z, 0.05, 0.05))
    assert res.n_segments == 6 and res.n_invalid_segments == 0
    assert res.mpd_mm == pytest.approx(expected_msd(0.8, 10.0), rel=2e-3)
    assert res.etd_mm == pytest.approx(1.1 * res.mpd_mm)
    assert res.sd_mm == pytest.approx(0.0, abs=1e-9)  # identical rows


def test_mpd_without_lowpass_and_point_sampling_difference():
    z, _ = sine_scan(lam=20.0)
    res = mean_profile_depth(Surface(z, 0.05, 0.05), lowpass_mm=None)
    # bin means are rounded to 1e-6 mm (captif-slp); the first bin also holds x = 0 (11 samples, not 10)
    assert res.mpd_mm == pytest.approx(expected_msd(0.8, 20.0, lowpass=False), abs=5e-6)


def test_dropout_and_spike_rules():
    z, _ = sine_scan(rows=4)
    z[1, 100:400] = np.nan  # 300 of the 2000 samples of the first segment: 15 % > 10 %: invalid
    z[2, 100:250] = np.nan  # 7.5 %: interpolated, valid
    z[3, 1000:1010] += 20.0  # one 0.5 mm bin jumps by 20 mm: spike, removed and interpolated
    res = mean_profile_depth(Surface(z, 0.05, 0.05))
    assert res.n_segments == 4 and res.n_invalid_segments == 1
    assert res.msd_mm.max() < 1.0  # the spike did not survive


def test_axis_columns_and_short_profiles():
    z, _ = sine_scan(rows=3)
    res = mean_profile_depth(Surface(z.T.copy(), 0.05, 0.05), axis=0)
    assert res.mpd_mm == pytest.approx(expected_msd(0.8, 10.0), rel=2e-3)


def test_short_profiles_give_nan_and_one_warning(caplog):
    # 84.95 mm profiles: 170 resampled samples, below 90 % of the 200 of a 100 mm segment
    with caplog.at_level("WARNING", logger="skidsim"):
        res = mean_profile_depth(Surface(np.zeros((4, 1700)), 0.05, 0.05, name="short"))
    assert np.isnan(res.mpd_mm) and np.isnan(res.etd_mm) and res.n_segments == 0
    assert [r.getMessage() for r in caplog.records] == [
        "short: MPD not available: profiles are 84.95 mm long, shorter than one 100 mm segment (at least 90 mm needed)"
    ]
    # 90 mm and more (180 samples at 0.5 mm: 90 % of a segment) is evaluated, as captif-slp does
    z, _ = sine_scan(rows=2, cols=1800)
    assert mean_profile_depth(Surface(z, 0.05, 0.05)).n_segments == 2


def test_texture_command_on_scan_shorter_than_one_segment(tmp_path, caplog, capsys):
    """`skidsim texture` on an 80 mm scan: areal parameters computed, MPD NaN, one warning line, exit 0."""
    import pandas as pd

    from skidsim.cli import main
    from skidsim.x3p import write_x3p

    rng = np.random.default_rng(3)
    x = np.arange(1601) * 0.05
    z = 0.5 * np.sin(2 * np.pi * x / 6.0)[None, :] + rng.normal(0, 0.05, (60, 1601))
    path = tmp_path / "short.x3p"
    write_x3p(path, Surface(z, 0.05, 0.05, name="short"))
    out = tmp_path / "short.csv"
    with caplog.at_level("WARNING", logger="skidsim"):
        assert main(["texture", str(path), "-q", "-o", str(out)]) == 0
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert warnings == [
        "short: MPD not available: profiles are 80.00 mm long, shorter than one 100 mm segment (at least 90 mm needed)"
    ]
    table = pd.read_csv(out)
    mpd = table[(table["band"] == "profile") & (table["parameter"] == "MPD")]["value"]
    assert len(mpd) == 1 and mpd.isna().all()
    sq = table[(table["band"] == "raw") & (table["parameter"] == "Sq")]["value"].iloc[0]
    assert sq == pytest.approx(np.sqrt(0.5**2 / 2 + 0.05**2), rel=0.05)  # sine + noise, areal parameters kept


def test_texture_options_reach_the_areal_mpd():
    from skidsim.errors import ConfigError
    from skidsim.texture import TextureOptions

    z, _ = sine_scan(rows=2, cols=4200)  # 210 mm: two 100 mm segments, or one 200 mm segment
    s = Surface(z, 0.05, 0.05)
    assert mean_profile_depth(s, **TextureOptions().mpd_kwargs()).n_segments == 4
    opt = TextureOptions(mpd_segment_mm=200.0, mpd_spike_alpha=2.0, mpd_max_dropout_pct=5.0)
    kw = opt.mpd_kwargs()
    assert kw == {
        "axis": 1,
        "segment_mm": 200.0,
        "spike_alpha": 2.0,
        "detect_plates": False,
        "plate_threshold_mm": 30.0,
        "max_dropout_pct": 5.0,
    }
    assert mean_profile_depth(s, **kw).n_segments == 2
    with pytest.raises(ConfigError, match="texture.mpd_spike_alpha: expected a positive number, got 0.0"):
        TextureOptions(mpd_spike_alpha=0.0)
