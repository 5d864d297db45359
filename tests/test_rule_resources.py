"""Every rule's resources against docs/cluster.md's table (section 5), without SLURM.

The rules come from Snakemake's own API (the workflow parsed with the default config, nothing run), in a
subprocess so that Snakemake's logging and global state stay out of the test process. ``tests/test_slurm.py``
compares the same table with what a real SLURM granted.
"""

from __future__ import annotations

import functools
import json
import re
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
CLUSTER_DOC = ROOT / "docs" / "cluster.md"

#: Parses the workflow and prints {rule: [threads, mem_mb, runtime, local, has a benchmark file]} as JSON.
_RULES_SCRIPT = r"""
import json, sys, tempfile
from pathlib import Path
from snakemake.api import SnakemakeApi
from snakemake.settings.types import ConfigSettings, OutputSettings, ResourceSettings, StorageSettings

root = Path(sys.argv[1])
with tempfile.TemporaryDirectory() as wd, SnakemakeApi(OutputSettings(quiet=True)) as api:
    wf = api.workflow(
        resource_settings=ResourceSettings(cores=2),
        config_settings=ConfigSettings(configfiles=[root / "config" / "config.yaml"]),
        storage_settings=StorageSettings(),
        snakefile=root / "Snakefile",
        workdir=Path(wd),
    )._workflow
    local = set(wf._localrules)

    def value(rule, key):
        try:
            return rule.resources[key].value
        except KeyError:
            return None

    out = {
        r.name: [value(r, "_cores"), value(r, "mem_mb"), value(r, "runtime"), r.name in local, r.benchmark is not None]
        for r in wf.rules
    }
print("RULES " + json.dumps(out))
"""


def resource_table(text: str | None = None) -> dict[str, tuple[int, int, int]]:
    """docs/cluster.md's table of what each SLURM job asks: job (rule or group) -> (CPUs, MB, minutes)."""
    text = CLUSTER_DOC.read_text() if text is None else text
    block = text.split("<!-- resources-table -->")[1].strip("\n").split("\n\n")[0]  # the table, to its blank line
    table = {}
    for m in re.finditer(r"^\| `(\w+)`[^|]*\| (\d+) \| (\d+) \| (\d+) \|", block, flags=re.M):
        assert m.group(1) not in table, f"two rows for {m.group(1)}"
        table[m.group(1)] = tuple(int(x) for x in m.group(2, 3, 4))
    return table


def declared_rules() -> dict[str, tuple[int | None, int | None, int | None, bool]]:
    """``{rule: (threads, mem_mb, runtime in min, runs locally)}`` of the workflow, from Snakemake's API."""
    return {k: v[:4] for k, v in _parsed_rules().items()}


@functools.cache
def _parsed_rules() -> dict[str, tuple]:
    """``{rule: (threads, mem_mb, runtime in min, runs locally, has a benchmark file)}`` (parsed once)."""
    r = subprocess.run(
        [sys.executable, "-c", _RULES_SCRIPT, str(ROOT)], capture_output=True, text=True, cwd=ROOT, timeout=300
    )
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("RULES ")]
    assert r.returncode == 0 and line, (r.stdout[-2000:], r.stderr[-3000:])
    return {k: tuple(v) for k, v in json.loads(line[0][len("RULES ") :]).items()}


def _profile_groups() -> set[str]:
    cfg = yaml.safe_load((ROOT / "profiles" / "slurm" / "config.yaml").read_text())
    return set((cfg.get("groups") or {}).values())


def table_drifts(table: dict, rules: dict, groups: set[str]) -> list[str]:
    """Each disagreement between the table and the rules, in words."""
    jobs = {name: res for name, res in rules.items() if not res[3]}
    out = []
    for name, (threads, mem, runtime, _) in sorted(jobs.items()):
        if name not in table:
            out.append(f"rule {name} ({threads} CPUs, {mem} MB, {runtime} min) has no row")
        elif table[name] != (threads, mem, runtime):
            out.append(f"rule {name} declares {(threads, mem, runtime)}, its row says {table[name]}")
    for name in sorted(set(table) - set(jobs) - groups):
        why = "runs locally" if name in rules else "is no rule or group"
        out.append(f"row {name} {why}")
    return out


def test_every_rule_has_the_resources_of_its_row():
    rules = declared_rules()
    assert {"calibrate", "report_gallery", "despeckle", "all"} <= set(rules)
    assert rules["calibrate"][:3] == (1, 1500, 120)
    assert rules["all"][3] and not rules["calibrate"][3]
    drifts = table_drifts(resource_table(), rules, _profile_groups())
    assert drifts == [], "docs/cluster.md's resources table and the rules differ:\n" + "\n".join(drifts)


def test_the_comparison_names_each_kind_of_drift():
    text = (
        "<!-- resources-table -->\n| job | CPUs | mem (MB) | time limit (min) | granted |\n|---|---|---|---|---|\n"
        "| `a` (3 jobs) | 1 | 1500 | 10 | x |\n| `b` | 2 | 500 | 5 | x |\n| `g` (group) | 2 | 4500 | 30 | x |\n"
        "| `gone` | 1 | 1 | 1 | x |\n| `loc` | 1 | 1 | 1 | x |\n\nprose | `z` | 1 | 1 | 1 |\n"
    )
    table = resource_table(text)
    assert table == {"a": (1, 1500, 10), "b": (2, 500, 5), "g": (2, 4500, 30), "gone": (1, 1, 1), "loc": (1, 1, 1)}
    rules = {"a": (1, 1500, 10, False), "b": (2, 1000, 5, False), "c": (1, 1000, 10, False), "loc": (1, 1, 1, True)}
    assert table_drifts(table, rules, {"g"}) == [
        "rule b declares (2, 1000, 5), its row says (2, 500, 5)",
        "rule c (1 CPUs, 1000 MB, 10 min) has no row",
        "row gone is no rule or group",
        "row loc runs locally",
    ]


def test_every_job_writes_a_benchmark_table():
    """Every rule that runs as a job (not a local rule) has a ``benchmark:`` file under ``benchmarks/out/``, so
    that the time and memory of every stage of a run can be summed (issue 36)."""
    missing = sorted(name for name, v in _parsed_rules().items() if not v[3] and not v[4])
    assert "calibrate" in _parsed_rules() and _parsed_rules()["calibrate"][4]
    assert missing == [], f"rules without a benchmark: file: {missing}"
