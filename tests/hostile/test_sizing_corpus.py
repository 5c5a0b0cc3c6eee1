"""Bad-input corpus for ``bayesfric size`` (issue #10): bad points, units, options, targets and reports.

Every case runs the CLI in-process through :func:`tests.hostile.harness.assert_user_error`: exit
status 2, one line ``bayesfric: error: ...`` naming the option (or file) and the problem, no
traceback, and nothing under the case's tree created, changed or removed. The tree holds a valid
tiny study with a ``[[sizing]]`` question, its data, a fit made by hand (no sampling), a fit of a
trajectory law, a file that is not a fit, and a report folder without its result tree.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from bayesfric.fsutil import MARKER
from bayesfric.inference import save_fit
from tests.hostile.harness import assert_user_error
from tests.sizing_helpers import hand_fit, write_basis

STUDY = ('[study]\nname = "tiny"\n[data]\ndataset = "bench.csv"\n[sampler]\ndraws = 300\ntune = 300\nchains = 2\n'
         '[[laws]]\nname = "coulomb_viscous"\n[compare]\nloo = true\nevidence = false\n'
         '[[compare.blocked]]\naxis = "velocity"\nthreshold = 1.0\n')
QUESTION = '[[sizing]]\nat = { velocity = "1..4 rad/s" }\nconfidence = 0.9\n'
AT = ("--at", "velocity=2 rad/s")


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    v = np.linspace(0.1, 2.0, 10)
    (tmp_path / "bench.csv").write_text("speed,torque\n" + "".join(f"{a},{5 + 2 * a}\n" for a in v))
    (tmp_path / "bench.toml").write_text(
        '[dataset]\nname = "bench"\nprovenance = "simulated"\nsource = "test"\n'
        '[columns.speed]\nrole = "input"\nquantity = "velocity"\nunit = "rad/s"\n'
        '[columns.torque]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n')
    (tmp_path / "s.toml").write_text(STUDY + QUESTION)
    (tmp_path / "plain.toml").write_text(STUDY)
    draws_cv = {"T_C": np.full((2, 50), 5.0), "c_v": np.full((2, 50), 2.0), "sigma": np.full((2, 50), 0.2)}
    fit = hand_fit("coulomb_viscous", draws_cv, {"velocity": v})
    save_fit(fit, tmp_path / "fit.nc")
    fit.attrs["law"] = "dahl"
    save_fit(fit, tmp_path / "dahl.nc")
    draws = {"f0": np.full((2, 50), 1.0), "f1": np.full((2, 50), 1e-3), "sigma": np.full((2, 50), 0.2)}
    save_fit(hand_fit("palmgren", draws, {"velocity": v, "bending_moment": 1e6 * v}), tmp_path / "two.nc")
    (tmp_path / "junk.nc").write_bytes(b"not a NetCDF file\x00\x01")
    old = tmp_path / "old_reports" / "tiny"  # a report from before sizing: marked, no results.nc
    (old / "fits").mkdir(parents=True)
    (old / MARKER).write_text(json.dumps({"tool": "bayesfric", "study": "tiny"}))
    older = tmp_path / "older_reports" / "tiny"  # a results.nc from before the sizing basis
    (older / "fits").mkdir(parents=True)
    (older / MARKER).write_text(json.dumps({"tool": "bayesfric", "study": "tiny"}))
    xr.DataTree.from_dict({"scores": xr.Dataset({"x": ("law", [1.0])})}).to_netcdf(older / "results.nc")
    stale = tmp_path / "stale_reports" / "tiny"  # a report whose fit was made from other data
    (stale / "fits").mkdir(parents=True)
    (stale / MARKER).write_text(json.dumps({"tool": "bayesfric", "study": "tiny"}))
    save_fit(hand_fit("coulomb_viscous", draws_cv, {"velocity": v}), stale / "fits" / "coulomb_viscous.nc")
    write_basis(stale, ["coulomb_viscous"])
    (tmp_path / "two.toml").write_text(STUDY.replace('[[laws]]', '[[laws]]\nname = "coulomb"\n[[laws]]', 1)
                                       + QUESTION)
    return tmp_path


CASES = [
    # -- bad points and units on a study ------------------------------------------------------------
    ("unit-dimension", ("size", "s.toml", "--at", "velocity=2 m"), ("--at velocity", "'2 m'", "dimension")),
    ("unknown-unit", ("size", "s.toml", "--at", "velocity=2 furlongs_per_fortnight"),
     ("--at velocity", "unknown unit")),
    ("not-an-input", ("size", "s.toml", "--at", "temperature=5 degC"),
     ("--at temperature", "not an input of the data", "velocity")),
    ("not-a-quantity", ("size", "s.toml", "--at", "speed=2 rad/s"), ("--at speed", "not an operating quantity")),
    ("no-equals", ("size", "s.toml", "--at", "velocity 2 rad/s"), ("--at", "expected INPUT=VALUE")),
    ("no-unit", ("size", "s.toml", "--at", "velocity=2"), ("--at velocity", "has no unit")),
    ("no-number", ("size", "s.toml", "--at", "velocity=fast"), ("--at velocity", "cannot read 'fast'")),
    ("reversed-range", ("size", "s.toml", "--at", "velocity=6..0.5 rad/s"), ("--at velocity", "smaller to the larger")),
    ("twice", ("size", "s.toml", "--at", "velocity=1 rad/s, velocity=2 rad/s"), ("--at", "given twice")),
    ("confidence-high", ("size", "s.toml", *AT, "--confidence", "1.5"), ("--confidence", "(0, 1)")),
    ("confidence-nan", ("size", "s.toml", *AT, "--confidence", "nan"), ("--confidence", "(0, 1)")),
    ("capacity-kind", ("size", "s.toml", *AT, "--capacity", "3 kg"), ("--capacity", "neither a torque")),
    ("capacity-force", ("size", "s.toml", *AT, "--capacity", "3 kN"), ("--capacity", "'3 kN'", "dimension")),
    ("capacity-range", ("size", "s.toml", *AT, "--capacity", "1..3 N*m"), ("--capacity", "single value")),
    ("rotation-unit", ("size", "s.toml", *AT, "--energy-rotation", "90 m"), ("--energy-rotation", "dimension")),
    ("rotation-zero", ("size", "s.toml", *AT, "--energy-rotation", "0 deg"), ("--energy-rotation", "positive")),
    ("option-without-at", ("size", "s.toml", "--confidence", "0.9"), ("--confidence", "only with --at")),
    # -- targets and reports ---------------------------------------------------------------------------
    ("no-report", ("size", "s.toml", "--reports", "reports"),
     ("s.toml", "no report of study 'tiny'", "bayesfric study")),
    ("old-report", ("size", "s.toml", "--reports", "old_reports"), ("results.nc", "run the study again")),
    ("older-report", ("size", "s.toml", "--reports", "older_reports"),
     ("results.nc: holds no sizing basis", "run the study again")),
    ("stale-data", ("size", "s.toml", "--reports", "stale_reports"), ("made from other data", "run the study again")),
    ("laws-changed", ("size", "two.toml", "--reports", "stale_reports"),
     ("no fit of coulomb", "laws changed", "run the study again")),
    ("no-question", ("size", "plain.toml"), ("plain.toml", "asks no sizing question", "[[sizing]]")),
    ("missing-study", ("size", "nope.toml"), ("nope.toml", "not found")),
    ("not-a-target", ("size", "bench.csv"), ("bench.csv", "study file (.toml) or a fit (.nc)")),
    # -- one fit -------------------------------------------------------------------------------------
    ("fit-without-at", ("size", "fit.nc"), ("--at", "required with a fit")),
    ("fit-foreign-input", ("size", "fit.nc", "--at", "bending_moment=8 MN*m"),
     ("--at bending_moment", "not an input of law 'coulomb_viscous'")),
    ("fit-missing-input", ("size", "two.nc", "--at", "velocity=1 rpm"),
     ("--at", "missing bending_moment")),
    ("fit-missing", ("size", "gone.nc", *AT), ("gone.nc", "not found")),
    ("fit-junk", ("size", "junk.nc", *AT), ("junk.nc", "not a readable fit")),
    # a stateful law answers from its steady state, which reads the velocity, not the loops' angle
    ("fit-trajectory", ("size", "dahl.nc", "--at", "angle=1 deg, preload=10 N"),
     ("--at angle", "not an input of law 'dahl_steady'", "velocity, preload")),
    ("fit-bad-unit", ("size", "fit.nc", "--at", "velocity=3 N"), ("--at velocity", "dimension")),
    # -- issue 27: silent acceptance and overflow ------------------------------------------------------
    ("capacity-negative", ("size", "s.toml", *AT, "--capacity", "-40 N*m"), ("--capacity", "'-40 N*m'", "positive")),
    ("capacity-zero", ("size", "s.toml", *AT, "--capacity", "0 kN*m"), ("--capacity", "positive")),
    ("fit-capacity-negative", ("size", "fit.nc", *AT, "--capacity", "-40 N*m"), ("--capacity", "positive")),
    ("fit-capacity-negative-force", ("size", "fit.nc", *AT, "--capacity", "-3 kN"), ("--capacity", "positive")),
    ("fit-velocity-1e300", ("size", "fit.nc", "--at", "velocity=1e300 rad/s"), ("--at velocity", "above the 1e+12")),
    ("fit-velocity-1e400", ("size", "fit.nc", "--at", "velocity=1e400 rad/s"), ("--at velocity", "not a finite")),
    ("fit-range-to-1e300", ("size", "fit.nc", "--at", "velocity=1..1e300 rad/s"), ("--at velocity", "above")),
    ("fit-velocity-huge-rpm", ("size", "fit.nc", "--at", "velocity=1e13 rpm"), ("--at velocity", "above")),
    ("capacity-1e300", ("size", "fit.nc", *AT, "--capacity", "1e300 N*m"), ("--capacity", "above")),
    ("rotation-1e300", ("size", "fit.nc", *AT, "--energy-rotation", "1e300 deg"), ("--energy-rotation", "above")),
    ("fit-absolute-zero-degF", ("size", "fit.nc", "--at", "velocity=1 rad/s, temperature=-459.67 degF"),
     ("--at temperature", "physical bound", "> 0 K")),
    ("fit-absolute-zero-degC", ("size", "fit.nc", "--at", "velocity=1 rad/s, temperature=-273.15 degC"),
     ("--at temperature", "> 0 K")),
    ("fit-prediction-beyond-1e12", ("size", "fit.nc", "--at", "velocity=9e11 rad/s"),
     ("asked point velocity = 9e+11", "coulomb_viscous", "1.8e+12", "beyond the 1e+12")),
    ("fit-range-prediction-beyond-1e12", ("size", "fit.nc", "--at", "velocity=1..9e11 rad/s", "--energy-rotation",
                                          "1e12 rad"), ("asked point", "beyond the 1e+12")),
]

#: ``[[sizing]]`` entries of a study file that must fail, through ``size`` and through ``study``.
STUDY_CASES = [
    ("capacity-negative", 'at = { velocity = "2 rad/s" }\ncapacity = "-40 N*m"\n', "sizing[0].capacity", "positive"),
    ("capacity-zero", 'at = { velocity = "2 rad/s" }\ncapacity = "0 N*m"\n', "sizing[0].capacity", "positive"),
    ("velocity-1e300", 'at = { velocity = "1e300 rad/s" }\n', "sizing[0].at.velocity", "above"),
    ("rotation-1e300", 'at = { velocity = "2 rad/s" }\nenergy_rotation = "1e300 deg"\n', "sizing[0].energy_rotation",
     "above"),
]


@pytest.mark.parametrize(("argv", "mentions"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_sizing_input_is_one_line(tree, argv, mentions):
    assert_user_error(argv, tree, mentions)


def test_study_sizing_question_errors_name_file_and_key(tree):
    (tree / "s.toml").write_text(STUDY + '[[sizing]]\nat = { velocity = "2 m" }\n')
    assert_user_error(("size", "s.toml"), tree, ("s.toml: sizing[0].at.velocity", "dimension"))
    (tree / "s.toml").write_text(STUDY + '[[sizing]]\nat = { temperature = "5 degC" }\n')
    assert_user_error(("study", "s.toml", "--out", "reports"), tree,
                      ("s.toml: sizing[0].at.temperature", "not an input of the data"))


@pytest.mark.parametrize("command", ["size", "study"])
@pytest.mark.parametrize(("entry", "key", "problem"), [c[1:] for c in STUDY_CASES], ids=[c[0] for c in STUDY_CASES])
def test_bad_sizing_entry_of_a_study_is_one_line(tree, command, entry, key, problem):
    (tree / "s.toml").write_text(STUDY + "[[sizing]]\n" + entry)
    argv = ("size", "s.toml") if command == "size" else ("study", "s.toml", "--out", "reports")
    assert_user_error(argv, tree, (f"s.toml: {key}", problem))
