"""Property-based tests of the loader on random CSV files (hypothesis).

* Well-formed numeric tables in random units, column orders and cell padding load, and every
  value equals pint's conversion to SI within 1e-12 relative.
* Random garbage (ragged rows, NaN, junk bytes, broken quoting, random encodings, mangled
  sidecars) either loads or raises :class:`DataError` with a one-line message: never another
  exception type.
* One bad cell in a good table is reported at its row and column.
* With a trajectory group, random label sequences load exactly when every label is one block.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bayesfric.datasets import DataError, load_dataset
from bayesfric.quantities import QUANTITIES, ureg

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])

UNITS = {
    "velocity": ["rpm", "rad/s", "deg/s", "°/s", "revolution/s"],
    "torque": ["N*m", "kN*m", "mN*m", "in*ozf", "ft*lbf"],
    "temperature": ["degC", "K", "degF", "°C"],
}
#: Value ranges in the chosen unit that stay well inside every physical bound and scale limit.
RANGES = {"degC": (-200.0, 500.0), "°C": (-200.0, 500.0), "K": (80.0, 800.0), "degF": (-300.0, 900.0)}
COLUMNS = {"velocity": "speed", "torque": "torque", "temperature": "temp"}


def sidecar(units: dict[str, str], extra: str = "") -> str:
    """A sidecar for columns speed (input), torque (response), temp (input), series (group)."""
    text = f'[dataset]\nprovenance = "simulated"\nsource = "hypothesis"\n{extra}\n'
    for quantity, col in COLUMNS.items():
        role = "response" if quantity == "torque" else "input"
        text += f'[columns.{col}]\nrole = "{role}"\nquantity = "{quantity}"\nunit = "{units[quantity]}"\n'
    return text + '[columns.series]\nrole = "group"\n'


def load(csv: bytes, meta: str | bytes) -> xr.Dataset:
    """Write the pair to a fresh folder and load it."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "t.csv"
        path.write_bytes(csv)
        meta_path = Path(tmp) / "t.toml"
        meta_path.write_bytes(meta if isinstance(meta, bytes) else meta.encode())
        return load_dataset(path)


def si(value: float, unit: str, quantity: str) -> float:
    """pint's own conversion, independent of the loader's affine map."""
    parsed = ureg.parse_units(unit.replace("°", "deg"))
    return ureg.Quantity(value, parsed).to(QUANTITIES[quantity].unit).magnitude


