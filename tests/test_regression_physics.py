"""The ``physics2`` model: OLS of the DFT curve on MPD and micro Sq, identity or log form by inner CV."""

import numpy as np
import pandas as pd
import pytest

from skidsim.errors import InputError
from skidsim.regression import check_model_name, fit_physics_ols, predict_parameters

SPEEDS = (20, 40, 60)


def _texture(n=36, seed=0):
    rng = np.random.default_rng(seed)
    return pd.DataFrame(
        {
            "profile_MPD": rng.uniform(0.4, 1.8, n),  # mm
            "micro_Sq": np.exp(rng.uniform(np.log(0.01), np.log(0.05), n)),  # mm
            "raw_Sq": rng.normal(size=n),
        },
        index=[f"S{i}" for i in range(n)],
    )


def _groups(n=36):
    return np.repeat(np.arange(n // 3), 3)


def test_recovers_a_planted_log_law_exactly():
    X = _texture()
    Y = pd.DataFrame(
        {f"dft@{v}": 0.6 + 0.04 * np.log(X["micro_Sq"]) - 0.01 * (v / 20) * np.log(X["profile_MPD"]) for v in SPEEDS}
    )
    m = fit_physics_ols(X, Y, groups=_groups())
    assert m.form == "log" and m.label == "log(profile_MPD)+log(micro_Sq)"
    assert m.inner_sse["log"] < 1e-20 < m.inner_sse["identity"]
    np.testing.assert_allclose(m.coef[1], [0.04] * 3, atol=1e-12)  # per unit of ln(Sq / mm)
    np.testing.assert_allclose(m.coef[0], [-0.01 * v / 20 for v in SPEEDS], atol=1e-12)
    np.testing.assert_allclose(m.predict(X).to_numpy(), Y.to_numpy(), atol=1e-12)


def test_recovers_a_planted_linear_law_and_prefers_it():
    X = _texture(seed=1)
    Y = pd.DataFrame({f"dft@{v}": 0.2 + 3.0 * X["micro_Sq"] - 0.05 * X["profile_MPD"] * v / 40 for v in SPEEDS})
    m = fit_physics_ols(X, Y, groups=_groups())
    assert m.form == "identity" and m.label == "profile_MPD+micro_Sq"
    np.testing.assert_allclose(m.coef[0], [-0.05 * v / 40 for v in SPEEDS], atol=1e-12)


def test_log_is_no_candidate_with_a_non_positive_value_and_predictions_clip_at_the_training_floor():
    X = _texture(seed=2)
    Y = pd.DataFrame({"dft@40": 0.5 + 0.03 * np.log(X["micro_Sq"])})
    X0 = X.copy()
    X0.iloc[0, 0] = 0.0  # an MPD of 0: a scan fault
    assert list(fit_physics_ols(X0, Y, groups=_groups()).inner_sse.index) == ["identity"]
    m = fit_physics_ols(X, Y, groups=_groups())
    assert m.form == "log"
    low = X.iloc[:1].copy()
    low["micro_Sq"] = 1e-9  # below every training value: raised to the smallest one before the log
    at_floor = X.iloc[:1].copy()
    at_floor["micro_Sq"] = X["micro_Sq"].min()
    np.testing.assert_allclose(m.predict(low).to_numpy(), m.predict(at_floor).to_numpy())


def test_the_dft_route_and_the_parameter_route():
    X = _texture(seed=3)
    g = _groups()
    D = pd.DataFrame({f"dft@{v}": 0.6 + 0.04 * np.log(X["micro_Sq"]) - 0.002 * v for v in SPEEDS}, index=X.index)
    P = pd.DataFrame(
        {"mu_s": 0.7 + 0.0 * X["raw_Sq"], "mu_k": 0.3 + 2 * X["micro_Sq"], "alpha": 0.5 + 0.1 * X["profile_MPD"]}
    )
    check_model_name("physics2@dft")
    tr, te = X.index[:27], X.index[27:]
    out = predict_parameters("physics2@dft", X.loc[tr], P.loc[tr], X.loc[te], groups_train=g[:27], dft_train=D)
    np.testing.assert_allclose(out[[f"dft@{v}" for v in SPEEDS]].to_numpy(), D.loc[te].to_numpy(), atol=1e-12)
    assert set(out["features"]) == {"log(profile_MPD)+log(micro_Sq)"}
    par = predict_parameters("physics2", X.loc[tr], P.loc[tr], X.loc[te], groups_train=g[:27])
    np.testing.assert_allclose(par["mu_k"], P.loc[te, "mu_k"], atol=1e-12)
    np.testing.assert_allclose(par["alpha"], P.loc[te, "alpha"], atol=1e-12)


def test_missing_column_is_a_clear_error():
    X = _texture().drop(columns="micro_Sq")
    with pytest.raises(InputError, match="micro_Sq"):
        fit_physics_ols(X, pd.DataFrame({"dft@40": np.ones(len(X))}))
