"""Bad-input corpus of the data loader: every case through ``data check`` and through ``fit``.

Each case is a small CSV (text or raw bytes) and a sidecar made from ``BASE_META`` by edits; the
harness asserts the bad-input contract (exit 2, one line naming the place, no traceback, the tree
unchanged). The ``fit`` runs fail while loading, before any sampling, so they stay fast.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.hostile.harness import assert_user_error

BASE_META = """\
[dataset]
name = "bench"
provenance = "measured"
source = "corpus"

[columns.speed]
role = "input"
quantity = "velocity"
unit = "rpm"

[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"

[columns.series]
role = "group"
"""
GOOD = "speed,torque,series\n60,1.5,a\n-120,-2.0,b\n"
HEADER = "speed,torque,series"
NO_SIDECAR = "<no sidecar>"
FOLDER = "<a folder>"
FIFO = "<a named pipe>"


def make(path: Path, content: str | bytes) -> None:
    """Create ``path`` as a folder, a named pipe, or a file with ``content`` (text is UTF-8)."""
    if content == FOLDER:
        path.mkdir()
    elif content == FIFO:
        os.mkfifo(path)
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")


def column(name: str, role: str, quantity: str | None = None, unit: str | None = None) -> str:
    """A ``[columns.<name>]`` table to append to the sidecar."""
    text = f'\n[columns.{name}]\nrole = "{role}"\n'
    text += f'quantity = "{quantity}"\n' if quantity else ""
    return text + (f'unit = "{unit}"\n' if unit else "")


def dataset_key(line: str) -> tuple[str, str]:
    """An edit that adds ``line`` to ``[dataset]``."""
    return ('source = "corpus"\n', f'source = "corpus"\n{line}\n')


TEMP_K = column("temp", "input", "temperature", "K")
TIME = column("t", "input", "time", "s")
TRAJ = dataset_key('trajectory = "series"')


@dataclass(frozen=True)
class Case:
    """One bad input: CSV content, sidecar edits and the fragments the message must contain."""

    id: str
    csv: str | bytes
    mentions: tuple[str, ...]
    edits: tuple[tuple[str, str], ...] = ()
    extra: str = ""
    meta: str | bytes | None = None  # whole sidecar instead of BASE_META + edits + extra

    def write(self, root: Path) -> None:
        make(root / "bench.csv", self.csv)
        meta = self.meta
        if meta is None:
            meta = BASE_META
            for old, new in self.edits:
                assert old in meta, (self.id, old)
                meta = meta.replace(old, new)
            meta += self.extra
        if meta != NO_SIDECAR:
            make(root / "bench.toml", meta)


CASES = [
    # -- encodings
    Case("csv-latin1-without-key", f"{HEADER}\n60,1.5,a\n60,1.5,caf\xe9\n".encode("latin-1"),
         ("bench.csv", "not UTF-8", "line 3", "byte 39", "0xe9", 'encoding = "', "[dataset]", "bench.toml")),
    Case("csv-latin1-degree-in-header", "speed,torque,series,temp \xb0C\n60,1.5,a,20\n".encode("latin-1"),
         ("bench.csv", "not UTF-8", "line 1", "0xb0", "bench.toml")),
    Case("csv-utf16-from-excel", "speed\ttorque\tseries\n60\t1.5\ta\n".encode("utf-16"),
         ("bench.csv", "not UTF-8", "line 1", "byte 0", 'encoding = "utf-16"', "bench.toml")),
    Case("encoding-unknown-codec", GOOD, ("bench.toml", "[dataset] encoding", "'klingon'"),
         edits=(dataset_key('encoding = "klingon"'),)),
    Case("encoding-not-a-text-codec", GOOD, ("bench.toml", "[dataset] encoding", "'rot13'"),
         edits=(dataset_key('encoding = "rot13"'),)),
    Case("encoding-not-a-string", GOOD, ("bench.toml", "[dataset]", "encoding must be a string"),
         edits=(dataset_key("encoding = 1252"),)),
    Case("encoding-wrong-codec", f"{HEADER}\n60,1.5,a\n60,1.5,\xb0\n".encode("latin-1"),
         ("bench.csv", "'ascii'", "line 3", "bench.toml"), edits=(dataset_key('encoding = "ascii"'),)),
    Case("encoding-latin1-but-utf8-bom", b"\xef\xbb\xbf" + GOOD.encode(),
         ("bench.csv", "byte-order mark", "encoding = 'latin-1'", "bench.toml"),
         edits=(dataset_key('encoding = "latin-1"'),)),
    Case("sidecar-not-utf8", GOOD, ("bench.toml", "not UTF-8", "line 4", "must be UTF-8"),
         meta=BASE_META.replace("corpus", "Pr\xfcfstand").encode("latin-1")),
    # -- header and column names
    Case("duplicate-column", "speed,torque,series,torque\n60,1.5,a,2\n",
         ("bench.csv", "column 'torque'", "columns 2 and 4")),
    Case("header-cell-empty-where-named", "speed,,series\n60,1.5,a\n",
         ("bench.csv", "column 'torque'", "missing", "header cell 2 empty")),
    Case("missing-column", "speed,series\n60,a\n", ("bench.csv", "column 'torque'", "bench.toml", "missing")),
    Case("sidecar-column-name-empty", GOOD, ("bench.toml", "empty"), extra=column('""', "aux")),
    Case("sidecar-column-name-whitespace", GOOD, ("bench.toml", "column ' speed'", "whitespace"),
         edits=(("[columns.speed]", '[columns." speed"]'),)),
    Case("two-columns-one-name", "speed,torque,velocity\n60,1.5,a\n", ("bench.toml", "'velocity'", "'speed'"),
         edits=(("[columns.series]", "[columns.velocity]"),)),
    # -- cells
    Case("nan", f"{HEADER}\n60,nan,a\n", ("bench.csv", "row 1", "column 'torque'", "non-finite")),
    Case("inf", f"{HEADER}\n60,1,a\ninf,1,b\n", ("bench.csv", "row 2", "column 'speed'", "non-finite")),
    Case("non-numeric", f"{HEADER}\n60,1.5,a\n7o,2,b\n", ("bench.csv", "row 2", "column 'speed'", "'7o'")),
    Case("long-garbage-cell", f"{HEADER}\n60,1.5,a\n{'x' * 5000},2,b\n",
         ("bench.csv", "row 2", "column 'speed'", "...", "is not a number")),
    Case("ragged-row", f"{HEADER}\n60,1.5,a\n60,1.5\n", ("bench.csv", "row 2", "2 cells", "header has 3")),
    Case("empty-file", "", ("bench.csv", "empty")),
    Case("comments-only", "# nothing but a comment\n\n", ("bench.csv", "empty")),
    Case("header-only", f"{HEADER}\n", ("bench.csv", "no data rows")),
    Case("group-cell-empty", f"{HEADER}\n60,1.5,a\n60,1.5,\n", ("bench.csv", "row 2", "column 'series'", "empty")),
    Case("group-cell-blank", f"{HEADER}\n60,1.5,  \n", ("bench.csv", "row 1", "column 'series'", "empty")),
    Case("overflow-in-si", f"{HEADER}\n60,1e307,a\n", ("bench.csv", "row 1", "column 'torque'", "overflows"),
         edits=(('unit = "N*m"', 'unit = "MN*m"'),)),
    # -- physical bounds
    Case("temperature-below-absolute-zero", f"{HEADER},temp\n60,1.5,a,20\n60,1.5,b,-300\n",
         ("bench.csv", "row 2", "column 'temp'", "-26.85 K", "> 0 K"),
         extra=column("temp", "input", "temperature", "degC")),
    Case("temperature-negative-kelvin", f"{HEADER},temp\n60,1.5,a,-5\n", ("bench.csv", "row 1", "column 'temp'"),
         extra=TEMP_K),
    Case("temperature-zero-kelvin", f"{HEADER},temp\n60,1.5,a,300\n60,1.5,a,0\n",
         ("bench.csv", "row 2", "column 'temp'", "> 0 K"), extra=TEMP_K),
    Case("preload-negative", f"{HEADER},pre\n60,1.5,a,6\n60,1.5,a,-6\n",
         ("bench.csv", "row 2", "column 'pre'", "-26.6893 N", ">= 0 N"),
         extra=column("pre", "input", "preload", "lbf")),
    Case("radial-force-negative", f"{HEADER},fr\n60,1.5,a,-1\n", ("bench.csv", "row 1", "column 'fr'", ">= 0 N"),
         extra=column("fr", "input", "radial_force", "kN")),
    Case("axial-force-negative", f"{HEADER},fa\n60,1.5,a,-1\n", ("bench.csv", "row 1", "column 'fa'", ">= 0 N"),
         extra=column("fa", "input", "axial_force", "N")),
    Case("aux-time-negative", f"{HEADER},t\n60,1.5,a,0\n60,1.5,a,-1\n", ("bench.csv", "row 2", "column 't'", ">= 0 s"),
         extra=column("t", "aux", "time", "s")),
    # -- trajectories
    Case("trajectory-interleaved", f"{HEADER}\n60,1,a\n60,1,b\n60,1,a\n",
         ("bench.csv", "row 3", "column 'series'", "'a'", "reappears", "row 1"), edits=(TRAJ,)),
    Case("trajectory-time-repeats", f"{HEADER},t\n60,1,a,0\n60,1,a,1\n60,1,a,1\n",
         ("bench.csv", "row 3", "column 't'", "strictly increase"), edits=(TRAJ,), extra=TIME),
    Case("trajectory-time-decreases", f"{HEADER},t\n60,1,a,0\n60,1,a,2\n60,1,b,0\n60,1,b,3\n60,1,b,2.5\n",
         ("bench.csv", "row 5", "column 't'", "'b'"), edits=(TRAJ,), extra=TIME),
    Case("trajectory-not-a-group", GOOD, ("bench.toml", "trajectory", "'speed'", "not a group", "'input'"),
         edits=(dataset_key('trajectory = "speed"'),)),
    Case("trajectory-no-such-column", GOOD, ("bench.toml", "trajectory", "'run'", "no column"),
         edits=(dataset_key('trajectory = "run"'),)),
    # -- degenerate scales
    Case("response-near-1e-300", f"{HEADER}\n60,1e-300,a\n60,-2e-300,b\n",
         ("bench.csv", "column 'torque'", "2e-300", "below 1e-12")),
    Case("response-all-zero", f"{HEADER}\n60,0,a\n-60,0.0,b\n", ("bench.csv", "column 'torque'", "zero in every row")),
    Case("response-huge", f"{HEADER}\n60,1e300,a\n", ("bench.csv", "column 'torque'", "above 1e+12")),
    Case("input-subnormal", f"{HEADER}\n1e-310,1,a\n0,1,b\n", ("bench.csv", "column 'speed'", "below 1e-12")),
    # -- sidecar
    Case("no-sidecar", GOOD, ("bench.toml", "metadata file not found"), meta=NO_SIDECAR),
    Case("toml-syntax-error", GOOD, ("bench.toml", "invalid TOML", "line 7"),
         edits=(('role = "input"', 'role = input"'),)),
    Case("bad-provenance", GOOD, ("bench.toml", "provenance 'guessed'"),
         edits=(('provenance = "measured"', 'provenance = "guessed"'),)),
    Case("missing-source", GOOD, ("bench.toml", "[dataset]", "'source'"), edits=(('source = "corpus"\n', ""),)),
    Case("missing-role", GOOD, ("bench.toml", "column 'series'", "'role'"), edits=(('role = "group"', ""),)),
    Case("unknown-role", GOOD, ("bench.toml", "column 'series'", "'grouping'"),
         edits=(('role = "group"', 'role = "grouping"'),)),
    Case("two-responses", GOOD, ("bench.toml", "exactly one", "found 2"),
         edits=(('role = "input"', 'role = "response"'),)),
    Case("no-response", GOOD, ("bench.toml", "exactly one", "found 0"), edits=(('role = "response"', 'role = "aux"'),)),
    Case("response-not-a-response-quantity", GOOD, ("bench.toml", "column 'torque'", "a response must be"),
         edits=(('quantity = "torque"', 'quantity = "angle"'), ('unit = "N*m"', 'unit = "rad"'))),
    Case("unknown-quantity", GOOD, ("bench.toml", "column 'speed'", "quantity 'speeed'"),
         edits=(('quantity = "velocity"', 'quantity = "speeed"'),)),
    Case("unknown-unit", GOOD, ("bench.toml", "column 'speed'", "unknown unit"),
         edits=(('unit = "rpm"', 'unit = "furlong_per_quux"'),)),
    Case("wrong-dimension", GOOD, ("bench.toml", "column 'speed'", "dimension"),
         edits=(('unit = "rpm"', 'unit = "N*m"'),)),
    Case("unit-not-a-string", GOOD, ("bench.toml", "column 'speed'", "unit must be a string"),
         edits=(('unit = "rpm"', "unit = 60"),)),
    Case("misspelt-column-key", GOOD, ("bench.toml", "column 'speed'", "unknown key 'units'"),
         edits=(('unit = "rpm"', 'unit = "rpm"\nunits = "rpm"'),)),
    Case("misspelt-dataset-key", GOOD, ("bench.toml", "[dataset]", "unknown key 'trajectroy'"),
         edits=(dataset_key('trajectroy = "series"'),)),
    Case("unknown-top-level-table", GOOD, ("bench.toml", "'column'"),
         extra=column("x", "aux").replace("columns", "column")),
    Case("group-flag-on-response", GOOD, ("bench.toml", "column 'torque'", "group = true"),
         edits=(('role = "response"', 'role = "response"\ngroup = true'),)),
    Case("csv-is-a-folder", FOLDER, ("bench.csv", "is a folder")),
    Case("csv-is-a-named-pipe", FIFO, ("bench.csv", "not a regular file")),
    Case("sidecar-is-a-folder", GOOD, ("bench.toml", "is a folder"), meta=FOLDER),
    Case("toml-nested-too-deeply", GOOD, ("bench.toml", "nested too deeply"),
         extra="deep = " + "[" * 5000 + "]" * 5000 + "\n"),
    Case("csv-field-too-large", f"{HEADER}\n60,1.5,a\n60,1.5,\"{'x' * 200_000}\"\n",
         ("bench.csv", "row 2", "column 'series'", "200000 characters")),
    # -- issue 27: a 1 MB cell names its row and column; absolute zero in any unit is not > 0 K
    Case("csv-cell-1mb", f"{HEADER}\n60,{'1' * 1_000_000},a\n", ("bench.csv", "row 1", "column 'torque'",
                                                              "1000000 characters")),
    Case("csv-header-cell-1mb", f"speed,torque,series,{'h' * 1_000_000}\n60,1.5,a,1\n",
         ("bench.csv", "header", "cell 4", "1000000 characters")),
    Case("temperature-absolute-zero-degF", f"{HEADER},temp\n60,1.5,a,20\n60,1.5,b,-459.67\n",
         ("bench.csv", "row 2", "column 'temp'", "-459.67 degF", "> 0 K"),
         extra=column("temp", "input", "temperature", "degF")),
    Case("temperature-absolute-zero-degC", f"{HEADER},temp\n60,1.5,a,-273.15\n",
         ("bench.csv", "row 1", "column 'temp'", "> 0 K"), extra=column("temp", "input", "temperature", "degC")),
]

COMMANDS = {
    "check": ["data", "check", "bench.csv"],
    "fit": ["fit", "bench.csv", "stribeck", "--draws", "10", "--tune", "10", "--chains", "1"],
}


def test_corpus_is_large_and_ids_unique():
    assert len(CASES) >= 35
    assert len({c.id for c in CASES}) == len(CASES)


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input(tmp_path, case, command):
    case.write(tmp_path)
    assert_user_error(COMMANDS[command], tmp_path, case.mentions)


@pytest.mark.parametrize("command", ["check", "fit", "study"])
def test_a_linked_csv_has_its_sidecar_beside_the_link(tmp_path, command):
    """Issue 27: one rule for a CSV reached through a symbolic link: its sidecar is looked up beside
    the path as given (the link), by ``data check``, ``fit`` and a study's ``dataset`` alike."""
    (tmp_path / "real").mkdir()
    make(tmp_path / "real" / "bench.csv", GOOD)
    make(tmp_path / "real" / "bench.toml", BASE_META)  # beside the target only
    (tmp_path / "link.csv").symlink_to(tmp_path / "real" / "bench.csv")
    (tmp_path / "s.toml").write_text('[data]\ndataset = "link.csv"\n[[laws]]\nname = "coulomb"\n'
                                     "[compare]\nevidence = false\n")
    argv = {"check": ["data", "check", "link.csv"], "fit": ["fit", "link.csv", "coulomb", "--draws", "10"],
            "study": ["study", "s.toml", "--out", "reports"]}[command]
    assert_user_error(argv, tmp_path, ("link.toml", "metadata file not found"))
    make(tmp_path / "link.toml", BASE_META)  # beside the link: accepted by all three
    from bayesfric.study import load_study
    from bayesfric.study.runner import load_study_data

    assert load_study_data(load_study(tmp_path / "s.toml")).attrs["csv_file"] == str(tmp_path / "link.csv")


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_file_too_large_to_load_is_refused_from_its_size(tmp_path, command, monkeypatch):
    """No fixed row limit: a file whose text would not fit the memory available is refused before
    it is read, in one line naming it and what to do (``available_memory`` made small here)."""
    import bayesfric.limits as limits

    Case("large", HEADER + "\n" + "60,1.5,a\n" * 2000, ()).write(tmp_path)
    monkeypatch.setattr(limits, "available_memory", lambda: 400_000)
    assert_user_error(COMMANDS[command], tmp_path,
                      ("bench.csv", "18 kB of text needs about 360 kB", "bayesfric data reduce"))
