"""End-to-end tests of skidsim.criticism.diagnose on campaigns with hidden effects, null campaigns and outputs.

The campaigns come from tests/diagnosis_campaigns.py; the analysis receives only the campaign-level tables
(sites, measured, simulated, predicted, texture); the truth returned beside them is used only to assert. The
machinery has its own tests: tests/test_criticism_residuals.py, test_criticism_screening.py, test_criticism_gain.py.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from diagnosis_campaigns import make_campaign, read_campaign, write_campaign

from skidsim import criticism as cr
from skidsim.criticism import DiagnosisInputs, DiagnosisOptions


def _diagnose(tables, **kw):
    """The diagnosis of a campaign's tables with options ``kw`` (fields of DiagnosisOptions)."""
    t = tables
    inputs = DiagnosisInputs(t["sites"], t["measured"], t["simulated"], t["predicted"], t["texture"])
    return cr.diagnose(inputs, DiagnosisOptions(**kw))


def _campaign_dir(tmp_path, seed, effect, **kw):
    """Write the campaign to disk and return the tables derived from that directory alone, and the truth."""
    d = tmp_path / f"campaign_{effect}_{seed}"
    truth = write_campaign(d, seed=seed, effect=effect, **kw)
    # what a user provides (sites.csv, DFT traces) and the derived texture table; no truth on disk
    files = sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.is_file())
    assert files[-2:] == ["sites.csv", "texture.csv"] and all(f.startswith("dft/") for f in files[:-2])
    assert not any("truth" in f for f in files)
    return read_campaign(d), truth


def test_campaign_directory_round_trip(tmp_path):
    """The directory path reproduces the raw campaign: sites.csv columns and DFT points at the test speeds."""
    from diagnosis_campaigns import generate_campaign

    tables, _ = _campaign_dir(tmp_path, 3, "wear")
    sites, measured, tex, _ = generate_campaign(3, "wear")
    assert list(tables["sites"].columns[:5]) == ["site", "section", "scan", "dft", "temperature_c"]
    assert tables["sites"]["test_order"].tolist() == sites["test_order"].tolist()
    cal = tables["measured"].query("kind == 'calibration'").set_index(["site", "speed_kmh"])["mu"]
    # the file holds the mean of the calibration and trace samples at 20/40/60 km/h
    exp = measured[measured["speed_kmh"].isin([20.0, 40.0, 60.0])].groupby(["site", "speed_kmh"])["mu"].mean()
    assert np.allclose(cal.sort_index().to_numpy(), exp.sort_index().to_numpy(), atol=1e-9)
    assert np.allclose(tables["texture"]["mpd_mm"], tex["mpd_mm"])


