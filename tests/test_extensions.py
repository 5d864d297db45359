"""Tests of skidsim.criticism.extensions and of the law-level recalibration (skidsim.criticism.recalibration)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skidsim.criticism.covariates import site_covariates
from skidsim.criticism.extensions import (
    CovariateTerm,
    DrainageIFI,
    TemperatureShift,
    TextureModelTerm,
    exp_curve,
    fit_exp_curves,
    ifi_speed_constant_kmh,
    wlf_log10_shift,
)
from skidsim.criticism.recalibration import predict_extended, recalibrate
from skidsim.criticism.scopes import centred_speed, make_scope
from skidsim.errors import ConfigError, InputError


def test_wlf_values_and_pole():
    # log10 a_T = -C1 dT / (C2 + dT): 0 at T_r, -8.86*50/151.6 at T_r + 50 K, +8.86*20/81.6 at T_r - 20 K
    assert wlf_log10_shift(20.0, 20.0) == pytest.approx(0.0)
    assert wlf_log10_shift(10.0, -40.0) == pytest.approx(-8.86 * 50 / 151.6, rel=1e-12)
    assert wlf_log10_shift(-60.0, -40.0) == pytest.approx(8.86 * 20 / 81.6, rel=1e-12)
    with pytest.raises(ConfigError):
        wlf_log10_shift(-150.0, -40.0)  # T - T_r = -110 K beyond the pole at -101.6 K


def test_temperature_shift_anchor_and_monotone():
    ext = TemperatureShift()
    t = np.array([5.0, 10.0, 16.0, 22.0, 30.0])
    k = ext.speed_factor(t, anchor_c=16.0, t_ref_c=-40.0)
    assert k[2] == pytest.approx(1.0)
    assert np.all(np.diff(k) < 0)  # warmer rubber behaves like slower sliding
    # sensitivity at T - T_r = 56 K: d log10 a_T / dT = -C1 C2 / (C2 + dT)^2
    h = 1e-4
    d = (np.log10(ext.speed_factor(16.0 + h, 16.0, -40.0)) - np.log10(ext.speed_factor(16.0 - h, 16.0, -40.0))) / (
        2 * h
    )
    assert d == pytest.approx(-8.86 * 101.6 / (101.6 + 56.0) ** 2, rel=1e-6)


def test_ifi_speed_constant_and_multiplier():
    assert ifi_speed_constant_kmh(1.0) == pytest.approx(103.9)
    assert ifi_speed_constant_kmh(np.array([0.0, 0.5])) == pytest.approx([14.2, 14.2 + 44.85])
    ext = DrainageIFI(form="ifi")
    inv = ext.inverse_speed_constant(0.8)
    assert ext.multiplier(60.0, inv, 1.0) == pytest.approx(1.0)
    # IFI: F(S) = F60 exp((60 - S)/Sp)
    assert ext.multiplier(20.0, inv, 1.0) == pytest.approx(np.exp(40.0 / (14.2 + 89.7 * 0.8)))


def _aitken(y1, y2, y3, dv_ms):
    """Closed form of the exponential through three equally spaced points (field notes)."""
    r = (y2 - y3) / (y1 - y2)
    alpha = -np.log(r) / dv_ms
    mu_k = (y1 * y3 - y2**2) / (y1 + y3 - 2 * y2)
    return mu_k, alpha


def test_fit_exp_curves_matches_aitken_and_recovers_truth():
    rng = np.random.default_rng(3)
    n = 12
    b = rng.uniform(0.25, 0.4, n)
    c = rng.uniform(0.15, 0.35, n)
    a = rng.uniform(0.03, 0.3, n)
    v = np.array([20.0, 40.0, 60.0])
    y = exp_curve(v[None, :], b[:, None], c[:, None], a[:, None])
    fb, fc, fa = fit_exp_curves(np.tile(v, (n, 1)), y)
    mu_k, alpha = _aitken(y[:, 0], y[:, 1], y[:, 2], 20.0 / 3.6)
    assert fa == pytest.approx(alpha, rel=2e-3)
    assert fb == pytest.approx(mu_k, abs=2e-4)
    assert fa == pytest.approx(a, rel=2e-3)
    # more points with NaN padding: same truth
    v6 = np.tile(np.arange(20.0, 71.0, 10.0), (n, 1))
    y6 = exp_curve(v6, b[:, None], c[:, None], a[:, None])
    y6[0, -1] = np.nan
    gb, gc, ga = fit_exp_curves(v6, y6)
    assert ga == pytest.approx(a, rel=2e-3)
    assert gb + gc == pytest.approx(b + c, abs=1e-3)


def test_fit_exp_curves_needs_three_points():
    with pytest.raises(InputError):
        fit_exp_curves(np.array([[20.0, 40.0, 60.0]]), np.array([[0.5, np.nan, 0.4]]))


def test_covariate_term_rejects_unknown_target():
    with pytest.raises(ConfigError):
        CovariateTerm("x", on="curvature")


def test_squeeze_multiplier_and_bad_form():
    ext = DrainageIFI(form="squeeze")
    inv = ext.inverse_speed_constant(0.8)
    assert ext.multiplier(0.0, inv, 0.3) == pytest.approx(1.0)
    assert ext.multiplier(60.0, inv, 0.3) == pytest.approx(1.0 - 0.3 * 3600.0 * inv**2)
    assert ext.multiplier(500.0, inv, 0.3) == pytest.approx(ext.floor)
    with pytest.raises(ConfigError, match="form"):
        DrainageIFI(form="hydro")
    with pytest.raises(ConfigError, match="not a curve"):
        DrainageIFI().multiplier(60.0, inv, 1.0)  # "auto" chooses a form when fitted; it has no curve itself


def _scope_tables(kappa=None, t_shift=False, n_sec=8, per=3, seed=0, form="ifi"):
    """Noise-free tables: within-site rows with a drainage factor, or between-site predictions vs a WLF truth."""
    rng = np.random.default_rng(seed)
    n = n_sec * per
    site = [f"s{i}" for i in range(n)]
    sites = pd.DataFrame(
        {
            "site": site,
            "section": np.repeat([f"S{k}" for k in range(n_sec)], per),
            "temperature_c": 16.0 + np.linspace(-6, 6, n)[rng.permutation(n)],
        }
    )
    mpd = rng.uniform(0.4, 1.4, n)
    tex = pd.DataFrame({"site": site, "mpd_mm": mpd})
    b, c, a = rng.uniform(0.3, 0.4, n), rng.uniform(0.2, 0.3, n), rng.uniform(0.06, 0.14, n)
    rows = []
    for i in range(n):
        for kind, vs in (("calibration", (20.0, 40.0, 60.0)), ("validation", (30.0, 50.0, 70.0, 80.0))):
            for v in vs:
                base = exp_curve(v, b[i], c[i], a[i])
                if kappa is not None and form == "squeeze":
                    meas = base * (1.0 - kappa * (v * v - 400.0) / (14.2 + 89.7 * mpd[i]) ** 2)
                elif kappa is not None:
                    meas = base * np.exp(-kappa * (v - 20.0) / (14.2 + 89.7 * mpd[i]))
                else:
                    k = TemperatureShift().speed_factor(sites["temperature_c"][i], 16.0, -40.0)
                    meas = exp_curve(v * k, b[i], c[i], a[i])
                rows.append((site[i], v, meas, kind, base))
    t = pd.DataFrame(rows, columns=["site", "speed_kmh", "measured", "kind", "base"])
    return sites, tex, t


@pytest.mark.parametrize("form,kappa", [("ifi", 0.8), ("squeeze", 0.3)])
def test_recalibrate_drainage_recovers_kappa_within_site(form, kappa):
    """form "auto" fits both curve forms on the training sites and keeps the one with the smaller training error:
    the true form and its kappa come back, and the held-out speeds are recovered."""
    sites, tex, t = _scope_tables(kappa=kappa, form=form)
    # the calibrated simulation: plain exponential through the measured calibration points
    cal = t[t["kind"] == "calibration"].sort_values(["site", "speed_kmh"])
    v3 = cal["speed_kmh"].to_numpy().reshape(-1, 3)
    b, c, a = fit_exp_curves(v3, cal["measured"].to_numpy().reshape(-1, 3))
    sb = dict(zip(cal["site"].unique(), zip(b, c, a)))
    t["model"] = [exp_curve(v, *sb[s]) for s, v in zip(t["site"], t["speed_kmh"])]
    res = t.assign(
        level="within-site",
        residual=t["measured"] - t["model"],
        section=t["site"].map(sites.set_index("site")["section"]),
    )
    cov, _ = site_covariates(sites, tex)
    sc = make_scope(res, "within-site")
    train = np.ones(len(sc.sites), bool)
    p = recalibrate(DrainageIFI(mpd_column="mpd_mm"), sc, cov, train)
    assert p["form"] == form
    # (the squeeze truth is 1 at 20 km/h, the extension at 0 km/h: a per-site factor 1 + 400 kappa / Sp^2 <= 1.04
    # that the refitted law absorbs only in part)
    assert p["kappa"] == pytest.approx(kappa, rel=0.025 if form == "ifi" else 0.08)
    after = predict_extended(DrainageIFI(mpd_column="mpd_mm"), p, sc, cov, train)
    before_err = np.abs(sc.rows["measured"] - sc.rows["before"]).max()
    assert before_err > 1e-3  # the plain law misses the drainage shape at held-out speeds ...
    assert np.abs(sc.rows["measured"] - after).max() < 0.05 * before_err  # ... the extension recovers it


def _wlf_between_scope():
    """(covariates, between-site scope) of :func:`_scope_tables` with a WLF truth (T_r = -40 C): the texture-model
    predictions are the temperature-free law."""
    sites, tex, t = _scope_tables(kappa=None)
    res = t.assign(
        level="between-site",
        model=t["base"],
        residual=t["measured"] - t["base"],
        section=t["site"].map(sites.set_index("site")["section"]),
    )
    cov, _ = site_covariates(sites, tex)
    return cov, make_scope(res, "between-site")


def test_recalibrate_temperature_recovers_reference_between_sites():
    cov, sc = _wlf_between_scope()
    train = np.ones(len(sc.sites), bool)
    p = recalibrate(TemperatureShift(), sc, cov, train)
    assert p["t_ref_c"] == pytest.approx(-40.0, abs=1.0)
    after = predict_extended(TemperatureShift(), p, sc, cov, train)
    assert np.sqrt(np.mean((after - sc.rows["measured"]) ** 2)) < 2e-4
    assert np.sqrt(np.mean((sc.rows["before"] - sc.rows["measured"]) ** 2)) > 5e-3


def _texture_model_scope(slope_of_site, level_of_site):
    """A between-site scope of 12 sites at 20-70 km/h whose residual is ``level_i + slope_i (v - 45)`` (mu)."""
    v = np.arange(20.0, 71.0, 10.0)
    rows = [
        (f"S{i}", f"C{i // 3}", float(x), 0.5, 0.5 + level_of_site[i] + slope_of_site[i] * (x - v.mean()))
        for i in range(len(slope_of_site))
        for x in v
    ]
    t = pd.DataFrame(rows, columns=["site", "section", "speed_kmh", "model", "measured"])
    res = t.assign(level="between-site", kind="validation", residual=t["measured"] - t["model"])
    return make_scope(res, "between-site")


def test_a_texture_model_term_on_the_speed_slope_recovers_a_slope_linear_in_its_design():
    """Residual speed slopes (mu per km/h) linear in the member's design, plus site levels that no design carries:
    the slope form (an x_speed cause) recovers the slope coefficients to 1e-12, predicts every row's slope part
    exactly and leaves each site's mean level alone; the level form fits site means and leaves the slopes."""
    rng = np.random.default_rng(4)
    Z = rng.normal(size=(12, 3))
    b = np.array([2e-4, 1e-3, -5e-4, 3e-4])  # [b0, b] in mu per km/h
    slope, level = np.c_[np.ones(12), Z] @ b, rng.normal(scale=0.02, size=12)
    sc = _texture_model_scope(slope, level)
    design = tuple(tuple(map(float, Z[i])) for i in range(12))
    ext = TextureModelTerm("texture_model[x]", tuple(f"S{i}" for i in range(12)), design, on="slope")
    train = np.ones(len(sc.sites), bool)
    p = recalibrate(ext, sc, None, train)
    np.testing.assert_allclose(p["beta"], b, rtol=0, atol=1e-12)
    after = predict_extended(ext, p, sc, None, train)
    lev = np.array([level[int(s[1:])] for s in sc.rows["site"]])
    np.testing.assert_allclose(after - sc.rows["before"], sc.rows["measured"] - sc.rows["before"] - lev, atol=1e-12)
    flat = TextureModelTerm("texture_model[x]", ext.sites, design)
    after_flat = predict_extended(flat, recalibrate(flat, sc, None, train), sc, None, train)
    d = after_flat - sc.rows["before"].to_numpy()
    assert np.allclose(d.reshape(12, -1).std(axis=1), 0.0, atol=1e-12)  # a level per site, no slope
    with pytest.raises(ConfigError):
        TextureModelTerm("texture_model[x]", on="shape")


