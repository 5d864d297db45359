"""A 3-site campaign through profiles/slurm on a real SLURM (cluster/single-node-slurm.sh), compared with a local run.

Runs only with SKIDSIM_TEST_SLURM=1 and the SLURM tools installed and answering (`make test-slurm` starts the
single-node cluster in each accounting mode and sets both). SKIDSIM_SLURM_ACCOUNTING=0/1 names the mode the caller
started; the test checks the cluster really is in it. One SLURM run takes the campaign end to end while the test
cancels its first running `calibrate` job with scancel (the profile's retry must take it to the end); a later run in
the same directory gives one job less memory than it uses.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from skidsim import cluster

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(
    os.environ.get("SKIDSIM_TEST_SLURM") != "1" or not all(shutil.which(t) for t in ("sbatch", "squeue", "scontrol")),
    reason="needs SKIDSIM_TEST_SLURM=1 and a SLURM cluster (make test-slurm)",
)

sys.path.insert(0, str(Path(__file__).parent))
from test_cluster import TINY  # noqa: E402  the 3-site campaign of the fake-cluster test, one definition
from test_rule_resources import resource_table  # noqa: E402  one parser of docs/cluster.md's table

#: JSON keys that hold wall-clock timings: they differ between any two runs.
TIMING_KEYS = re.compile(r"(^|_)(wall|overhead|elapsed)(_|$)")  # wall_s, fe_wall_s, wall_s_run, overhead_s
ACCOUNT = os.environ.get("SKIDSIM_SLURM_ACCOUNT", "skidsim")


#: The workflow as the runs see it: a copy of the checkout taken once (every SLURM job re-reads the Snakefile,
#: rules and library; a copy keeps edits made to the checkout during the test out of the runs).
CODE: Path | None = None


@pytest.fixture(scope="module", autouse=True)
def code_snapshot(tmp_path_factory):
    global CODE
    CODE = tmp_path_factory.mktemp("code")
    for name in ("Snakefile", "workflow", "config", "src", "profiles"):
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, CODE / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            shutil.copy2(src, CODE / name)
    return CODE


def _cmd(workdir: Path, *args: str, targets: tuple[str, ...] = ()) -> list[str]:
    # targets first: options such as --resources and --set-resources take every word after them
    return [
        sys.executable,
        "-m",
        "snakemake",
        *targets,
        "-s",
        str(CODE / "Snakefile"),
        "--directory",
        str(workdir),
        "--configfile",
        str(CODE / "config" / "config.yaml"),
        str(workdir / "tiny.yaml"),
        *args,
    ]


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=str(CODE / "src"), SKIDSIM_SLURM_ACCOUNT=ACCOUNT)


def _profile() -> list[str]:
    return ["--profile", str(CODE / "profiles" / "slurm")]


def _slurm_args(caps: tuple[int, int]) -> list[str]:
    cpus, mem = caps
    return [*_profile(), "--jobs", "2", "--cores", str(cpus), "--resources", f"mem_mb={mem}"]


def _job_ids() -> set[int]:
    out = subprocess.run(
        ["squeue", "--states=all", "-h", "-o", "%i"], capture_output=True, text=True, check=True
    ).stdout
    return {int(x) for x in out.split() if x.isdigit()}


def _squeue() -> dict[int, tuple[str, str]]:
    out = subprocess.run(
        ["squeue", "--states=all", "-h", "-o", "%i|%T|%k"], capture_output=True, text=True, check=True
    ).stdout
    jobs = {}
    for line in out.splitlines():
        jid, state, comment = line.split("|", 2)
        if jid.isdigit():
            jobs[int(jid)] = (state, comment)
    return jobs


@pytest.fixture(scope="module")
def slurm_cluster():
    ping = subprocess.run(["scontrol", "ping"], capture_output=True, text=True)
    assert ping.returncode == 0, f"no SLURM controller answers (cluster/single-node-slurm.sh start): {ping.stdout}"
    conf = subprocess.run(["scontrol", "show", "config"], capture_output=True, text=True, check=True).stdout
    storage = re.search(r"^AccountingStorageType\s*=\s*(\S+)", conf, flags=re.M).group(1)
    min_job_age = int(re.search(r"^MinJobAge\s*=\s*(\d+)", conf, flags=re.M).group(1))
    return {
        "accounting": storage.endswith("slurmdbd"),
        "min_job_age_s": min_job_age,
        "caps": cluster.caps(cluster.nodes()),
    }


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    wd = tmp_path_factory.mktemp("local")
    (wd / "tiny.yaml").write_text(TINY)
    r = subprocess.run(_cmd(wd, "--cores", "1"), capture_output=True, text=True, env=_env(), cwd=CODE, timeout=1200)
    assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    return wd


@pytest.fixture(scope="module")
def slurm_run(tmp_path_factory, slurm_cluster):
    """The campaign through profiles/slurm; the first calibrate job seen running is cancelled with scancel."""
    wd = tmp_path_factory.mktemp("slurm")
    (wd / "tiny.yaml").write_text(TINY)
    before = max(_job_ids(), default=0)
    t0 = time.monotonic()
    log = open(wd / "snakemake.log", "w")
    proc = subprocess.Popen(
        _cmd(wd, *_slurm_args(slurm_cluster["caps"])),
        stdout=log,
        stderr=subprocess.STDOUT,
        cwd=CODE,
        text=True,
        env=_env(),
    )
    cancelled, seen = None, set()
    try:
        while proc.poll() is None:
            if time.monotonic() - t0 > 1800:
                proc.terminate()
                pytest.fail("the SLURM run did not finish in 30 min (stall)")
            for jid, (state, comment) in _squeue().items():
                if jid > before:
                    seen.add(jid)
                    if cancelled is None and state == "RUNNING" and comment.startswith("rule_calibrate"):
                        subprocess.run(["scancel", str(jid)], check=True)
                        cancelled = jid
            time.sleep(2)
    finally:
        log.close()
    wall_s = time.monotonic() - t0
    seen |= {j for j in _job_ids() if j > before}
    text = (wd / "snakemake.log").read_text()
    report = {
        "accounting": slurm_cluster["accounting"],
        "wall_s": round(wall_s, 1),
        "jobs": len(seen),
        "cancelled": cancelled,
        "returncode": proc.returncode,
    }
    print("SLURM run:", json.dumps(report))
    if os.environ.get("SKIDSIM_SLURM_REPORT"):  # make test-slurm collects the measured figures here
        with open(os.environ["SKIDSIM_SLURM_REPORT"], "a") as f:
            grants = [cluster.granted(str(j)).__dict__ for j in sorted(seen)]
            f.write(json.dumps({**report, "grants": grants}) + "\n")
    return {
        "dir": wd,
        "rc": proc.returncode,
        "log": text,
        "jobs": sorted(seen),
        "cancelled": cancelled,
        "wall_s": wall_s,
    }


def test_cluster_is_in_the_requested_accounting_mode(slurm_cluster):
    want = os.environ.get("SKIDSIM_SLURM_ACCOUNTING")
    if want is not None:
        assert slurm_cluster["accounting"] == (want == "1"), slurm_cluster
    # squeue must remember finished jobs longer than the plugin's longest status-poll interval (180 s)
    assert slurm_cluster["min_job_age_s"] >= 180


def test_campaign_completes_through_slurm(slurm_run):
    assert slurm_run["rc"] == 0, slurm_run["log"][-6000:]
    assert len(slurm_run["jobs"]) >= 10  # synth x3, ingest, group x3, calibrate x6 (+ retry), validate x3 ...
    assert "trying to guess" not in slurm_run["log"]  # the account came from the environment, no failed guess


def test_cancelled_job_is_reported_failed_and_retried(slurm_run):
    jid = slurm_run["cancelled"]
    assert jid is not None, "no calibrate job was seen running, nothing was cancelled"
    log = slurm_run["log"]
    assert f"SLURM-job '{jid}' failed, SLURM status is: 'CANCELLED" in log, log[-6000:]
    assert "Error in rule calibrate" in log
    assert slurm_run["rc"] == 0  # the retry (profile: retries: 1) finished the job


def _compare_json(a, b, path, dirs):
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            if not TIMING_KEYS.search(k):
                _compare_json(a[k], b[k], f"{path}.{k}", dirs)
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _compare_json(x, y, f"{path}[{i}]", dirs)
    elif isinstance(a, str):  # paths name the run's directory
        assert a.replace(dirs[0], "<wd>") == b.replace(dirs[1], "<wd>"), (path, a, b)
    else:
        assert a == b, (path, a, b)


def _relative(df: pd.DataFrame, wd: Path) -> pd.DataFrame:
    df = df.drop(columns=[c for c in df.columns if TIMING_KEYS.search(str(c))])
    for c in df.columns[df.dtypes.map(lambda t: pd.api.types.is_object_dtype(t) or str(t).startswith("str"))]:
        df[c] = df[c].map(lambda v: v.replace(str(wd), "<wd>") if isinstance(v, str) else v)
    return df


def test_every_output_equals_the_local_run(slurm_run, local_run):
    assert slurm_run["rc"] == 0
    local, remote = local_run / "results", slurm_run["dir"] / "results"
    files = sorted(
        p.relative_to(local)
        for p in local.rglob("*")
        if p.suffix in (".parquet", ".json", ".csv") and "cache" not in p.parts
    )
    assert len(files) >= 30, files
    for rel in files:
        a, b = local / rel, remote / rel
        assert b.exists(), f"{rel} missing from the SLURM run"
        if rel.suffix == ".parquet":
            pd.testing.assert_frame_equal(
                _relative(pd.read_parquet(a), local_run), _relative(pd.read_parquet(b), slurm_run["dir"]), obj=str(rel)
            )
        elif rel.suffix == ".json":
            _compare_json(
                json.loads(a.read_text()), json.loads(b.read_text()), str(rel), (str(local_run), str(slurm_run["dir"]))
            )
        else:
            pd.testing.assert_frame_equal(
                _relative(pd.read_csv(a), local_run), _relative(pd.read_csv(b), slurm_run["dir"]), obj=str(rel)
            )
    # figures: same set of files
    pngs = {p.relative_to(local) for p in local.rglob("*.png")}
    assert pngs == {p.relative_to(remote) for p in remote.rglob("*.png")}


def _resource_table() -> dict[str, tuple[int, int, int]]:
    """docs/cluster.md's table of what each SLURM job asks: job -> (CPUs, MB, minutes)."""
    return resource_table()


