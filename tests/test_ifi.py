"""The International Friction Index (ASTM E1960) and the PIARC/IFI speed model: formulas against hand-computed
values, the per-site table, the comparison with FE-calibrated laws, and the workflow rules on a tiny results set."""

from __future__ import annotations

import json
import os
import runpy
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from conftest import run_snakemake

from skidsim import ifi

ROOT = Path(__file__).resolve().parents[1]


def test_formulas_by_hand():
    # MPD 1.0 mm, DFT20 0.5: Sp = 14.2 + 89.7 = 103.9 km/h; 40 / 103.9 = 0.384986; exp(-0.384986) = 0.680462;
    # FR60 = 0.340231; F60 = 0.081 + 0.732 x 0.340231 = 0.330049
    r = ifi.ifi(1.0, 0.5)
    assert r["sp_kmh"] == pytest.approx(103.9, abs=1e-12)
    assert r["fr60"] == pytest.approx(0.340231, abs=1e-6)
    assert r["f60"] == pytest.approx(0.330049, abs=1e-6)
    # MPD 0.5 mm, DFT20 0.8: Sp = 59.05 km/h; exp(-40 / 59.05) = exp(-0.677392) = 0.5 exp(0.015755) = 0.507940;
    # FR60 = 0.406352; F60 = 0.081 + 0.297450 = 0.378450
    r = ifi.ifi(0.5, 0.8)
    assert (r["sp_kmh"], r["fr60"], r["f60"]) == pytest.approx((59.05, 0.406352, 0.378450), abs=2e-6)
    # the speed model passes through DFT20 at 20 km/h and through FR60 at 60 km/h
    assert ifi.piarc_mu(20.0, 0.5, 103.9) == pytest.approx(0.5)
    assert ifi.piarc_mu([60.0], 0.5, 103.9)[0] == pytest.approx(0.340231, abs=1e-6)
    assert np.isnan(ifi.ifi(float("nan"), 0.5)["f60"])


def test_dft20_from_traces_and_table():
    v = np.arange(10.0, 81.0, 1.0)
    traces = pd.concat(
        [
            pd.DataFrame({"site": "B", "speed_kmh": v, "mu": 0.7 - 0.004 * v}),  # straight: exact
            pd.DataFrame({"site": "A", "speed_kmh": v, "mu": 0.6 - 0.002 * v + 1e-5 * v**2}),
        ]
    )
    d = ifi.dft20_of_traces(traces, window_kmh=5.0)
    assert d["B"] == pytest.approx(0.62, abs=1e-12)
    # local linear fit of a parabola within +-5 km/h: bias curvature x w^2 / 6 ... here 1e-5 x (sum of squares mean)
    assert d["A"] == pytest.approx(0.6 - 0.04 + 1e-5 * (400 + 10.0), abs=1e-9)  # 1e-5 x (20^2 + mean(dv^2) = 10)
    assert ifi.dft20_of_traces(traces, None)["A"] == pytest.approx(0.6 - 0.04 + 1e-5 * 400, abs=1e-12)
    table = ifi.ifi_table({"B": 1.0, "A": float("nan")}, d)
    assert list(table.columns) == ["site", "mpd_mm", "dft20", "sp_kmh", "fr60", "f60"]
    assert list(table["site"]) == ["A", "B"] and np.isnan(table["f60"].iloc[0])
    assert table["sp_kmh"].iloc[1] == pytest.approx(103.9)
    with pytest.raises(Exception, match="same sites"):
        ifi.ifi_table({"A": 1.0}, {"B": 0.5})


def validation_table():
    """Two sites, FE method 'ours' at calibration and validation speeds, measured mu following the PIARC model
    exactly at S1 and off by +0.02 at S2; the FE law is off by -0.01 everywhere."""
    rows = []
    params = {"S1": (0.6, 1.0), "S2": (0.5, 0.6)}  # DFT20, MPD
    for site, (d20, mpd) in params.items():
        sp = 14.2 + 89.7 * mpd
        for v, kind in [
            (20, "calibration"),
            (30, "validation"),
            (40, "calibration"),
            (50, "validation"),
            (60, "calibration"),
            (70, "validation"),
        ]:
            meas = d20 * np.exp((20 - v) / sp) + (0.02 if site == "S2" else 0.0)
            rows.append(
                {
                    "site": site,
                    "method": "ours",
                    "speed_kmh": float(v),
                    "kind": kind,
                    "sn_sim": meas - 0.01,
                    "mu_measured": meas,
                    "err": -0.01,
                    "rel_err": -0.01 / meas,
                    "n_steps": 10,
                    "wall_s": 1.0,
                }
            )
    return pd.DataFrame(rows), params