def test_a_categorical_term_on_the_speed_slope_fits_each_groups_level_and_slope():
    """A categorical x speed cause (a polished aggregate that loses low-speed friction lowers its mean too): the
    slope form fits each group's residual level and speed slope, recovers both to 1e-12 and every training row;
    a group unseen in training gets the least squares over all training rows; the level form fits group means."""
    groups = np.array(list("ABCD"))[np.arange(12) % 4]
    coef = {"A": (0.0, 0.0), "B": (-0.03, 8e-4), "C": (0.01, -2e-4), "D": (0.02, 5e-4)}  # mu, mu per km/h
    sc = _texture_model_scope([coef[g][1] for g in groups], [coef[g][0] for g in groups])
    cov = pd.DataFrame({"aggregate": groups}, index=[f"S{i}" for i in range(12)])
    ext = CovariateTerm("aggregate", on="slope")
    train = np.ones(len(sc.sites), bool)
    p = recalibrate(ext, sc, cov, train)
    for g, (level, slope) in coef.items():
        np.testing.assert_allclose(p["groups"][g], [level, slope], rtol=0, atol=1e-12)
    after = predict_extended(ext, p, sc, cov, train)
    np.testing.assert_allclose(after, sc.rows["measured"], rtol=0, atol=1e-12)
    unseen = np.array([g != "D" for g in cov.loc[sc.sites, "aggregate"]])
    p = recalibrate(ext, sc, cov, unseen)
    assert set(p["groups"]) == {"A", "B", "C"}
    rows_tr = unseen[sc.row_site]
    dv = centred_speed(sc)
    resid = (sc.rows["measured"] - sc.rows["before"]).to_numpy()
    overall = np.linalg.lstsq(np.c_[np.ones(rows_tr.sum()), dv[rows_tr]], resid[rows_tr], rcond=None)[0]
    after = predict_extended(ext, p, sc, cov, unseen)
    d_rows = ~rows_tr
    np.testing.assert_allclose(
        after[d_rows] - sc.rows["before"].to_numpy()[d_rows], overall[0] + overall[1] * dv[d_rows], atol=1e-12
    )
    flat = CovariateTerm("aggregate")
    p = recalibrate(flat, sc, cov, train)
    for g, (level, _) in coef.items():  # the mean over the symmetric speeds of level + slope (v - 45) is the level
        np.testing.assert_allclose(p["groups"][g], [level], rtol=0, atol=1e-12)


