"""Independent campaigns through the real workflow (issue 25): scans, FE, calibration, identifiability, regression.

The tests of both generators live here; ``tests/test_independent_campaigns_chips.py`` and
``tests/test_independent_campaigns_spectral.py`` import them and set the module-scoped ``generator`` fixture, so
that ``make test`` (``--dist loadfile``) hands the two campaigns to different workers.

A small campaign of each generator independent of :mod:`skidsim.generators.default` (``chips``: aggregate chips in
binder,
PIARC/IFI friction; ``spectral``: spectral texture, Rado friction; :mod:`skidsim.generators`) is written to a
temporary directory and run once per test session through ``snakemake`` with ``config/quick.yaml`` (quick solver
preset, our calibration only) up to the calibration and regression outputs. The tests read only what the workflow
wrote; of the generator only its configured trace noise (0.01 mu) is used, by the test that checks the noise the
identifiability flags are measured against.

Size (the cost of the module): 10 sites in 5 sections per generator (5 folds of the section-grouped CV, 2 sites
each), scans of 230 x 360 points at 0.2 mm (46 x 72 mm: the 40 mm FE strip within the 44 mm texture band, a 70 mm
pavement for the 20 mm slider's 40 mm slide), MPD on 70 mm segments. The bounds below come from the values measured
on these campaigns on 2026-11-26 (working tree after commit 08b0b35; table in :data:`MEASURED`), with the margins
said beside each bound. Cost measured the same day: 304 CPU-seconds (user + system of every process) for both
generators, about 2.5 min of the 2 cores; 18 min wall on the 2-core machine shared at load average 17-22.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import ROOT, run_snakemake, snakemake_env

from skidsim.atomic import write_text

GENERATORS = ("chips", "spectral")
N_SITES, N_SECTIONS = 10, 5
SHAPE = (230, 360)  # rows (y), cols (x), points
SPACING_MM = 0.2
SEED = 7
#: generator's trace noise (the DFT's repeatability, mu; skidsim.generators.campaign.COMMON["dft"]["noise_mu"])
NOISE_MU = 0.01

CONFIG = """
mesh:
  length_mm: 70.0          # 72 mm scans: the quick preset's 40 mm slide of the 20 mm slider (window from 5 mm)
texture:
  mpd_segment_mm: 70.0     # one MPD segment per 72 mm profile (the ISO 100 mm segment does not fit)
mesh_study:
  sizes_mm: []
"""

#: only the references compete: the chosen model is the mean or the baseline itself, so the warning must fire
REFERENCES_ONLY = """
regression:
  models: ["mean@dft", "ols2@dft"]
