"""Tests of the synthetic campaign generator (skidsim.generators.default): design, determinism, realism, files."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pandas as pd
import pytest
from scipy import fft as sfft

from skidsim.errors import ConfigError
from skidsim.generators import default as S
from skidsim.generators import truth as T
from skidsim.generators.default import surface


def small_cfg(rows=96, cols=128, **kw):
    cfg = S.default_config()
    cfg["shape"] = [rows, cols]
    cfg.update(kw)
    return cfg


def row_of(design: pd.DataFrame, site: str) -> dict:
    return design.set_index("site").loc[site].to_dict() | {"site": site}


# ------------------------------------------------------------------------------------------------ design


def test_default_design_mirrors_sps10():
    d = S.design_campaign(S.default_config())
    assert len(d) == 36
    assert list(d.columns[:3]) == ["site", "section", "temperature_c"]
    assert d["site"].is_unique
    assert list(d["site"][:4]) == ["E1-1", "E1-2", "E1-3", "E2-1"]
    assert sorted(d["section"].unique()) == sorted([f"E{i}" for i in range(1, 7)] + [f"C{i}" for i in range(1, 7)])
    assert (d.groupby("section").size() == 3).all()
    # pavement temperature spans exactly the study's range
    assert d["temperature_c"].min() == pytest.approx(11.8) and d["temperature_c"].max() == pytest.approx(18.9)
    assert sorted(d["test_order"]) == list(range(1, 37))
    # sites of a section are tested consecutively, in station order
    for _, g in d.groupby("section"):
        assert np.all(np.diff(g.sort_values("station_ft")["test_order"]) == 1)
    st = d.set_index("site")["station_ft"]
    assert [st["E3-1"], st["E3-2"], st["E3-3"]] == [0, 100, 200]
    assert [st["C3-1"], st["C3-2"], st["C3-3"]] == [0, 300, 600]
    tab = d.drop_duplicates("section").set_index("section")
    assert tab.loc["E4", "binder"] == "PG 64-22" and tab.loc["E5", "binder"] == "PG 58-28"
    assert tab.loc["E6", "aggregate_combination"] == 2 and tab.loc["E6", "mix"] == "WMA stone mix"
    assert (tab.loc[[f"C{i}" for i in range(1, 7)], "aggregate_combination"] == 3).all()
    assert (tab.loc[[f"E{i}" for i in range(1, 6)], "aggregate_combination"] == 1).all()
    assert tab.loc["E2", "mix"] == "WMA foaming"
    # the day's clock runs with the test order
    t = d.sort_values("test_order")["test_time"].tolist()
    assert t == sorted(t)


def test_design_deterministic_and_seeded():
    a = S.design_campaign(S.default_config())
    b = S.design_campaign(S.default_config())
    pd.testing.assert_frame_equal(a, b)
    c = S.design_campaign(S.default_config() | {"seed": 7})
    assert not np.array_equal(a["test_order"], c["test_order"])


def test_design_configurable_and_errors():
    d = S.design_campaign({"sections": ["E6", "C2"], "sites_per_section": 2})
    assert list(d["site"]) == ["E6-1", "E6-2", "C2-1", "C2-2"]
    assert list(d["station_ft"]) == [0, 100, 0, 300]
    # workflow form of the config
    d2 = S.design_campaign({"synthetic": {"sections": ["E6", "C2"], "sites_per_section": 2}, "truth": {}})
    pd.testing.assert_frame_equal(d, d2)
    with pytest.raises(ConfigError, match="X9"):
        S.design_campaign({"sections": ["X9"]})
    with pytest.raises(ConfigError, match="no_such_key"):
        S.design_campaign({"no_such_key": 1})


# ------------------------------------------------------------------------------------------------ determinism


def test_site_alone_equals_site_in_campaign(tmp_path):
    cfg = small_cfg()
    d = S.design_campaign(cfg)
    alone = S.generate_site(row_of(d, "C4-2"), cfg)
    # within a campaign: other sites generated before it
    for site in ["E1-1", "E6-3"]:
        S.generate_site(row_of(d, site), cfg)
    again = S.generate_site(row_of(d, "C4-2"), cfg)
    assert np.array_equal(alone.surface.heights, again.surface.heights, equal_nan=True)
    pd.testing.assert_frame_equal(alone.dft, again.dft)
    assert alone.truth == again.truth
    # a different site differs
    other = S.generate_site(row_of(d, "C4-3"), cfg)
    assert not np.array_equal(alone.surface.heights, other.surface.heights, equal_nan=True)
    # identical bytes on disk
    digests = []
    for k, sd in enumerate([alone, again]):
        paths = [tmp_path / f"r{k}" / n for n in ("scans/C4-2.x3p", "dft/C4-2.csv", "truth/C4-2.json")]
        S.write_site(sd, *paths)
        digests.append([hashlib.md5(p.read_bytes()).hexdigest() for p in paths])
    assert digests[0] == digests[1]


def test_truth_consistent_with_trace():
    cfg = small_cfg()
    d = S.design_campaign(cfg)
    sd = S.generate_site(row_of(d, "E2-1"), cfg)
    tr = sd.truth
    json.loads(json.dumps(tr))  # serialisable
    v = np.array(tr["dft_true"]["speeds_kmh"])
    assert np.allclose(v, sd.dft["speed_kmh"])
    assert np.allclose(T.mu_true(v, tr), tr["dft_true"]["mu"], atol=1e-6)
    # the measured trace is the true one with ~3 % noise
    rel = sd.dft["mu"].to_numpy() / np.array(tr["dft_true"]["mu"]) - 1
    assert 0.015 < rel.std() < 0.05 and abs(rel.mean()) < 0.02
    # the descriptors in the truth are those of the clean surface
    desc = T.texture_descriptors(sd.clean.heights, 0.05, 0.05)
    assert desc["mpd_mm"] == pytest.approx(tr["descriptors"]["mpd_mm"], rel=1e-12)


# ------------------------------------------------------------------------------------------------ realism


def test_reduced_surfaces_are_pavement_like():
    """100 mm long strips (160 x 2048 points): MPD, negative skew, micro Sq in the study's ranges."""
    cfg = small_cfg(160, 2048)
    d = S.design_campaign(cfg)
    mpds = {}
    for site in ["E3-1", "E6-2", "C5-3"]:
        h, info = S.synthesize_surface(row_of(d, site), cfg)
        desc = T.texture_descriptors(h, 0.05, 0.05)
        mpds[site] = desc["mpd_mm"]
        assert 0.3 < desc["mpd_mm"] < 2.0, (site, desc)
        assert -2.6 < desc["ssk"] < -0.4, (site, desc)
        assert 0.01 < desc["micro_sq_mm"] < 0.045, (site, desc)
        assert 0.4 < info["stone_area_fraction"] < 0.95
        assert np.isfinite(h).all()