def test_wlf_from_curves_separates_temperature_from_the_macrotexture_decay():
    """PIARC/IFI-like curves whose decay constant is set by the macrotexture (Sp = 14.2 + 89.7 MPD km/h) and
    shifted by WLF (T_r 20 deg C) over a narrow temperature range (sections at 18-22 deg C) on campaigns whose
    sections happen to be rougher where warmer: with the log MPD term of the decay constant (``decay_column``)
    T_r comes back near 20 deg C (median of 8 campaigns) with the slope of the IFI form; without it the
    macrotexture's share of the decay constants is read as temperature and T_r is biased by more than 10 K. The
    decay covariate is None where the column is missing or not positive."""
    from skidsim.criticism.wlf import decay_covariate, wlf_from_curves

    ext = TemperatureShift(decay_column="profile_MPD")
    v = np.tile(np.arange(20.0, 70.1, 2.0), (36, 1))
    with_x, without_x, slopes = [], [], []
    for seed in range(8):
        rng = np.random.default_rng(seed)
        t_sec = rng.uniform(18.0, 22.0, 12)
        t = np.repeat(t_sec, 3) + rng.normal(0.0, 0.7, 36)
        mpd = np.repeat(0.9 * np.exp(0.1 * (t_sec - 20.0)), 3) * np.exp(rng.normal(0.0, 0.15, 36))
        a_t = 10.0 ** (wlf_log10_shift(t, 20.0) - wlf_log10_shift(t.mean(), 20.0))
        alpha = 3.6 / (14.2 + 89.7 * mpd) * a_t  # s/m: exp(-alpha v / 3.6) = exp(-v a_T / Sp), v in km/h
        y = 0.9 * np.exp(-alpha[:, None] * v / 3.6) + rng.normal(0.0, 0.005, v.shape)
        cov = pd.DataFrame({"profile_MPD": mpd}, index=[f"s{i}" for i in range(36)])
        x, mean = decay_covariate(ext, cov, list(cov.index))
        assert mean == pytest.approx(np.log10(mpd).mean()) and abs(x.mean()) < 1e-12
        fit = wlf_from_curves(ext, t, v, y, ext.t_ref_bounds_c(t), x=x)
        plain = wlf_from_curves(ext, t, v, y, ext.t_ref_bounds_c(t))
        assert fit["sse"] <= plain["sse"] and plain["decay_slope"] is None
        with_x.append(fit["t_ref_c"])
        without_x.append(plain["t_ref_c"])
        slopes.append(fit["decay_slope"])
    assert np.median(with_x) == pytest.approx(20.0, abs=4.0), with_x
    assert np.median(without_x) > 30.0, without_x
    assert -1.0 < np.median(slopes) < -0.6, slopes  # d log10(1/Sp) / d log10 MPD near MPD 0.9 mm: -0.85
    for bad in (pd.DataFrame({"other": mpd}, index=cov.index), cov.assign(profile_MPD=-mpd)):
        assert decay_covariate(ext, bad, list(cov.index)) == (None, None)


