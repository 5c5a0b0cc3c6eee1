"""The figures docs/architecture.md states, computed from the code.

``tests/test_docs_figures.py`` fails when the document and the code differ, so a figure there is
either one of these or absent. Run from the repository root::

    .venv/bin/python scripts/architecture_figures.py          # the figures, and what the doc lacks
    .venv/bin/python scripts/architecture_figures.py --write  # rewrite the doc's generated table

What is computed, reading the source with ``ast`` (nothing of the package is imported, so no JAX):

* the table of modules over the line limit, with the reason ``tests/test_structure.py`` gives each
  (the only part of the doc this script writes, between :data:`BEGIN` and :data:`END`);
* every sentence of :func:`phrases`: import cycles between modules and between packages at the three
  levels of ``tests/test_structure.py``, the registered laws and their families (from the stored
  law catalogue while it is current, else from the registry in a fresh process), the
  :class:`~bayesfric.errors.UserError` subclasses, the ``raise ValueError`` left, the limits of
  ``tests/test_structure.py`` and the constants of the code the doc names by value;
* the modules the doc does not name (:func:`unnamed_modules`): a module added without its line
  in the doc fails too.

Current sizes (lines per module, the longest functions) are printed, not kept in the doc: they
change with every edit.
"""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "bayesfric"
DOC = REPO / "docs" / "architecture.md"
BEGIN = "<!-- begin: long modules, written by scripts/architecture_figures.py -->"
END = "<!-- end: long modules -->"
LEVELS = ("at import time", "with function-local imports", "with `TYPE_CHECKING` imports")

if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))
from tests import test_structure as structure  # noqa: E402 -- the repository root first


def _read(rel: str) -> ast.Module:
    return ast.parse((PACKAGE / rel).read_text(encoding="utf-8"))


def constant(rel: str, name: str) -> Any:
    """The value of a module-level ``name = <arithmetic of numbers>`` in ``bayesfric/<rel>``, or of
    ``Class.field`` (a dataclass field's default); a dict of such values too."""
    owner, _, field = name.rpartition(".")
    body = _read(rel).body
    if owner:
        body = next(n for n in body if isinstance(n, ast.ClassDef) and n.name == owner).body
    for node in body:
        target = node.target if isinstance(node, ast.AnnAssign) else (
            node.targets[0] if isinstance(node, ast.Assign) else None)
        if isinstance(target, ast.Name) and target.id == (field or name) and node.value is not None:
            return eval(compile(ast.Expression(node.value), rel, "eval"), {"__builtins__": {}})  # literals only
    raise KeyError(f"{rel}: no {name}")


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else str(value)


def _power_of_two(value: float) -> str:
    exponent = int(value).bit_length() - 1
    assert 2**exponent == value, value
    return "2" + str(exponent).translate(str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹"))


def laws() -> tuple[int, int]:
    """(registered laws, families): from the stored catalogue while it describes the package,
    else built in a fresh process (a test process may have registered laws of its own)."""
    from bayesfric import lawcatalogue

    data = lawcatalogue._current()
    if data is None:
        code = "import json; from bayesfric import lawcatalogue; print(json.dumps(lawcatalogue.build()))"
        data = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                         cwd=REPO, check=True).stdout)
    return len(data["names"]), len({family for _, family in data["names"]})


def user_errors() -> list[str]:
    """Every subclass of :class:`bayesfric.errors.UserError` the package declares, sorted."""
    bases: dict[str, set[str]] = {}
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                bases[node.name] = {ast.unparse(b).rpartition(".")[2] for b in node.bases}
    found = {"UserError"}
    while grown := {name for name, of in bases.items() if of & found} - found:
        found |= grown
    return sorted(found - {"UserError"})


def raises_value_error() -> int:
    """``raise ValueError(...)`` statements in the package."""
    return sum(isinstance(n, ast.Raise) and n.exc is not None and
               ast.unparse(n.exc).split("(")[0] == "ValueError"
               for p in PACKAGE.rglob("*.py") for n in ast.walk(ast.parse(p.read_text(encoding="utf-8"))))


def cycles() -> tuple[list[int], list[int]]:
    """Import cycles between modules and between packages, at the three levels."""
    return ([len(structure._cycles(structure._graph(level))) for level in range(3)],
            [len(structure._cycles(structure._package_graph(level))) for level in range(3)])


def _counts(counts: list[int]) -> str:
    return ", ".join(f"{n} {level}" for n, level in zip(counts, LEVELS, strict=True))


