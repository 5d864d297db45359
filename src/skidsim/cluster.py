"""What a SLURM cluster offers and what it granted, read from its own tools (``sinfo``, ``scontrol``, ``sacct``).

Used by the SLURM test (tests/test_slurm.py) and by ``python -m skidsim.cluster caps`` (docs/cluster.md), which
prints the ``--cores``/``--resources mem_mb=`` caps under which Snakemake stacks a group job's members in series
so that the group fits one node (a group asking for more than any node has pends forever in SLURM, reason
``PartitionConfig``). The parsers are pure functions of the tools' text output.
"""

from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import dataclass

from skidsim.errors import SkidsimError

#: SLURM memory units in MB (sinfo/scontrol print e.g. 4500M, 2G).
_MEM_UNITS_MB = {"K": 1 / 1024, "M": 1, "G": 1024, "T": 1024 * 1024}


class ClusterError(SkidsimError):
    """A SLURM tool failed or printed something this module cannot read."""


@dataclass(frozen=True)
class Node:
    name: str
    cpus: int
    mem_mb: int  #: RealMemory (MB) of the node


@dataclass(frozen=True)
class Grant:
    """What SLURM granted one job (``scontrol show job`` or ``sacct``)."""

    job_id: str
    state: str
    cpus: int
    mem_mb: int
    time_limit_min: int | None  #: None: no limit
    comment: str  #: the executor plugin's "rule_<rule>_wildcards_<values>"


def mem_to_mb(text: str, what: str = "memory") -> int:
    """'4500M' / '2G' / '1500' (MB) -> MB."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)([KMGT]?)[n c]?\s*", text)
    if not m:
        raise ClusterError(f"{what}: expected a SLURM memory size such as 4500M or 2G, found {text!r}")
    return int(round(float(m.group(1)) * _MEM_UNITS_MB[m.group(2) or "M"]))


def time_to_min(text: str, what: str = "time limit") -> int | None:
    """SLURM time limit '[days-]hours:minutes:seconds', 'minutes:seconds' or 'UNLIMITED' -> minutes (None)."""
    text = text.strip()
    if text.upper() in ("UNLIMITED", "INFINITE"):
        return None
    m = re.fullmatch(r"(?:(\d+)-)?(\d+)(?::(\d+))?(?::(\d+))?", text)
    if not m:
        raise ClusterError(f"{what}: expected a SLURM time such as 1:30:00 or 2-00:00:00, found {text!r}")
    days = int(m.group(1) or 0)
    parts = [int(p) for p in m.group(2, 3, 4) if p is not None]
    if m.group(1) is not None or len(parts) == 3:  # [d-]h:m:s
        h, mi, s = (parts + [0, 0])[:3]
    elif len(parts) == 2:  # m:s
        h, mi, s = 0, parts[0], parts[1]
    else:  # minutes
        h, mi, s = 0, parts[0], 0
    return days * 1440 + h * 60 + mi + (1 if s else 0)


def parse_sinfo_nodes(text: str) -> list[Node]:
    """Lines of ``sinfo -h -N -o '%N|%c|%m'`` -> nodes (a node in several partitions is listed once)."""
    nodes = {}
    for line in text.splitlines():
        if not line.strip():
            continue
        fields = line.strip().split("|")
        if len(fields) != 3:
            raise ClusterError(f"sinfo: expected 'node|cpus|memory' lines, found {line!r}")
        name, cpus, mem = fields
        nodes[name] = Node(name, int(cpus.rstrip("+")), mem_to_mb(mem.rstrip("+"), f"sinfo memory of {name}"))
    return list(nodes.values())


def parse_scontrol_job(text: str) -> Grant:
    """One-line ``scontrol -o show job ID`` -> Grant. CPUs and memory from the allocated TRES (cpu=, mem=)."""
    fields = dict(re.findall(r"(\w+(?::\w+)?)=(\S*)", text))
    for key in ("JobId", "JobState", "NumCPUs", "TimeLimit"):
        if key not in fields:
            raise ClusterError(f"scontrol show job: no field {key} in {text[:200]!r}")
    tres = dict(kv.split("=", 1) for kv in fields.get("TRES", "").split(",") if "=" in kv)
    mem = tres.get("mem") or fields.get("MinMemoryNode")
    if mem is None:
        raise ClusterError(f"scontrol show job {fields['JobId']}: neither TRES mem= nor MinMemoryNode")
    return Grant(
        job_id=fields["JobId"],
        state=fields["JobState"],
        cpus=int(tres.get("cpu", fields["NumCPUs"])),
        mem_mb=mem_to_mb(mem, f"memory of job {fields['JobId']}"),
        time_limit_min=time_to_min(fields["TimeLimit"]),
        comment=fields.get("Comment", ""),
    )


def parse_sacct(text: str) -> list[Grant]:
    """``sacct -X -P -n -o JobIDRaw,State,AllocCPUS,ReqMem,Timelimit,Comment`` -> grants."""
    grants = []
    for line in text.splitlines():
        if not line.strip():
            continue
        f = line.split("|")
        if len(f) < 6:
            raise ClusterError(f"sacct: expected 6 '|'-separated fields, found {line!r}")
        grants.append(
            Grant(
                job_id=f[0],
                state=f[1].split()[0],
                cpus=int(f[2]),
                mem_mb=mem_to_mb(f[3], f"sacct ReqMem of job {f[0]}"),
                time_limit_min=time_to_min(f[4]),
                comment="|".join(f[5:]),
            )
        )
    return grants


def rule_of(comment: str) -> str:
    """The executor plugin's job comment 'rule_<rule>[_wildcards_<values>]' -> rule name; a group job's
    'rule_<group>_<members...>' -> the group's name is left to the caller (returned whole, without 'rule_')."""
    if not comment.startswith("rule_"):
        raise ClusterError(f"job comment {comment!r}: expected 'rule_<rule>...' as the SLURM executor writes it")
    return comment[len("rule_") :].split("_wildcards_")[0]


