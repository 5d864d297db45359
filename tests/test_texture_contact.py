"""Contact-zone microtexture (skidsim.texture.contact): analytic values, the top zone, errors, and LS-40-like scans
(integer 0.01 mm codes, flat binder, dropouts, tilt) through the whole texture stage."""

from __future__ import annotations

import numpy as np
import pytest
from test_texture_despeckle import DX_MM, flat_binder_scan

from skidsim.errors import ConfigError
from skidsim.surface import Surface
from skidsim.texture import TextureOptions, characterise, cross_band_parameters, separate_bands
from skidsim.texture.contact import contact_parameters, top_zone


def plateau_surface(rows=40, cols=400, plateau_cols=(100, 300)):
    """Raw heights (mm): binder at 0, one plateau of tops at 1 mm over the columns ``plateau_cols``."""
    raw = np.zeros((rows, cols))
    raw[:, plateau_cols[0] : plateau_cols[1]] = 1.0
    return raw


def test_sine_on_the_tops_only_gives_its_rms_and_its_discrete_slope():
    """micro = A sin(k x) on the plateau (whole periods), 0 on the binder: Sq_top = A / sqrt(2) exactly, while the
    whole-scan rms is diluted by the plateau's share; Sdq_top = A sqrt(1 - cos(k dx)) / dx, the forward
    difference's rms over whole periods (the differences leaving the plateau on its right edge included)."""
    dx, amp, period = 0.05, 0.02, 20  # mm, mm, points
    raw = plateau_surface()
    j = np.arange(raw.shape[1])
    micro = np.where(raw > 0, amp * np.sin(2 * np.pi * j / period)[None, :], 0.0)
    p = contact_parameters(raw, micro, dx, dx, top_pct=10.0)  # ties: the whole plateau (50 %) is the zone
    assert p["Sq_top"] == pytest.approx(amp / np.sqrt(2), rel=1e-12)
    whole = np.sqrt(np.mean((micro - micro.mean()) ** 2))
    assert whole == pytest.approx(amp / np.sqrt(2) * np.sqrt(0.5), rel=1e-9)
    k_dx = 2 * np.pi / period
    assert p["Sdq_top"] == pytest.approx(amp * np.sqrt(1 - np.cos(k_dx)) / dx, rel=1e-9)


def test_a_plane_has_its_gradient_on_any_zone():
    rng = np.random.default_rng(3)
    raw = rng.normal(size=(60, 80))
    y, x = np.mgrid[0:60, 0:80]
    dx, dy, a, b = 0.05, 0.1, 0.03, -0.02  # mm, mm, mm/mm, mm/mm
    micro = a * x * dx + b * y * dy
    for pct in (5.0, 10.0, 50.0, 100.0):
        assert contact_parameters(raw, micro, dx, dy, pct)["Sdq_top"] == pytest.approx(np.hypot(a, b), rel=1e-12)


def test_top_zone_is_the_material_ratio_share_of_distinct_heights():
    z = np.random.default_rng(0).normal(size=(101, 99))
    for pct in (1.0, 10.0, 37.5):
        share = top_zone(z, pct).mean()
        assert abs(share - pct / 100) <= 1.0 / z.size
    assert top_zone(z, 100.0).all()
    codes = np.round(z, 1)  # ties at the bound are all in the zone
    c = np.quantile(codes, 0.9)
    assert top_zone(codes, 10.0).sum() == np.count_nonzero(codes >= c) >= 0.1 * z.size


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: top_zone(np.zeros((4, 4)), 0.0), "top_pct must lie in"),
        (lambda: top_zone(np.full((4, 4), np.nan), 10.0), "invalid points"),
        (lambda: contact_parameters(np.zeros((4, 4)), np.zeros((4, 5)), 0.05, 0.05), "differ in shape"),
        (lambda: contact_parameters(np.zeros((4, 4)), np.full((4, 4), np.nan), 0.05, 0.05), "micro band has invalid"),
    ],
)
def test_bad_input_is_named(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_option_is_checked_and_the_group_can_be_left_out():
    with pytest.raises(ConfigError, match="texture.contact_top_pct"):
        TextureOptions(contact_top_pct=0.0)
    with pytest.raises(ConfigError, match="unknown group"):
        TextureOptions(groups=("contact", "tops"))
    s = Surface(np.random.default_rng(1).normal(size=(32, 64)), 0.05, 0.05, name="s")
    bands = separate_bands(s, macro=(0.5, 50.0))
    assert cross_band_parameters(bands, {"groups": ["height"]}) == {}
    got = cross_band_parameters(bands, {"contact_top_pct": 20.0})["micro"]
    direct = contact_parameters(bands["raw"].heights, bands["micro"].heights, 0.05, 0.05, 20.0)
    assert got == {"Sq_top": (direct["Sq_top"], "mm"), "Sdq_top": (direct["Sdq_top"], "1")}


def _micro(df, name):
    return float(df[(df.band == "micro") & (df.parameter == name)]["value"].iloc[0])


@pytest.fixture(scope="module")
def binder_series():
    """The whole texture stage on LS-40-like scans whose stones carry the same microtexture (0.03 mm rms white
    noise, integer 0.01 mm codes) and whose flat binder covers 40 %, 70 % and 88 % of the scan; with tilt and 1 %
    dropouts."""
    out = {}
    for share in (0.4, 0.7, 0.88):
        h = flat_binder_scan(
            share, seed=7, shape=(160, 1024), tilt=(0.004, -0.002), dropout_share=0.01, stone_noise_mm=0.03
        )
        df, _ = characterise(Surface(h, DX_MM, DX_MM, name=f"binder{share}"), {"groups": ["height", "contact"]})
        out[share] = df
    return out


def test_flat_binder_dilutes_the_whole_scan_micro_sq_but_not_the_contact_zones(binder_series):
    sq = {s: _micro(df, "Sq") for s, df in binder_series.items()}
    top = {s: _micro(df, "Sq_top") for s, df in binder_series.items()}
    # the whole-scan micro Sq falls with the binder's share (sqrt of the stones' share, roughly) ...
    assert sq[0.88] / sq[0.4] < 0.6
    # ... the contact zone sees the stones' microtexture at every share (at 88 % binder the top 10 % reaches the
    # flanks of the stones, 12 % of the scan, whose edges put some of the cap shape into the micro band)
    assert 0.9 < top[0.7] / top[0.4] < 1.1 and 0.9 < top[0.88] / top[0.4] < 1.25
    for s in binder_series:
        # white noise of 0.03 mm rms, quantised to 0.01 mm codes, below the 0.5 mm cut: most of its variance
        assert 0.022 < top[s] < 0.034, (s, top[s])
        assert _micro(binder_series[s], "Sdq_top") > 0.3  # rms slope of 0.03 mm noise on a 0.05 mm grid