def test_the_wlf_shift_is_read_from_the_whole_measured_curve_below_the_simulated_speeds():
    """Exponential-decay curves shifted by WLF (T_r 20 deg C, the universal C1 and C2) over a season's
    temperatures (sections at 8-28 deg C), DFT noise 0.0075 mu: the residual rows stop at the simulated speeds
    (20-70 km/h), where the per-site decay constants are poorly pinned (b and c are free per site); the spin-down
    trace goes on down to 5 km/h. Read from the whole measured curves (``make_scope(..., measured)``, gain.json's
    ``t_ref_c_all_sites``), T_r comes back within 5 deg C in at least 7 of 8 campaigns; from the rows alone in at
    most 4. ``measured_curves`` keeps the points at or above 5 km/h, averages equal speeds and gives None when a
    site has none."""
    from skidsim.criticism.scopes import measured_curves
    from skidsim.criticism.wlf import temperature_identifiability

    within = {"curves": 0, "rows": 0}
    v = np.arange(5.0, 80.1, 2.5)
    for seed in range(8):
        rng = np.random.default_rng(seed)
        site = [f"s{i}" for i in range(36)]
        t = np.repeat(rng.uniform(8.0, 28.0, 12), 3) + rng.normal(0.0, 0.7, 36)
        sites = pd.DataFrame({"site": site, "section": np.repeat([f"S{k}" for k in range(12)], 3), "temperature_c": t})
        mu_k = rng.uniform(0.3, 0.6, 36)
        c = 0.08 + 0.14 * np.exp(rng.normal(np.log(0.8), 0.3, 36))
        a_t = 10.0 ** wlf_log10_shift(t, 20.0)
        y = mu_k[:, None] + c[:, None] * np.exp(-0.08 * a_t[:, None] * v / 3.6) + rng.normal(0.0, 0.0075, (36, v.size))
        measured = pd.DataFrame({"site": np.repeat(site, v.size), "speed_kmh": np.tile(v, 36), "mu": y.ravel()})
        res = measured[(measured["speed_kmh"] >= 20.0) & (measured["speed_kmh"] <= 70.0)].rename(
            columns={"mu": "measured"}
        )
        res = res.assign(level="between-site", kind="trace", model=res["measured"].mean(), section="S0")
        res["residual"] = res["measured"] - res["model"]
        cov, _ = site_covariates(sites, pd.DataFrame({"site": site, "mpd_mm": np.ones(36)}))
        for key, scope in (
            ("curves", make_scope(res, "between-site", measured)),
            ("rows", make_scope(res, "between-site")),
        ):
            assert (scope.curves is not None) == (key == "curves")
            fit = temperature_identifiability(TemperatureShift(), scope, cov, n_perm=0)
            within[key] += abs(fit["t_ref_c"] - 20.0) <= 5.0
    assert within["curves"] >= 7 and within["rows"] <= 4, within
    low = pd.DataFrame(
        {
            "site": ["a"] * 6 + ["b"] * 3,
            "speed_kmh": [3.0, 10.0, 10.0, 20.0, 30.0, 40.0, 20.0, 30.0, 40.0],
            "mu": [0.9, 0.6, 0.8, 0.5, 0.45, 0.4, 0.5, 0.45, 0.4],
        }
    )
    V, Y = measured_curves(low, ["a", "b"])
    assert np.isfinite(V).sum(axis=1).tolist() == [4, 3] and V[0, 0] == 10.0 and Y[0, 0] == pytest.approx(0.7)
    assert measured_curves(low[low["speed_kmh"] != 40.0], ["a", "b"]) is None  # no site with 4 speeds
    assert measured_curves(low, ["a", "b", "c"]) is None