def test_stone_cap_equals_the_whole_patch_formula():
    """The stone outline and cap with the powers taken only in the box |u/a| < 1, |v/b| < 1 are those of the
    superellipse evaluated on every point of the patch, bit for bit (the formula before the box), for rotated
    stones of every shape the default gradations draw, points exactly on the box edge included."""
    rng = np.random.default_rng(5)
    n_inside = 0
    for k in range(300):
        a = rng.uniform(0.5, 10.0)
        b = a * rng.uniform(0.4, 1.0)
        n_pl, m_v = rng.uniform(1.5, 6.0), rng.uniform(1.2, 4.0)
        theta = np.pi * rng.random()
        ct, st = np.cos(theta), np.sin(theta)
        if k % 3 == 0:  # axis-aligned on a grid through the box edges: |u / a| == 1 exactly at some points
            ct, st = 1.0, 0.0
            X = np.linspace(-1.2 * a, 1.2 * a, 49)
            Y = np.linspace(-1.2 * b, 1.2 * b, 37)[:, None]
        else:
            X = np.arange(-30, 31) * 0.05 * a / 1.2
            Y = (np.arange(-30, 31) * 0.05 * a / 1.2)[:, None]
        u, v = X * ct + Y * st, Y * ct - X * st
        base, thick, t0, t1 = -rng.uniform(0.5, 3.0), rng.uniform(0.2, 4.0), rng.normal(0, 0.06), rng.normal(0, 0.06)
        inside, z = surface._stone_cap(u, v, a, b, n_pl, m_v, base, thick, t0, t1)
        rho_n = np.abs(u * (1.0 / a)) ** n_pl + np.abs(v * (1.0 / b)) ** n_pl
        ref_inside = rho_n < 1.0
        w = 1.0 - np.minimum(rho_n[ref_inside], 1.0) ** (m_v / n_pl)
        ref_z = base + t0 * u[ref_inside] + t1 * v[ref_inside] + thick * w ** (1.0 / m_v)
        np.testing.assert_array_equal(inside, ref_inside)
        assert z.tobytes() == ref_z.tobytes(), k
        n_inside += int(ref_inside.sum())
    assert n_inside > 100_000  # the comparison covered the caps, not empty outlines


