"""The rates figure of issue 33 (``skidsim.plotting.diagnosis.plot_naming_rates``) and the merge of rates tables
(``benchmarks/diagnosis_rates.py``): what each cell counts, on hand-made tables read back as from CSV."""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from skidsim.plotting.diagnosis import naming_rate_cells, plot_naming_rates, wilson_interval

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

# one row per campaign, as benchmarks/diagnosis_rates.py writes rates.csv (empty: not scored)
CSV = """generator,kind,seed,named,named_top,false_category,gain_established
chips,none,0,profile_MPD (between-site x_speed),,False,
chips,none,1,temperature_c (between-site main),,True,
chips,none,2,,,False,
chips,texture_speed,0,macro_Sdq (between-site main),True,,True
chips,texture_speed,1,raw_Sdq (between-site main),False,,False
chips,texture_speed,2,texture_model[curved] (between-site x_speed),True,,
chips,texture_speed,3,macro_Sdr (between-site main),True,,True
chips,texture_speed,4,texture PCs 1-3 (between-site x_speed),True,,True
chips+sectionlatent,none,0,section (between-site main),True,,
chips+sectionlatent,none,1,binder (between-site main),False,,
"""


def rates() -> pd.DataFrame:
    return pd.read_csv(io.StringIO(CSV))


def test_each_cell_counts_the_right_answers_of_its_kind():
    cells = naming_rate_cells(rates()).set_index(["generator", "kind"])
    null = cells.loc[("chips", "none")]  # right: no cause other than the texture model (false_category False)
    assert (null["n"], null["right"], null["goal"], bool(null["met"])) == (3, 2, 0.95, False)
    eff = cells.loc[("chips", "texture_speed")]  # 4 of 5 named top: the 80 % goal met exactly
    assert (eff["n"], eff["right"], bool(eff["met"])) == (5, 4, True)
    assert eff["share"] == pytest.approx(0.8)
    assert (eff["gain_n"], eff["gain_right"]) == (4, 3)  # the campaign without a measured gain is not counted
    latent = cells.loc[("chips+sectionlatent", "none")]  # its hidden effect is the section factors: named_top
    assert (latent["n"], latent["right"], latent["gain_n"]) == (2, 1, 0)


@pytest.mark.parametrize("k,n", [(15, 20), (20, 20), (0, 20), (1, 3), (13, 20)])
def test_the_wilson_interval_matches_statsmodels(k, n):
    from statsmodels.stats.proportion import proportion_confint

    lo, hi = proportion_confint(k, n, alpha=0.05, method="wilson")
    assert wilson_interval(k, n) == pytest.approx((lo, hi), abs=1e-9)


def test_twenty_campaigns_cannot_tell_75_from_80_percent():
    cells = naming_rate_cells(rates()).set_index(["generator", "kind"])
    eff = cells.loc[("chips", "texture_speed")]  # 4 / 5: Wilson [0.376, 0.964]
    assert (eff["share_low"], eff["share_high"]) == pytest.approx((0.3755, 0.9638), abs=1e-4)
    assert not eff["goal_excluded"]
    low, high = wilson_interval(15, 20)
    assert (round(low, 2), round(high, 2)) == (0.53, 0.89) and high > 0.8  # 15 / 20 does not show a miss of 80 %
    assert wilson_interval(8, 20)[1] < 0.8  # 8 / 20 does


def test_the_figure_is_written_with_and_without_gains(tmp_path):
    r = rates()
    assert plot_naming_rates(r, tmp_path / "rates.png").stat().st_size > 0
    screen_only = r.assign(gain_established=np.nan)
    assert plot_naming_rates(screen_only, tmp_path / "screen.png").stat().st_size > 0


def test_merge_takes_the_named_causes_once_and_the_gains_where_measured():
    from diagnosis_rates import merge_rates

    screen = rates().assign(gain_established=np.nan)
    whole = rates()[rates()["kind"] == "texture_speed"]
    merged = merge_rates([screen, whole])
    assert len(merged) == len(screen)
    cells = naming_rate_cells(merged).set_index(["generator", "kind"])
    assert (cells.loc[("chips", "texture_speed"), "gain_right"], cells.loc[("chips", "none"), "gain_n"]) == (3, 0)
    other = whole.assign(named="aadt (between-site main)")
    with pytest.raises(SystemExit, match="named causes differ in 5 campaigns"):
        merge_rates([screen, other])


def test_drainage_is_named_by_mpd_at_either_level_or_by_the_texture_models_form_in_mpd():
    from types import SimpleNamespace

    from diagnosis_rates import hit

    def cause(variable, source="texture", group=()):
        return SimpleNamespace(variable=variable, source=source, group=group, label="")

    truth = {"kind": "drainage", "variable": "profile_MPD", "source": "chips"}
    assert hit(cause("profile_MPD"), truth)  # within sites x speed or between sites: the column itself
    assert hit(cause("macro_Sq", group=("macro_Sq", "profile_MPD")), truth)  # a cluster holding it
    curved = "texture_model[curved in log(profile_MPD) and log(micro_Sq)]"
    assert hit(cause(curved, source="texture_model"), truth)
    assert not hit(cause("texture_model[nonlinear in log(micro_Sq)]", source="texture_model"), truth)
    assert not hit(cause("functional_form", source="model"), truth) and not hit(None, truth)
    # the texture x speed kind counts every texture-model member; drainage only those in MPD
    assert hit(
        cause("texture_model[nonlinear in log(micro_Sq)]", source="texture_model"),
        {**truth, "kind": "texture_speed", "variable": "macro_Sdq"},
    )