def test_model_rows_and_side_by_side_statistics():
    vt, params = validation_table()
    table = ifi.ifi_table({s: p[1] for s, p in params.items()}, {s: p[0] for s, p in params.items()})
    rows = ifi.model_validation_rows(table, vt)
    assert len(rows) == 12 and set(rows["method"]) == {"piarc_ifi"}
    s1 = rows[rows["site"] == "S1"]
    np.testing.assert_allclose(s1["err"], 0.0, atol=1e-15)  # S1 follows the model
    np.testing.assert_allclose(rows[rows["site"] == "S2"]["err"], -0.02, atol=1e-15)
    both = pd.concat([vt[rows.columns], rows], ignore_index=True)
    stats = ifi.comparison_statistics(both, [30, 50, 70])
    assert list(stats["speed_kmh"]) == ["all", "30", "50", "70"]
    assert list(stats.columns) == [
        "speed_kmh",
        "n",
        "ours_rmse",
        "ours_r2",
        "piarc_ifi_rmse",
        "piarc_ifi_r2",
        "best_model",
    ]
    # FE: error -0.01 at all 6 validation points; IFI: 0 at 3, -0.02 at 3 -> RMSE sqrt(0.0002) = 0.014142
    assert stats["ours_rmse"].iloc[0] == pytest.approx(0.01)
    assert stats["piarc_ifi_rmse"].iloc[0] == pytest.approx(np.sqrt(0.5 * 0.02**2))
    assert stats["n"].iloc[0] == 6 and list(stats["best_model"]) == ["ours"] * 4
    assert ifi.wins(stats) == []
    # make the FE law worse at 70 km/h only: the one-line model wins there, and it is said
    worse = both.copy()
    worse.loc[(worse["method"] == "ours") & (worse["speed_kmh"] == 70), "sn_sim"] -= 0.05
    stats2 = ifi.comparison_statistics(worse, [30, 50, 70])
    assert stats2.set_index("speed_kmh").loc["70", "best_model"] == "piarc_ifi"
    assert any(w.startswith("PIARC/IFI model beats ours at 70 km/h") for w in ifi.wins(stats2))
    with pytest.raises(Exception, match="an IFI row for every site"):
        ifi.model_validation_rows(table[table["site"] == "S1"], vt)


def _run_script(name: str, **ns):
    runpy.run_path(str(ROOT / "workflow" / "scripts" / name), init_globals={"snakemake": SimpleNamespace(**ns)})


def test_rule_scripts_on_a_tiny_results_set(tmp_path):
    vt, params = validation_table()
    res = tmp_path / "results"
    mpd_paths = []
    for site, (_, mpd) in params.items():
        p = res / "sites" / site / "mpd.json"
        p.parent.mkdir(parents=True)
        p.write_text(json.dumps({"site": site, "mpd_mm": mpd, "sd_mm": 0.1}))
        mpd_paths.append(str(p))
    p = res / "sites" / "S3" / "mpd.json"  # a short scan: MPD null
    p.parent.mkdir(parents=True)
    p.write_text(json.dumps({"site": "S3", "mpd_mm": None}))
    mpd_paths.append(str(p))
    v = np.arange(10.0, 81.0, 2.0)
    traces = pd.concat(
        [
            pd.DataFrame({"site": s, "speed_kmh": v, "mu": d20 - 0.003 * (v - 20)})
            for s, (d20, _) in {**params, "S3": (0.45, None)}.items()
        ]
    )
    (res / "ingest").mkdir()
    traces.to_parquet(res / "ingest" / "dft_traces.parquet")
    out = res / "ifi" / "ifi.csv"
    _run_script(
        "ifi.py",
        input=SimpleNamespace(mpd=mpd_paths, traces=str(res / "ingest" / "dft_traces.parquet")),
        output=SimpleNamespace(ifi=str(out)),
        params=SimpleNamespace(smooth_window_kmh=5.0),
        log=[str(tmp_path / "logs" / "ifi.log")],
    )
    table = pd.read_csv(out)
    assert list(table["site"]) == ["S1", "S2", "S3"]
    np.testing.assert_allclose(table["dft20"], [0.6, 0.5, 0.45], atol=1e-12)  # straight traces: exact at 20 km/h
    np.testing.assert_allclose(
        table["f60"][:2],
        [0.081 + 0.732 * 0.6 * np.exp(-40 / 103.9), 0.081 + 0.732 * 0.5 * np.exp(-40 / (14.2 + 89.7 * 0.6))],
    )
    assert np.isnan(table["f60"][2])
    assert "IFI not available for 1 site(s) without an MPD: S3" in (tmp_path / "logs" / "ifi.log").read_text()
    # the comparison rule on the IFI of S1, S2 and the validation table
    (res / "calibration").mkdir()
    vt.to_parquet(res / "calibration" / "validation.parquet")
    pd.read_csv(out).iloc[:2].to_csv(out, index=False)
    outs = SimpleNamespace(
        table=str(res / "ifi" / "validation.csv"),
        rows=str(res / "ifi" / "rows.parquet"),
        figure=str(res / "ifi" / "ifi_vs_fe.png"),
    )
    _run_script(
        "ifi_validation.py",
        input=SimpleNamespace(ifi=str(out), validation=str(res / "calibration" / "validation.parquet")),
        output=outs,
        params=SimpleNamespace(validation_speeds=[30, 50, 70]),
        log=[str(tmp_path / "logs" / "ifi_validation.log")],
    )
    stats = pd.read_csv(outs.table)
    assert stats["ours_rmse"].iloc[0] == pytest.approx(0.01)
    assert stats["piarc_ifi_rmse"].iloc[0] == pytest.approx(np.sqrt(0.5 * 0.02**2))
    assert Path(outs.figure).stat().st_size > 10_000
    assert "higher RMSE than every FE-calibrated method" in (tmp_path / "logs" / "ifi_validation.log").read_text()


