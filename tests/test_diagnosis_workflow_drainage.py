"""A hidden macrotexture-drainage effect through the whole workflow (own file so that pytest-xdist's loadfile runs
it beside the other workflow-diagnosis files).

The truth's drainage is switched to its "squeeze" form (partial hydroplaning: ``x (1 - 0.3 (v^2 - 20^2) / Sp^2)``,
``Sp = 14.2 + 89.7 MPD`` km/h, docs/synthetic-campaign.md), the only effect on. Its loss is concave in speed, which
the study's exponential-decay law cannot absorb, and it is larger on shallow texture: within sites the calibrated
simulation's residual shape grows with 1/Sp. The IFI form of the truth (an exponential in speed) is absorbed by
the per-site calibration and the texture model over 20-70 km/h and is not identifiable through the workflow
(measured in docs/model-criticism.md, section 9); this test therefore hides the form that leaves a trace.
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
    assert gain["extension"] == "DrainageIFI" and gain["scope"] == "held_out_speeds", gain["extension"]
    speeds = gain["scopes"]["held_out_speeds"]
    assert speeds["gain_excludes_zero"] and speeds["rmse_after"] < speeds["rmse_before"], speeds
    # the squeeze form is chosen on the training data in a good share of the folds, with kappa near the hidden 0.3
    # wherever it is chosen; elsewhere the IFI form (kappa about 1.6) fits the training sites about as well (one
    # fold: training SSE 0.330 against 0.337 for squeeze). Measured 2026-11-26 (commit 1d3ab97, `local`
    # despeckle): squeeze in 5 of 12 folds. The form is a per-fold choice; the gain above is the extension's test.
    folds = speeds["extension"]["params_per_fold"]
    squeeze = [p["kappa"] for p in folds if p["form"] == "squeeze"]
    assert len(squeeze) >= len(folds) / 3 and all(0.2 < k < 0.45 for k in squeeze), folds
