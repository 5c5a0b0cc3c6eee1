"""The README is a newcomer's door: short, naming the two set-up commands, every link alive.

``.ci/run`` runs ``make test`` and the Makefile's header points to the README for both commands,
so the README must name them exactly; its relative links must lead to files that exist (the
measurement history, design notes and changelog live behind them).
"""

import re
from pathlib import Path
from urllib.parse import unquote

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_LINES = 300

#: Markdown links ``[text](target)``; images ``![alt](target)`` too.
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def relative_targets(text: str) -> list[str]:
    """The link targets of ``text`` that point into the repository (no scheme, no bare anchor)."""
    targets = []
    for target in LINK.findall(text):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
            continue
        targets.append(unquote(target.split("#", 1)[0]))
    return targets


def test_readme_is_short():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_LINES, f"README.md has {len(lines)} lines (at most {MAX_LINES}): move detail to docs/"


def test_readme_names_both_commands():
    text = README.read_text(encoding="utf-8")
    for command in ("make main", "make test"):
        assert re.search(rf"^{command}\b", text, re.M), f"README.md does not show `{command}` as a command line"


def test_readme_links_point_to_files():
    targets = relative_targets(README.read_text(encoding="utf-8"))
    assert targets, "README.md links to nothing in the repository"
    missing = [t for t in targets if not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"


def test_relative_targets_reads_links():
    text = "[a](docs/x.md#y) ![b](img.png) [c](https://x.org) [d](#top) [e](data/)"
    assert relative_targets(text) == ["docs/x.md", "img.png", "data/"]
