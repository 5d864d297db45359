"""A hidden macrotexture-drainage effect through the whole workflow (own file so that pytest-xdist's loadfile runs
it beside the other workflow-diagnosis files).

The truth's drainage is switched to its "squeeze" form (partial hydroplaning: ``x (1 - 0.3 (v^2 - 20^2) / Sp^2)``,
``Sp = 14.2 + 89.7 MPD`` km/h, docs/synthetic-campaign.md), the only effect on. Its loss is concave in speed, which
the study's exponential-decay law cannot absorb, and it is larger on shallow texture: within sites the calibrated
simulation's residual shape grows with 1/Sp. The IFI form of the truth (an exponential in speed) is absorbed by
the per-site calibration and the texture model over 20-70 km/h and is not identifiable through the workflow
(measured in docs/model-criticism-measured.md, section 3); this test therefore hides the form that leaves a trace.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from test_diagnosis_workflow import NO_EFFECTS, named, run_campaign


@pytest.mark.slow
@pytest.mark.campaign
def test_workflow_names_hidden_macrotexture_drainage(tmp_path):
    effects = NO_EFFECTS.replace("drainage: {enabled: false}", "drainage: {enabled: true, form: squeeze, size: 0.3}")
    out = run_campaign(tmp_path, seed=7, effects=effects)
    top = named(out["causes"])
    assert top is not None, [(c["variable"], c["level"], c["kind"], c["p_adjusted"]) for c in out["causes"][:5]]
    # the MPD column of the texture table (the pipeline finds it by name; the test knows only that it is MPD)
    assert "MPD" in top["variable"].upper() and top["level"] == "within-site" and top["kind"] == "x_speed", top
    assert top["direction"] == -1, top  # deeper texture drains better: a weaker shape error
    ff = next(c for c in out["causes"] if c["kind"] == "functional_form" and c["level"] == "within-site")
    assert out["causes"].index(ff) > 0  # the shared shape is the mean of the MPD-dependent one
    gain = out["gain"]
    # the gain on held-out speeds is established by the extension chosen: the physical DrainageIFI, or the generic
    # covariate term when the physical one's interval includes zero and the generic one's lower bound is higher
    # (criticism.gain.evaluate_extension). Measured 2026-11-27 with the default contact (penalty friction, Rayleigh
    # damping; fresh clone of ad07112): DrainageIFI 0.00013 [-0.00013, 0.00034], the generic term 0.00025
    # [0.00010, 0.00043], chosen; with the stick limit of the first releases DrainageIFI 0.00028 [0.00006, 0.00047]
    assert gain["extension"] in ("DrainageIFI", "CovariateTerm") and gain["scope"] == "held_out_speeds", gain
    speeds = gain["scopes"]["held_out_speeds"]
    assert speeds["gain_excludes_zero"] and speeds["rmse_after"] < speeds["rmse_before"], speeds
    drainage = speeds if gain["extension"] == "DrainageIFI" else None
    for alt in gain["alternatives"]:
        if alt["extension"] == "DrainageIFI":
            drainage = alt["scopes"]["held_out_speeds"]
    assert drainage is not None, [gain["extension"]] + [a["extension"] for a in gain["alternatives"]]
    assert drainage["rmse_after"] < drainage["rmse_before"], drainage
    # the physical extension identifies the hidden form: squeeze in a good share of the folds, with kappa near the
    # hidden 0.3 wherever it is chosen; elsewhere the IFI form (kappa about 1.6) fits the training sites about as
    # well. Measured: squeeze in 5 of 12 folds (2026-11-26, commit 1d3ab97, stick limit), in 12 of 12 with kappa
    # 0.33-0.38 (2026-11-27, default contact).
    folds = drainage["extension"]["params_per_fold"]
    squeeze = [p["kappa"] for p in folds if p["form"] == "squeeze"]
    assert len(squeeze) >= len(folds) / 3 and all(0.2 < k < 0.45 for k in squeeze), folds
    # issue 33, item 3: the physical extension recovers its own physics, and says so in gain.json and the report:
    # fitted on every site, the hidden form with an interval over the sections that holds the hidden kappa 0.3.
    # Measured 2026-12-01 (commit ebf3e0c): squeeze, kappa 0.363 [0.273, 0.453], 12 of 12 folds, perm p 0.02.
    ident = gain["identifiability"]
    assert ident["extension"] == "DrainageIFI" and ident["identifiable"] is True, ident
    assert ident["form_all_sites"] == "squeeze" and ident["perm_p"] <= 0.05, ident
    lo, hi = ident["kappa_interval_95"]
    assert lo <= 0.3 <= hi and hi - lo < 0.3, ident
    report = (tmp_path / "results" / "diagnosis" / "report.md").read_text()
    assert "Drainage factor kappa of DrainageIFI: identified" in report, report[:2000]
