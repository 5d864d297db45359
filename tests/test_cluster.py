"""Cluster execution without a cluster: a SLURM dry run checks the resolved resources; a fake cluster
(profiles/fake-cluster: real job scripts submitted through the generic cluster executor, run locally) takes a
3-site campaign end to end."""

from __future__ import annotations

import re
import subprocess
import sys

import pandas as pd
import pytest
from conftest import ROOT, run_snakemake

TINY = """
synthetic:
  seed: 5
  sections: [E1, E6, C2]
  sites_per_section: 1
  shape: [512, 640]
  spacing_mm: 0.2
solver:
  preset: quick
  load_n: 11.8
calibration:
  study:
    max_iter: 4
mesh_study:
  sizes_mm: []
  speeds_kmh: [60]
"""


def _run(args, cwd, timeout=1500):
    return run_snakemake(
        *args, workdir=cwd, configfiles=[cwd / "tiny.yaml"], cores=None, cwd=ROOT, timeout=timeout, check=False
    )


@pytest.fixture()
def workdir(tmp_path):
    (tmp_path / "tiny.yaml").write_text(TINY)
    return tmp_path


def test_slurm_dry_run_resolves_rule_resources(workdir):
    r = _run(["-n", "--executor", "slurm", "--profile", str(ROOT / "profiles" / "slurm"), "--jobs", "10"], workdir)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-3000:]
    # every calibrate job carries the resources its rule declares (runtime 120 min, mem_mb 1500)
    blocks = re.findall(r"rule calibrate:.*?resources: ([^\n]*)", out, flags=re.S)
    assert len(blocks) == 6, out[-2000:]  # 3 sites x 2 methods
    for res in blocks:
        assert "runtime=120" in res and "mem_mb=1500" in res, res
    # the per-site texture chain is submitted as one group job per site
    assert len(re.findall(r"group job site_texture", out, flags=re.I)) == 3, out[-2000:]


@pytest.mark.slow
def test_fake_cluster_runs_a_3_site_campaign(workdir):
    r = _run(["--profile", str(ROOT / "profiles" / "fake-cluster")], workdir)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-5000:]
    res = workdir / "results"
    params = pd.read_parquet(res / "calibration" / "parameters.parquet")
    assert sorted(params["site"].unique()) == ["C2-1", "E1-1", "E6-1"]
    assert set(params["method"]) == {"study", "ours"}
    val = pd.read_parquet(res / "calibration" / "validation.parquet")
    ours = val[val["method"] == "ours"]
    # the fitted law reproduces the measured DFT at the speeds it never saw within a few hundredths
    assert (ours[ours["kind"] == "validation"]["err"].abs() < 0.05).all(), ours
    long = pd.read_parquet(res / "texture" / "texture_long.parquet")
    assert set(long["band"]) >= {"raw", "macro", "micro"}
    # jobs really went through the fake scheduler: one status file per submitted job
    submitted = list((workdir / ".fake-cluster").glob("*.rc"))
    assert submitted, "no job was submitted through profiles/fake-cluster"


# --- skidsim.cluster: reading what SLURM offers and grants (text captured from SLURM 22.05 on 2026-11-25) ---

SCONTROL_GROUP_JOB = (
    "JobId=8 JobName=6fd1e9ee UserId=root(0) GroupId=root(0) MCS_label=N/A Priority=1 Nice=0 Account=(null) "
    "QOS=(null) JobState=COMPLETED Reason=None Dependency=(null) Requeue=1 Restarts=0 BatchFlag=1 Reboot=0 "
    "ExitCode=0:0 RunTime=00:00:50 TimeLimit=00:30:00 TimeMin=N/A AllocNode:Sid=localhost:3281 NumNodes=1 "
    "NumCPUs=2 NumTasks=1 CPUs/Task=2 ReqB:S:C:T=0:0:*:* TRES=cpu=2,mem=4500M,node=1,billing=2 MinCPUsNode=2 "
    "MinMemoryNode=4500M Comment=rule_site_texture_despeckle_figure7_mpd_reconstruct_separate_bands_...  "
    "StdErr=/tmp/x/8.log"
)


def test_scontrol_job_is_read_into_a_grant():
    from skidsim.cluster import parse_scontrol_job, rule_of

    g = parse_scontrol_job(SCONTROL_GROUP_JOB)
    assert (g.job_id, g.state, g.cpus, g.mem_mb, g.time_limit_min) == ("8", "COMPLETED", 2, 4500, 30)
    assert rule_of(g.comment).startswith("site_texture_despeckle")
    assert rule_of("rule_calibrate_wildcards_E1-1_ours") == "calibrate"


@pytest.mark.parametrize(
    "text, minutes",
    [
        ("00:30:00", 30),
        ("2:00:00", 120),
        ("1-00:00:00", 1440),
        ("10:00", 10),
        ("45", 45),
        ("UNLIMITED", None),
        ("0:00:30", 1),
    ],
)
def test_slurm_time_limits_in_minutes(text, minutes):
    from skidsim.cluster import time_to_min

    assert time_to_min(text) == minutes


def test_sinfo_nodes_sacct_lines_and_caps():
    from skidsim.cluster import caps, mem_to_mb, parse_sacct, parse_sinfo_nodes

    nodes = parse_sinfo_nodes("vm|2|23081\nbig|64|512000\nbig|64|512000\n")
    assert [(n.name, n.cpus, n.mem_mb) for n in nodes] == [("vm", 2, 23081), ("big", 64, 512000)]
    assert caps(nodes) == (2, 23081)
    assert mem_to_mb("2G") == 2048 and mem_to_mb("1500M") == 1500 and mem_to_mb("1500") == 1500
    (g,) = parse_sacct("13|CANCELLED by 0|1|1500M|02:00:00|rule_calibrate_wildcards_E1-1_ours\n")
    assert (g.state, g.cpus, g.mem_mb, g.time_limit_min, g.comment) == (
        "CANCELLED",
        1,
        1500,
        120,
        "rule_calibrate_wildcards_E1-1_ours",
    )


def test_unreadable_slurm_output_names_the_field():
    from skidsim.cluster import ClusterError, mem_to_mb, parse_scontrol_job

    with pytest.raises(ClusterError, match="memory of node7.*'lots'"):
        mem_to_mb("lots", "memory of node7")
    with pytest.raises(ClusterError, match="no field JobState"):
        parse_scontrol_job("JobId=3 NumCPUs=1 TimeLimit=10")


def test_cluster_profile_settings_are_not_overridden_by_the_workflow_profile():
    """profiles/default is loaded as the workflow profile also under --profile profiles/slurm, and wins: the
    effective settings must be the cluster profile's (latency-wait 60 s, squeue status, retries)."""
    code = (
        "from snakemake.cli import parse_args; "
        "p, a = parse_args(['-s', 'Snakefile', '--profile', 'profiles/slurm', '-n']); "
        "print(a.latency_wait, a.slurm_status_command, a.retries, a.jobs, a.executor); "
        "p, a = parse_args(['-s', 'Snakefile', '-n']); print(a.latency_wait, a.executor)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]
    cluster_line, local_line = r.stdout.strip().splitlines()[-2:]
    assert cluster_line.split() == ["60", "squeue", "1", "100", "slurm"]
    assert local_line.split()[0] == "5"  # Snakemake's default locally
