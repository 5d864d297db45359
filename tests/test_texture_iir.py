"""skidsim.texture.iir: SciPy's butter(2, ..., output="sos") and sosfiltfilt, the same bits without scipy.signal;
skidsim._lazy and skidsim._lean (start-up only)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from skidsim.texture.iir import butter2_sos, sosfiltfilt

signal = pytest.importorskip("scipy.signal")


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.view(np.int64), b.view(np.int64))


@pytest.mark.parametrize("btype", ["low", "high"])
def test_butter2_sos_is_scipy_bit_for_bit(btype):
    wns = np.r_[np.random.default_rng(3).uniform(1e-4, 0.999, 400), 0.5, 0.25, 0.1, 1 / 3, 0.5 / 2.4 / 1.0]
    for wn in wns:
        assert _same_bits(butter2_sos(float(wn), btype), signal.butter(2, float(wn), btype=btype, output="sos")), wn


@pytest.mark.parametrize("seed", range(6))
def test_sosfiltfilt_is_scipy_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    rows, n = int(rng.integers(1, 40)), int(rng.integers(10, 500))
    x = rng.standard_normal((rows, n)).cumsum(axis=1) * rng.uniform(0.01, 10.0)
    for btype in ("low", "high"):
        sos = signal.butter(2, float(rng.uniform(0.01, 0.99)), btype=btype, output="sos")
        assert _same_bits(sosfiltfilt(sos, x), signal.sosfiltfilt(sos, x, axis=1))


def test_sosfiltfilt_long_rows_go_to_scipy(monkeypatch):
    from skidsim.texture import iir

    rng = np.random.default_rng(9)
    x = rng.standard_normal((3, 300)).cumsum(axis=1)
    sos = butter2_sos(0.2, "high")
    own = sosfiltfilt(sos, x)
    monkeypatch.setattr(iir, "MAX_SAMPLES", 100)
    assert _same_bits(sosfiltfilt(sos, x), own)
    assert _same_bits(own, signal.sosfiltfilt(sos, x, axis=1))


def test_sosfiltfilt_short_profile_raises_like_scipy():
    sos = butter2_sos(0.3, "low")
    x = np.ones((2, 9))
    with pytest.raises(ValueError):
        signal.sosfiltfilt(sos, x, axis=1)
    with pytest.raises(ValueError, match="padlen"):
        sosfiltfilt(sos, x)
    with pytest.raises(ValueError):
        butter2_sos(1.0, "low")
    with pytest.raises(ValueError):
        butter2_sos(0.3, "band")


def test_mpd_step_imports_no_scipy_and_lean_keeps_docstrings():
    """The MPD step's imports load no SciPy module (lazy scipy.ndimage / scipy.fft in skidsim.texture); with
    skidsim._lean, SciPy imports and computes as before, docstrings kept."""
    code = (
        "import sys, skidsim._lean; from skidsim import texture; from skidsim.texture import TextureOptions\n"
        "import skidsim.texture.mpd, skidsim.texture.iir\n"
        "loaded = [m for m, v in sys.modules.items() if type(v).__name__ == 'module']\n"
        "assert not [m for m in loaded if m.startswith(('scipy.ndimage', 'scipy.fft', 'scipy.signal'))], loaded\n"
        "import numpy as np; from scipy import ndimage, signal\n"
        "assert 'Butterworth' in signal.butter.__doc__ and ndimage.label(np.eye(3))[1] == 3\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
