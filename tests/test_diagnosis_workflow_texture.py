"""Texture effects through the whole workflow (issue 33, item 4): a texture x speed effect and friction driven by a
texture measure the texture table does not hold, each hidden in an independent generator's campaign
(:mod:`skidsim.generators`) and run with the real FE, calibration, texture and regression to the diagnosis.

* texture x speed (``spectral``, ``hidden_effect: hysteresis``, kappa 0.8): the rubber's hysteresis on the
  macrotexture grows with speed and with the macro rms slope Sdq, ``x max(0.05, 1 + 0.8 (Sdq - 0.5) (v - 20) / 50)``
  (:func:`skidsim.generators.friction_models.hidden_factor`; on this campaign about +-10 % of mu at 70 km/h
  across sites);
* texture measure (``chips``, ``hidden_effect: contact_micro``, kappa 2.0): the low-speed level is set by the
  microtexture on the chip tops the slider touches (the micro band's rms within 0.5 mm of the highest tops,
  rescaled by 2.0 to the whole-scan micro Sq's mean), not by the whole-scan micro Sq the table holds and the
  texture model uses (site means move by sd about 0.05 mu).

sites.csv carries decoy columns with no effect (:func:`diagnosis_rate_campaigns.site_design`: aadt,
cum_traffic_msa, year_laid, mix, binder, region, aggregate at section level; station_ft, test_order, operator at
site level); the generator's own temperature_c is kept. The test asserts that the top named cause is the texture
(the texture model, or for texture x speed a texture parameter x speed) and not section identity or a decoy.

Cost: 36 sites (12 sections), 300 x 600 scans at 0.2 mm, ``config/quick.yaml`` (the settings of the independent
generators' runs of docs/model-criticism.md, section 9): both campaigns side by side (``-n 2``) in 8 min 19 s on a
quiet 2-core machine, 2026-11-29 (the texture x speed campaign alone took 26 min 39 s on the slower machine of
2026-11-28, shared with other work; alone, beside other work, 8 min 55 s on 2026-11-29). Measured results and
rates: docs/model-criticism.md, "Rates by effect kind".
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd
import pytest
from conftest import ROOT, run_snakemake, snakemake_env

sys.path.insert(0, str(Path(__file__).parent))
from diagnosis_rate_campaigns import hide_column_effect, site_design

from skidsim.atomic import write_text

CONFIG = """
mesh_study:
  sizes_mm: []
