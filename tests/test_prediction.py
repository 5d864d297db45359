"""Friction for scans without DFT (skidsim.prediction, docs/prediction.md): the model file, CV+ intervals at unseen
sections, the training domain, and ``skidsim predict``.

One module-scoped set of campaigns (36 sites in 12 sections of each generator: chips, spectral and the default
generator; scans 100 x 600 points at 0.2 mm; texture group ``height`` only, which holds every column of
``physics2@dft``) serves every test; their tables come from :func:`skidsim.prediction.campaign_tables`.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from skidsim import prediction, regression
from skidsim.errors import ConfigError, InputError
from skidsim.prediction.options import PredictOptions
from skidsim.texture import TextureOptions
from skidsim.texture.quality import QualityOptions

ROOT = Path(__file__).resolve().parents[1]
SEED = 20261125
TEXTURE = TextureOptions(groups=("height",))
QUALITY = QualityOptions.from_dict({}, strip_length_mm=114.3)


def _generate(gen: str, path: Path) -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("_pred_bench", ROOT / "benchmarks" / "prediction_across_campaigns.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    bench.generate(gen, path, SEED, SimpleNamespace(shape=[100, 600], spacing_mm=0.2, sites=36))


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    root = tmp_path_factory.mktemp("prediction")
    out = {}
    for gen in ("chips", "spectral", "default"):
        _generate(gen, root / gen)
        X, D, groups, breaches = prediction.campaign_tables(root / gen, TEXTURE, QUALITY)
        out[gen] = SimpleNamespace(dir=root / gen, X=X, D=D, groups=groups, breaches=breaches)
    return out


# --- intervals and maps on hand-made tables ------------------------------------------------------------------------


def _toy(n_sections=10, per=3, seed=0):
    rng = np.random.default_rng(seed)
    sites = [f"S{s:02d}-{k}" for s in range(n_sections) for k in range(per)]
    X = pd.DataFrame(
        {"profile_MPD": rng.uniform(0.4, 1.8, len(sites)), "micro_Sq": rng.uniform(0.005, 0.03, len(sites))},
        index=pd.Index(sites, name="site"),
    )
    noise = rng.normal(0, 0.02, len(sites))
    D = pd.DataFrame(
        {f"dft@{v:g}": 0.3 + 8.0 * X["micro_Sq"] - v / 1000 * (2 - X["profile_MPD"]) + noise for v in (20, 40, 60)},
        index=X.index,
    )
    return X, D, np.repeat([f"S{s:02d}" for s in range(n_sections)], per)


def test_cvplus_bounds_are_the_order_statistics_of_fold_predictions_and_residuals():
    X, D, groups = _toy()
    cvp, oof = prediction.fit_cvplus(X, D, groups, lambda x, d, g: prediction.fit_map("physics2@dft", x, d, groups=g))
    new = X.iloc[[4]] * 1.1
    lo, hi = cvp.interval(new, 0.8)
    n = len(X)  # 30 sites: lower rank floor(0.2 * 31) = 6, upper rank ceil(0.8 * 31) = 25
    mu = np.array([cvp.folds[j].predict(new).to_numpy()[0] for j in cvp.site_fold])
    assert lo[0] == pytest.approx(np.sort(mu - cvp.residuals, axis=0)[5])
    assert hi[0] == pytest.approx(np.sort(mu + cvp.residuals, axis=0)[24])
    assert np.allclose(cvp.residuals, np.abs(D - oof))
    # too few sites for the level: unbounded, returned as NaN
    assert np.isnan(cvp.interval(new, 1 - 1 / (n + 2))[0]).all()
    with pytest.raises(InputError, match="between 0 and 1"):
        cvp.interval(new, 90)


@pytest.mark.parametrize("model", ["physics2@dft", "ols2@dft", "ridge@dft", "pca@dft", "pls@dft", "mean@dft"])
def test_the_linear_map_is_the_workflows_fitted_model(model):
    X, D, groups = _toy(n_sections=6)
    X["micro_Sa"] = X["micro_Sq"] * 0.8 + 0.001 * np.arange(len(X)) % 3
    lin = prediction.fit_map(model, X.iloc[3:], D.iloc[3:], groups=groups[3:])
    ref = regression.predict_parameters(
        model,
        X.iloc[3:],
        pd.DataFrame({"mu_s": 0.5, "mu_k": 0.3, "alpha": 0.1}, index=X.index[3:]),
        X.iloc[:3],
        groups_train=groups[3:],
        dft_train=D.iloc[3:],
    )
    assert np.max(np.abs(lin.predict(X.iloc[:3]).to_numpy() - ref[list(D.columns)].to_numpy())) < 1e-12
    back = prediction.LinearMap.from_dict(json.loads(json.dumps(lin.to_dict())))
    assert np.array_equal(back.predict(X).to_numpy(), lin.predict(X).to_numpy())


def test_a_model_on_parameters_is_refused_for_the_file():
    X, D, groups = _toy()
    with pytest.raises(InputError, match="@dft"):
        prediction.fit_map("ridge@curve", X, D, groups=groups)


# --- the model file -------------------------------------------------------------------------------------------------


def test_model_file_round_trips_and_its_folds_are_the_cross_validated_predictions(campaigns, tmp_path):
    c = campaigns["chips"]
    model = prediction.train_model(c.X, c.D, c.groups, "physics2@dft", texture=TEXTURE, quality=QUALITY)
    model.chosen.skill["heldout"] = {"rmse_flagged": float("nan"), "coverage": 0.9}  # no site flagged: null
    path = prediction.save_model(model, tmp_path / "model.json")
    assert json.loads(path.read_text())["chosen"]["skill"]["heldout"] == {"rmse_flagged": None, "coverage": 0.9}
    text = path.read_text()
    assert "NaN" not in text and json.loads(text)["format"] == prediction.FORMAT
    back = prediction.load_model(path)
    assert back.to_dict() == json.loads(text)
    for a, b in ((model.chosen, back.chosen), (model.baseline, back.baseline)):
        assert np.array_equal(a.map.predict(c.X).to_numpy(), b.map.predict(c.X).to_numpy())
        assert np.array_equal(np.stack(a.intervals.interval(c.X, 0.9)), np.stack(b.intervals.interval(c.X, 0.9)))
    # the section folds reproduce the workflow's leave-one-section-out predictions
    Y = pd.DataFrame({"mu_s": 0.5, "mu_k": 0.3, "alpha": 0.1}, index=c.X.index)
    cvp = regression.cross_validated_predictions(c.X, Y, c.groups, ["physics2@dft", "ols2@dft"], dft=c.D)
    for part in (back.chosen, back.baseline):
        iv = part.intervals
        oof = np.vstack([iv.folds[j].predict(c.X.loc[[s]]).to_numpy()[0] for s, j in zip(iv.sites, iv.site_fold)])
        ref = cvp[cvp["model"] == part.name].set_index("site").loc[list(iv.sites), list(c.D.columns)]
        assert np.max(np.abs(oof - ref.to_numpy(dtype=float))) < 1e-12
        assert part.skill["cv_rmse"] == pytest.approx(np.sqrt(np.mean((oof - c.D.to_numpy()) ** 2)))
    assert back.texture_options == TEXTURE and back.quality_options == QUALITY
    assert back.training["n_sections"] == 12 and len(back.training["table_digest"]) == 64


def test_a_bad_model_file_names_the_field(campaigns, tmp_path):
    c = campaigns["chips"]
    d = prediction.train_model(c.X, c.D, c.groups, "physics2@dft").to_dict()
    bad = json.loads(json.dumps(d))
    bad["chosen"]["map"]["coef"] = bad["chosen"]["map"]["coef"][:1]
    (tmp_path / "m.json").write_text(json.dumps(bad))
    with pytest.raises(InputError, match="chosen.map"):
        prediction.load_model(tmp_path / "m.json")
    bad = dict(d, format_version=99)
    (tmp_path / "m.json").write_text(json.dumps(bad))
    with pytest.raises(InputError, match="format_version"):
        prediction.load_model(tmp_path / "m.json")
    (tmp_path / "m.json").write_bytes(b"\x80\x04\x95 a pickle, not JSON")
    with pytest.raises(InputError, match="JSON"):
        prediction.load_model(tmp_path / "m.json")


# --- coverage at unseen sections and extrapolation ---------------------------------------------------------------


@pytest.mark.parametrize("gen", ["chips", "spectral", "default"])
def test_nominal_90_percent_intervals_cover_85_to_95_percent_at_unseen_sections(campaigns, gen):
    c = campaigns[gen]
    s, table = prediction.heldout_coverage(c.X, c.D, c.groups, "physics2@dft", 0.9)
    assert 0.85 <= s["coverage"] <= 0.95, s
    assert s["rmse"] < s["mean_width"] < 5 * s["rmse"]
    assert s["share_flagged"] <= 0.15
    assert len(table) == 36 * 6 and table["lo"].le(table["hi"]).all()


def test_chips_model_flags_spectral_scans_and_names_the_features(campaigns):
    a, b = campaigns["chips"], campaigns["spectral"]
    model = prediction.train_model(a.X.drop(columns="temperature_c"), a.D, a.groups, "ridge@dft")
    dft, ifi = prediction.predict_rows(model, b.X, 0.9)
    own, _ = prediction.predict_rows(model, a.X, 0.9)
    assert ifi["extrapolation"].mean() >= 0.8
    assert own["extrapolation"].mean() <= 0.1  # the training sites lie inside but for at most domain_alpha
    flagged = dft[dft["extrapolation"]]
    assert flagged["dft_lo"].isna().all() and flagged["dft"].notna().all()  # interval withheld, prediction kept
    assert flagged["reason"].str.contains("training range").all()
    assert (flagged["status"] == "flagged").all()


@pytest.mark.parametrize("model", ["physics2@dft", "ridge@dft"])
def test_spectral_model_holds_chips_scans_inside_its_domain_and_its_intervals_cover_them(campaigns, model):
    # the reverse: spectral's texture spans chips' (height parameters and MPD), so chips scans are no
    # extrapolation, and the intervals (wider: spectral's residuals) cover chips' measured DFT
    a, b = campaigns["spectral"], campaigns["chips"]
    trained = prediction.train_model(a.X.drop(columns="temperature_c"), a.D, a.groups, model)
    s = prediction.transfer_scores(trained.chosen, b.X, b.D, 0.9)
    assert s["share_flagged"] <= 0.1
    assert s["coverage_unflagged"] >= 0.9


def test_a_scan_outside_the_two_columns_of_physics2_names_the_column(campaigns):
    c = campaigns["chips"]
    model = prediction.train_model(c.X, c.D, c.groups, "physics2@dft")
    X = c.X.iloc[:2].copy()
    X.iloc[1, X.columns.get_loc("micro_Sq")] = 3 * c.X["micro_Sq"].max()
    dft, ifi = prediction.predict_rows(model, X, 0.9)
    assert list(ifi["extrapolation"]) == [False, True]
    assert "micro_Sq" in ifi["reason"].iloc[1] and "above the training range" in ifi["reason"].iloc[1]
    # IFI: F60 from the predicted DFT20 and the scan's own MPD (ASTM E1960), the interval mapped through it
    r = ifi.iloc[0]
    sp = 14.2 + 89.7 * X["profile_MPD"].iloc[0]
    assert r["sp_kmh"] == pytest.approx(sp)
    assert r["f60"] == pytest.approx(0.081 + 0.732 * r["dft20"] * np.exp(-40 / sp))
    assert r["f60_lo"] < r["f60"] < r["f60_hi"]


def test_quality_breaches_flag_or_refuse(campaigns):
    c = campaigns["chips"]
    model = prediction.train_model(c.X, c.D, c.groups, "physics2@dft", quality=QUALITY)
    X = c.X.iloc[:2]
    br = {X.index[0]: ["dropout_pct 12 % above the limit 10 %"]}
    dft, _ = prediction.predict_rows(model, X, 0.9, br)
    first = dft[dft["scan"] == X.index[0]]
    assert (first["status"] == "flagged").all() and first["reason"].str.contains("dropout_pct").all()
    assert first["dft"].notna().all()
    stop = prediction.PredictionModel(**{**model.__dict__, "quality": {**model.quality, "action": "stop"}})
    dft, ifi = prediction.predict_rows(stop, X, 0.9, br)
    first = dft[dft["scan"] == X.index[0]]
    assert (first["status"] == "refused").all() and first["dft"].isna().all() and np.isnan(ifi["f60"].iloc[0])
    assert (dft[dft["scan"] == X.index[1]]["status"] == "ok").all()


# --- skidsim predict ----------------------------------------------------------------------------------------------


def test_skidsim_predict_reproduces_the_out_of_fold_predictions_of_a_held_out_section(campaigns, tmp_path, capsys):
    from skidsim.cli import main

    c = campaigns["default"]
    held = c.groups == c.groups[0]
    model = prediction.train_model(
        c.X[~held], c.D[~held], c.groups[~held], "ridge@dft", texture=TEXTURE, quality=QUALITY
    )
    assert "temperature_c" in model.chosen.map.features
    prediction.save_model(model, tmp_path / "model.json")
    sites = pd.read_csv(c.dir / "sites.csv")
    scans = [str(c.dir / p) for p in sites.set_index("site").loc[list(c.X.index[held]), "scan"]]
    out = tmp_path / "out.csv"
    args = [str(tmp_path / "model.json"), *scans, "-o", str(out), "--sites", str(c.dir / "sites.csv")]
    assert main(["predict", *args, "--level", "0.9", "--jobs", "2"]) == 0
    printed = capsys.readouterr().out
    assert all(s in printed for s in c.X.index[held]) and "F60" in printed
    got = pd.read_csv(out)
    assert list(got.columns[:6]) == ["scan", "speed_kmh", "dft", "dft_lo", "dft_hi", "extrapolation"]
    Y = pd.DataFrame({"mu_s": 0.5, "mu_k": 0.3, "alpha": 0.1}, index=c.X.index)
    cvp = regression.cross_validated_predictions(c.X, Y, c.groups, ["ridge@dft"], dft=c.D)
    ref = cvp.set_index("site").loc[list(c.X.index[held]), list(c.D.columns)].to_numpy().ravel()
    assert np.max(np.abs(got["dft"].to_numpy() - ref)) < 1e-12
    ifi = pd.read_csv(tmp_path / "out_ifi.csv")
    assert len(ifi) == held.sum() and ifi["f60"].notna().all()
    # without the temperatures the model needs: a clear error naming the field
    assert main(["predict", str(tmp_path / "model.json"), scans[0]]) == 2
    assert "temperature_c" in capsys.readouterr().err


def test_predict_options_name_a_bad_value():
    assert PredictOptions.from_dict(None) == PredictOptions()
    with pytest.raises(ConfigError, match="predict.interval_level: expected a number between 0 and 1"):
        PredictOptions.from_dict({"interval_level": 90})
    with pytest.raises(ConfigError, match="unknown key"):
        PredictOptions.from_dict({"level": 0.9})
