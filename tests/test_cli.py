"""The `skidsim` command line: synth -> validate -> texture -> simulate on a small campaign."""

from __future__ import annotations

import pandas as pd
import pytest

from skidsim.cli import main


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "camp"
    rc = main(["synth", str(out), "--sites", "2", "--shape", "512", "640", "--spacing-mm", "0.2", "--seed", "3"])
    assert rc == 0
    return out


def test_synth_writes_a_campaign_that_validates(campaign, capsys):
    sites = pd.read_csv(campaign / "sites.csv")
    assert list(sites["site"]) == ["E1-1", "E1-2"]
    assert (campaign.parent / "camp-truth" / "E1-1.json").is_file()  # truth beside, never inside, the campaign
    assert main(["validate", str(campaign)]) == 0
    out = capsys.readouterr().out
    assert "OK, 2 sites in 1 sections" in out


def test_validate_names_the_problem(campaign, tmp_path, capsys):
    bad = tmp_path / "bad"
    bad.mkdir()
    text = (campaign / "sites.csv").read_text().replace(",scans/E1-2.x3p,", ",scans/missing.x3p,")
    (bad / "sites.csv").write_text(text)
    for d in ("scans", "dft"):
        (bad / d).symlink_to(campaign / d)
    assert main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "sites.csv" in err and "scan" in err and "missing.x3p" in err


def test_texture_table_to_csv(campaign, tmp_path, capsys):
    out = tmp_path / "t.csv"
    assert main(["texture", str(campaign / "scans" / "E1-1.x3p"), "-o", str(out), "-q"]) == 0
    t = pd.read_csv(out)
    assert set(t["band"]) >= {"raw", "macro", "micro"}
    sq = t.set_index(["band", "parameter"])["value"]
    # the bands split the variance: raw Sq^2 ~ macro Sq^2 + micro Sq^2 (+ the long-wavelength rest, small here)
    assert sq[("macro", "Sq")] < sq[("raw", "Sq")]
    assert sq[("micro", "Sq")] < sq[("macro", "Sq")]


def test_simulate_prints_sn(campaign, tmp_path, capsys):
    trace = tmp_path / "trace.parquet"
    rc = main(
        [
            "simulate",
            str(campaign / "scans" / "E1-1.x3p"),
            "--speed",
            "60",
            "--mu-s",
            "0.5",
            "--mu-k",
            "0.4",
            "--alpha",
            "0.3",
            "--preset",
            "quick",
            "--trace",
            str(trace),
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    sn = float(out.split("SN = ")[1].split()[0])
    assert 0.3 < sn < 0.6  # mu(60 km/h) = 0.4037; the texture moves SN by a few per cent
    tr = pd.read_parquet(trace)
    assert {"time_s", "position_mm", "tangential_n", "normal_n"} <= set(tr.columns)


def test_progress_is_a_solver_progress_callback(caplog):
    """The solver calls ``progress(step, n_steps, elapsed_s, eta_s)``; :class:`skidsim.runlog.Progress` takes that
    call and reports the solver's step count, not the total it was built with."""
    import logging

    from skidsim.runlog import Progress

    p = Progress(1, "simulate", logging.getLogger("skidsim.test"), every_s=0.0)
    with caplog.at_level(logging.INFO, logger="skidsim.test"):
        p(250, 1000, 1.5, 4.5)
    assert "250/1000 (25 %)" in caplog.text
