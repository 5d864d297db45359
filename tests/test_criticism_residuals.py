"""Tests of skidsim.criticism.residuals: the residual table at both levels, its errors, and the texture model's
shape (sim - pred)."""

from __future__ import annotations

import pandas as pd
import pytest

from skidsim import criticism as cr
from skidsim.criticism.residuals import texture_model_shape
from skidsim.errors import InputError


def _tiny():
    sites = pd.DataFrame({"site": ["a", "b"], "section": ["S1", "S1"], "temperature_c": [10.0, 20.0]})
    measured = pd.DataFrame(
        {
            "site": ["a", "a", "a", "b", "b"],
            "speed_kmh": [20.0, 25.0, 95.0, 20.0, 40.0],
            "mu": [0.60, 0.55, 0.30, 0.50, 0.45],
            "kind": ["calibration", "trace", "trace", "calibration", "validation"],
        }
    )
    simulated = pd.DataFrame(
        {"site": ["a", "a", "b", "b"], "speed_kmh": [20.0, 40.0, 20.0, 40.0], "sn": [0.58, 0.48, 0.50, 0.40]}
    )
    predicted = pd.DataFrame({"site": ["b", "b"], "speed_kmh": [20.0, 60.0], "sn_pred": [0.52, 0.40]})
    return sites, measured, simulated, predicted


def test_build_residuals_interpolates_and_drops_out_of_range():
    sites, measured, simulated, predicted = _tiny()
    r = cr.build_residuals(sites, measured, simulated, predicted)
    w = r[r["level"] == "within-site"].set_index(["site", "speed_kmh"])
    assert len(w) == 4  # a@95 km/h lies outside the simulated 20-40 km/h: dropped, not extrapolated
    assert w.loc[("a", 25.0), "model"] == pytest.approx(0.58 - 0.10 * 5 / 20)
    assert w.loc[("a", 25.0), "residual"] == pytest.approx(0.55 - 0.555)
    assert w.loc[("b", 40.0), "residual"] == pytest.approx(0.05)
    b = r[r["level"] == "between-site"].set_index(["site", "speed_kmh"])
    assert set(b.index.get_level_values("site")) == {"b"}
    assert b.loc[("b", 40.0), "model"] == pytest.approx(0.46)
    assert (r["section"] == "S1").all()


def test_texture_model_shape_is_sim_minus_pred():
    """The between-site functional form's profile: between residual - within residual = sn_sim - sn_pred."""
    sites, measured, simulated, predicted = _tiny()
    r = cr.build_residuals(sites, measured, simulated, predicted)
    d = texture_model_shape(r, 10.0)
    assert list(d.index) == ["b"] and list(d.columns) == [20.0, 40.0]
    assert d.loc["b", 20.0] == pytest.approx(0.50 - 0.52)
    assert d.loc["b", 40.0] == pytest.approx(0.40 - 0.46)
    # a between-site point without a within-site residual: None (the test falls back to the between residual)
    drop = (r["level"] == "within-site") & (r["site"] == "b") & (r["speed_kmh"] == 40.0)
    assert texture_model_shape(r[~drop], 10.0) is None


@pytest.mark.parametrize(
    "mutate, column",
    [
        (lambda m: m.assign(kind=["calibration", "bogus", "trace", "calibration", "validation"]), "kind"),
        (lambda m: m.drop(columns="mu"), "mu"),
        (lambda m: m.assign(speed_kmh=["20", "x", "95", "20", "40"]), "speed_kmh"),
    ],
)
def test_build_residuals_bad_input_names_the_field(mutate, column):
    sites, measured, simulated, predicted = _tiny()
    with pytest.raises(InputError) as e:
        cr.build_residuals(sites, mutate(measured), simulated, predicted)
    assert e.value.column == column
    assert "measured table" in str(e.value)


def test_build_residuals_unknown_site():
    sites, measured, simulated, predicted = _tiny()
    with pytest.raises(InputError, match="sites listed in the sites table"):
        cr.build_residuals(sites.iloc[:1], measured, simulated, predicted)
