"""Which sites.csv columns the model criticism tests as causes, and the ones it does not (with why): a column
measured at a few sites only is not mean-filled into a candidate, and report.md says so."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
from diagnosis_campaigns import make_campaign

from skidsim import criticism as cr
from skidsim.criticism import DiagnosisInputs, DiagnosisOptions
from skidsim.criticism.covariates import MIN_PRESENT_SHARE
from skidsim.criticism.report import report_markdown


def sites_table(n_sections: int = 12, per: int = 3) -> pd.DataFrame:
    n = n_sections * per
    rng = np.random.default_rng(4)
    sec = np.repeat([f"S{k:02d}" for k in range(n_sections)], per)
    region = np.where(np.arange(n) % 5 == 0, None, np.where(np.arange(n) % 2 == 0, "north", "south"))
    return pd.DataFrame(
        {
            "site": [f"{s}-{j}" for s, j in zip(sec, np.tile(np.arange(1, per + 1), n_sections))],
            "section": sec,
            "aadt": rng.uniform(1e3, 2e4, n),
            "skid_temp_c": np.where(np.arange(n) < 10, rng.normal(20, 3, n), np.nan),  # 10 of 36 measured
            "half_measured": np.where(np.arange(n) < n // 2, rng.normal(size=n), np.nan),  # 18 of 36: kept
            "crew": "A",
            "sample_id": [f"ID{k:03d}" for k in range(n)],
            "region": region,  # some missing: the level "NA"
            "scan_path": [f"scans/{k}.x3p" for k in range(n)],
        }
    )


def test_untested_columns_say_why_and_match_the_candidates():
    s = sites_table()
    assert MIN_PRESENT_SHARE == 0.5
    assert cr.untested_columns(s) == {
        "skid_temp_c": "values at 10 of 36 sites (fewer than 50%)",
        "crew": "one value at every site",
        "sample_id": "a different value at every site (an identifier, not a grouping)",
    }
    cov, info = cr.site_covariates(s)
    assert set(cov.columns) == {"section", "aadt", "half_measured", "region"}  # scan_path: a path, excluded
    assert info["half_measured"] == ("sites", "numeric") and info["region"] == ("sites", "categorical")
    assert sorted(cov["region"].unique()) == ["NA", "north", "south"]
    # the half-measured column is mean-filled: its missing sites sit at the mean of the measured ones
    measured = s["half_measured"].dropna()
    assert np.allclose(cov["half_measured"].to_numpy()[len(measured) :], measured.mean())


def test_texture_columns_with_too_few_values_are_not_candidates_either():
    s = sites_table()
    n = len(s)
    tex = pd.DataFrame(
        {
            "site": s["site"],
            "macro_Sq": np.linspace(0.3, 0.9, n),
            "micro_Sq_top": np.where(np.arange(n) % 4 == 0, 0.02, np.nan),  # 9 of 36 scans had tops
            "spacing": 0.05,
            "method": "LS-40",  # text: not a texture parameter at all
        }
    )
    why = cr.untested_columns(s, tex)
    assert why["micro_Sq_top"] == "texture table: values at 9 of 36 sites (fewer than 50%)"
    assert why["spacing"] == "texture table: one value at every site" and "method" not in why
    cov, info = cr.site_covariates(s, tex)
    assert [c for c in cov.columns if info[c][0] == "texture"] == ["macro_Sq"]


def test_a_sparsely_measured_column_is_not_a_cause_and_the_report_lists_it(tmp_path):
    tables, _ = make_campaign(seed=2, effect=None)
    sites = tables["sites"].copy()
    n = len(sites)
    # a sparse 'temperature' column: a name the criticism would take for a physical hypothesis
    sites["pavement_temp_c"] = np.where(np.arange(n) < 6, 15.0 + np.arange(n), np.nan)
    inputs = DiagnosisInputs(sites, tables["measured"], tables["simulated"], tables["predicted"], tables["texture"])
    r = cr.diagnose(inputs, DiagnosisOptions(seed=2, n_boot=20))
    assert r.untested == {"pavement_temp_c": f"values at 6 of {n} sites (fewer than 50%)"}
    assert not any(c.variable == "pavement_temp_c" for c in r.causes)
    cr.write_outputs(tmp_path, r.residuals, r.causes, r.gain, untested=r.untested)
    text = (tmp_path / "report.md").read_text()
    assert "## Columns not tested as causes (sites.csv, texture table)" in text
    assert f"* `pavement_temp_c`: values at 6 of {n} sites (fewer than 50%)" in text
    assert "not tested as causes" not in report_markdown([], {}, None, Path("."))