def test_slurm_granted_what_the_resources_table_says(slurm_run, slurm_cluster):
    table = _resource_table()
    assert {"synth_site", "calibrate", "site_texture", "validate_campaign"} <= set(table), table
    checked = set()
    for jid in slurm_run["jobs"]:
        g = cluster.granted(str(jid))
        name = cluster.rule_of(g.comment)
        name = "site_texture" if name.startswith("site_texture") else name
        assert name in table, f"job {jid} ({g.comment}) is not in docs/cluster.md's resources table"
        assert (g.cpus, g.mem_mb, g.time_limit_min) == table[name], (jid, name, g)
        checked.add(name)
    assert {"synth_site", "calibrate", "site_texture"} <= checked
    cpus, mem = slurm_cluster["caps"]
    assert table["site_texture"][0] <= cpus and table["site_texture"][1] <= mem  # the group fits the node
    if slurm_cluster["accounting"]:  # the accounting database agrees with the controller
        by_id = {g.job_id: g for g in cluster.granted_sacct([str(j) for j in slurm_run["jobs"]])}
        for jid in slurm_run["jobs"]:
            g = cluster.granted(str(jid))
            assert (by_id[str(jid)].cpus, by_id[str(jid)].mem_mb, by_id[str(jid)].time_limit_min) == (
                g.cpus,
                g.mem_mb,
                g.time_limit_min,
            ), jid


