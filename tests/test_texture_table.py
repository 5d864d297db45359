"""Long/wide tables, Table 4 statistics, the whole stage on a small scan, options, figures."""

import numpy as np
import pandas as pd
import pytest
from scipy import ndimage

from skidsim.surface import Surface
from skidsim.texture import (
    GROUPS,
    UNITS,
    TextureOptions,
    areal_parameters,
    campaign_table,
    characterise,
    table4_statistics,
    texture_table,
    write_texture_table,
)
from skidsim.texture.mpd import MPDResult


def small_scan(seed=0, rows=48, cols=2100):
    rng = np.random.default_rng(seed)
    z = ndimage.gaussian_filter(rng.standard_normal((rows, cols)), (3, 12)) * 3.0
    z += 0.02 * rng.standard_normal((rows, cols)) + 0.001 * np.arange(cols)[None, :]
    z[5, cols // 3] = 9.0  # a speckle
    z[10, 20:30] = np.nan  # dropouts
    return Surface(z, 0.05, 0.05, name=f"site{seed}")


def test_characterise_small_scan_long_table():
    df, bands = characterise(small_scan(), {"workers": 1})
    assert list(df.columns) == ["site", "band", "parameter", "value", "unit"]
    assert set(df["band"]) == {"raw", "macro", "micro", "profile"}
    single_band = [k for k in UNITS if k not in GROUPS["contact"]]
    for band in ("raw", "macro", "micro"):
        names = df.loc[df["band"] == band, "parameter"].tolist()
        assert names == (list(UNITS) if band == "micro" else single_band), band  # contact zone: with micro only
    assert bands["despeckled"].meta["n_despeckled"] >= 1
    assert not np.isnan(bands["micro"].heights).any()
    # consistency: band values are the ones areal_parameters gives for that band
    direct = areal_parameters(bands["macro"], "macro", {"groups": ["height"]})
    got = df[(df.band == "macro") & (df.parameter == "Sq")]["value"].iloc[0]
    assert got == pytest.approx(direct["Sq"][0], rel=1e-12) and direct["Sq"][1] == "mm"
    mpd = df[(df.band == "profile") & (df.parameter == "MPD")]["value"].iloc[0]
    etd = df[(df.band == "profile") & (df.parameter == "ETD")]["value"].iloc[0]
    assert etd == pytest.approx(1.1 * mpd)


def test_campaign_table_and_table4(tmp_path):
    params = {"macro": {"Sq": (0.3, "mm")}, "micro": {"Sq": (0.02, "mm")}}
    t1 = texture_table("A", params, MPDResult(0.5, 0.1, 10, 0, 0.55, np.array([0.5])))
    t2 = texture_table(
        "B",
        {"macro": {"Sq": (0.5, "mm")}, "micro": {"Sq": (0.04, "mm")}},
        MPDResult(0.7, 0.1, 10, 1, 0.77, np.array([0.7])),
    )
    write_texture_table(t1, tmp_path / "A.parquet")
    back = pd.read_parquet(tmp_path / "A.parquet")
    assert back.shape == t1.shape and not list(tmp_path.glob(".*tmp"))
    sites = pd.DataFrame({"site": ["A", "B", "C"], "mix": ["HMA", "WMA", "WMA"]})
    wide = campaign_table([t1, t2], sites)
    assert list(wide["site"]) == ["A", "B", "C"]
    assert wide.loc[1, "macro_Sq"] == 0.5 and np.isnan(wide.loc[2, "macro_Sq"])
    assert wide.loc[0, "profile_MPD"] == 0.5
    t4 = table4_statistics(wide)
    assert t4.loc["Sq", ("Average", "macro")] == pytest.approx(0.4)
    assert t4.loc["Sq", ("Maximum", "micro")] == pytest.approx(0.04)
    assert t4.loc["Sq", ("Standard Deviation", "macro")] == pytest.approx(np.std([0.3, 0.5], ddof=1))
    with pytest.raises(ValueError, match="duplicated"):
        campaign_table([t1, t1])


def test_options_validation_and_incomplete_surface():
    from skidsim.errors import ConfigError

    with pytest.raises(ConfigError, match="unknown key"):
        TextureOptions.from_dict({"pruning": 5})
    with pytest.raises(ConfigError, match="group"):
        TextureOptions.from_dict({"groups": ["height", "fractal"]})
    with pytest.raises(ConfigError, match="texture.despeckle_method"):
        TextureOptions.from_dict({"despeckle_method": "median"})
    with pytest.raises(ConfigError, match="texture.macro_mm"):
        TextureOptions.from_dict({"macro_mm": [50, 0.5]})
    assert TextureOptions.from_dict({"macro_mm": [0.4, 40]}).macro_mm == (0.4, 40)
    z = np.zeros((20, 20))
    z[3, 3] = np.nan
    with pytest.raises(ValueError, match="fill"):
        areal_parameters(Surface(z, 0.05, 0.05, name="x"), "raw")


def test_figures_are_written(tmp_path):
    from skidsim.plotting.texture import plot_campaign_distributions, plot_despeckle_comparison, plot_figure7

    s = small_scan(rows=40, cols=300)
    plot_figure7(s, s, s, s, tmp_path / "f7.png")
    plot_despeckle_comparison(s.heights[5], 0.05, {"tukey": s.heights[5] * 0}, tmp_path / "d.png")
    wide = pd.DataFrame({"site": ["a", "b", "c"], "macro_Sq": [0.1, 0.2, 0.3], "micro_Sq": [0.01, 0.02, 0.03]})
    plot_campaign_distributions(wide, tmp_path / "c.png")
    for f in ("f7.png", "d.png", "c.png"):
        assert (tmp_path / f).stat().st_size > 5000
    with pytest.raises(ValueError, match="none of"):
        plot_campaign_distributions(wide, tmp_path / "x.png", parameters=("Sk",))


def test_thread_pool_gives_identical_results():
    s = small_scan(seed=1, rows=40, cols=2050)
    a, _ = characterise(s, {"workers": 1})
    b, _ = characterise(s, {"workers": 2})
    pd.testing.assert_frame_equal(a, b)
