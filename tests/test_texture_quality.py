"""Scan quality: the measures on scans with known answers, the limits (warn / stop), the workflow's table."""

from __future__ import annotations

import json
import logging
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import ROOT, run_snakemake, snakemake_env

from skidsim.errors import ConfigError
from skidsim.surface import Surface
from skidsim.texture import despeckle_detail
from skidsim.texture.quality import (
    QualityOptions,
    ScanQualityError,
    check_quality,
    plane_slopes,
    quality_table,
    relief_breach,
    relief_mm,
    scan_quality,
    usable_length_mm,
)

DX = 0.05


def tilted_scan(sx=0.02, sy=-0.01, shape=(80, 400), seed=0):
    """Plane of slopes sx (x), sy (y) in mm/mm plus 0.2 mm of texture, quantised to 0.01 mm."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]] * DX
    h = sx * x + sy * y + 0.2 * rng.standard_normal(shape)
    return np.round(h / 0.01) * 0.01


def test_plane_slopes_and_tilt_recover_the_plane():
    h = tilted_scan()
    h[10:20, 30:60] = np.nan  # dropouts do not bias the fit
    sx, sy = plane_slopes(Surface(h, DX, DX))
    assert sx == pytest.approx(0.02, abs=5e-4) and sy == pytest.approx(-0.01, abs=5e-4)
    q = scan_quality("A", Surface(h, DX, DX), np.zeros(h.shape, bool), 0.01, "data")
    assert q.tilt_deg == pytest.approx(np.degrees(np.arctan(np.hypot(sx, sy))))
    assert q.tilt_x_mm_per_m == pytest.approx(1000 * sx) and q.tilt_y_mm_per_m == pytest.approx(1000 * sy)


def test_usable_length_is_the_longest_run_of_valid_enough_columns():
    h = np.zeros((20, 1000))
    h[:, 300] = np.nan  # a fully invalid column
    h[:3, 700:705] = np.nan  # 15 % invalid in these columns: unusable at 90 %, usable at 80 %
    s = Surface(h, DX, DX)
    # runs: 0-299 (300 columns), 301-699 (399), 705-999 (295); with the 80 % rule 301-999 (699)
    assert usable_length_mm(s, 90.0) == pytest.approx(398 * DX)
    assert usable_length_mm(s, 80.0) == pytest.approx(698 * DX)
    assert usable_length_mm(Surface(np.full((3, 5), np.nan), DX, DX)) == 0.0


def test_scan_quality_counts_dropouts_replaced_points_and_spike_clusters():
    h = tilted_scan(sx=0.0, sy=0.0, shape=(100, 500))
    h = np.round(np.clip(h, -0.3, 0.3) / 0.01) * 0.01
    h[50:60, 50:60] = np.nan  # 100 dropouts = 0.2 %
    h[20, 100] += 4.0
    h[70, 300:302] -= 4.0  # one cluster of two points
    h[80, 400] += 3.0
    s = Surface(h, DX, DX)
    res = despeckle_detail(s)
    q = scan_quality("B", s, res.mask, res.step_mm, res.step_source)
    assert q.dropout_pct == pytest.approx(100 * 100 / h.size)
    assert res.n_replaced == 4 and q.replaced_pct == pytest.approx(100 * 4 / h.size)
    assert q.spikes_found == 3
    assert q.height_step_mm == pytest.approx(0.01) and q.height_step_source == "data"
    assert q.scan_length_mm == pytest.approx(499 * DX)
    with pytest.raises(ValueError, match="mask"):
        scan_quality("B", s, res.mask[:10], 0.01, "data")


def _quality(**changes):
    plane = np.tile(0.1 * DX * np.arange(400), (80, 1))  # slope 0.1 along x: tilt atan(0.1) = 5.711 deg
    # 1 mm of relief: a cosine along y, symmetric about the middle row (no slope along y)
    plane += 0.5 * np.cos(2 * np.pi * (np.arange(80) - 39.5) * DX / 1.0)[:, None]
    q = scan_quality("C7", Surface(plane, DX, DX), np.zeros((80, 400), bool), 0.0, "none")
    return q if not changes else type(q)(**{**q.to_dict(), **changes})


def test_limits_warn_or_stop_naming_site_measure_value_and_limit(caplog):
    q = _quality()  # tilt atan(0.1) = 5.71 deg, usable length 19.95 mm
    warn = QualityOptions.from_dict({"max_tilt_deg": 5.0}, strip_length_mm=114.3)
    assert warn.min_usable_length_mm == 114.3
    with caplog.at_level(logging.WARNING):
        found = check_quality(q, warn)
    assert len(found) == 2 and "tilt_deg 5.71 deg above the limit 5 deg" in found[0]
    assert "usable_length_mm 19.95 mm below the limit 114.3 mm" in found[1]
    assert sum("SCAN QUALITY site C7" in r.getMessage() for r in caplog.records) == 2
    ok = QualityOptions(max_tilt_deg=6.0, min_usable_length_mm=10.0)
    assert check_quality(q, ok) == []
    stop = QualityOptions(max_tilt_deg=6.0, min_usable_length_mm=10.0, max_dropout_pct=1.0, action="stop")
    with pytest.raises(ScanQualityError, match=r"site 'C7': dropout_pct 2 % above the limit 1 %"):
        check_quality(_quality(dropout_pct=2.0), stop)


def test_quality_options_are_checked():
    with pytest.raises(ConfigError, match="quality.action"):
        QualityOptions(action="ignore")
    with pytest.raises(ConfigError, match="unknown keys"):
        QualityOptions.from_dict({"max_dropouts": 3})
    with pytest.raises(ConfigError, match="quality.max_replaced_pct"):
        QualityOptions(max_replaced_pct=-1.0)
    assert QualityOptions.from_dict({"min_usable_length_mm": 50.0}, 114.3).min_usable_length_mm == 50.0


def test_quality_table_and_figure(tmp_path):
    measures = [_quality(site="A1"), _quality(site="A2", dropout_pct=20.0)]
    opt = QualityOptions(max_tilt_deg=6.0, min_usable_length_mm=10.0)
    table = quality_table(measures, opt)
    assert table["status"].tolist() == ["ok", "flagged"]
    assert table["flags"].iloc[1] == "dropout_pct 20 % above the limit 10 %"
    with pytest.raises(ScanQualityError, match=r"1 of 2 sites beyond the limits: site 'A2'"):
        quality_table(measures, QualityOptions(max_tilt_deg=6.0, min_usable_length_mm=10.0, action="stop"))
    from dataclasses import asdict

    from skidsim.plotting.texture import plot_scan_quality

    plot_scan_quality(table, asdict(opt), tmp_path / "q.png")
    assert (tmp_path / "q.png").stat().st_size > 10_000


def test_cli_texture_offers_every_despeckle_rule_and_defaults_to_local():
    from skidsim.cli import build_parser
    from skidsim.texture import TextureOptions
    from skidsim.texture.despeckle import METHODS

    parser = build_parser()
    action = next(
        a
        for sp in parser._subparsers._group_actions
        for name, p in sp.choices.items()
        if name == "texture"
        for a in p._actions
        if a.dest == "despeckle"
    )
    assert sorted(action.choices) == sorted(METHODS)
    assert action.default == TextureOptions().despeckle_method == "local"


SMALL = """
synthetic:
  sections: [E1]
  sites_per_section: 2
  shape: [220, 600]
  spacing_mm: 0.2
