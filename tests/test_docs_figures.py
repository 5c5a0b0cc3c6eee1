"""docs/architecture.md states no figure the code does not give: each is computed by
``scripts/architecture_figures.py`` (run it to see what differs; ``--write`` rewrites the doc's
generated table), and every module of the package is named there."""

from __future__ import annotations

import importlib.util
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("architecture_figures", REPO / "scripts" / "architecture_figures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


figures = _script()
TEXT = figures.DOC.read_text(encoding="utf-8")
HINT = "run `.venv/bin/python scripts/architecture_figures.py` and update docs/architecture.md"


def test_every_figure_of_the_doc_is_the_code_s():
    missing = [p for p in figures.phrases() if figures.flat(p) not in figures.flat(TEXT)]
    assert not missing, f"{HINT}; not in the doc: {missing}"


def test_the_long_module_table_is_generated():
    assert figures.generated_block(TEXT) == figures.long_modules_table(), \
        "run `.venv/bin/python scripts/architecture_figures.py --write`"


def test_every_module_is_named_in_the_doc():
    assert figures.unnamed_modules(TEXT) == [], f"{HINT}: place each module in the layer table or the flow"


def test_the_figures_are_read_from_the_code():
    assert figures.constant("samplerconfig.py", "CHUNK_STEPS") > 0
    assert figures.constant("inference/modes.py", "ModeGate.separation") > figures.constant(
        "inference/modes.py", "ModeGate.link")
    assert "UsageError" in figures.user_errors() and "InternalError" not in figures.user_errors()
    assert figures.unnamed_modules("`model` `laws.base`") and "model.py" not in figures.unnamed_modules("`model`")
    assert figures.flat("a\n   b") == "a b"
