"""What a texture model predicts of a hidden effect at unseen sections (skidsim.regression.capture)."""

import numpy as np
import pandas as pd
import pytest

from skidsim.errors import InputError
from skidsim.regression import effect_capture, section_cv_predictions

SPEEDS = (20.0, 40.0, 60.0)


def _campaign(n_sections=6, per=3, seed=0):
    rng = np.random.default_rng(seed)
    sites = [f"S{s:02d}-{k}" for s in range(n_sections) for k in range(1, per + 1)]
    X = pd.DataFrame(
        {"profile_MPD": rng.uniform(0.4, 1.8, len(sites)), "micro_Sq": rng.uniform(0.01, 0.05, len(sites))},
        index=pd.Index(sites, name="site"),
    )
    groups = np.repeat(np.arange(n_sections), per)
    D = pd.DataFrame(
        {f"dft@{v:g}": 0.3 + 4.0 * X["micro_Sq"] + (0.05 - v / 2000) * X["profile_MPD"] for v in SPEEDS},
        index=X.index,
    )
    return X, D, groups


def test_an_effect_linear_in_the_model_columns_is_captured_in_full():
    X, D, groups = _campaign()
    # an MPD x speed effect, linear in MPD at each speed: physics2 (identity form) spans it exactly
    effect = pd.DataFrame({c: -(v - 20) / 400 * (2.0 - X["profile_MPD"]) for c, v in zip(D.columns, SPEEDS)})
    r = effect_capture(X, D, D + effect, groups)
    assert r["captured_share"] == pytest.approx(1.0, abs=1e-9)
    assert r["slope"] == pytest.approx(1.0, abs=1e-9)
    assert r["captured_share_between_sites"] == pytest.approx(1.0, abs=1e-9)
    assert r["between_site_rms"] > 0.01
    assert r["effect_by_speed"]["dft@20"] == 0.0 and r["effect_by_speed"]["dft@60"] < 0
    assert r["n_sections"] == 6 and r["n_sites"] == 18


def test_a_section_effect_unrelated_to_texture_is_not_predicted():
    X, D, groups = _campaign(seed=1)
    rng = np.random.default_rng(5)
    offsets = rng.normal(0.0, 0.05, groups.max() + 1)[groups]  # one random level per section
    effect = pd.DataFrame(dict.fromkeys(D.columns, offsets), index=D.index)
    r = effect_capture(X, D, D + effect, groups)
    # held-out sections: their own offset is not in the training data, so nothing of it is predicted
    assert r["captured_share"] < 0.2
    assert abs(r["slope"]) < 0.3
    assert r["captured_share_between_sites"] < 0.2


def test_a_campaign_wide_shift_is_captured_but_has_no_between_site_part():
    X, D, groups = _campaign(seed=3)
    effect = pd.DataFrame({c: np.full(len(D), -(v - 20) / 1000) for c, v in zip(D.columns, SPEEDS)}, index=D.index)
    r = effect_capture(X, D, D + effect, groups)
    # the intercept per speed carries a shift common to every site; nothing differs between sites
    assert r["captured_share"] == pytest.approx(1.0, abs=1e-9)
    assert r["between_site_rms"] == pytest.approx(0.0, abs=1e-12)


def test_predictions_are_held_out_by_section():
    X, D, groups = _campaign(seed=2)
    D2 = D.copy()
    D2.iloc[0] += 1.0  # a wild site: it moves only the predictions of the other sections, never its own
    p, p2 = section_cv_predictions(X, D, groups), section_cv_predictions(X, D2, groups)
    own = groups == groups[0]
    assert np.allclose(p[own], p2[own])
    assert not np.allclose(p[~own], p2[~own])


def test_bad_input_names_what_is_expected():
    X, D, groups = _campaign()
    with pytest.raises(InputError, match="same sites"):
        section_cv_predictions(X.iloc[:-1], D, groups)
    with pytest.raises(InputError, match="changes the DFT"):
        effect_capture(X, D, D.copy(), groups)
    with pytest.raises(InputError, match="two sections"):
        section_cv_predictions(X, D, np.zeros(len(D), int))


def test_capture_tables_read_the_workflows_texture_and_dft_tables():
    from skidsim.regression import capture_tables

    wide = pd.DataFrame({"site": ["A-1", "A-2", "B-1"], "section": ["A", "A", "B"], "profile_MPD": [0.5, 0.7, 1.1]})
    points = pd.DataFrame(
        [(s, v, 0.5 - v / 1000 + i / 100) for i, s in enumerate(["B-1", "A-1", "A-2"]) for v in SPEEDS]
        + [("A-1", 80.0, 0.2)],  # a speed not asked for is left out
        columns=["site", "speed_kmh", "mu"],
    )
    X, D, groups = capture_tables(wide, points, SPEEDS)
    assert list(X.index) == list(D.index) == ["A-1", "A-2", "B-1"] and list(groups) == ["A", "A", "B"]
    assert list(D.columns) == ["dft@20", "dft@40", "dft@60"]
    assert D.loc["B-1", "dft@40"] == pytest.approx(0.46) and D.loc["A-2", "dft@20"] == pytest.approx(0.50)
    with pytest.raises(InputError, match="C-1"):  # a site of the texture table without a DFT value
        capture_tables(pd.concat([wide, wide.iloc[[0]].assign(site="C-1")]), points, SPEEDS)