quality:
  max_replaced_pct: 0.0
  action: {action}
"""


def _run(workdir: Path, action: str) -> subprocess.CompletedProcess:
    cfg = workdir / f"{action}.yaml"
    cfg.write_text(SMALL.format(action=action))
    return run_snakemake(
        "results/texture/quality.csv",
        workdir=workdir,
        configfiles=[cfg],
        cwd=ROOT,
        env=snakemake_env(OMP_NUM_THREADS="1"),
        timeout=600,
        check=False,
    )


def test_workflow_quality_table_warns_then_stops(tmp_path):
    """Two small synthetic sites (0.05 % speckle) with max_replaced_pct 0: warn writes the table with both sites
    flagged and WARNINGs; stop (only scan_quality re-runs: the limits are not params of despeckle) fails naming
    the sites."""
    r = _run(tmp_path, "warn")
    assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    table = pd.read_csv(tmp_path / "results" / "texture" / "quality.csv")
    assert table["site"].tolist() == ["E1-1", "E1-2"] and (table["status"] == "flagged").all()
    assert (table["height_step_mm"] == 0.01).all() and (table["height_step_source"] == "x3p").all()
    assert table["replaced_pct"].between(0.04, 0.1).all()  # the generator's 0.05 % speckle
    assert table["flags"].str.startswith("replaced_pct").all()
    assert "SCAN QUALITY site E1-1" in (tmp_path / "logs" / "scan_quality.log").read_text()
    assert (tmp_path / "results" / "texture" / "quality.png").exists()
    site = json.loads((tmp_path / "results" / "sites" / "E1-1" / "quality.json").read_text())
    assert site["method"] == "local" and site["site"] == "E1-1"
    r = _run(tmp_path, "stop")
    assert r.returncode != 0
    out = r.stdout + r.stderr
    assert "2 of 2 sites beyond the limits: site 'E1-1': replaced_pct" in out
    assert "rule despeckle" not in out  # changing a limit re-ran scan_quality only


# ------------------------------------------------------------------------------------ relief that is no road


def test_relief_is_the_peak_to_peak_of_the_heights_about_their_plane():
    """A sine of amplitude A on a tilted plane: the 0.5-99.5 % range of a sine is 2 A cos(0.005 pi)."""
    y, x = np.mgrid[0:200, 0:2000] * DX
    # 8 whole periods of a cosine symmetric about the middle: it does not bias the plane
    h = 0.03 * x - 0.02 * y + 0.8 * np.cos(2 * np.pi * (x - 999.5 * DX) / 12.5)
    assert relief_mm(Surface(h, DX, DX)) == pytest.approx(2 * 0.8 * np.cos(0.005 * np.pi), rel=1e-3)
    h[:, :100] = h[:, -100:] = np.nan  # dropouts at both ends (symmetric: the plane stays unbiased)
    h[5, 500] = 50.0  # one spike: not counted (0.5 % each side)
    assert relief_mm(Surface(h, DX, DX)) == pytest.approx(2 * 0.8 * np.cos(0.005 * np.pi), rel=2e-3)
    assert np.isnan(relief_mm(Surface(np.full((3, 3), np.nan), DX, DX)))


def test_relief_limits_on_real_shaped_scans():
    """LS-40-like scans (stones on a flat binder at one 0.01 mm code, chips, porous; the despeckle study's
    builders) are pavements; the same scans in metres, in micrometres, or one code everywhere with speckle are
    not."""
    from test_texture_despeckle import CASES, DX_MM, flat_binder_scan, inject_spikes

    opt = QualityOptions()
    reliefs = []
    for n, name in enumerate(["binder 67 %", "porous (negative skew)", "chips, vertical sides"]):
        h = flat_binder_scan(seed=n, **CASES[name])
        r = relief_mm(Surface(h, DX_MM, DX_MM))
        reliefs.append(r)
        assert relief_breach(r, opt) is None, name
        assert "below the limit min_relief_mm 0.05 mm" in relief_breach(relief_mm(Surface(h / 1000, DX_MM, DX_MM)), opt)
        assert "above the limit max_relief_mm 30 mm" in relief_breach(relief_mm(Surface(h * 1000, DX_MM, DX_MM)), opt)
    assert min(reliefs) > 2.0 and max(reliefs) < 4.0  # measured 2026-11-28: 3.01, 2.73, 3.03 mm
    one_code, _ = inject_spikes(np.full((100, 2048), 1.23), seed=1)  # speckle of 3-5 mm on one height
    assert relief_mm(Surface(one_code, DX_MM, DX_MM)) < 0.002  # the spikes tilt the plane by a few um
    q = scan_quality("F1", Surface(one_code, DX_MM, DX_MM), np.zeros(one_code.shape, bool), 0.01, "data")
    found = check_quality(q, QualityOptions(max_tilt_deg=90, min_usable_length_mm=0))
    assert len(found) == 1 and found[0].endswith(
        " mm below the limit min_relief_mm 0.05 mm (no pavement is this flat: one height everywhere, "
        "or heights in m read as mm)"
    )
    with pytest.raises(ConfigError, match="quality.max_relief_mm: expected a relief above min_relief_mm"):
        QualityOptions(min_relief_mm=5.0, max_relief_mm=1.0)


@pytest.fixture(scope="module")
def small_campaign(tmp_path_factory) -> Path:
    from skidsim.cli import main

    out = tmp_path_factory.mktemp("relief") / "camp"
    assert main(["synth", str(out), "--sites", "2", "--shape", "300", "600", "--spacing-mm", "0.2", "--seed", "5"]) == 0
    return out


def test_validate_refuses_or_flags_a_relief_that_cannot_be_a_road(small_campaign, tmp_path, capsys, caplog):
    """`skidsim validate` (the check of the workflow's first rule): the campaign's own scans (LS-40-like: tilt,
    dropouts, codes of 0.01 mm, speckle) pass; a grid scan of one height, or in metres, is refused with
    quality.action stop and flagged (a WARNING, validation goes on) with the default action warn."""
    import shutil

    import yaml

    from skidsim.cli import main
    from skidsim.gridtext import write_grid_text
    from skidsim.scans import read_scan

    stop = tmp_path / "stop.yaml"
    stop.write_text(yaml.safe_dump({"quality": {"action": "stop"}}))
    assert main(["validate", str(small_campaign), "--configfile", str(stop)]) == 0, capsys.readouterr().err
    capsys.readouterr()
    sites = (small_campaign / "sites.csv").read_text()
    first = sites.splitlines()[1].split(",")[0]
    scan = next(c for c in sites.splitlines()[1].split(",") if c.endswith(".x3p"))
    real = read_scan(small_campaign / scan)
    cases = {
        "flat": np.where(np.isfinite(real.heights), 12.34, np.nan),
        "metres": real.heights / 1000.0,
    }
    for name, heights in cases.items():
        camp = tmp_path / name
        shutil.copytree(small_campaign, camp)
        grid = f"scans/{first}.csv"
        write_grid_text(camp / grid, type(real)(heights, real.dx, real.dy, name=real.name))
        (camp / "sites.csv").write_text(sites.replace(scan, grid))
        assert main(["validate", str(camp), "--configfile", str(stop)]) == 2, name
        err = capsys.readouterr().err
        assert f"{grid}: column 'heights': expected a relief of a pavement surface, 0.05 to 30 mm" in err, err
        assert "below the limit min_relief_mm 0.05 mm" in err and "quality.action: stop" in err
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="skidsim"):
        assert main(["validate", str(tmp_path / "metres")]) == 0  # the default action: warn
    assert any("SCAN RELIEF" in r.getMessage() and "relief_mm" in r.getMessage() for r in caplog.records)
