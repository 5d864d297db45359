"""The memory settings of the scan steps (skidsim.allocator.scan_process_memory) against glibc's and NumPy's
defaults, side by side: the workflow's own jobs, as Snakemake runs them, on a small synthetic campaign.

    .venv/bin/python benchmarks/bench_allocator.py WORKDIR [--sections E1,C1] [--sites-per-section 2]
        [--repeats 2] [--cores 2]

Each repeat runs the workflow twice in fresh directories (``WORKDIR/<mode>-<repeat>``, the two modes in
alternating order): once with ``SKIDSIM_MALLOC=default`` (every script's call is then a no-op: glibc's and
NumPy's defaults) and once as shipped. Targets: every site's scan (synth_site), despeckle, separate_bands, mpd,
texture_parameters, reconstruct and figure7, and validate_campaign before them. Prints, per rule, the jobs' CPU
seconds (user + system, the ``cpu_time`` of Snakemake's ``benchmark:`` files) in each mode (median over the
repeats of the per-job mean) and the ratio, and checks that both modes wrote the same bytes (scans, texture
tables, MPD results; the pavements' and figures' files carry times).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import os
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tests")]  # the library, and the tests' workflow command line
RULES = (
    "synth_site",
    "validate_campaign",
    "despeckle",
    "separate_bands",
    "mpd",
    "texture_parameters",
    "reconstruct",
    "figure7",
)
#: Outputs compared byte for byte between the modes (per site; figures and logs carry times, so they are left out).
COMPARED = ("campaign/scans/{site}.x3p", "sites/{site}/texture.parquet", "sites/{site}/mpd.json")


def sites_of(sections: list[str], per_section: int) -> list[str]:
    from skidsim.config import synthetic_config
    from skidsim.generators import default as synthetic

    cfg = synthetic_config({"synthetic": {"sections": sections, "sites_per_section": per_section}})
    return [str(s) for s in synthetic.design_campaign(cfg)["site"]]


def run_mode(workdir: Path, mode: str, sections: list[str], per_section: int, sites: list[str], cores: int) -> None:
    if workdir.exists():
        shutil.rmtree(workdir)
    workdir.mkdir(parents=True)
    (workdir / "campaign.yaml").write_text(
        f"synthetic:\n  sections: [{', '.join(sections)}]\n  sites_per_section: {per_section}\n"
    )
    targets = []
    for s in sites:
        targets += [f"results/sites/{s}/{f}" for f in ("texture.parquet", "mpd.json", "pavement.npz", "figure7.png")]
    from conftest import snakemake_cmd, snakemake_env  # the tests' command line and environment of the workflow

    env = snakemake_env(OMP_NUM_THREADS="1")
    env.pop("SKIDSIM_MALLOC", None)
    if mode == "default":
        env["SKIDSIM_MALLOC"] = "default"
    cmd = snakemake_cmd(*targets, workdir=workdir, configfiles=[workdir / "campaign.yaml"], cores=cores)
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=workdir)
    if r.returncode != 0:
        raise SystemExit(f"snakemake failed in {workdir} (exit {r.returncode}):\n{r.stderr[-3000:]}")


def cpu_by_rule(workdir: Path) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {}
    for rule in RULES:
        files = sorted((workdir / "benchmarks" / "out").glob(f"{rule}/*.tsv")) + sorted(
            (workdir / "benchmarks" / "out").glob(f"{rule}.tsv")
        )
        for f in files:
            for row in csv.DictReader(f.open(), delimiter="\t"):
                out.setdefault(rule, []).append(float(row["cpu_time"]))
    return out


def digest(workdir: Path, sites: list[str]) -> dict[str, str]:
    res = workdir / "results"
    return {
        p.format(site=s): hashlib.sha256((res / p.format(site=s)).read_bytes()).hexdigest()
        for s in sites
        for p in COMPARED
    }


def _ratio(a: float, b: float) -> str:
    """``a / b`` as ``1.23x``; ``-`` where ``b`` is 0 (a job too short for Snakemake's CPU sampling)."""
    return f"{a / b:.2f}x" if b > 0 else "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--sections", default="E1,C1")
    ap.add_argument("--sites-per-section", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--cores", type=int, default=2)
    a = ap.parse_args()
    sections = a.sections.split(",")
    sites = sites_of(sections, a.sites_per_section)
    print(f"load average before: {os.getloadavg()}; sites: {', '.join(sites)}; cores {a.cores}")
    per_job = {m: {r: [] for r in RULES} for m in ("default", "retained")}
    digests = {}
    for rep in range(a.repeats):
        for mode in ("default", "retained") if rep % 2 == 0 else ("retained", "default"):
            wd = a.workdir / f"{mode}-{rep}"
            run_mode(wd, mode, sections, a.sites_per_section, sites, a.cores)
            for rule, cpu in cpu_by_rule(wd).items():
                per_job[mode][rule].append(statistics.fmean(cpu))
            digests[(mode, rep)] = digest(wd, sites)
            print(f"  repeat {rep} {mode}: done", flush=True)
    same = all(d == digests[("default", 0)] for d in digests.values())
    print(f"load average after: {os.getloadavg()}")
    print("\n| rule | CPU s per job, glibc and NumPy defaults | with scan_process_memory | ratio |")
    print("|---|---|---|---|")
    tot_d = tot_r = 0.0
    for rule in RULES:
        d, r = per_job["default"][rule], per_job["retained"][rule]
        if not d or not r:
            continue
        md, mr = statistics.median(d), statistics.median(r)
        n = 1 if rule == "validate_campaign" else len(sites)
        tot_d += md * n
        tot_r += mr * n
        print(f"| {rule} | {md:.2f} | {mr:.2f} | {_ratio(md, mr)} |")
    print(f"| all jobs of the {len(sites)} sites | {tot_d:.1f} | {tot_r:.1f} | {_ratio(tot_d, tot_r)} |")
    print(f"\noutputs byte-identical across modes and repeats ({len(digests[('default', 0)])} files): {same}")
    if not same:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