"""

TARGETS = (
    "results/calibration/fit_statistics.csv",
    "results/calibration/identifiability.csv",
    "results/calibration/parameters.parquet",
    "results/regression/prediction_skill.csv",
    "results/prediction/model.json",
)

#: Measured on these campaigns: method ours' fit R^2 at the calibration / validation speeds (2026-11-27, make test
#: of commit aa0fd4b: penalty friction, Rayleigh damping, the alpha trust region; with the stick-limit contact of
#: the first releases, 2026-11-26: chips 0.919 / 0.932, spectral 0.820 / 0.939); the prediction-skill table's
#: chosen model, its section-grouped CV R^2 of the DFT, the mean's (mean@dft) and the baseline's (ols2@dft)
#: (2026-11-26, working tree after commit 08b0b35; they do not depend on the FE: the same mean and baseline on
#: 2026-11-27).
MEASURED = {
    "chips": {"fit_r2": (0.963, 0.950), "chosen": ("pca@dft", 0.917), "mean_r2": 0.713, "baseline_r2": 0.187},
    "spectral": {"fit_r2": (0.913, 0.977), "chosen": ("pca@dft", 0.803), "mean_r2": 0.694, "baseline_r2": 0.770},
}
#: Lower bound of method ours' fit R^2 at the calibration and at the validation speeds: the generator's lower
#: measured value with the stick-limit contact less 0.07 (chips: 0.919 -> 0.85) or 0.10 (spectral: 0.820 -> 0.72;
#: its calibration-speed fit is the worse one: 9 of 10 sites at the mu_s bound 0.85, flagged at_bound and
#: fit_beyond_noise); the default contact is above both by 0.10 or more.
FIT_R2_MIN = {"chips": 0.85, "spectral": 0.72}
#: Lower bound of the chosen model's section-grouped CV R^2 of the DFT: the measured value less 0.1.
CHOSEN_R2_MIN = {"chips": 0.82, "spectral": 0.70}


def snakemake(workdir: Path, *configs: Path, targets=TARGETS) -> None:
    run_snakemake(
        "--config",
        f"campaign={workdir / 'campaign'}",
        "--",
        *targets,
        workdir=workdir,
        configfiles=(ROOT / "config" / "quick.yaml", *configs),
        cores=2,
        env=snakemake_env(OMP_NUM_THREADS="1"),
    )


def read_results(results: Path) -> dict:
    reg, cal = results / "regression", results / "calibration"
    return {
        "fit": pd.read_csv(cal / "fit_statistics.csv"),
        "ident": pd.read_csv(cal / "identifiability.csv", keep_default_na=False, na_values=[""]),
        "records": {
            p.parent.name: json.loads(p.read_text())
            for p in sorted((results / "sites").glob("*/identifiability_ours.json"))
        },
        "params": pd.read_parquet(cal / "parameters.parquet"),
        "skill": pd.read_csv(reg / "prediction_skill.csv", keep_default_na=False),
        "best": (reg / "best_model.txt").read_text().strip(),
    }


def campaign_overrides(**friction) -> dict:
    """The generator settings of these campaigns (``friction``: settings of its friction model on top)."""
    over = {"n_sites": N_SITES, "n_sections": N_SECTIONS, "shape": list(SHAPE), "spacing_mm": SPACING_MM, "seed": SEED}
    if friction:
        over["friction"] = friction
    return over


@pytest.fixture(scope="module")
def run(generator, tmp_path_factory):
    """One campaign of ``generator`` (a module-scoped fixture of the test file: one of :data:`GENERATORS`) through
    the workflow, then the regression again with only the references listed. Returns the tables of both runs and
    the regression logs."""
    from skidsim.generators import write_campaign

    assert generator in GENERATORS, generator
    gen = generator
    wd = tmp_path_factory.mktemp(f"independent_{gen}")
    write_campaign(wd / "campaign", gen, campaign_overrides())
    cfg = wd / "test.yaml"
    write_text(cfg, CONFIG)
    snakemake(wd, cfg)
    out = {
        "generator": gen,
        "workdir": wd,
        "first": read_results(wd / "results"),
        "first_log": (wd / "logs" / "regression.log").read_text(),
    }
    shutil.copytree(wd / "results" / "regression", wd / "regression_first")
    refs = wd / "references.yaml"
    write_text(refs, REFERENCES_ONLY)
    snakemake(wd, cfg, refs, targets=("results/regression/prediction_skill.csv",))
    out["references"] = read_results(wd / "results")
    out["references_log"] = (wd / "logs" / "regression.log").read_text()
    return out


# ---------------------------------------------------------------------------------------------------------------
# (a) the calibration: fit, flags with reasons, the noise the flags are measured against


@pytest.mark.slow
def test_back_calculation_fits_at_calibration_and_validation_speeds(run):
    st = run["first"]["fit"]
    ours = st[st["method"] == "ours"].set_index("kind")
    assert set(ours.index) == {"calibration", "validation"}
    assert (ours["n"] == 3 * N_SITES).all(), ours  # 3 speeds x every site
    for kind in ("calibration", "validation"):
        assert ours.loc[kind, "r2"] > FIT_R2_MIN[run["generator"]], (run["generator"], kind, ours.loc[kind].to_dict())


@pytest.mark.slow
def test_identifiability_flags_carry_their_reasons(run):
    """Every site has a record; each flag has a reason with its numbers; the table's flag columns, the record's
    flags and the parameters agree (a flag ``at_bound`` names a parameter that sits on its bound)."""
    res = run["first"]
    ident, records = res["ident"], res["records"]
    ours = ident[ident["method"] == "ours"].set_index("site")
    assert len(ours) == N_SITES and len(records) == N_SITES
    params = res["params"]
    params = params[params["method"] == "ours"].set_index("site")
    flags = ("not_converged", "at_bound", "outside_law", "fe_not_smooth", "fit_beyond_noise")
    for site, rec in records.items():
        assert sorted(rec["reasons"]) == sorted(rec["flags"]), (site, rec["flags"])
        assert set(rec["flags"]) <= set(flags), rec["flags"]
        for flag in flags:
            assert bool(ours.loc[site, flag]) == (flag in rec["flags"]), (site, flag)
        for flag, reason in rec["reasons"].items():
            assert isinstance(reason, str) and any(ch.isdigit() for ch in reason), (site, flag, reason)
        # fit_beyond_noise is the fit's RMSE against the noise measured on the trace, > 2 sigma
        beyond = max(
            float(ours.loc[site, "rmse_fe_calibration_sigma"]), float(ours.loc[site, "rmse_fe_validation_sigma"])
        )
        assert ("fit_beyond_noise" in rec["flags"]) == (beyond > 2.0), (site, beyond, rec["flags"])
        assert bool(rec["within_noise"]) == ("fit_beyond_noise" not in rec["flags"])
        assert ("at_bound" in rec["flags"]) == bool(rec["at_bound"]), (site, rec["at_bound"])
        for d in rec["at_bound"]:  # the parameter named sits on the bound named (within 1 % of the bounds' width)
            lo, hi = rec["bounds"][d["param"]]
            assert d["bound_value"] == (hi if d["bound"] == "upper" else lo), (site, d)
            assert float(params.loc[site, d["param"]]) == pytest.approx(d["bound_value"], abs=0.01 * (hi - lo))
            assert d["param"] in rec["reasons"]["at_bound"], rec["reasons"]
        assert rec["statement"].startswith("identified parameters"), rec["statement"]


@pytest.mark.slow
def test_trace_noise_is_the_generators(run):
    """The noise the flags are measured against, estimated from each trace, is the generator's (0.01 mu): the
    campaign median within 20 %, every site within a factor 1.6."""
    sigma = run["first"]["ident"].query("method == 'ours'")["sigma"].astype(float)
    assert abs(float(np.median(sigma)) / NOISE_MU - 1.0) < 0.2, sigma.describe()
    assert (sigma / NOISE_MU).between(1 / 1.6, 1.6).all(), sigma.describe()


# ---------------------------------------------------------------------------------------------------------------
# (b) the prediction skill at unseen sections


def _row(skill: pd.DataFrame, role: str) -> pd.Series:
    rows = skill[skill["role"].astype(str).str.split("+").map(lambda r: role in r)]
    assert len(rows) == 1, (role, skill[["model", "role"]])
    return rows.iloc[0]


@pytest.mark.slow
def test_chosen_model_predicts_unseen_sections_and_is_never_below_the_baseline(run):
    res = run["first"]
    skill = res["skill"]
    chosen, base, mean = _row(skill, "chosen"), _row(skill, "baseline"), _row(skill, "mean")
    assert chosen["model"] == res["best"]
    assert base["model"] == "ols2@dft" and mean["model"] == "mean@dft"
    assert (skill["n"] == 6 * N_SITES).all()  # 6 prediction speeds (20-70 km/h) x every site
    # by construction of the selection (the baseline is among the listed models): lowest RMSE, so R^2 >= baseline's
    assert float(chosen["rmse"]) <= float(base["rmse"]) and float(chosen["r2"]) >= float(base["r2"])
    assert float(chosen["r2"]) > CHOSEN_R2_MIN[run["generator"]], skill[["model", "r2", "rmse"]]
    assert "fold" in str(base["note"])  # the baseline's chosen columns per fold


@pytest.mark.slow
def test_skill_warning_fires_exactly_when_the_chosen_model_does_not_beat_both(run):
    for key in ("first", "references"):
        skill = run[key]["skill"]
        log = run[f"{key}_log"]
        chosen = _row(skill, "chosen")
        beats = str(chosen["beats_both"]) == "True"
        assert (chosen["warning"] == "") == beats, (key, chosen.to_dict())
        assert ("WARNING" in log and str(chosen["warning"])[:40] in log) == (not beats), key
        assert (skill.loc[skill["model"] != chosen["model"], "warning"] == "").all()
    # with only the references listed the chosen model is one of them, which cannot beat itself: the warning fires
    chosen = _row(run["references"]["skill"], "chosen")
    assert chosen["model"] in ("mean@dft", "ols2@dft")
    assert chosen["warning"].startswith("WARNING: the chosen model is")


# ---------------------------------------------------------------------------------------------------------------
# (c) a hidden texture-and-speed effect at unseen sections (issue 25, item 5)

#: The hidden effect: partial hydroplaning, ``max(0.05, 1 - kappa (v^2 - 20^2) / Sp^2)`` on mu with Sp from MPD
#: (skidsim.generators.friction_models.hidden_factor).
HIDDEN = {"hidden_effect": "squeeze", "hidden_kappa": 0.3}
#: Measured on these campaigns (2026-11-27, working tree after commit 6c2918d; the effect: -0.091 / -0.064 mu at
#: 70 km/h on chips / spectral): physics2's captured share of the effect at held-out sections 0.986 / 0.849 (slope
#: 0.959 / 0.816), of its differences between sites 0.776 / 0.205 (slope 0.970 / 0.290; with 36 sites in 12
#: sections 0.83 / 0.68, docs/regression.md). Bounds: the measured value less 0.09-0.17.
CAPTURED_SHARE_MIN = {"chips": 0.9, "spectral": 0.7}
SLOPE_RANGE = {"chips": (0.8, 1.1), "spectral": (0.65, 1.0)}
BETWEEN_SHARE_MIN = {"chips": 0.6, "spectral": 0.0}


@pytest.fixture(scope="module")
def hidden(run):
    """The same campaign (same seed: the same scans and trace noise) with the hidden squeeze effect on friction;
    the workflow's ingest gives its measured DFT; the texture table is the first run's."""
    from skidsim.generators import write_campaign
    from skidsim.regression import capture_tables

    wd = run["workdir"] / "hidden"
    write_campaign(wd / "campaign", run["generator"], campaign_overrides(**HIDDEN))
    cfg = wd / "test.yaml"
    write_text(cfg, CONFIG)
    snakemake(wd, cfg, targets=("results/ingest/dft_points.parquet",))
    base = run["workdir"]
    wide = pd.read_parquet(base / "results" / "texture" / "campaign.parquet")
    X, without, groups = capture_tables(wide, pd.read_parquet(base / "results" / "ingest" / "dft_points.parquet"))
    _, with_, _ = capture_tables(wide, pd.read_parquet(wd / "results" / "ingest" / "dft_points.parquet"))
    scans = {p.name: p.read_bytes() for p in sorted((base / "campaign" / "scans").glob("*"))}
    same = scans == {p.name: p.read_bytes() for p in sorted((wd / "campaign" / "scans").glob("*"))}
    return {"X": X, "without": without, "with": with_, "groups": groups, "same_scans": same}


@pytest.mark.slow
def test_texture_model_predicts_a_hidden_squeeze_at_unseen_sections(run, hidden):
    """The workflow's texture model on the independent generators (physics2: the DFT at each speed on MPD and
    micro Sq), cross-validated by section on the campaign with and without the hidden effect: the held-out
    predictions move with the effect (captured share and slope) and still predict unseen sections."""
    from skidsim.regression import effect_capture

    assert hidden["same_scans"]  # the effect changes friction only
    r = effect_capture(hidden["X"], hidden["without"], hidden["with"], hidden["groups"])
    gen = run["generator"]
    assert r["effect_by_speed"]["dft@20"] == pytest.approx(0.0, abs=0.003)  # anchored at 20 km/h (+- rounding)
    assert r["effect_by_speed"]["dft@70"] < -0.02  # a real loss at speed
    assert r["captured_share"] > CAPTURED_SHARE_MIN[gen], r
    assert SLOPE_RANGE[gen][0] < r["slope"] < SLOPE_RANGE[gen][1], r
    # the part that rides on texture: the predictions move with the effect's differences between sites
    assert r["captured_share_between_sites"] > BETWEEN_SHARE_MIN[gen], r
    assert r["slope_between_sites"] > 0.15, r
    assert r["r2_with"] > CHOSEN_R2_MIN[gen] - 0.1, r


# ---------------------------------------------------------------------------------------------------------------
# (d) the model file: skidsim predict runs the workflow's texture pipeline on a scan


@pytest.mark.slow
def test_skidsim_predict_on_a_campaign_scan_gives_the_workflow_model_on_the_workflow_texture(run, tmp_path):
    """The model file the workflow wrote, applied by ``skidsim predict`` to two of the campaign's own scans, gives
    the chosen model's map on the texture table the workflow computed from the same scans (so the texture pipeline
    in the model file is the workflow's), and intervals that contain the point prediction."""
    from skidsim import prediction, regression
    from skidsim.cli import main

    wd = run["workdir"]
    model_path = wd / "results" / "prediction" / "model.json"
    model = prediction.load_model(model_path)
    wide_path = wd / "results" / "texture" / "campaign.parquet"
    X = regression.assemble_design(pd.read_parquet(wide_path), campaign_file=wide_path).X
    sites = pd.read_csv(wd / "campaign" / "sites.csv").set_index("site")
    picked = list(X.index[:2])
    scans = [str(wd / "campaign" / sites.loc[s, "scan"]) for s in picked]
    out = tmp_path / "out.csv"
    assert (
        main(["predict", str(model_path), *scans, "-o", str(out), "--sites", str(wd / "campaign" / "sites.csv")]) == 0
    )
    got = pd.read_csv(out)
    assert len(got) == len(picked) * len(model.chosen.map.targets)
    expect = model.chosen.map.predict(X.loc[picked]).to_numpy().ravel()
    assert np.max(np.abs(got["dft"].to_numpy() - expect)) < 1e-9
    inside = got.dropna(subset=["dft_lo", "dft_hi"])
    assert ((inside["dft_lo"] <= inside["dft"]) & (inside["dft"] <= inside["dft_hi"])).all()
