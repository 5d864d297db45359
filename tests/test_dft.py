"""DFT trace reading, interpolation against hand values, local regression, and every bad trace."""

from __future__ import annotations

import numpy as np
import pytest

from skidsim.dft import DftTrace, read_dft
from skidsim.errors import DftError


def write(tmp_path, text, name="t.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_read_unsorted_extra_columns_duplicates_averaged(tmp_path):
    p = write(
        tmp_path,
        "time_s,mu,speed_kmh,torque_nm\n"
        "0.0,0.40,80,1\n"
        "0.5,0.50,40,1\n"
        "0.7,0.52,40,1\n"  # duplicate speed: mean 0.51
        "0.9,0.60,10,1\n"
        "\n",
    )
    tr = read_dft(p)
    np.testing.assert_array_equal(tr.speeds_kmh, [10.0, 40.0, 80.0])
    np.testing.assert_allclose(tr.mu, [0.60, 0.51, 0.40])
    assert tr.range_kmh == (10.0, 80.0)
    # hand values: 20 km/h is 1/3 of the way 10 -> 40: 0.60 + (0.51 - 0.60) / 3 = 0.57
    #              60 km/h is halfway 40 -> 80: (0.51 + 0.40) / 2 = 0.455
    np.testing.assert_allclose(tr.at([20, 60, 10, 80]), [0.57, 0.455, 0.60, 0.40], rtol=1e-12)
    assert tr.at(40.0) == pytest.approx(0.51)


def test_at_outside_range_names_file_speed_and_range(tmp_path):
    tr = read_dft(write(tmp_path, "speed_kmh,mu\n25,0.5\n65,0.4\n", name="short.csv"))
    with pytest.raises(DftError) as ei:
        tr.at([30, 70])
    msg = str(ei.value)
    assert "short.csv" in msg and "25-65 km/h" in msg and "70" in msg
    assert ei.value.got == 70.0
    assert tr.covers([30, 60]) and not tr.covers([20, 30])


def test_smooth_at_reproduces_a_line_and_averages_noise():
    v = np.linspace(10, 80, 141)  # 0.5 km/h steps
    line = 0.7 - 0.004 * v
    tr = DftTrace.from_samples(v, line)
    np.testing.assert_allclose(
        tr.smooth_at([20, 45.2, 79], window_kmh=5), 0.7 - 0.004 * np.array([20, 45.2, 79]), rtol=1e-12
    )
    # on a noisy trace the local fit is closer to the truth than the raw samples (variance ~ 1/n)
    rng = np.random.default_rng(7)
    noisy = DftTrace.from_samples(v, line + rng.normal(0, 0.02, v.size))
    targets = np.arange(20.0, 71.0, 10.0)
    err_smooth = np.abs(noisy.smooth_at(targets, window_kmh=5) - (0.7 - 0.004 * targets))
    err_interp = np.abs(noisy.at(targets) - (0.7 - 0.004 * targets))
    assert err_smooth.max() < 0.02 and err_smooth.mean() < err_interp.mean()


def test_smooth_at_hand_value_and_one_sided_window():
    # points (10, .6), (20, .5), (30, .5): OLS over all three at v=20: slope -0.005, mean .5333 at 20 -> .5333
    tr = DftTrace.from_samples([10, 20, 30], [0.6, 0.5, 0.5])
    assert tr.smooth_at(20, window_kmh=10) == pytest.approx(1.6 / 3)
    # at the end v=30 with window 10: points 20, 30 only -> the line through them: 0.5
    assert tr.smooth_at(30, window_kmh=10) == pytest.approx(0.5)
    with pytest.raises(DftError, match="within \\+-2 km/h"):
        tr.smooth_at(25, window_kmh=2)


@pytest.mark.parametrize(
    "text,row,column,fragment",
    [
        ("speed,mu\n20,0.5\n30,0.4\n", 1, None, "missing speed_kmh"),
        ("speed_kmh,friction\n20,0.5\n30,0.4\n", 1, None, "missing mu"),
        ("speed_kmh,mu\n20,0.5\n30,abc\n40,0.3\n", 3, "mu", "a number"),
        ("speed_kmh,mu\n20,0.5\n\n30,0.4\nfast,0.3\n", 5, "speed_kmh", "a number"),
        ("speed_kmh,mu\n20,0.5\n30,nan\n", 3, "mu", "a finite number"),
        ("speed_kmh,mu\n20,0.5\n30,1.5\n", 3, "mu", "between 0 and 1.5"),
        ("speed_kmh,mu\n20,0\n30,0.4\n", 2, "mu", "between 0 and 1.5"),
        ("speed_kmh,mu\n-5,0.5\n30,0.4\n", 2, "speed_kmh", ">= 0"),
        ("speed_kmh,mu\n20,0.5\n", None, None, "at least 2 data rows"),
        ("speed_kmh,mu\n20,0.5\n20,0.4\n", None, None, "2 or more distinct speeds"),
        ("", 1, None, "empty file"),
    ],
)
def test_bad_traces(tmp_path, text, row, column, fragment):
    p = write(tmp_path, text, name="bad.csv")
    with pytest.raises(DftError) as ei:
        read_dft(p)
    e = ei.value
    assert e.file == str(p) and e.row == row and e.column == column
    assert fragment in str(e)
    if row is not None:
        assert f"row {row}" in str(e)


def test_missing_file(tmp_path):
    with pytest.raises(DftError, match="no such file"):
        read_dft(tmp_path / "none.csv")


def test_trace_constructor_rejects_unsorted():
    with pytest.raises(DftError, match="strictly increasing"):
        DftTrace(np.array([30.0, 20.0]), np.array([0.4, 0.5]))
