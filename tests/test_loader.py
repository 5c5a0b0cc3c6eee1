"""CSV + TOML loading: unit conversion to SI and one-line errors for every bad-input case."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bayesfric.cli import main
from bayesfric.datasets import DataError, load_dataset

META = """
[dataset]
name = "bench"
title = "test bench"
provenance = "measured"
source = "unit test"

[columns.speed]
role = "input"
quantity = "velocity"
unit = "{speed_unit}"

[columns.torque]
role = "response"
quantity = "torque"
unit = "{torque_unit}"

[columns.series]
role = "group"
"""


def write(tmp_path: Path, rows: str, speed_unit="rpm", torque_unit="N*m", meta=None) -> Path:
    csv = tmp_path / "bench.csv"
    csv.write_text(rows)
    (tmp_path / "bench.toml").write_text(meta or META.format(speed_unit=speed_unit, torque_unit=torque_unit))
    return csv


GOOD = "speed,torque,series\n60,1.5,a\n-120,-2.0,b\n"


def test_loads_and_converts(tmp_path):
    ds = load_dataset(write(tmp_path, GOOD))
    np.testing.assert_allclose(ds["velocity"].values, [2 * math.pi, -4 * math.pi])  # 60 rpm = 2π rad/s
    assert ds["velocity"].attrs["units"] == "rad/s" and ds["velocity"].attrs["original_unit"] == "rpm"
    assert ds.attrs["provenance"] == "measured" and ds.attrs["response"] == "torque"
    assert list(ds["series"].values) == ["a", "b"]
    assert len(ds.attrs["data_hash"]) == 16


@pytest.mark.parametrize(
    ("unit", "quantity", "value", "si"),
    [
        ("rpm", "velocity", 1.0, 2 * math.pi / 60),
        ("deg/s", "velocity", 180.0, math.pi),
        ("°/s", "velocity", 90.0, math.pi / 2),
        ("lbf", "preload", 1.0, 4.4482216152605),
        ("in*ozf", "torque", 1.0, 0.0254 * 0.27801385095378125),
        ("degC", "temperature", 20.0, 293.15),
        ("°C", "temperature", 38.0, 311.15),
        ("MN*m", "bending_moment", 6.0, 6e6),
        ("kN*m", "torque", 2.5, 2500.0),
        ("deg", "angle", 11.25, 11.25 * math.pi / 180),
    ],
)
def test_unit_conversions(unit, quantity, value, si):
    from bayesfric.quantities import to_canonical

    assert to_canonical(value, unit, quantity) == pytest.approx(si, rel=1e-12)


BAD_CASES = [
    # (rows, speed_unit, expected fragments of the one-line message)
    ("speed,series\n1,a\n", "rpm", ["bench.csv", "column 'torque'", "missing"]),
    (GOOD, "furlong_per_quux", ["bench.toml", "column 'speed'", "unknown unit"]),
    (GOOD, "N*m", ["bench.toml", "column 'speed'", "dimension"]),
    ("speed,torque,series\n60,nan,a\n", "rpm", ["bench.csv", "row 1", "column 'torque'", "non-finite"]),
    ("speed,torque,series\n60,1,a\ninf,1,b\n", "rpm", ["bench.csv", "row 2", "column 'speed'", "non-finite"]),
    ("", "rpm", ["bench.csv", "empty"]),
    ("speed,torque,series\n", "rpm", ["bench.csv", "no data rows"]),
    ("speed,torque,series\n60,1.5,a\n7o,2,b\n", "rpm",
     ["bench.csv", "row 2", "column 'speed'", "'7o' is not a number"]),
    ("speed,torque,series\n60,1.5\n", "rpm", ["bench.csv", "row 1", "cells"]),
]


@pytest.mark.parametrize(("rows", "unit", "fragments"), BAD_CASES)
def test_bad_input_one_line(tmp_path, rows, unit, fragments):
    with pytest.raises(DataError) as info:
        load_dataset(write(tmp_path, rows, speed_unit=unit))
    message = str(info.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_bad_metadata(tmp_path):
    meta = META.format(speed_unit="rpm", torque_unit="N*m").replace('provenance = "measured"', 'provenance = "guessed"')
    with pytest.raises(DataError, match="provenance 'guessed'"):
        load_dataset(write(tmp_path, GOOD, meta=meta))
    with pytest.raises(DataError, match="metadata file not found"):
        csv = tmp_path / "other.csv"
        csv.write_text(GOOD)
        load_dataset(csv)


def test_cli_bad_input_exit_2_no_traceback_nothing_written(tmp_path, capsys):
    csv = write(tmp_path, "speed,torque,series\n60,x,a\n")
    out = tmp_path / "fit.nc"
    code = main(["fit", str(csv), "coulomb", "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err and "row 1" in err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.csv", "bench.toml"]


def test_cli_unknown_law_exit_2(tmp_path):
    csv = write(tmp_path, GOOD)
    proc = subprocess.run([sys.executable, "-m", "bayesfric", "fit", str(csv), "no_such_law"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "unknown law 'no_such_law'" in proc.stderr and "Traceback" not in proc.stderr


def test_cli_data_check(tmp_path, capsys):
    csv = write(tmp_path, GOOD)
    assert main(["data", "check", str(csv)]) == 0
    text = capsys.readouterr().out
    assert "rpm -> rad/s" in text and "OK" in text


# -- inputs that must load (the hardening must not over-reject) ------------------------------------
def test_utf8_bom_loads_like_plain_utf8(tmp_path):
    plain = load_dataset(write(tmp_path, GOOD))
    (tmp_path / "bench.csv").write_bytes(b"\xef\xbb\xbf" + GOOD.encode())
    sidecar = tmp_path / "bench.toml"
    sidecar.write_bytes(b"\xef\xbb\xbf" + sidecar.read_bytes())
    with_bom = load_dataset(tmp_path / "bench.csv")
    np.testing.assert_array_equal(with_bom["velocity"].values, plain["velocity"].values)
    assert list(with_bom["series"].values) == ["a", "b"]


@pytest.mark.parametrize("encoding", ["latin-1", "cp1252", "utf-8"])
def test_declared_encoding_decodes_the_csv(tmp_path, encoding):
    meta = META.format(speed_unit="rpm", torque_unit="N*m").replace(
        'source = "unit test"', f'source = "unit test"\nencoding = "{encoding}"')
    csv = write(tmp_path, "", meta=meta)
    csv.write_bytes("speed,torque,series\n60,1.5,Prüfstand 20 °C\n".encode(encoding))
    assert list(load_dataset(csv)["series"].values) == ["Prüfstand 20 °C"]


def test_micro_newton_response_and_all_zero_input_load(tmp_path):
    meta = META.format(speed_unit="rad/s", torque_unit="uN*m")
    ds = load_dataset(write(tmp_path, "speed,torque,series\n0,1,a\n0,-2,b\n", meta=meta))
    np.testing.assert_allclose(ds["torque"].values, [1e-6, -2e-6])
    assert not ds["velocity"].values.any()


def test_bounds_are_inclusive_where_declared(tmp_path):
    meta = META.format(speed_unit="rpm", torque_unit="N*m") + (
        '[columns.pre]\nrole = "input"\nquantity = "preload"\nunit = "lbf"\n'
        '[columns.temp]\nrole = "input"\nquantity = "temperature"\nunit = "degC"\n')
    ds = load_dataset(write(tmp_path, "speed,torque,series,pre,temp\n60,1,a,0,-273.1\n", meta=meta))
    assert ds["preload"].values[0] == 0.0 and ds["temperature"].values[0] == pytest.approx(0.05)


def test_unnamed_header_cells_are_ignored_columns(tmp_path):
    ds = load_dataset(write(tmp_path, ",speed,torque,series,\n0,60,1.5,a,x\n1,-120,-2.0,b,y\n"))
    assert ds.sizes["obs"] == 2 and ds["torque"].values.tolist() == [1.5, -2.0]


TRAJ_META = """
[dataset]
provenance = "measured"
source = "unit test"
trajectory = "loop"
[columns.loop]
role = "group"
[columns.angle]
role = "input"
quantity = "angle"
unit = "deg"
[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"
"""


def test_trajectory_without_time_may_go_back_and_forth(tmp_path):
    rows = "loop,angle,torque\n1,0,0.1\n1,2,0.5\n1,-2,-0.5\n1,2,0.4\n2,0,0.1\n2,-1,-0.3\n"
    ds = load_dataset(write(tmp_path, rows, meta=TRAJ_META))
    assert ds.attrs["trajectory"] == "loop" and ds.sizes["obs"] == 6


def test_trajectory_time_restarts_in_each_block(tmp_path):
    meta = TRAJ_META + '[columns.t]\nrole = "input"\nquantity = "time"\nunit = "ms"\n'
    rows = "loop,angle,torque,t\n1,0,0.1,0\n1,2,0.5,10\n2,0,0.1,0\n2,-1,-0.3,5\n"
    np.testing.assert_allclose(load_dataset(write(tmp_path, rows, meta=meta))["time"].values, [0, 0.01, 0, 0.005])


def test_no_fixed_row_limit(tmp_path):
    """10⁵ rows load (the old fixed limit was 20 000): only memory bounds a data set."""
    ds = load_dataset(write(tmp_path, "speed,torque,series\n" + "60,1.5,a\n" * 100_000))
    assert ds.sizes["obs"] == 100_000


def test_a_file_too_large_for_the_memory_is_refused_from_its_size_before_reading(tmp_path, monkeypatch):
    import bayesfric.limits as limits
    from bayesfric.datasets.loader import DataError

    path = write(tmp_path, "speed,torque,series\n" + "60,1.5,a\n" * 1000)
    monkeypatch.setattr(limits, "available_memory", lambda: 200_000)  # 200 kB: 9 kB of text needs 180 kB
    expected = r"bench.csv: 9 kB of text needs about 180 kB of memory to load, more than half of the 200 kB available"
    with pytest.raises(DataError, match=expected + r".*\(bayesfric data reduce\)"):
        load_dataset(path)


def test_builtin_data_sets_load():
    from bayesfric.datasets import builtin_names, load_builtin

    seeds = {"dahl_duplex", "drum_campaigns", "drum_rollout", "pitch_bearing", "robot_joint", "unwinder"}  # papers
    examples = {"asym_joint", "gms_loops", "tribo_loops"}  # simulated with known truth (studies/examples/)
    names = builtin_names()
    assert set(names) == seeds | examples
    for name in names:
        ds = load_builtin(name)
        assert ds.sizes["obs"] > 100, name
        assert ds.attrs["provenance"] == ("reconstructed" if name in seeds else "simulated"), name
