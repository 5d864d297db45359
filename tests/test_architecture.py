"""The shape of the library: no import circles in ``src/skidsim``, low floors that do not reach up, and no function
over 150 lines (docs/architecture.md).

The import graph is built from the source (``ast``), not by importing: every ``import`` and ``from ... import``
of a ``skidsim`` module anywhere in a file (at the top or inside a function; those under ``if TYPE_CHECKING:`` are
left out, they never run) is an edge to the most specific module it names.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

#: The longest function allowed in ``src/`` (lines from ``def`` to the last line of its body).
MAX_FUNCTION_LINES = 150
#: Allowances above MAX_FUNCTION_LINES: none. (The explicit solver's time loop, once one 200-line ``_simulate``, is a
#: preload and a slide loop around ``_step``, every function under 150 lines.) Nothing may be added here.
LONG_FUNCTIONS: dict[str, int] = {}


def _modules(src: Path) -> dict[str, tuple[Path, bool]]:
    """``{dotted name: (file, is a package)}`` for every module under ``src/skidsim``."""
    out = {}
    for path in sorted((src / "skidsim").rglob("*.py")):
        parts = list(path.relative_to(src).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        if is_pkg:
            parts = parts[:-1]
        out[".".join(parts)] = (path, is_pkg)
    return out


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for n in ast.walk(node))
    return skip


def _targets(module: str, is_pkg: bool, node: ast.Import | ast.ImportFrom, known) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if node.level:
        base = module.split(".") if is_pkg else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    return [f"{target}.{a.name}" if f"{target}.{a.name}" in known else target for a in node.names]


def import_graph(src: Path = SRC) -> dict[str, set[str]]:
    """``{module: the skidsim modules it imports}`` from the source under ``src``."""
    mods = _modules(src)
    graph: dict[str, set[str]] = {}
    for name, (path, is_pkg) in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        skip = _type_checking_nodes(tree)
        edges: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in skip:
                for target in _targets(name, is_pkg, node, mods):
                    while target not in mods and "." in target:
                        target = target.rsplit(".", 1)[0]
                    if target in mods and target != name:
                        edges.add(target)
        graph[name] = edges
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (each an import circle), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for w in graph[todo.pop()]:
            if w not in seen:
                seen.add(w)
                todo.append(w)
    return seen


def _walk_functions(node: ast.AST, prefix: str, rel: str, out: dict[str, int]) -> None:
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
            name = f"{prefix}{child.name}"
            out[f"{rel}:{name}"] = child.end_lineno - child.lineno + 1
            _walk_functions(child, f"{name}.", rel, out)
        elif isinstance(child, ast.ClassDef):
            _walk_functions(child, f"{prefix}{child.name}.", rel, out)


def function_lengths(src: Path = SRC) -> dict[str, int]:
    """``{"skidsim/path.py:qualified.name": lines}`` of every function and method under ``src/skidsim``."""
    out: dict[str, int] = {}
    for path in sorted((src / "skidsim").rglob("*.py")):
        _walk_functions(ast.parse(path.read_text(encoding="utf-8")), "", path.relative_to(src).as_posix(), out)
    return out


def test_graph_builder_sees_relative_absolute_and_function_level_imports(tmp_path):
    pkg = tmp_path / "skidsim"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from . import b\n")
    (pkg / "b.py").write_text("def f():\n    from skidsim.sub.c import g\n")
    (pkg / "sub" / "__init__.py").write_text("from .c import g\n")
    (pkg / "sub" / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..a import x\nfrom .. import errors\n"
    )
    graph = import_graph(tmp_path)
    assert graph["skidsim.a"] == {"skidsim.b"}
    assert graph["skidsim.b"] == {"skidsim.sub.c"}
    assert graph["skidsim.sub"] == {"skidsim.sub.c"}
    assert graph["skidsim.sub.c"] == {"skidsim"}  # the TYPE_CHECKING import is no edge; `errors` is no module here
    assert import_cycles(graph) == []
    (pkg / "sub" / "c.py").write_text("def h():\n    from skidsim.a import x\n")
    assert import_cycles(import_graph(tmp_path)) == [["skidsim.a", "skidsim.b", "skidsim.sub.c"]]


def test_no_import_circles_in_skidsim():
    cycles = import_cycles(import_graph())
    assert cycles == [], "import circles (each a set of modules that import each other): " + "; ".join(
        " <-> ".join(c) for c in cycles
    )


@pytest.mark.parametrize("low", ["skidsim.config", "skidsim.campaign", "skidsim.errors", "skidsim.options"])
def test_low_floors_do_not_reach_up(low):
    """The config reader and the campaign directory are read by every stage: they never import the stages that
    read them (regression, calibration, criticism, the workflow's fan-in)."""
    graph = import_graph()
    up = sorted(
        m
        for m in reachable(graph, low)
        if m.split(".")[1:2] in (["regression"], ["calibration"], ["criticism"], ["plotting"])
    )
    assert up == [], f"{low} imports (directly or through other modules) {up}"


def test_function_length_walk_counts_methods_and_nested(tmp_path):
    pkg = tmp_path / "skidsim"
    pkg.mkdir()
    (pkg / "m.py").write_text("class K:\n    def f(self):\n        def g():\n            pass\n\n        return 1\n")
    assert function_lengths(tmp_path) == {"skidsim/m.py:K.f": 5, "skidsim/m.py:K.f.g": 2}


def test_no_function_over_150_lines():
    lengths = function_lengths()
    too_long = {name: n for name, n in sorted(lengths.items()) if n > LONG_FUNCTIONS.get(name, MAX_FUNCTION_LINES)}
    assert too_long == {}, f"functions over {MAX_FUNCTION_LINES} lines (or over their allowance): {too_long}"
