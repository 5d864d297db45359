"""MPD per ISO 13473-1:2019 on profiles with known answers."""

import numpy as np
import pytest
from scipy import signal

from skidsim.surface import Surface
from skidsim.texture import mean_profile_depth


def sine_scan(rows=6, cols=2448, dx=0.05, amp=0.8, lam=10.0):
    x = np.arange(cols) * dx
    # crests at bin centres (0.225 mm + k 0.5 mm), the first 5 mm from the start (away from filter transients)
    z = amp * np.cos(2 * np.pi * (x - 0.225 - 5.0) / lam)
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
    assert res.mpd_mm == pytest.approx(expected_msd(0.8, 20.0, lowpass=False), rel=1e-9)


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
    with pytest.raises(ValueError, match="shorter than one"):
        mean_profile_depth(Surface(np.zeros((4, 100)), 0.05, 0.05))