def test_larger_aggregate_gives_larger_mpd():
    base = small_cfg(160, 2048)
    big = small_cfg(160, 2048)
    big["components"] = {"chips_5_8": {"size_mm": [7.6, 25.4]}}  # 1" chips instead of 5/8"
    d = S.design_campaign(base)
    m0, m1 = [], []
    for site in ["C1-1", "C2-2", "C3-3"]:
        for cfg, out in ((base, m0), (big, m1)):
            h, _ = S.synthesize_surface(row_of(d, site), cfg)
            out.append(T.mpd_mm(h, 0.05))
    assert np.mean(m1) > 1.25 * np.mean(m0), (m0, m1)


def test_scanner_artefacts_as_configured():
    cfg = small_cfg(256, 320, speckle_fraction=0.002, dropout_fraction=0.02)
    d = S.design_campaign(cfg)
    sd = S.generate_site(row_of(d, "E5-2"), cfg)
    h = sd.surface.heights
    n = h.size
    nan = np.isnan(h)
    assert nan.sum() == round(0.02 * n)
    # dropouts come in clusters: a NaN point has NaN 4-neighbours far more often than random points would
    nb = (np.roll(nan, 1, 0) & nan).sum() + (np.roll(nan, 1, 1) & nan).sum()
    assert nb / nan.sum() > 1.0
    # speckle: exactly the configured number of isolated spikes (>= 0.5 mm) against the clean surface
    diff = np.abs(h - sd.clean.heights)
    spikes = np.nan_to_num(diff, nan=0.0) > 0.3
    assert spikes.sum() == round(0.002 * n)
    # away from spikes the scan is the clean surface plus a tilt below 0.2 % and 0.01 mm quantisation
    ok = ~nan & ~spikes
    assert np.nanmax(diff[ok]) < 0.002 * 0.05 * (256 + 320) + 0.0051
    codes = h[~nan] / 0.01
    assert np.allclose(codes, np.rint(codes), atol=1e-6)
    assert sd.surface.shape == (256, 320) and sd.surface.dx == 0.05


def test_micro_field_band_rms_and_hurst():
    rng = np.random.default_rng(3)
    shape, dx, hurst, roll = (256, 512), 0.05, 0.75, 1.0
    f = S.micro_field(rng, shape, dx, hurst, roll)
    F = sfft.fft2(f)
    qy = 2 * np.pi * sfft.fftfreq(shape[0], dx)[:, None]
    qx = 2 * np.pi * sfft.fftfreq(shape[1], dx)[None, :]
    q = np.sqrt(qy**2 + qx**2)
    power = np.abs(F) ** 2 / f.size**2
    band = q > 2 * np.pi / 0.5
    assert np.sqrt(power[band].sum()) == pytest.approx(1.0, rel=0.05)
    # radially averaged PSD slope well above the roll-off: -(2 + 2H)
    edges = np.geomspace(2 * np.pi / 0.4, 2 * np.pi / 0.12, 9)
    idx = np.digitize(q.ravel(), edges)
    qs, ps = [], []
    for k in range(1, len(edges)):
        sel = idx == k
        qs.append(q.ravel()[sel].mean())
        ps.append(power.ravel()[sel].mean())
    slope = np.polyfit(np.log(qs), np.log(ps), 1)[0]
    exact = np.polyfit(np.log(qs), np.log(((2 * np.pi / roll) ** 2 + np.square(qs)) ** (-(1 + hurst))), 1)[0]
    assert slope == pytest.approx(exact, abs=0.15)
    assert exact < -3.0


