"""The Snakemake workflow: DAG of the default campaign, the truth firewall, config validation, user campaigns.

These tests run `snakemake` in dry-run mode (no job is executed) in a copy-free way: the repository's Snakefile
with ``--directory`` pointing at a temporary working directory, so nothing is written into the checkout. The dry run
of the default campaign is made once per test session (``default_dry_run`` in tests/conftest.py) and shared with
test_report_gallery.py.
"""

from __future__ import annotations

import re

import pytest
from conftest import ROOT, run_snakemake

#: Rules allowed to touch results/truth/: the generator writes it, synth_truth gathers it. Nothing else may read it.
TRUTH_RULES = {"synth_site", "synth_truth", "all"}


def job_counts(text: str) -> dict[str, int]:
    """Parse the 'Job stats' table of a dry run."""
    counts = {}
    for line in text.splitlines():
        m = re.match(r"^([A-Za-z_][\w]*)\s+(\d+)\s*$", line.strip())
        if m and m.group(1) != "total":
            counts[m.group(1)] = int(m.group(2))
    return counts


def test_dry_run_lists_36_sites(default_dry_run):
    counts = job_counts(default_dry_run)
    assert counts.get("synth_site") == 36, counts
    for rule in ("despeckle", "separate_bands", "mpd", "texture_parameters", "reconstruct", "validate_speeds"):
        assert counts.get(rule) == 36, (rule, counts)
    assert counts.get("calibrate") == 72, counts  # 36 sites x 2 methods
    assert counts.get("predict_fe") == 9, counts  # the study's 27/9 split
    for fan_in in (
        "synth_table",
        "validate_campaign",
        "texture_campaign",
        "calibration_summary",
        "regression",
        "figure11",
        "diagnosis",
        "mesh_study",
    ):
        assert counts.get(fan_in) == 1, (fan_in, counts)


def job_inputs(text: str) -> list[tuple[str, list[str]]]:
    """(rule, input files) of every job a dry run lists."""
    jobs = []
    for m in re.finditer(r"^\s*(?:local)?rule (\w+):\n((?:\s+\w[\w ]*: .*\n)*)", text, flags=re.M):
        inputs = re.search(r"^\s+input: (.*)$", m.group(2), flags=re.M)
        jobs.append((m.group(1), inputs.group(1).split(", ") if inputs else []))
    return jobs


def truth_readers(text: str) -> list[str]:
    return [
        rule
        for rule, inputs in job_inputs(text)
        if any("results/truth/" in f for f in inputs) and rule not in TRUTH_RULES
    ]


def test_no_analysis_rule_reads_truth(default_dry_run):
    """The ground truth of the synthetic campaign is written to results/truth/ and read by no analysis rule."""
    jobs = job_inputs(default_dry_run)
    assert len(jobs) > 36 * 8  # the parser really saw the per-site jobs and their inputs
    assert sum(1 for rule, inputs in jobs if rule == "despeckle" and inputs) == 36
    assert truth_readers(default_dry_run) == []


def test_our_calibration_waits_for_the_three_reference_sites(default_dry_run):
    """calibration.ours.prior_sites = 3: E1-1, C1-1, C6-3 are calibrated without a prior; every other site's 'ours'
    job reads their three results, and no 'study' job reads any calibration."""
    refs = {f"results/sites/{s}/calibration_ours.json" for s in ("E1-1", "C1-1", "C6-3")}
    jobs = [inputs for rule, inputs in job_inputs(default_dry_run) if rule == "calibrate"]
    assert len(jobs) == 72
    with_prior = [inputs for inputs in jobs if refs <= set(inputs)]
    without = [inputs for inputs in jobs if not any(f.endswith("calibration_ours.json") for f in inputs)]
    assert len(with_prior) == 33 and len(without) == 39  # 33 non-reference 'ours'; 36 'study' + 3 references


def test_truth_firewall_detects_a_leak(tmp_path):
    """The check above can fail: a rule that reads a truth file is reported."""
    leaky = tmp_path / "Snakefile"
    leaky.write_text(
        f'include: "{ROOT}/Snakefile"\n'
        'rule leak:\n    input: "results/truth/campaign.json"\n    output: "results/leak.txt"\n'
        '    shell: "touch {output}"\n'
    )
    r = run_snakemake("-n", "results/leak.txt", workdir=tmp_path, cores=None, snakefile=leaky, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    assert truth_readers(r.stdout + r.stderr) == ["leak"]


@pytest.mark.parametrize(
    "text, culprit",
    [
        ("texture:\n  despeckle_method: median-of-nothing\n", "median-of-nothing"),  # a bad value
        ("campagne: /tmp/x\n", "campagne"),  # a misspelt top-level key
        ("synthetic:\n  sites_per_sektion: 2\n", "sites_per_sektion"),  # caught by the generator's own check
    ],
)
def test_bad_config_is_rejected_naming_the_key(tmp_path, text, culprit):
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    r = run_snakemake("-n", "--configfile", bad, workdir=tmp_path, check=False)
    assert r.returncode != 0
    assert culprit in (r.stdout + r.stderr)


def test_user_campaign_dag_has_no_generator(tmp_path):
    camp = tmp_path / "camp"
    (camp / "scans").mkdir(parents=True)
    (camp / "dft").mkdir()
    rows = ["site,section,scan,dft,temperature_c,operator"]
    for i in range(4):
        rows.append(f"S{i},A{i // 2},scans/S{i}.x3p,dft/S{i}.csv,15.0,ann")
        (camp / "scans" / f"S{i}.x3p").write_bytes(b"")
        (camp / "dft" / f"S{i}.csv").write_text("speed_kmh,mu\n10,0.5\n80,0.4\n")
    (camp / "sites.csv").write_text("\n".join(rows) + "\n")
    r = run_snakemake("-n", "--config", f"campaign={camp}", workdir=tmp_path)
    counts = job_counts(r.stdout + r.stderr)
    assert "synth_site" not in counts and "synth_table" not in counts
    assert counts.get("despeckle") == 4
