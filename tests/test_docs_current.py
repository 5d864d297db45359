"""The documentation describes the current state: no temporary paths, no lab-notebook history.

Measured figures carry their date and commit instead ("measured 2026-11-23, commit 24584a4"); references to
rounds of work ("session 3", "the old code", "no longer", "before this change") and to paths that exist only on
one machine (/tmp/..., /work/..., /home/...) are refused, with the file, line and phrase of every hit.
"""

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"

#: Paths of one machine's scratch space or checkout.
TEMPORARY_PATH = re.compile(r"(?<![\w.~-])/(?:tmp|work|home)/")

#: Phrases of a lab notebook (case-insensitive); "history" as a data column (``*_history.parquet``) is fine.
HISTORY_PHRASES = [
    r"\bsessions?\b",
    r"\bprevious (?:session|run|try|tries|version|best)\b",
    r"\bearlier (?:session|run|runs|try|tries|version|versions|preset|measurements?)\b",
    r"\bthe old (?:code|version|definition|test|preset)\b",
    r"\bno longer\b",
    r"\bbefore this change\b",
    r"\bwas changed\b",
    r"\bwith the final code\b",
    r"\btried and rejected\b",
    r"^\*\*History\b",
]
HISTORY = re.compile("|".join(HISTORY_PHRASES), re.IGNORECASE | re.MULTILINE)


def _docs():
    files = sorted(DOCS.glob("*.md"))
    assert files, f"no Markdown files found in {DOCS}"
    return files


def _hits(pattern: re.Pattern, text: str) -> list[tuple[int, str]]:
    """(line number, matched text) of every match of ``pattern`` in ``text``."""
    return [(text.count("\n", 0, m.start()) + 1, m.group(0)) for m in pattern.finditer(text)]


@pytest.mark.parametrize("doc", _docs(), ids=lambda p: p.name)
def test_docs_name_no_temporary_path(doc):
    hits = _hits(TEMPORARY_PATH, doc.read_text(encoding="utf-8"))
    assert not hits, "\n".join(f"{doc.name}:{line}: temporary path {found!r}" for line, found in hits)


@pytest.mark.parametrize("doc", _docs(), ids=lambda p: p.name)
def test_docs_hold_no_history_of_earlier_work(doc):
    hits = _hits(HISTORY, doc.read_text(encoding="utf-8"))
    assert not hits, "\n".join(
        f"{doc.name}:{line}: history phrase {found!r} (describe the current state; "
        f"date and commit a measured figure instead)"
        for line, found in hits
    )


@pytest.mark.parametrize(
    "text, expected",
    [
        ("see /tmp/repro2/results", ["/tmp/"]),
        ("cd /work/main && make", ["/work/"]),
        ("in /home/me/data", ["/home/"]),
        ("results/tmp/x, a/work/b and ~/home/c", []),
    ],
)
def test_temporary_path_pattern(text, expected):
    assert [found for _, found in _hits(TEMPORARY_PATH, text)] == expected


@pytest.mark.parametrize(
    "text, named",
    [
        ("Session 5: the texture-adjusted test", True),
        ("the session-3 default run", True),
        ("agree with the old code to 4e-16", True),
        ("so drainage is no longer named", True),
        ("**History: null campaigns", True),
        ("the verification runs in its history", False),
        ("calibration_ours_history.parquet", False),
        ("measured 2026-11-23, commit 24584a4", False),
    ],
)
def test_history_pattern(text, named):
    assert bool(HISTORY.search(text)) is named