def test_texture_adjusted_test_recovers_an_effect_the_texture_model_absorbed():
    """Temperature correlates with texture; the texture model (fitted on curves that carry the temperature effect)
    absorbs most of it, so the residual test is weak. Conditioning on texture names temperature, and its
    texture-refit extension gains on held-out sites where the plain residual term cannot."""
    rng = np.random.default_rng(8)
    n, secs = 36, np.repeat([f"S{k:02d}" for k in range(12)], 3)
    tex = rng.normal(size=(n, 4))
    temp = 20 + 4 * tex[:, 0] + rng.normal(0, 3, n)
    level = 0.45 + 0.05 * tex[:, 0] + 0.03 * tex[:, 1] - 0.006 * (temp - 20)
    leak = np.polyfit(tex[:, 0], temp, 1)  # the texture model learns temperature through texture column 0
    pred_level = (
        0.45 + 0.05 * tex[:, 0] + 0.03 * tex[:, 1] - 0.006 * (np.polyval(leak, tex[:, 0]) - 20) + rng.normal(0, 0.01, n)
    )
    v = np.arange(20.0, 71.0, 10.0)
    shape = -0.002 * (v - 45)
    sites = pd.DataFrame({"site": [f"s{i}" for i in range(n)], "section": secs, "temperature_c": temp})
    wide = pd.DataFrame({"site": sites["site"], **{f"macro_P{j}": tex[:, j] for j in range(4)}})
    rows_m, rows_s, rows_p = [], [], []
    for i, s in enumerate(sites["site"]):
        mu = level[i] + shape + rng.normal(0, 0.004, len(v))
        rows_m += [dict(site=s, speed_kmh=vv, mu=m, kind="validation") for vv, m in zip(v, mu)]
        rows_s += [dict(site=s, speed_kmh=vv, sn=level[i] + sh) for vv, sh in zip(v, shape)]
        rows_p += [dict(site=s, speed_kmh=vv, sn_pred=pred_level[i] + sh) for vv, sh in zip(v, shape)]
    r = cr.diagnose(
        DiagnosisInputs(sites, pd.DataFrame(rows_m), pd.DataFrame(rows_s), pd.DataFrame(rows_p), wide),
        DiagnosisOptions(seed=1, n_boot=300),
    )
    top = r.named
    assert top is not None and top.variable == "temperature_c" and top.level == "between-site", r.causes[:3]
    assert top.kind == "main" and top.texture_pcs >= 1 and top.direction == -1
    own = r.gain["scopes"]["held_out_sites"]
    assert own["gain_excludes_zero"] and own["rmse_after"] < own["rmse_before"], own
    generic = (
        own
        if r.gain["extension"] == "CovariateTerm"
        else next(a["scopes"]["held_out_sites"] for a in r.gain["alternatives"] if a["extension"] == "CovariateTerm")
    )
    assert generic["extension"]["settings"]["texture_pcs"] == top.texture_pcs_cv
    assert generic["gain_excludes_zero"] and generic["over_texture_refit"]["rmse_gain_ci"][0] > 0
    # the added-variable data recover the true partial effect, -0.006 mu per K (Frisch-Waugh slope)
    av = r.added_variable
    assert len(av) == n and np.polyfit(av["covariate_adj"], av["measured_adj"], 1)[0] == pytest.approx(
        -0.006, abs=0.0015
    )
    # two sections leave no texture PC to condition on: the residual test is kept
    few = sites["site"].iloc[:6]
    small = cr.screen_candidates(
        r.residuals[r.residuals["site"].isin(few)], sites.iloc[:6], wide.iloc[:6], DiagnosisOptions(seed=1)
    )
    assert all(c.texture_pcs == -1 for c in small)
    plain = cr.screen_candidates(r.residuals, sites, wide, DiagnosisOptions(seed=1, adjust_texture=False))
    t_plain = next(c for c in plain if c.variable == "temperature_c" and c.kind == "main")
    # the plain test is the weaker one: a p-value no smaller (both can sit at the permutation floor) and a smaller
    # cross-validated gain at held-out sections
    assert t_plain.texture_pcs == -1 and t_plain.p_value >= top.p_value and t_plain.cv_gain < top.cv_gain


@pytest.mark.parametrize("effect", ["temperature", "drainage", "squeeze", "wear", "mix"])
def test_hidden_effect_is_named_and_extension_gains(tmp_path, effect):
    tables, truth = _campaign_dir(tmp_path, 0, effect)
    r = _diagnose(tables, seed=0, n_boot=400)
    top = r.named
    assert top is not None and top.significant and top is r.causes[0]
    hidden = truth["variable"]
    assert top.variable == hidden or hidden in top.group, (top, hidden)
    assert top.level == "between-site"
    # the extension's gain on held-out data (held-out sites for a between-site cause) excludes zero
    own = r.gain["scopes"][r.gain["scope"]]
    assert r.gain["scope"] == "held_out_sites"
    assert own["rmse_gain_ci"][0] > 0 and own["rmse_after"] < own["rmse_before"]
    assert own["r2_after"] > own["r2_before"]
    assert r.gain["gain_excludes_zero"]
    # and beyond a campaign-wide level offset of the texture model: the named variable itself carries the gain
    assert own["over_shared_level"]["rmse_gain_ci"][0] > 0
    # the physical extension is used where one exists
    expected = {"temperature": "TemperatureShift", "drainage": "DrainageIFI", "squeeze": "DrainageIFI"}.get(effect)
    if expected is not None:
        assert expected in [r.gain["extension"]] + [a["extension"] for a in r.gain["alternatives"]]
    if effect in ("drainage", "squeeze"):  # kappa identified: at neither bound, the shape follows MPD (permutations)
        ident = r.gain["identifiability"]
        assert ident["extension"] == "DrainageIFI" and ident["identifiable"] and ident["why"] is None, ident
        assert ident["perm_p"] <= 0.05 and ident["kappa_interval_95"][0] > 0
        if effect == "drainage":  # the IFI truth, kappa 0.5
            assert ident["form_all_sites"] == "ifi" and ident["kappa_all_sites"] == pytest.approx(0.5, abs=0.15)
    if r.gain["extension"] == "DrainageIFI":  # form "auto": the chosen curve form per fold is recorded and reported
        folds = own["extension"]["params_per_fold"]
        assert all(f["form"] in ("ifi", "squeeze") and f["train_sse"] >= 0 for f in folds)
        report = Path(cr.write_outputs(tmp_path / "out", r.residuals, r.causes, r.gain)["report"]).read_text()
        assert "Drainage curve form chosen on the training data, per fold:" in report
        assert "Drainage factor kappa of DrainageIFI: identified (kappa " in report


