"""The campaign builders of the rates by effect kind (tests/diagnosis_rate_campaigns.py) and the generators' hidden
texture effects (skidsim.generators.friction_models.hidden_factor: hysteresis, contact_micro): effect sizes as
specified, the null has no effect, every kind has the same sites.csv columns."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
import diagnosis_rate_campaigns as rc


@pytest.fixture(scope="module")
def chips_texture():
    # small scans: the builders only need a texture table of the generator's surfaces
    return rc.generator_texture("chips", 0, shape=(480, 480))


def _noise_free(source, kind, seed=3, texture=None):
    sites, measured, tex, truth = rc.generate(source, kind, seed, noise_mu=0.0, trace_step_kmh=0, texture=texture)
    wide = measured.pivot_table(index="site", columns="speed_kmh", values="mu").loc[sites["site"]]
    return sites, wide, tex, truth


@pytest.mark.parametrize("source", ["default", "chips", "chips+sectionlatent"])
def test_effect_kinds_change_friction_as_specified(source, chips_texture):
    texture = None if source == "default" else chips_texture
    sites, none, tex, t0 = _noise_free(source, "none", texture=texture)
    assert t0["effect_sd_mu"] == 0.0 and t0["variable"] is None
    v = none.columns.to_numpy(float)
    columns = list(sites.columns)
    for kind in rc.KINDS[1:]:
        s, mu, tx, truth = _noise_free(source, kind, texture=texture)
        assert list(s.columns) == columns and s.equals(sites) and tx.equals(tex)  # only the friction differs
        assert truth["effect_rms_mu"] > 0.005, (kind, truth)
        if kind == "section_column":
            factor = 1 - rc.POLISH_PER_MSA * (sites["cum_traffic_msa"].to_numpy() - 10.0)
            assert np.allclose(mu.to_numpy(), none.to_numpy() * factor[:, None])
            assert sites.groupby("section")["cum_traffic_msa"].nunique().max() == 1  # section level
        elif kind == "site_column":
            factor = 1 - rc.STATION_PER_FT * sites["station_ft"].to_numpy()
            assert np.allclose(mu.to_numpy(), none.to_numpy() * factor[:, None])
        elif kind == "texture_speed":
            sdq = tex["macro_Sdq"].to_numpy()
            z = (sdq - sdq.mean()) / sdq.std()
            assert np.allclose(mu.to_numpy() - none.to_numpy(), rc.HYST_MU * z[:, None] * (v - 20) / 50)
        elif kind == "categorical_speed":
            pol = (sites["aggregate"] == rc.POLISHED).to_numpy()
            assert pol.sum() == 3 * rc.SITES_PER_SECTION
            d = mu.to_numpy() - none.to_numpy()
            ramp = np.clip((60 - v) / 40, 0, 1)
            assert np.allclose(d[~pol], 0) and np.allclose(d[pol], -rc.POLISH_LOW_SPEED_MU * ramp)
        elif kind == "temperature":
            d = (mu.to_numpy() - none.to_numpy()).mean(axis=1)
            warm = sites["temperature_c"].to_numpy() - rc.WLF["t_ref_c"]
            # a colder rubber behaves as at a higher slip speed: lower friction on a falling curve
            assert np.corrcoef(warm, d)[0, 1] > 0.8, np.corrcoef(warm, d)
        elif kind == "drainage":
            sp = 14.2 + 89.7 * tex["profile_MPD"].to_numpy()[:, None]
            factor = np.maximum(0.05, 1 - rc.DRAIN_KAPPA * (v**2 - 400) / sp**2)
            assert np.allclose(mu.to_numpy(), none.to_numpy() * factor)
            assert np.all(factor[:, v <= 20] == 1) and np.all(np.diff(factor, axis=1) <= 0)
            # shallow texture loses more at speed: the factor at the highest speed rises with MPD, strictly
            order = np.argsort(tex["profile_MPD"].to_numpy())
            assert np.all(np.diff(factor[order, -1]) >= 0) and factor[order[0], -1] < factor[order[-1], -1] - 0.05
        elif kind == "texture_measure":
            assert "hidden_micro_contact" not in tx.columns and "micro_Sq" in tx.columns
            ratio = mu.to_numpy() / none.to_numpy()
            if source != "default":  # PIARC: the level changes, not the speed dependence
                assert np.allclose(ratio, ratio[:, :1])
            assert np.ptp(ratio) > 0.05


def test_wlf_shift_constants():
    assert rc.wlf_log10_shift(20.0) == 0.0
    assert rc.wlf_log10_shift(10.0) == pytest.approx(8.86 * 10 / 91.6)


def test_campaign_tables_hold_no_hidden_measure_and_predict_held_out_sections(chips_texture):
    t, truth = rc.make_rate_campaign("chips", "texture_measure", 5, texture=chips_texture)
    assert not any(c.startswith("hidden_") for c in t["texture"].columns)
    assert t["prediction_features"] == ("log(profile_MPD)", "log(micro_Sq)")
    assert set(t["predicted"]["site"]) == set(t["sites"]["site"]) and t["predicted"]["sn_pred"].notna().all()
    # physics2-like: a held-out section's prediction does not change with its own calibrated curves
    sim = t["simulated"].copy()
    own = sim["site"].str.startswith("S01-")
    sim.loc[own, "sn"] += 0.1
    p2 = rc.physics2_predictions(sim, t["sites"], t["texture"])
    keep = p2["site"].str.startswith("S01-")
    assert np.allclose(p2.loc[keep, "sn_pred"], t["predicted"].loc[keep.to_numpy(), "sn_pred"])
    assert not np.allclose(p2.loc[~keep, "sn_pred"], t["predicted"].loc[(~keep).to_numpy(), "sn_pred"])


def test_generator_hidden_texture_effects():
    from skidsim.errors import ConfigError
    from skidsim.generators import campaign as gc
    from skidsim.generators import friction_models as fm

    v = np.array([20.0, 45.0, 70.0])
    f = fm.hidden_factor("hysteresis", 0.8, 80.0, v, macro_sdq=0.75)
    assert np.allclose(f, 1 + 0.8 * 0.25 * (v - 20) / 50)
    r = fm.hidden_factor("contact_micro", 2.0, 80.0, v, micro_contact_mm=0.01, micro_sq_mm=0.03, sq_ref_mm=0.015)
    assert np.allclose(r, fm.level_from_micro(0.02, 0.015) / fm.level_from_micro(0.03, 0.015))
    with pytest.raises(ConfigError):
        fm.hidden_factor("hysteresis", 0.8, 80.0, v)
    for effect, key in (("hysteresis", "macro_sdq"), ("contact_micro", "micro_contact_mm")):
        cfg = gc.generator_config(
            "spectral",
            {
                "n_sites": 2,
                "n_sections": 1,
                "shape": [100, 150],
                "spacing_mm": 0.2,
                "seed": 1,
                "friction": {"hidden_effect": effect, "hidden_kappa": 1.0},
            },
        )
        row = gc.design_campaign(cfg).iloc[0]
        site = gc.generate_site(row, cfg)
        h = site.truth["hidden"]
        assert h["effect"] == effect and h[key] > 0
        plain = {**site.truth, "hidden": {**h, "effect": None}}
        ratio = gc.site_mu(site.truth, v) / gc.site_mu(plain, v)
        extra = {k: h[k] for k in ("macro_sdq", "micro_contact_mm", "micro_sq_mm", "sq_ref_mm") if k in h}
        assert np.allclose(ratio, fm.hidden_factor(effect, 1.0, h["sp_kmh"], v, **extra))
    # campaigns without these effects record no extra measure (their bytes are unchanged)
    cfg = gc.generator_config("spectral", {"n_sites": 1, "shape": [100, 150], "spacing_mm": 0.2, "seed": 1})
    assert set(gc.generate_site(gc.design_campaign(cfg).iloc[0], cfg).truth["hidden"]) == {"effect", "kappa", "sp_kmh"}


@pytest.mark.parametrize("source", ["default", "chips"])
def test_speed_shape_kinds_are_sized_like_the_default_campaigns_effect(source, chips_texture):
    """texture_speed and categorical_speed hide an effect of about the default campaign's size (sd over sites of
    the effect's mean over 20-70 km/h 0.035-0.04 mu, like its temperature effect, 0.038 mu)."""
    texture = None if source == "default" else chips_texture
    for kind in ("texture_speed", "categorical_speed"):
        truth = _noise_free(source, kind, texture=texture)[3]
        assert 0.033 <= truth["effect_sd_mu"] <= 0.042, (kind, truth)