def test_ifi_rules_are_default_targets(tmp_path):
    """A dry run of the default target on a 3-site campaign schedules ifi and ifi_validation once each."""
    camp = tmp_path / "camp"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    subprocess.run(
        [sys.executable, "-m", "skidsim.cli", "synth", str(camp), "--sites", "3", "--shape", "40", "60"],
        check=True,
        capture_output=True,
        env=env,
    )
    r = run_snakemake("-n", "--config", f"campaign={camp}", workdir=tmp_path, env=env)
    text = r.stdout + r.stderr
    counts = {
        ln.split()[0]: ln.split()[1] for ln in text.splitlines() if len(ln.split()) == 2 and ln.split()[1].isdigit()
    }
    assert counts.get("ifi") == "1" and counts.get("ifi_validation") == "1", counts


def test_calibration_summary_puts_the_ifi_model_beside_fe_methods(tmp_path):
    """calibration_summary.py with an `ifi` input adds method piarc_ifi to fit_statistics.csv (same statistics as
    comparison_statistics) and leaves the FE rows and validation.parquet as without it."""
    from skidsim.calibration import FEOutcome, calibrate_fast, simulate_speeds, validation_table
    from skidsim.friction import ExponentialDecay

    def fe(speed_kmh, law):  # a surrogate FE model: SN = 1.05 mu(v)
        return FEOutcome(sn=1.05 * float(law.mu_kmh(speed_kmh)), n_steps=100, wall_s=1e-4)

    v = np.arange(5.0, 85.0, 1.0)
    results, runs, meas, traces = {}, {}, {}, []
    for i, site in enumerate(["A", "B", "C"]):
        law = ExponentialDecay(0.6 + 0.05 * i, 0.3, 0.08 + 0.02 * i)
        mu = np.array([1.05 * float(law.mu_kmh(s)) for s in v]) * (1 - 0.001 * (v - 20) * i)
        meas[site] = pd.DataFrame({"speed_kmh": v, "mu": mu})
        traces.append(meas[site].assign(site=site))
        results[site] = {"ours": calibrate_fast(fe, meas[site])}
        runs[site] = {"ours": simulate_speeds(fe, results[site]["ours"].params, (20, 30, 40, 50, 60, 70))}
    vt = validation_table(runs, meas)
    cal, val = [], []
    for site in results:
        p = tmp_path / "sites" / site / "calibration_ours.json"
        results[site]["ours"].to_json(p)
        cal.append(str(p))
        q = tmp_path / "sites" / site / "validation.parquet"
        vt[vt["site"] == site].to_parquet(q)
        val.append(str(q))
    pd.concat(traces).to_parquet(tmp_path / "traces.parquet")
    table = ifi.ifi_table({"A": 0.6, "B": 0.9, "C": 1.2}, ifi.dft20_of_traces(pd.concat(traces), 5.0))
    table.to_csv(tmp_path / "ifi.csv", index=False)
    stats = {}
    for label, extra in (("plain", {}), ("ifi", {"ifi": str(tmp_path / "ifi.csv")})):
        out = {
            k: str(tmp_path / label / f"{k}.{e}")
            for k, e in [
                ("table2", "csv"),
                ("comparison", "csv"),
                ("stats", "csv"),
                ("validation", "parquet"),
                ("params", "parquet"),
                ("figure10", "png"),
                ("curves", "png"),
            ]
        }
        _run_script(
            "calibration_summary.py",
            input=SimpleNamespace(
                ingest="", calibrations=cal, validations=val, traces=str(tmp_path / "traces.parquet"), **extra
            ),
            output=SimpleNamespace(**out),
            params=SimpleNamespace(methods=["ours"]),
            log=[str(tmp_path / label / "log.txt")],
        )
        stats[label] = pd.read_csv(out["stats"])
    plain, with_ifi = stats["plain"], stats["ifi"]
    assert list(plain["method"]) == ["ours", "ours"]
    assert list(with_ifi["method"]) == ["ours", "ours", "piarc_ifi", "piarc_ifi"]
    pd.testing.assert_frame_equal(with_ifi.iloc[:2], plain)
    pd.testing.assert_frame_equal(
        pd.read_parquet(tmp_path / "ifi" / "validation.parquet"),
        pd.read_parquet(tmp_path / "plain" / "validation.parquet"),
    )
    model = ifi.model_validation_rows(table, vt)
    side = ifi.comparison_statistics(pd.concat([vt[model.columns], model]), [30, 50, 70])
    row = with_ifi[(with_ifi["method"] == "piarc_ifi") & (with_ifi["kind"] == "validation")].iloc[0]
    assert row["rmse"] == pytest.approx(side["piarc_ifi_rmse"].iloc[0]) and row["n"] == 9
    assert row["r2"] == pytest.approx(side["piarc_ifi_r2"].iloc[0])