# ------------------------------------------------------------------------------------------------ files


def test_write_site_and_sites_csv_round_trip(tmp_path):
    from skidsim.dft import read_dft
    from skidsim.x3p import read_x3p

    cfg = small_cfg(64, 80)
    d = S.design_campaign(cfg)
    sd = S.generate_site(row_of(d, "E1-2"), cfg)
    camp = tmp_path / "campaign"
    S.write_site(sd, camp / "scans/E1-2.x3p", camp / "dft/E1-2.csv", tmp_path / "truth/E1-2.json")
    s = read_x3p(camp / "scans/E1-2.x3p")
    assert np.array_equal(s.heights, sd.surface.heights, equal_nan=True)
    assert s.meta["x3p_dtype"] in ("I", "L") and s.meta["z_increment_mm"] == pytest.approx(0.01)
    tr = read_dft(camp / "dft/E1-2.csv")
    assert np.allclose(tr.speeds_kmh, np.sort(sd.dft["speed_kmh"]))
    assert (camp / "dft/E1-2.csv").read_text().splitlines()[0] == "speed_kmh,mu"
    assert json.loads((tmp_path / "truth/E1-2.json").read_text())["site"] == "E1-2"
    S.write_sites_csv(d, camp, camp / "sites.csv")
    sites = pd.read_csv(camp / "sites.csv")
    assert list(sites.columns[:5]) == ["site", "section", "scan", "dft", "temperature_c"]
    assert {"mix", "binder", "aggregate_combination", "station_ft", "test_order"} <= set(sites.columns)
    assert sites.loc[1, "scan"] == "scans/E1-2.x3p" and sites.loc[1, "dft"] == "dft/E1-2.csv"
    assert len(sites) == 36
    assert not any(p.name.startswith(".") for p in camp.rglob("*"))  # no temporary leftovers


def test_site_figure(tmp_path):
    from skidsim.plotting.campaign import plot_synthetic_site

    cfg = small_cfg(64, 80)
    d = S.design_campaign(cfg)
    sd = S.generate_site(row_of(d, "E6-1"), cfg)
    titles = plot_synthetic_site(sd, tmp_path / "site.png")
    assert (tmp_path / "site.png").stat().st_size > 10_000
    assert f"MPD {sd.truth['descriptors']['mpd_mm']:.2f} mm" in titles[0]
    assert f"a_T {sd.truth['effects']['temperature']['a_T']:.2f}" in titles[1]


def test_bad_truth_or_dft_keys_fail_at_design_time():
    with pytest.raises(ConfigError, match="tempreature"):
        S.design_campaign({"truth": {"effects": {"tempreature": {"enabled": False}}}})
    with pytest.raises(ConfigError, match="noise"):
        S.design_campaign({"dft": {"noise": 0.1}})
    with pytest.raises(ConfigError, match="dropout_fraction"):
        S.design_campaign({"dropout_fraction": 0.9})


def test_null_campaign_site_has_only_the_base_curve():
    cfg = small_cfg()
    for eff in cfg["truth"]["effects"].values():
        eff["enabled"] = False
    d = S.design_campaign(cfg)
    sd = S.generate_site(row_of(d, "C6-1"), cfg)
    curve = sd.truth["curve"]
    assert curve["total"] == curve["base"]
    b = sd.truth["base"]
    v = sd.dft["speed_kmh"].to_numpy()
    family = b["mu_k"] + (b["mu_s"] - b["mu_k"]) * np.exp(-b["alpha_s_per_m"] * v / 3.6)
    assert np.allclose(sd.truth["dft_true"]["mu"], family, atol=1e-6)
    # the default campaign's truth differs from its base (temperature and drainage are on)
    default = S.generate_site(row_of(d, "C6-1"), small_cfg())
    assert np.max(np.abs(np.subtract(default.truth["curve"]["total"], default.truth["curve"]["base"]))) > 0.02