def phrases() -> list[str]:
    """The sentences the doc must contain word for word (whitespace aside), each with figures of the
    code."""
    n_laws, n_families = laws()
    modules, packages = cycles()
    errors = user_errors()
    return [
        f"There are {n_laws} registered laws in {n_families} families",
        f"Import cycles between modules: {_counts(modules)}; between packages: {_counts(packages)}",
        f"No function has more than {structure.MAX_FUNCTION_CODE_LINES} lines of code",
        f"fails on a module over {structure.MAX_MODULE_LINES} lines",
        f"the {len(errors)} subclasses name the input: " + ", ".join(f"`{e}`" for e in errors),
        f"`raise ValueError` statements left in the package: {raises_value_error()}",
        f"chunks of {_number(constant('samplerconfig.py', 'CHUNK_STEPS'))} schedule rows",
        f"chains × draws × rows = {_power_of_two(constant('limits.py', 'FULL_NUMBERS'))}",
        f"condition number exceeds {_number(constant('inference/adaptation.py', 'DENSE_ABOVE'))}",
        f"a once-run program over a data set of at most {constant('exported.py', 'ONE_SHOT_ROWS')} rows (tables, "
        f"pointwise likelihood, checks' curves) at optimisation level "
        f"{constant('exported.py', 'ONE_SHOT')['xla_backend_optimization_level']}",
        f"R-hat of its halves ≤ {constant('inference/modes.py', 'ModeGate.chain_rhat_max')}",
        f"one mode within {constant('inference/modes.py', 'ModeGate.link')}, modes at least "
        f"{constant('inference/modes.py', 'ModeGate.separation')} apart",
    ]


def long_modules_table(indent: str = "   ") -> str:
    """The doc's table of the modules over the line limit, from ``tests/test_structure.py``, each
    line after the first indented by ``indent`` (the table sits in a list item)."""
    rows = [f"| `{module}` | {reason} |" for module, reason in sorted(structure.LONG_MODULES.items())]
    lines = ["", "| module | why it is long |", "| --- | --- |", *rows, "", END]
    return BEGIN + "".join("\n" + (indent + line if line else "") for line in lines)


def generated_block(text: str) -> str | None:
    """The part of ``text`` between :data:`BEGIN` and :data:`END`, both included."""
    match = re.search(re.escape(BEGIN) + r".*?" + re.escape(END), text, flags=re.S)
    return match.group(0) if match else None


def flat(text: str) -> str:
    """``text`` with every run of whitespace one space (a sentence may wrap across lines)."""
    return " ".join(text.split())


def unnamed_modules(text: str) -> list[str]:
    """Modules of the package the doc never names in backticks: as ``pkg.name``, ``pkg/name.py``,
    ``name`` alone, or as the start of a dotted name (``name.function``, ``pkg.name.function``)."""
    names = {" ".join(n.split()) for n in re.findall(r"`([^`]+)`", text)}  # a span may wrap
    starts = {re.split(r"[^\w./]", n, maxsplit=1)[0] for n in names}
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        if parts[-1] in ("__init__", "__main__"):
            continue
        dotted, slashed = ".".join(parts), "/".join(parts) + ".py"
        forms = {dotted, slashed, f"bayesfric.{dotted}", parts[-1], ".".join(parts[-2:])}
        if not any(s in forms or any(s.startswith(f + ".") for f in forms) for s in starts):
            out.append(slashed)
    return out


def sizes() -> list[str]:
    """Lines per module over 300, and the functions over 45 lines of code (for the reader, not the doc)."""
    lines = {p.relative_to(PACKAGE).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
             for p in PACKAGE.rglob("*.py")}
    out = [f"{len(lines)} modules, {sum(lines.values())} lines"]
    out += [f"  {n:5d}  {m}" for m, n in sorted(lines.items(), key=lambda kv: -kv[1]) if n > 300]
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and structure._code_lines(node) > 45:
                out.append(f"  function {path.relative_to(PACKAGE).as_posix()}:{node.name} "
                           f"{structure._code_lines(node)} lines of code")
    return out


def main(argv: list[str]) -> int:
    text = DOC.read_text(encoding="utf-8")
    if "--write" in argv:
        old = generated_block(text)
        if old is None:
            print(f"{DOC}: no {BEGIN!r} ... {END!r} block to write into", file=sys.stderr)
            return 1
        DOC.write_text(text.replace(old, long_modules_table()), encoding="utf-8")
        text = DOC.read_text(encoding="utf-8")
    print("\n".join(sizes()))
    problems = [f"missing: {p}" for p in phrases() if flat(p) not in flat(text)]
    problems += [f"not named: {m}" for m in unnamed_modules(text)]
    if generated_block(text) != long_modules_table():
        problems.append("the long-module table differs from tests/test_structure.py: run with --write")
    print("\n".join(problems) if problems else f"{DOC.relative_to(REPO)}: every figure matches the code")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