@pytest.mark.slow
def test_null_campaigns_name_nothing(tmp_path):
    """Null campaigns with DFT traces every 4 km/h (as real campaigns have): many dependent points per site."""
    named = []
    for seed in range(20):
        tables, _ = _campaign_dir(tmp_path, 100 + seed, None, trace_step_kmh=4.0)
        # per site the trace file holds 20-80 km/h every 4 km/h plus the validation samples at 30/50/70 km/h
        assert (tables["measured"]["kind"] == "trace").sum() == 36 * (16 + 3)
        res = cr.build_residuals(tables["sites"], tables["measured"], tables["simulated"], tables["predicted"])
        causes = cr.screen_candidates(res, tables["sites"], tables["texture"], DiagnosisOptions(seed=seed))
        # enough permutations for the smallest p-value to pass BH in the larger family at its share of fdr
        n_units = len({(c.family, c.unit, c.level, c.kind) for c in causes if c.family == "secondary"})
        assert causes[0].n_permutations + 1 >= 4 * n_units / (0.5 * 0.05)
        named.append(cr.named_cause(causes) is not None)
    assert sum(named) <= 1, named  # >= 95 % of null seeds name nothing


def test_write_outputs_and_figures(tmp_path):
    from skidsim.plotting.diagnosis import diagnosis_figures

    tables, _ = make_campaign(seed=0, effect="wear", trace_step_kmh=10.0)
    r = _diagnose(tables, seed=0, n_boot=200, n_permutations=2999)
    figs = diagnosis_figures(r, tmp_path)
    paths = cr.write_outputs(tmp_path, r.residuals, r.causes, r.gain, figs)
    res = pd.read_parquet(paths["residuals"])
    assert set(res["level"]) == {"within-site", "between-site"}
    assert np.allclose(res["residual"], res["measured"] - res["model"])
    causes = json.loads(Path(paths["causes"]).read_text())
    for key in ("variable", "level", "effect", "cv_gain", "p_value", "p_adjusted", "significant", "rank"):
        assert key in causes[0]
    assert [c["rank"] for c in causes] == list(range(1, len(causes) + 1))
    gain = json.loads(Path(paths["gain"]).read_text())
    for sc in gain["scopes"].values():
        for key in ("rmse_before", "rmse_after", "r2_before", "r2_after", "rmse_gain_ci", "r2_after_ci"):
            assert key in sc
    report = Path(paths["report"]).read_text()
    assert causes[0]["variable"] in report
    for p in figs.values():
        assert Path(p).stat().st_size > 1000 and f"]({Path(p).name})" in report
    assert not list(tmp_path.glob("*.tmp*"))


def test_a_grouping_that_refines_the_named_one_ranks_below_it(tmp_path):
    """Parsimony between section-level groupings: a free-text column that splits the mixes further (as the study's
    'comment' does) holds the evidence of mix; where both are significant, mix is named and the finer one follows.
    Without the refinement (the finer column no longer nests in mix) no such reordering applies."""
    tables, truth = _campaign_dir(tmp_path, 0, "mix")
    sites = tables["sites"].copy()
    hidden = truth["variable"]
    sec_rank = sites["section"].rank(method="dense").astype(int)
    sites["comment"] = sites[hidden].astype(str) + np.where(sec_rank % 2 == 0, " with RAP", " with RAP + RAS")
    r = _diagnose({**tables, "sites": sites}, seed=0, n_boot=50)
    sig = [c.variable for c in r.causes if c.significant and c.level == "between-site" and c.kind == "main"]
    assert "comment" in sig and hidden in sig, sig  # both carry the effect
    assert r.named.variable == hidden and sig.index(hidden) < sig.index("comment"), sig