def test_the_reference_temperature_keeps_off_the_wlf_pole_at_a_texture_adjusted_temperature():
    """A texture-adjusted temperature cause evaluates the shift at ``T~`` = the training mean plus the part of T the
    texture PCs do not predict; at a held-out site whose texture predicts 56 deg C where it measured 16, ``T~`` is
    about 40 K below every measured temperature. T_r's upper bound then keeps 5 K inside the WLF pole at ``T~``
    (it was set from the measured temperatures alone, and the fit raised "WLF undefined" on the bound)."""
    from skidsim.criticism.recalibration import _physical_params, _shift_temperatures

    cov, sc = _wlf_between_scope()
    temps = cov.loc[sc.sites, "temperature_c"].to_numpy(float)
    train = np.ones(len(sc.sites), bool)
    held = int(np.argmin(np.abs(temps - 16.0)))
    train[held] = False
    tpc = (temps - 16.0) / 2.0
    tpc[held] = 20.0  # the texture of this site says 56 deg C
    cov.loc[sc.sites, "_tpc1"] = tpc
    ext = TemperatureShift(texture_pcs=1)
    t_eval, _ = _shift_temperatures(ext, sc, cov, train)
    assert t_eval.min() < temps.min() - 30.0
    names, bounds = _physical_params(ext, sc, cov, train)
    assert names == ["t_ref_c", "level_per_c"] and bounds[0][1] == pytest.approx(t_eval.min() + 101.6 - 5.0)
    assert _physical_params(ext, sc, cov)[1][0][1] == pytest.approx(temps.min() + 101.6 - 5.0)
    p = recalibrate(ext, sc, cov, train)
    assert np.isfinite(predict_extended(ext, p, sc, cov, train)).all()
