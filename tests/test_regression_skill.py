"""Tests of the simple baseline (OLS on at most two texture columns chosen by inner CV), the ``<model>@dft``
models (targets: the measured DFT) and the prediction-skill table with its warning (issue 25, items 3-4)."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest

from skidsim import regression as R
from skidsim.errors import InputError

SPEEDS = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)


def campaign(n_sections=12, per=3, p=30, seed=0):
    """Independent standard-normal texture columns of three bands (different units by scale and offset)."""
    rng = np.random.default_rng(seed)
    n = n_sections * per
    idx = pd.Index([f"S{i:02d}" for i in range(n)], name="site")
    names = ["profile_MPD", "micro_Sq"] + [f"{('raw', 'macro', 'micro')[j % 3]}_P{j:02d}" for j in range(p - 2)]
    Z = rng.normal(size=(n, p))
    X = pd.DataFrame(Z * rng.uniform(0.1, 3.0, p) + rng.uniform(-1, 5, p), columns=names, index=idx)
    groups = pd.Series(np.repeat([f"E{i:02d}" for i in range(n_sections)], per), index=idx, name="section")
    return X, Z, groups, rng


def long_dft(D: pd.DataFrame) -> pd.DataFrame:
    """Wide dft@<v> targets -> long (site, speed_kmh, mu)."""
    return pd.DataFrame(
        {
            "site": np.repeat(D.index.astype(str), D.shape[1]),
            "speed_kmh": np.tile(R.dft_speeds(D), len(D)),
            "mu": D.to_numpy().ravel(),
        }
    )


def two_column_curves(X, Z, rng, a="macro_P04", b="micro_P14", noise=0.004):
    """DFT at SPEEDS linear in two texture columns (standardised values), the speed trend of an IFI-like curve."""
    za = Z[:, list(X.columns).index(a)]
    zb = Z[:, list(X.columns).index(b)]
    v = np.asarray(SPEEDS)
    D = (0.62 - 0.003 * v)[None, :] + np.outer(0.05 * za, np.exp(-v / 100)) + np.outer(-0.03 * zb, np.ones(len(v)))
    D = D + noise * rng.normal(size=D.shape)
    return pd.DataFrame(D, index=X.index, columns=[R.dft_column(s) for s in SPEEDS])


def laws_for(X):
    """Some calibrated laws (the parameter rows; the @dft models do not use them)."""
    return pd.DataFrame({"mu_s": 0.6, "mu_k": 0.3, "alpha": 0.05}, index=X.index)


# --------------------------------------------------------------------------------------------------- baseline


def test_subset_sse_closed_forms_match_least_squares():
    rng = np.random.default_rng(1)
    Atr, Ate = rng.normal(size=(14, 5)), rng.normal(size=(4, 5))
    Atr[:, 3] = 2.0  # constant on the training rows
    Atr[:, 4] = -3 * Atr[:, 0] + 1.0  # collinear with column 0
    Ate[:, 4] = -3 * Ate[:, 0] + 1.0
    Ytr, Yte = rng.normal(size=(14, 3)), rng.normal(size=(4, 3))
    subsets = R.candidate_subsets(5)
    assert len(subsets) == 1 + 5 + 10 and tuple(subsets[0]) == (-1, -1)
    sse = R.subset_test_sse(Atr, Ytr, Ate, Yte, subsets)
    for k, (i, j) in enumerate(subsets):
        cols = sorted({c for c in (i, j) if c >= 0})
        if 3 in cols or cols == [0, 4]:
            assert sse[k] == np.inf, cols
            continue
        A = np.column_stack([np.ones(14), Atr[:, cols]])
        beta, *_ = np.linalg.lstsq(A, Ytr, rcond=None)
        ref = ((np.column_stack([np.ones(4), Ate[:, cols]]) @ beta - Yte) ** 2).sum()
        assert sse[k] == pytest.approx(ref, rel=1e-9), cols


def test_baseline_recovers_two_parameter_linear_truth_and_picks_the_pair():
    X, Z, groups, rng = campaign(seed=2)
    D = two_column_curves(X, Z, rng)
    fit = R.fit_subset_ols(X, D, groups=groups.to_numpy())
    assert set(fit.columns) == {"macro_P04", "micro_P14"}
    assert fit.inner_sse.idxmin() in ("macro_P04+micro_P14", "micro_P14+macro_P04")
    # coefficients per unit of each column: X = scale * Z + offset, so the truth (per unit of Z) times dz/dx
    v = np.asarray(SPEEDS)
    k = {c: i for i, c in enumerate(fit.columns)}
    dzdx = {c: 1.0 / np.polyfit(Z[:, list(X.columns).index(c)], X[c].to_numpy(), 1)[0] for c in fit.columns}
    np.testing.assert_allclose(fit.coef[k["macro_P04"]] / dzdx["macro_P04"], 0.05 * np.exp(-v / 100), atol=0.003)
    np.testing.assert_allclose(fit.coef[k["micro_P14"]] / dzdx["micro_P14"], -0.03 * np.ones(6), atol=0.003)
    # and out of section: every fold of the CV picks the pair, the pooled R^2 is near 1
    cvt = R.cross_validate_models(
        X, laws_for(X), groups, ["mean@dft", R.BASELINE_MODEL], measured_dft=long_dft(D), speeds_kmh=SPEEDS
    )
    pooled = cvt[(cvt["quantity"] == "dft") & cvt["speed_kmh"].isna()].set_index("model")
    assert pooled.loc[R.BASELINE_MODEL, "r2"] > 0.98
    assert pooled.loc[R.BASELINE_MODEL, "rmse"] < 0.006
    cvp = R.cross_validated_predictions(X, laws_for(X), groups, [R.BASELINE_MODEL], dft=D)
    assert set(cvp["features"]) == {"macro_P04+micro_P14"}
    assert R.baseline_notes(cvp)[R.BASELINE_MODEL] == "macro_P04+micro_P14 in 12 of 12 folds"


def test_baseline_keeps_the_intercept_only_when_no_column_helps():
    """The empty subset is a candidate and wins exact ties (a curve that does not vary between sites)."""
    X, Z, groups, rng = campaign(n_sections=8, p=8, seed=3)
    D = pd.DataFrame(
        np.tile(0.6 - 0.002 * np.asarray(SPEEDS), (len(X), 1)), index=X.index, columns=[R.dft_column(s) for s in SPEEDS]
    )
    fit = R.fit_subset_ols(X, D, groups=groups.to_numpy())
    assert fit.columns == () and fit.label == "(intercept only)"
    np.testing.assert_allclose(fit.predict(X.iloc[:2]).to_numpy(), np.tile(D.mean().to_numpy(), (2, 1)))
    assert fit.inner_sse.iloc[0] == pytest.approx(0.0, abs=1e-20) and fit.inner_sse.index[0] == ""


def _brute_force_baseline(X, D, groups, *, leak: bool):
    """Reference nested CV by explicit least squares; ``leak=True`` lets the held-out section into the inner CV
    (the mistake the library must not make). Returns the chosen subsets per section and the predictions."""
    A, Y, g = X.to_numpy(float), D.to_numpy(float), groups.to_numpy()
    p = A.shape[1]
    subsets = [()] + [(i,) for i in range(p)] + list(itertools.combinations(range(p), 2))

    def ols(rows_tr, rows_te, cols):
        M = np.column_stack([np.ones(rows_tr.sum()), A[rows_tr][:, cols]])
        beta, *_ = np.linalg.lstsq(M, Y[rows_tr], rcond=None)
        return np.column_stack([np.ones(rows_te.sum()), A[rows_te][:, cols]]) @ beta

    chosen, pred = {}, np.full_like(Y, np.nan)
    for s in sorted(set(g)):
        outer_tr = g != s
        pool = np.ones(len(g), bool) if leak else outer_tr
        inner = []
        for cols in subsets:
            sse = 0.0
            for s2 in sorted(set(g[pool])):
                te = g == s2
                sse += ((ols(pool & ~te, te, list(cols)) - Y[te]) ** 2).sum()
            inner.append(sse)
        cols = list(subsets[int(np.argmin(inner))])
        chosen[s] = "+".join(X.columns[c] for c in cols) if cols else "(intercept only)"
        pred[g == s] = ols(outer_tr, g == s, cols)
    return chosen, pred


def test_baseline_inner_cv_never_sees_the_held_out_section():
    """The library's nested CV equals a brute-force one whose inner CV uses the training sections only; a leaky
    version (held-out section inside the inner CV) chooses different columns on these data, so the comparison
    would catch it."""
    X, Z, groups, rng = campaign(n_sections=7, per=3, p=9, seed=5)
    D = 0.2 * two_column_curves(X, Z, rng, a="macro_P01", b="raw_P06", noise=0.0)
    D = D + 0.05 * rng.normal(size=(len(X), 1))  # a weak signal: the choice depends on which sections vote
    cvp = R.cross_validated_predictions(X, laws_for(X), groups, [R.BASELINE_MODEL], dft=D)
    ours = cvp.drop_duplicates("section").set_index("section")["features"].to_dict()
    honest, pred = _brute_force_baseline(X, D, groups, leak=False)
    leaky, _ = _brute_force_baseline(X, D, groups, leak=True)
    assert ours == honest
    np.testing.assert_allclose(
        cvp[[R.dft_column(s) for s in SPEEDS]].to_numpy(),
        pd.DataFrame(pred, index=X.index).loc[cvp["site"]].to_numpy(),
        rtol=1e-9,
    )
    assert len(set(honest.values())) > 1 and len(set(leaky.values())) == 1
    assert sum(leaky[k] != honest[k] for k in honest) >= 3  # the test can tell a leak from none
    # and the held-out section's DFT does not move its own prediction
    held = groups == "E03"
    D2 = D.copy()
    D2.loc[held] += 5.0
    cvp2 = R.cross_validated_predictions(X, laws_for(X), groups, [R.BASELINE_MODEL], dft=D2)
    rows = cvp["section"] == "E03"
    cols = [R.dft_column(s) for s in SPEEDS]
    np.testing.assert_array_equal(cvp.loc[rows, cols].to_numpy(), cvp2.loc[rows, cols].to_numpy())
    assert np.abs(cvp.loc[~rows, cols].to_numpy() - cvp2.loc[~rows, cols].to_numpy()).max() > 0.1


def test_subset_ols_errors():
    X, Z, groups, rng = campaign(n_sections=4, p=4, seed=6)
    D = pd.DataFrame({"dft@20": rng.normal(size=len(X))}, index=X.index)
    with pytest.raises(InputError, match="texture columns"):
        R.fit_subset_ols(pd.DataFrame({"temperature_c": np.arange(len(X), dtype=float)}, index=X.index), D)
    with pytest.raises(InputError, match="at most 2"):
        R.candidate_subsets(4, max_features=3)
    bad = D.copy()
    bad.iloc[0, 0] = np.nan
    with pytest.raises(InputError, match="finite"):
        R.fit_subset_ols(X, bad)
    with pytest.raises(InputError, match="DFT targets"):
        R.predict_parameters(R.BASELINE_MODEL, X, laws_for(X), X)


# ------------------------------------------------------------------------------------------- @dft models


def test_dft_models_are_scored_on_their_own_predictions_and_hand_a_law_to_the_fe():
    X, Z, groups, rng = campaign(n_sections=6, p=10, seed=7)
    D = two_column_curves(X, Z, rng, a="macro_P01", b="raw_P06")
    meas = long_dft(D)
    g = meas.rename(columns={"mu": "g"}).assign(g=1.1)
    cvp = R.cross_validated_predictions(X, laws_for(X), groups, ["mean@dft", "ridge@dft"], dft=D, g=g)
    cvt = R.score_predictions(cvp, laws_for(X), g=g, measured_dft=meas, speeds_kmh=SPEEDS)
    cols = [R.dft_column(s) for s in SPEEDS]
    for m in ("mean@dft", "ridge@dft"):
        p = cvp[cvp["model"] == m].set_index("site")
        e = p[cols].to_numpy() - D.loc[p.index, cols].to_numpy()
        sst = ((D.to_numpy() - D.to_numpy().mean()) ** 2).sum()
        row = cvt[(cvt["model"] == m) & (cvt["quantity"] == "dft") & cvt["speed_kmh"].isna()].iloc[0]
        assert row["r2"] == pytest.approx(1 - (e**2).sum() / sst, rel=1e-12)
        assert row["rmse"] == pytest.approx(np.sqrt((e**2).mean()), rel=1e-12)
    # mean@dft: the training sections' mean DFT at each speed
    held = groups == "E02"
    p = cvp[(cvp["model"] == "mean@dft") & (cvp["section"] == "E02")]
    np.testing.assert_allclose(p[cols].to_numpy(), np.tile(D[~held.to_numpy()].mean().to_numpy(), (3, 1)))
    # the law handed to the FE: g * mu(v) of it is the least-squares fit of the predicted DFT
    r = p.iloc[0]
    from skidsim.friction import ExponentialDecay

    fitted = 1.1 * ExponentialDecay(r["mu_s"], r["mu_k"], r["alpha"]).mu_kmh(np.asarray(SPEEDS))
    assert np.max(np.abs(fitted - r[cols].to_numpy(float))) < 0.01


def test_dft_targets_from_measured_or_from_the_laws():
    X, Z, groups, rng = campaign(n_sections=3, p=30, seed=8)
    D = two_column_curves(X, Z, rng)
    back = R.dft_targets(None, measured_dft=long_dft(D), sites=X.index, speeds_kmh=SPEEDS)
    pd.testing.assert_frame_equal(back, D.rename_axis("site"), check_exact=False, rtol=1e-12)
    laws = laws_for(X)
    from_laws = R.dft_targets(laws, speeds_kmh=(20.0, 60.0))
    np.testing.assert_allclose(from_laws["dft@60"], R.predict_dft(laws.iloc[:1], None, (60.0,))["mu"].iloc[0])
    with pytest.raises(InputError, match="at 25 km/h"):
        R.dft_targets(None, measured_dft=long_dft(D), sites=X.index, speeds_kmh=(20.0, 25.0))


# -------------------------------------------------------------------------------------- prediction skill


def _cv_table(rows):
    return pd.DataFrame(
        [{"model": m, "quantity": "dft", "speed_kmh": np.nan, "n": 36, "r2": r2, "rmse": rmse} for m, r2, rmse in rows]
        + [{"model": "pca", "quantity": "mu_s", "speed_kmh": np.nan, "n": 36, "r2": 0.1, "rmse": 0.02}]
    )


def test_skill_table_warns_when_the_chosen_model_is_worse_than_the_mean():
    cvt = _cv_table(
        [("pca", -0.30, 0.080), ("mean@dft", 0.20, 0.060), ("ols2@dft", 0.55, 0.045), ("ridge@curve", 0.70, 0.038)]
    )
    sk = R.prediction_skill(cvt, "pca", notes={"ols2@dft": "raw_Sq+micro_Vvc in 12 of 12 folds"})
    assert list(sk["model"]) == ["ridge@curve", "ols2@dft", "mean@dft", "pca"]  # by RMSE
    c = sk.set_index("model")
    assert c.loc["pca", "role"] == "chosen" and c.loc["mean@dft", "role"] == "mean"
    assert not c.loc["pca", "beats_mean"] and not c.loc["pca", "beats_both"]
    assert c.loc["pca", "r2_minus_mean"] == pytest.approx(-0.50)
    w = sk.attrs["warning"]
    assert w.startswith("WARNING: the chosen model pca") and "mean@dft" in w and "ols2@dft" in w
    assert c.loc["pca", "warning"] == w and (c.drop("pca")["warning"] == "").all()
    assert c.loc["ols2@dft", "note"].startswith("raw_Sq+micro_Vvc")
    assert c.loc["ridge@curve", "beats_both"] and not c.loc["ols2@dft", "beats_baseline"]
    # beats the mean, not the baseline: the warning names the baseline only
    sk = R.prediction_skill(cvt, "mean@dft")
    assert sk.attrs["warning"].startswith("WARNING: the chosen model is the intercept-only mean mean@dft itself")
    assert (
        "2 model(s) of the comparison have a lower RMSE; it does not beat the simple baseline ols2@dft"
        in sk.attrs["warning"]
    )
    cvt2 = _cv_table([("pls", 0.40, 0.050), ("mean@dft", 0.20, 0.060), ("ols2@dft", 0.55, 0.045)])
    w2 = R.prediction_skill(cvt2, "pls").attrs["warning"]
    assert "ols2@dft" in w2 and "intercept-only" not in w2
    # no warning when the chosen model beats both
    sk = R.prediction_skill(cvt, "ridge@curve")
    assert sk.attrs["warning"] == "" and (sk["warning"] == "").all()
    with pytest.raises(InputError, match="baseline"):
        R.prediction_skill(cvt[cvt["model"] != "ols2@dft"], "pca")


def test_run_analysis_always_compares_with_mean_and_baseline_and_writes_the_skill_table(tmp_path):
    X, Z, groups, rng = campaign(n_sections=8, p=10, seed=9)
    D = two_column_curves(X, Z, rng, a="macro_P01", b="raw_P06")
    Y = pd.DataFrame(
        {
            "mu_s": 0.6 + 0.01 * rng.normal(size=len(X)),
            "mu_k": 0.3 + 0.01 * rng.normal(size=len(X)),
            "alpha": 0.05 + 0.005 * rng.normal(size=len(X)),
        },
        index=X.index,
    )
    d = R.Design(X=X, Y=Y, groups=groups)
    opts = dict(seed=1, grouped_by="section", figure11_models=("best",), prediction_speeds_kmh=SPEEDS)
    kw = dict(n_train=18, measured_dft=long_dft(D))
    # the references are cross-validated even when not listed, but compete for "best" only when listed
    a = R.run_analysis(d, R.RegressionOptions(models=("mean", "pca"), **opts), **kw)
    assert set(a.cv_predictions["model"]) == {"mean", "pca", R.MEAN_MODEL, R.BASELINE_MODEL}
    assert a.best in ("mean", "pca") and set(a.ranking["model"]) == {"mean", "pca"}
    # the laws carry nothing (noise), the DFT is linear in two columns: the chosen model loses to both
    w = a.skill.attrs["warning"]
    assert w.startswith(f"WARNING: the chosen model {a.best}") and "mean@dft" in w and "ols2@dft" in w
    paths = R.write_analysis(a, tmp_path / "reg")
    back = pd.read_csv(paths["prediction_skill"], keep_default_na=False)
    assert list(back["model"]) == list(a.skill["model"])
    assert back.loc[back["model"] == a.best, "warning"].iloc[0] == w
    assert back.loc[back["model"] == a.best, "beats_both"].astype(str).iloc[0] == "False"
    # listed, the baseline wins, and hands the FE a law
    b = R.run_analysis(d, R.RegressionOptions(models=("mean", "pca", R.BASELINE_MODEL), **opts), **kw)
    assert b.best == R.BASELINE_MODEL
    assert b.skill.attrs["warning"].startswith("WARNING: the chosen model is the simple baseline")
    assert b.skill.attrs["warning"].endswith("no other model of the comparison beats it")
    tp = b.test_parameters
    assert set(tp["model"]) == {R.BASELINE_MODEL} and tp[list(R.PARAMETERS)].notna().all().all()
    assert set(tp["features"]) == {"macro_P01+raw_P06"}


def test_plot_prediction_skill(tmp_path):
    from skidsim.plotting import regression as P

    cvt = _cv_table([("pca", -1.7, 0.080), ("mean@dft", 0.20, 0.060), ("ols2@dft", 0.55, 0.045)])
    for chosen in ("pca", "ols2@dft"):
        out = P.plot_prediction_skill(R.prediction_skill(cvt, chosen), tmp_path / f"{chosen}.png")
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5000
    with pytest.raises(InputError):
        P.plot_prediction_skill(pd.DataFrame({"model": []}), tmp_path / "x.png")