def test_plain_generator_sources_hide_no_section_factor(chips_texture):
    """One hidden effect per campaign: on the plain chips source the friction level at 20 km/h over the
    generator's own level law of the site's micro Sq (its site factor) varies within sections about as much as
    between them (share of the section means in its variance about 1/3 with 3 sites per section); the
    +sectionlatent source keeps the generator's random section factors (the share rises towards 1)."""
    from skidsim.generators import campaign as gc
    from skidsim.generators import friction_models as fm

    assert rc.generator_of("chips+sectionlatent") == "chips" and "spectral+sectionlatent" in rc.SOURCES
    sq_ref_mm = gc.generator_config("chips")["friction"]["sq_ref_mm"]
    law = np.array([fm.level_from_micro(x, sq_ref_mm) for x in chips_texture["hidden_micro_sq_mm"]])

    def section_share_of_level(source):
        sites, mu, _, _ = _noise_free(source, "none", texture=chips_texture)
        assert mu.columns[0] == 20.0
        r = np.log(mu.iloc[:, 0].to_numpy() / law)
        sec = sites["section"].to_numpy()
        means = np.array([r[sec == s].mean() for s in sec])
        return float(means.var() / r.var())

    plain, latent = section_share_of_level("chips"), section_share_of_level("chips+sectionlatent")
    assert plain < 0.5 and latent > plain + 0.3, (plain, latent)