def magnitude(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.tuples(st.sampled_from([1.0, -1.0]), st.floats(lo, hi)).map(lambda t: t[0] * t[1])


@st.composite
def numeric_tables(draw):
    units = {q: draw(st.sampled_from(us)) for q, us in UNITS.items()}
    n = draw(st.integers(1, 12))
    values = {
        "velocity": draw(st.lists(st.one_of(st.just(0.0), magnitude(1e-3, 1e4)), min_size=n, max_size=n)),
        "torque": draw(st.lists(magnitude(1e-3, 1e4), min_size=n, max_size=n)),
        "temperature": draw(st.lists(st.floats(*RANGES.get(units["temperature"], (80.0, 800.0))),
                                     min_size=n, max_size=n)),
    }
    labels = draw(st.lists(st.one_of(st.integers(0, 99).map(str), st.text("abcXYZ_-", min_size=1, max_size=4)),
                           min_size=n, max_size=n))
    order = draw(st.permutations([*COLUMNS.values(), "series", ""]))  # "" is an unnamed extra column
    pad = draw(st.sampled_from(["", " ", "  "]))
    return units, values, labels, order, pad


@SETTINGS
@given(numeric_tables())
def test_well_formed_tables_round_trip_to_si(table):
    units, values, labels, order, pad = table
    quantity_of = {col: q for q, col in COLUMNS.items()}
    lines = [",".join(f"{pad}{c}{pad}" for c in order)]
    for i in range(len(labels)):
        cells = {col: repr(values[q][i]) for q, col in COLUMNS.items()} | {"series": labels[i], "": "junk"}
        lines.append(",".join(f"{pad}{cells[c]}{pad}" for c in order))
    ds = load(("\n".join(lines) + "\n").encode(), sidecar(units))
    for col, quantity in quantity_of.items():
        expected = [si(v, units[quantity], quantity) for v in values[quantity]]
        np.testing.assert_allclose(ds[quantity].values, expected, rtol=1e-12, atol=0)
        assert ds[quantity].attrs["original_unit"] == units[quantity] and ds[quantity].attrs["column"] == col
    assert [str(v) for v in ds["series"].values] == labels


JUNK_CELLS = ["nan", "inf", "-inf", "", "  ", "1e400", "1e-400", "0x10", "1,5", '"', '""', "#", "\ufeff",
              "é", "\x00", "\r", "1_000", "-0", "1e-310", "0", "1e300", "x" * 50, "\t2"]
CELL = st.one_of(st.sampled_from(JUNK_CELLS), st.floats(allow_nan=True, allow_infinity=True).map(repr),
                 st.integers(-10**30, 10**30).map(str), st.text(max_size=4))
HEADER_NAMES = ["speed", "torque", "temp", "series", "", " torque", "speed", "x"]
META_EXTRAS = ["", "", 'trajectory = "series"', 'encoding = "latin-1"', 'encoding = "utf-16"']


@st.composite
def garbage(draw):
    """A valid table corrupted by a few random mutations, or (one time in four) pure junk."""
    if draw(st.integers(0, 3)) == 0:
        header = draw(st.lists(st.sampled_from(HEADER_NAMES), max_size=6))
        table = [header, *draw(st.lists(st.lists(CELL, max_size=7), max_size=8))]
    else:
        header = draw(st.permutations(["speed", "torque", "temp", "series"]))
        good = {"speed": "60", "torque": "1.5", "temp": "300", "series": "a"}
        table = [header] + [[good[c] for c in header] for _ in range(draw(st.integers(1, 6)))]
        for _ in range(draw(st.integers(1, 3))):
            i, j = draw(st.integers(0, len(table) - 1)), draw(st.integers(0, 3))
            action = draw(st.sampled_from(["cell", "cell", "drop", "add", "junk-line"]))
            if action == "cell" and j < len(table[i]):
                table[i][j] = draw(st.sampled_from(HEADER_NAMES) if i == 0 else CELL)
            elif action == "drop" and table[i]:
                del table[i][-1]
            elif action == "add":
                table[i].append(draw(CELL))
            elif action == "junk-line":
                table.insert(i + 1, [draw(st.text(max_size=10))])
    newline = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    text = newline.join(",".join(r) for r in table)
    encoding = draw(st.sampled_from(["utf-8", "utf-8", "utf-8-sig", "latin-1", "utf-16"]))
    data = text.encode(encoding, errors="replace")
    data += draw(st.one_of(st.just(b""), st.just(b""), st.binary(max_size=8)))
    units = {q: draw(st.sampled_from(us)) for q, us in UNITS.items()}
    return data, sidecar(units, draw(st.sampled_from(META_EXTRAS)))


def assert_loads_or_data_error(csv: bytes, meta: str | bytes) -> None:
    try:
        ds = load(csv, meta)
    except DataError as exc:
        message = str(exc)
        assert message and "\n" not in message and "\r" not in message, repr(message)
        return
    assert isinstance(ds, xr.Dataset) and ds.sizes["obs"] >= 1
    for var in [*ds.coords.values(), *ds.data_vars.values()]:
        if "quantity" in var.attrs:  # converted to SI: finite and inside the quantity's bound
            assert np.isfinite(var.values).all() and not QUANTITIES[var.attrs["quantity"]].violations(var.values).any()


@SETTINGS
@given(garbage())
def test_garbage_tables_load_or_raise_one_line_data_error(case):
    assert_loads_or_data_error(*case)


TOML_VALUES = ["1", "true", "[1, 2]", "{ a = 1 }", '"x"', '""', "1.5", "2026-01-01", '"°C"', '"speed"', '"series"']


@st.composite
def mangled_sidecars(draw):
    lines = sidecar({q: us[0] for q, us in UNITS.items()}, 'trajectory = "series"').splitlines()
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(lines) - 1))
        action = draw(st.sampled_from(["delete", "duplicate", "value", "bytes"]))
        if action == "delete":
            del lines[i]
        elif action == "duplicate":
            lines.insert(i, lines[i])
        elif action == "value" and "=" in lines[i]:
            lines[i] = lines[i].split("=")[0] + "= " + draw(st.sampled_from(TOML_VALUES))
        elif action == "bytes":
            lines[i] += draw(st.text(max_size=3))
        if not lines:
            break
    meta = "\n".join(lines).encode(draw(st.sampled_from(["utf-8", "latin-1"])), errors="replace")
    return b"speed,torque,temp,series\n60,1.5,300,a\n-60,-1.5,310,b\n", meta


@SETTINGS
@given(mangled_sidecars())
def test_mangled_sidecars_load_or_raise_one_line_data_error(case):
    assert_loads_or_data_error(*case)


@SETTINGS
@given(st.integers(1, 8), st.data())
def test_one_bad_cell_is_reported_at_its_row_and_column(n, data):
    row = data.draw(st.integers(0, n - 1))
    column = data.draw(st.sampled_from(["speed", "torque", "temp"]))
    bad = data.draw(st.sampled_from(["abc", "nan", "inf", "", "1..2", "--1", "1e999"]))
    cells = [{"speed": "60", "torque": "1.5", "temp": "300", "series": "a"} for _ in range(n)]
    cells[row][column] = bad
    text = "speed,torque,temp,series\n" + "".join(f"{c['speed']},{c['torque']},{c['temp']},{c['series']}\n"
                                                  for c in cells)
    units = {"velocity": "rpm", "torque": "N*m", "temperature": "K"}
    try:
        load(text.encode(), sidecar(units))
    except DataError as exc:
        assert f"row {row + 1}: column '{column}'" in str(exc), str(exc)
    else:
        raise AssertionError(f"{bad!r} in row {row + 1}, column {column!r} loaded")


@SETTINGS
@given(st.lists(st.sampled_from("abc"), min_size=1, max_size=12))
def test_trajectories_load_exactly_when_each_is_one_block(labels):
    blocks = [label for i, label in enumerate(labels) if i == 0 or label != labels[i - 1]]
    contiguous = len(blocks) == len(set(blocks))
    units = {"velocity": "rpm", "torque": "N*m", "temperature": "K"}
    text = "speed,torque,temp,series\n" + "".join(f"60,1.5,300,{label}\n" for label in labels)
    try:
        ds = load(text.encode(), sidecar(units, 'trajectory = "series"'))
    except DataError as exc:
        assert not contiguous and "reappears" in str(exc), str(exc)
    else:
        assert contiguous and ds.attrs["trajectory"] == "series"