def test_job_over_its_memory_is_reported_with_rule_and_site(slurm_run):
    wd = slurm_run["dir"]
    target = "results/sites/E6-1/calibration_ours.json"
    r = subprocess.run(
        _cmd(
            wd,
            *_profile(),
            "--jobs",
            "1",
            "--retries",
            "0",
            "--force",
            "--set-resources",
            "calibrate:mem_mb=100",
            targets=(target,),
        ),
        capture_output=True,
        text=True,
        env=_env(),
        cwd=CODE,
        timeout=900,
    )
    out = r.stdout + r.stderr
    assert r.returncode != 0, out[-3000:]
    err = out[out.index("Error in rule calibrate") :]
    assert "output: results/sites/E6-1/calibration_ours.json" in err[:1500], err[:2000]  # rule and site
    assert "SLURM status is: 'FAILED'" in err or "OUT_OF_MEMORY" in err, err[:2000]
    assert "exceeded memory limit" in out, out[-3000:]  # the SLURM log, shown by show-failed-logs


def test_group_larger_than_the_node_is_refused_at_submission(slurm_run, slurm_cluster):
    """Without the node's caps the site's texture group asks for 3 CPUs (separate_bands, mpd and reconstruct can
    run at once) on a 2-CPU node. The single-node cluster sets EnforcePartLimits=ALL: sbatch refuses the job
    ("More processors requested than permitted") and the run stops with "Error in group site_texture", instead of
    the job pending forever (reason PartitionConfig). Snakemake 9.27 drops the plugin's message for a group job
    (GroupJob.log_error ignores it), so SLURM's reason itself is not in the output. Runs last: it forces the
    texture chain of E1-1, whose outputs Snakemake removes after the refused submission."""
    cpus, _ = slurm_cluster["caps"]
    if cpus >= 3:
        pytest.skip(f"the smallest node has {cpus} CPUs: the uncapped group (3 CPUs) fits it")
    conf = subprocess.run(["scontrol", "show", "config"], capture_output=True, text=True, check=True).stdout
    assert re.search(r"^EnforcePartLimits\s*=\s*(ALL|ANY)", conf, flags=re.M), "cluster without EnforcePartLimits"
    wd = slurm_run["dir"]
    before = _job_ids()
    t0 = time.monotonic()
    r = subprocess.run(
        _cmd(
            wd,
            *_profile(),
            "--jobs",
            "1",
            "--retries",
            "0",
            "--forcerun",
            "despeckle",
            targets=("results/sites/E1-1/texture.parquet", "results/sites/E1-1/pavement.npz"),
        ),
        capture_output=True,
        text=True,
        env=_env(),
        cwd=CODE,
        timeout=600,
    )
    out = r.stdout + r.stderr
    assert r.returncode != 0, out[-3000:]
    assert "Error in group site_texture" in out, out[-3000:]
    assert "Exiting because a job execution failed" in out, out[-3000:]
    assert _job_ids() == before, "a job was queued although sbatch should have refused it"
    assert time.monotonic() - t0 < 300  # refused at once, no wait for a job that can never start
    # the same request by hand: SLURM's reason, which the run's output lacks
    sb = subprocess.run(
        ["sbatch", "--test-only", "-c", "3", "--mem", "5500", "--wrap", "true"], capture_output=True, text=True
    )
    assert sb.returncode != 0 and "More processors requested than permitted" in sb.stderr, sb.stderr