def test_the_contact_zone_columns_follow_the_hidden_contact_microtexture_better_than_micro_sq(chips_texture):
    """On the chips generator's surfaces (microtexture on the chip tops only, flat binder between) the measured
    micro_Sq_top (skidsim.texture.contact: the micro band on the top 10 % of the raw surface) follows the hidden
    contact microtexture (the micro band within 0.5 mm of the highest tops, a different zone) more closely than the
    whole-scan micro_Sq does; the table holds both, the hidden measure stays out of it."""
    assert set(rc.TABLE_COLUMNS) <= set(chips_texture.columns)
    hidden = np.log(chips_texture["hidden_micro_contact"].to_numpy())
    r = {c: np.corrcoef(np.log(chips_texture[c].to_numpy()), hidden)[0, 1] for c in ("micro_Sq", "micro_Sq_top")}
    assert r["micro_Sq_top"] > r["micro_Sq"] + 0.1, r


def test_hide_column_effect_changes_a_written_campaign_as_the_rate_campaigns(tmp_path):
    """The rate campaigns' column effects hidden in a campaign the spectral generator wrote: each DFT trace moves by
    the effect of its site's sites.csv row on the generator's own friction (the noise kept, 0.001 rounding), and
    only the polished aggregate's sites move for the categorical kind."""
    import json

    import pandas as pd

    from skidsim.generators import write_campaign
    from skidsim.generators.campaign import site_mu

    over = {"n_sites": 8, "n_sections": 4, "shape": [60, 80], "spacing_mm": 0.2, "seed": 2}
    for kind in rc.COLUMN_KINDS:
        camp, truth_dir = tmp_path / kind, tmp_path / f"{kind}-truth"
        write_campaign(camp, "spectral", over, truth_dir=truth_dir)
        sites = pd.read_csv(camp / "sites.csv").drop(columns="temperature_c")
        design = rc.site_design(2, sites["site"], sites["section"])
        sites = pd.concat([sites, design.drop(columns=["site", "section"])], axis=1)
        sites.loc[sites["section"] == sites["section"].iloc[0], "aggregate"] = rc.POLISHED
        sites.to_csv(camp / "sites.csv", index=False)
        before = {s: pd.read_csv(camp / "dft" / f"{s}.csv") for s in sites["site"]}
        rc.hide_column_effect(camp, truth_dir, kind)
        for row in sites.to_dict("records"):
            old, new = before[row["site"]], pd.read_csv(camp / "dft" / f"{row['site']}.csv")
            v = old["speed_kmh"].to_numpy(float)
            assert np.array_equal(new["speed_kmh"].to_numpy(float), v)
            fr = json.loads((truth_dir / f"{row['site']}.json").read_text())
            mu = site_mu(fr, v)
            if kind == "section_column":
                want = mu * (-rc.POLISH_PER_MSA * (row["cum_traffic_msa"] - 10.0))
            elif kind == "site_column":
                want = mu * (-rc.STATION_PER_FT * row["station_ft"])
            elif kind == "temperature":
                want = site_mu(fr, v * 10.0 ** rc.wlf_log10_shift(row["temperature_c"])) - mu
            else:
                ramp = np.clip((60.0 - v) / 40.0, 0.0, 1.0)
                want = -rc.POLISH_LOW_SPEED_MU * ramp if row["aggregate"] == rc.POLISHED else 0.0 * v
            got = new["mu"].to_numpy(float) - old["mu"].to_numpy(float)
            assert np.abs(got - want).max() <= 0.0011, (kind, row["site"], np.abs(got - want).max())
        moved = [not before[s].equals(pd.read_csv(camp / "dft" / f"{s}.csv")) for s in sites["site"]]
        if kind == "categorical_speed":
            assert moved == list(sites["aggregate"] == rc.POLISHED)
        elif kind == "site_column":  # the first station of a section is 0 ft: no effect there
            assert moved == list(sites["station_ft"] != 0) and any(moved)
        else:
            assert all(moved)
    with pytest.raises(ValueError, match="kind"):
        rc.column_effect("texture_speed", {}, [20.0], lambda u: u)