"""
DECOYS = (
    "station_ft",
    "test_order",
    "operator",
    "aadt",
    "cum_traffic_msa",
    "year_laid",
    "mix",
    "binder",
    "region",
    "aggregate",
)


def run_texture_campaign(
    workdir: Path,
    generator: str,
    effect: str | None,
    kappa: float,
    seed: int = 7,
    column_kind: str | None = None,
    section_factors: bool = True,
) -> dict:
    """Write the campaign (36 sites, the hidden effect, decoy columns), run the workflow to the diagnosis, return
    causes.json and gain.json. ``column_kind`` (one of :data:`diagnosis_rate_campaigns.COLUMN_KINDS`, with
    ``effect`` None): instead of a texture effect, the rate campaigns' effect of a sites.csv column is hidden in the
    DFT traces (:func:`diagnosis_rate_campaigns.hide_column_effect`), the generator's random section factors are
    off (one hidden effect per campaign), and for ``temperature`` the rate campaigns' temperature_c (18-22 deg C per
    section) replaces the generator's. ``section_factors`` False turns the generator's random section factors off
    without a column effect: friction then depends on the texture alone (and the random site factors)."""
    from skidsim.generators import write_campaign

    camp = workdir / "campaign"
    over = {
        "n_sites": 36,
        "shape": [300, 600],
        "spacing_mm": 0.2,
        "seed": seed,
        "friction": {"hidden_effect": effect, "hidden_kappa": kappa},
    }
    if column_kind is not None or not section_factors:
        over["friction"].update(section_level_sd=0.0, section_sp_sd=0.0)
    write_campaign(camp, generator, over, truth_dir=workdir / "truth")
    sites = pd.read_csv(camp / "sites.csv")
    cols = list(DECOYS) + (["temperature_c"] if column_kind == "temperature" else [])
    decoys = site_design(seed, sites["site"], sites["section"])[cols]
    pd.concat([sites.drop(columns=[c for c in cols if c in sites.columns]), decoys], axis=1).to_csv(
        camp / "sites.csv", index=False
    )
    if column_kind is not None:
        hide_column_effect(camp, workdir / "truth", column_kind)
    cfg = workdir / "test.yaml"
    write_text(cfg, CONFIG)
    try:
        run_snakemake(
            "--config",
            f"campaign={camp}",
            "--",
            "results/diagnosis/causes.json",
            "results/diagnosis/gain.json",
            workdir=workdir,
            configfiles=(ROOT / "config" / "quick.yaml", cfg),
            cores=2,
            env=snakemake_env(OMP_NUM_THREADS="1"),
            timeout=3600,
        )
    except AssertionError as failed:
        # a failed run is a failure even under the tests' xfail(raises=AssertionError), which only a wrong name
        # may meet
        raise RuntimeError(f"the workflow failed on the {generator} campaign ({effect})") from failed
    diag = workdir / "results" / "diagnosis"
    return {
        "causes": json.loads((diag / "causes.json").read_text()),
        "gain": json.loads((diag / "gain.json").read_text()),
    }


def _top(causes: list[dict]) -> dict | None:
    return causes[0] if causes and causes[0]["significant"] else None


def _is_texture_model(c: dict) -> bool:
    return c.get("source") == "texture_model" or str(c["variable"]).startswith("texture_model[")


def _summary(causes: list[dict]) -> list:
    return [(c["variable"], c["level"], c["kind"], c.get("label"), c["p_adjusted"]) for c in causes[:6]]


def _not_unrelated(top: dict) -> None:
    assert top["variable"] != "section" and top["variable"] not in DECOYS + ("temperature_c",), top
    assert not top.get("section_level"), top


@pytest.mark.slow
@pytest.mark.campaign
def test_workflow_names_hidden_texture_x_speed(tmp_path):
    out = run_texture_campaign(tmp_path, "spectral", "hysteresis", 0.8)
    top = _top(out["causes"])
    assert top is not None, _summary(out["causes"])
    _not_unrelated(top)
    # the texture model, or a texture parameter x speed (the macro slope's cluster; Sdq and MPD correlate here)
    assert _is_texture_model(top) or (top.get("source") == "texture" and top["kind"] == "x_speed"), _summary(
        out["causes"]
    )


@pytest.mark.slow
@pytest.mark.campaign
@pytest.mark.xfail(
    strict=True,
    raises=AssertionError,
    reason="issue 33 item 4 open. Through the workflow (2026-11-29, commit 4c33994): named 'section (unexplained)' "
    "(between sites, main and x speed, p_adjusted 0.0062 each), then the within-site functional form (0.013); "
    "macro_Sdq x speed p 0.048, p_adjusted 1. At the residual level "
    "(benchmarks/diagnosis_rates.py, 20 seeds of chips campaigns with this effect) the texture model is named in "
    "0 / 20: [1, log micro_Sq, log MPD] explains 82-90 % of the log contact microtexture. With commit 461cc35 "
    "(2026-11-29; texture columns tested beyond the prediction terms, here ols2@dft's macro_Spk and micro_Ssk) the "
    "same names and p-values; at the residual level with physics2's terms 11 / 20. Why (2026-11-29, the stored run of "
    "461cc35): the regression chose ols2@dft on macro_Spk and micro_Ssk, which carry R^2 0.906 of the log contact "
    "microtexture over the 36 sites, so the held-out predictions already follow the hidden measure; what is left "
    "correlates 0.23 with it (even the true measure would not be significant), while the generator's random section "
    "factors (sd 0.056 in log level) are a real section effect that nothing carries. With the contact-zone "
    "microtexture in the texture table (micro_Sq_top, micro_Sdq_top; 2026-11-30, working tree on top of a575612) the "
    "same name: micro_Sq_top correlates 0.83 with the log contact microtexture over the 36 sites, micro_Ssk -0.84, and "
    "ols2@dft again chose micro_Ssk with a macro column; micro_Sq_top between sites p 0.93 (main) and 0.23 (x speed). "
    "Remove the mark when it passes.",
)
def test_workflow_names_the_texture_model_for_an_unheld_texture_measure(tmp_path):
    out = run_texture_campaign(tmp_path, "chips", "contact_micro", 2.0)
    top = _top(out["causes"])
    assert top is not None, _summary(out["causes"])
    _not_unrelated(top)
    assert _is_texture_model(top) and top["level"] == "between-site", _summary(out["causes"])