def _run(cmd: list[str]) -> str:
    try:
        return subprocess.run(cmd, capture_output=True, text=True, check=True, timeout=60).stdout
    except FileNotFoundError as e:
        raise ClusterError(f"{cmd[0]}: not installed (SLURM client tools are needed)") from e
    except subprocess.CalledProcessError as e:
        raise ClusterError(f"{' '.join(cmd)} failed ({e.returncode}): {e.stderr.strip()}") from e


def nodes() -> list[Node]:
    return parse_sinfo_nodes(_run(["sinfo", "-h", "-N", "-o", "%N|%c|%m"]))


def granted(job_id: str) -> Grant:
    """What SLURM granted a job that is queued, running, or finished less than MinJobAge ago."""
    return parse_scontrol_job(_run(["scontrol", "-o", "show", "job", str(job_id)]))


def granted_sacct(job_ids: list[str]) -> list[Grant]:
    """The same from the accounting database (needs slurmdbd)."""
    return parse_sacct(
        _run(
            [
                "sacct",
                "-X",
                "-P",
                "-n",
                "-j",
                ",".join(job_ids),
                "-o",
                "JobIDRaw,State,AllocCPUS,ReqMem,Timelimit,Comment%200",
            ]
        )
    )


def caps(node_list: list[Node]) -> tuple[int, int]:
    """(CPUs, MB) of the smallest node: caps under which every group job fits any node."""
    if not node_list:
        raise ClusterError("sinfo lists no node")
    return min(n.cpus for n in node_list), min(n.mem_mb for n in node_list)


def main(argv: list[str]) -> int:
    if argv[:1] != ["caps"]:
        print(
            "usage: python -m skidsim.cluster caps   # prints --cores N --resources mem_mb=M for snakemake",
            file=sys.stderr,
        )
        return 2
    cpus, mem = caps(nodes())
    print(f"--cores {cpus} --resources mem_mb={mem}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