def test_a_design_per_seed_gives_every_campaign_its_own_texture(monkeypatch, chips_texture):
    """``n_designs`` 0 (``benchmarks/diagnosis_rates.py --designs 0``): campaign seed s reads texture design s;
    by default seeds 4 apart share a design (the documented table's 4 designs)."""
    assert [rc.design_of(s) for s in (0, 1, 4, 7, 9)] == [0, 1, 0, 3, 1]
    assert [rc.design_of(s, 0) for s in (0, 1, 4, 7, 9)] == [0, 1, 4, 7, 9]
    assert rc.design_of(9, 5) == 4
    with pytest.raises(ValueError, match="n_designs"):
        rc.design_of(3, -1)
    asked = []

    def fake_texture(generator, design, cache_dir=None, shape=None, table="harness"):
        asked.append((generator, design, table))
        return chips_texture

    monkeypatch.setattr(rc, "generator_texture", fake_texture)
    rc.generate("chips", "none", 6, trace_step_kmh=0)
    rc.generate("spectral+sectionlatent", "none", 6, trace_step_kmh=0, n_designs=0, texture_table="workflow")
    assert asked == [("chips", 2, "harness"), ("spectral", 6, "workflow")]


def test_the_workflow_table_holds_the_harness_columns_with_the_same_values():
    """The workflow table of a generator surface (every areal parameter of the three bands, as the texture_parameters
    rule computes them) against the harness's own computation of its 27 columns (height parameters, Sdq and Sdr by
    their functions, the contact zone): the same values, the same hidden measures, and many more columns."""
    from skidsim.generators import campaign as gc

    cfg = gc.generator_config("spectral", {"seed": 5, "n_sites": 3, "n_sections": 1, "shape": [160, 160]})
    dx = float(cfg["spacing_mm"])
    r = gc.design_campaign(cfg).iloc[0]
    rng = np.random.default_rng(gc._seq(cfg, str(r["site"])).spawn(4)[0])
    sec = {k[4:]: float(r[k]) for k in r.keys() if k.startswith("sec_") and "factor" not in k}
    ones = dict.fromkeys(("protrusion_factor", "macro_factor", "micro_factor"), 1.0)
    clean, _ = gc.TEXTURES[cfg["texture"]].render(rng, (160, 160), dx, sec, ones, cfg["texture_params"])
    cut = cfg["friction"]["micro_cut_mm"]
    harness, hidden = rc.texture_table_of_surface(clean, dx, cut)
    workflow, hidden_w = rc.workflow_table_of_surface(clean, dx, cut)
    assert set(harness) == set(rc.TABLE_COLUMNS) and set(harness) < set(workflow)
    assert len(workflow) > 100
    for k in rc.TABLE_COLUMNS:
        assert workflow[k] == pytest.approx(harness[k], rel=1e-9, abs=1e-12), k
    assert hidden_w == hidden


