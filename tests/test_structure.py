"""Structural checks of the package: no import cycle between modules nor between packages, no
function over 60 lines of code, no module over 400 lines without a reason stated here (and in
docs/architecture.md).

Lines of code of a function are its lines without its docstring: numpydoc docstrings with
runnable examples are asked for on every public function and are not what makes one hard to read.
The import graph is read with ``ast`` (nothing imported), at three levels: imports at module level,
plus imports inside functions, plus ``if TYPE_CHECKING:`` imports; a package's ``__init__`` counts
as imported when one of its submodules is imported from outside it. The package graph merges each
subpackage of bayesfric (``study``, ``report`` ...) into one node, a top-level module being its own:
a deferred import that only breaks a module cycle still closes a package cycle, and fails there.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "bayesfric"
MAX_FUNCTION_CODE_LINES = 60
MAX_MODULE_LINES = 400

#: Modules allowed above MAX_MODULE_LINES, with the reason (kept in step with docs/architecture.md).
LONG_MODULES = {
    "model.py": "Program and the fit's record of its program (the record may move to a module of its own)",
    "sizing/compute.py": "per-law predictive draws at the query points, required capacity and exceedance",
    "laws/hysteresis.py": "the Dahl, LuGre and GMS laws with their shared loop helpers, one family",
    "compare/checks.py": "the checks unit: prior predictive, LOO-PIT band and shape, power-scaling sensitivity",
    "laws/base.py": "the law declaration and its checks, its variants as methods, a trajectory law's Steady",
}
#: Functions allowed above MAX_FUNCTION_CODE_LINES, with the reason.
LONG_FUNCTIONS: dict[str, str] = {}


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        out[".".join(parts[:-1] if path.stem == "__init__" else parts)] = path
    return out


def _graph(level: int) -> dict[str, set[str]]:
    """Module -> package modules it imports at ``level`` (the script of docs/architecture.md)."""
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}

    def walk(m: str, node: ast.AST, depth: int) -> None:
        for ch in ast.iter_child_nodes(node):
            d = max(depth, 1) if isinstance(ch, ast.FunctionDef | ast.AsyncFunctionDef) else depth
            d = 2 if isinstance(ch, ast.If) and "TYPE_CHECKING" in ast.unparse(ch.test) else d
            if isinstance(ch, ast.ImportFrom) and d <= level and (ch.module or "").startswith("bayesfric"):
                subs = {f"{ch.module}.{a.name}" for a in ch.names} & mods.keys()
                graph[m] |= subs | ({ch.module} if len(subs) < len(ch.names) else set())
            elif isinstance(ch, ast.Import) and d <= level:
                graph[m] |= {a.name for a in ch.names}
            walk(m, ch, d)

    for m, path in mods.items():
        walk(m, ast.parse(path.read_text()), 0)
        for t in list(graph[m]):  # importing a.b.c runs a.b's __init__ too, unless m is inside a.b
            graph[m] |= {q for i in range(2, t.count(".") + 1) if not m.startswith(q := ".".join(t.split(".")[:i]))}
        graph[m] = {t for t in graph[m] if t in mods and t != m}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles of ``graph``: each set of modules that reach one another, sorted."""
    reach: dict[str, set[str]] = {}
    for start in graph:
        seen: set[str] = set()
        todo = list(graph[start])
        while todo:
            n = todo.pop()
            if n not in seen:
                seen.add(n)
                todo.extend(graph.get(n, ()))
        reach[start] = seen
    cycles = {tuple(sorted(x for x in graph if x in reach[m] and m in reach[x])) for m in graph if m in reach[m]}
    return [list(c) for c in sorted(cycles)]


@pytest.mark.parametrize("level", [0, 1, 2], ids=["import time", "+ function-local", "+ TYPE_CHECKING"])
def test_no_import_cycle(level):
    assert _cycles(_graph(level)) == []


def _package_graph(level: int) -> dict[str, set[str]]:
    """Subpackage (or top-level module) -> those it imports at ``level``: bayesfric.study.runner
    and bayesfric.study.tree are both ``study``."""
    def node(module: str) -> str:
        return module.split(".")[1] if "." in module else module

    graph: dict[str, set[str]] = {}
    for module, targets in _graph(level).items():
        graph.setdefault(node(module), set()).update(node(t) for t in targets if node(t) != node(module))
    return graph


@pytest.mark.parametrize("level", [0, 1, 2], ids=["import time", "+ function-local", "+ TYPE_CHECKING"])
def test_no_package_cycle(level):
    assert _cycles(_package_graph(level)) == []


def test_the_package_graph_merges_a_package():
    graph = _package_graph(1)
    assert "report" in graph["pipeline"] and "study" in graph["report"]
    assert "pipeline" not in graph["study"] | graph["report"]


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def _code_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    total = node.end_lineno - node.lineno + 1
    first = node.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        total -= first.end_lineno - first.lineno + 1
    return total


def test_no_function_over_sixty_lines_of_code():
    long = {}
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and \
                    _code_lines(node) > MAX_FUNCTION_CODE_LINES:
                long[f"{path.relative_to(PACKAGE).as_posix()}:{node.name}"] = _code_lines(node)
    assert set(long) <= set(LONG_FUNCTIONS), {k: v for k, v in long.items() if k not in LONG_FUNCTIONS}


def test_no_module_over_four_hundred_lines_without_a_reason():
    long = {path.relative_to(PACKAGE).as_posix(): len(path.read_text().splitlines())
            for path in PACKAGE.rglob("*.py")}
    long = {k: n for k, n in long.items() if n > MAX_MODULE_LINES}
    assert set(long) <= set(LONG_MODULES), {k: v for k, v in long.items() if k not in LONG_MODULES}
    stale = set(LONG_MODULES) - set(long)
    assert not stale, f"no longer over {MAX_MODULE_LINES} lines: drop their reasons {sorted(stale)}"