def test_the_wide_member_reads_the_harness_table_whole():
    """The harness's rates rest on the wide member reading all of the harness's columns: its table is exactly the
    wide member's core set (texture_candidate.wide_member_columns), so a harness rate and a workflow-table rate
    compare one model on two tables. A column added to one list and not the other fails here."""
    from skidsim.criticism import texture_candidate as tc

    core = {f"{b}_{q}" for b in tc.WIDE_CORE_BANDS for q in tc.WIDE_CORE_PARAMETERS} | set(tc.WIDE_CORE_EXTRA)
    assert core == set(rc.TABLE_COLUMNS)  # a core column the harness lacks would have it read whole, silently
    assert tc.wide_member_columns(rc.TABLE_COLUMNS) == list(rc.TABLE_COLUMNS)
    # a workflow column beyond the harness's is left out, so the harness table is the core set, not a superset of it
    assert len(tc.wide_member_columns([*rc.TABLE_COLUMNS, "raw_Vmp"])) == len(rc.TABLE_COLUMNS)


def test_a_friction_model_in_place_of_the_generators_own_keeps_its_draws(chips_texture):
    """``friction_model``: the chips campaign with another friction-speed model of the same draws. Every model
    passes through the same level at 20 km/h (the generator's level law times the same random factors); PIARC and
    Penn State are exponentials in v whose log-slopes, -1 / (Sp f) and -PNG / (100 f) with the same speed-constant
    factor f, stand in the ratio 100 / (Sp(MPD) PNG(MPD)) of the published relations at each site's MPD; Rado's
    curve is not an exponential in v. The default source keeps its own law."""
    from skidsim.errors import ConfigError
    from skidsim.generators import friction_models as fm

    curves = {}
    for model in (None, "piarc", "penn_state", "rado"):
        sites, mu, tex, truth = rc.generate(
            "chips", "none", 3, noise_mu=0.0, trace_step_kmh=0, texture=chips_texture, friction_model=model
        )
        curves[model] = mu.pivot_table(index="site", columns="speed_kmh", values="mu").loc[sites["site"]]
        assert truth["friction_model"] == (model or "")
    v = curves[None].columns.to_numpy(float)
    assert v[0] == 20.0 and v[-1] >= 60.0
    np.testing.assert_array_equal(curves[None].to_numpy(), curves["piarc"].to_numpy())
    for model, apart in (("penn_state", 0.002), ("rado", 0.02)):  # largest difference (PNG follows 1 / Sp)
        np.testing.assert_allclose(curves[model][20.0], curves["piarc"][20.0], rtol=1e-12)
        assert np.abs(curves[model].to_numpy() - curves["piarc"].to_numpy()).max() > apart
    lines = {}  # per model: the least-squares line of log mu in v per site, and its largest residual
    for m in ("piarc", "penn_state", "rado"):
        log_mu = np.log(curves[m].to_numpy().T)
        coef = np.polyfit(v, log_mu, 1)
        lines[m] = (coef[0], np.abs(log_mu - np.polyval(coef, v[:, None])).max())
    mpd = tex["profile_MPD"].to_numpy(float)
    expected = 100.0 / (
        np.array([fm.ifi_speed_constant_kmh(x) for x in mpd]) * np.array([fm.penn_state_png(x) for x in mpd])
    )
    np.testing.assert_allclose(lines["piarc"][0] / lines["penn_state"][0], expected, rtol=1e-9)
    assert lines["piarc"][1] < 1e-9 and lines["penn_state"][1] < 1e-9  # exponentials in v: log mu is a line
    assert lines["rado"][1] > 1e-3
    with pytest.raises(ValueError, match="friction_model"):
        rc.generate("default", "none", 3, friction_model="penn_state")
    with pytest.raises(ConfigError, match="friction model"):
        rc.generate("chips", "none", 3, texture=chips_texture, friction_model="linear")
