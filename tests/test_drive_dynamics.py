"""Drive dynamics as terms (issue 29, item 3): the ``acceleration`` quantities (given or derived),
the ``inertia`` and ``gravity`` terms, the ``normal_force`` quantity and the simulated ball-screw
drive (examples/ball_screw/, known truth)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from bayesfric.datasets import load_dataset
from bayesfric.laws import get_law
from bayesfric.laws.variants import VariantError, vary
from tests.hostile.harness import assert_user_error

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "ball_screw"
#: The simulation's truth (examples/ball_screw/generate.py, stated there once).
TRUTH = {"T_C": 35.0, "c_v_pos": 150.0, "c_v_neg": 110.0, "M": 25.0, "offset": 13.0}

_COLUMNS = {"t": '[columns.t]\nrole = "input"\nquantity = "time"\nunit = "s"\n',
            "w": '[columns.w]\nrole = "input"\nquantity = "velocity"\nunit = "rad/s"\n',
            "run": '[columns.run]\nrole = "group"\n',
            "torque": '[columns.torque]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n'}


def _meta(header: str, extra: str) -> str:
    """A sidecar for the CSV columns named in ``header``."""
    columns = "".join(_COLUMNS[c] for c in header.split(","))
    return f'[dataset]\nprovenance = "simulated"\nsource = "test"\n{extra}\n{columns}'


def _acceleration_as_aux() -> str:
    """The ball-screw sidecar with its acceleration column read as aux, not as an input."""
    text = (EXAMPLE / "ball_screw.toml").read_text()
    return text.replace('[columns.a]\nrole = "input"', '[columns.a]\nrole = "aux"')


def _generator():
    spec = importlib.util.spec_from_file_location("ball_screw_gen", EXAMPLE / "generate.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    return gen


def _sine_log(tmp_path: Path, derive: str, extra: str = 'trajectory = "run"', rows: str | None = None) -> Path:
    """Two trajectories of w = sin(2π t + φ) at 100 Hz (or ``rows``); returns the CSV path."""
    if rows is None:
        t = np.arange(200) * 0.01
        lines = [f"{r},{ti:.2f},{np.sin(2 * np.pi * ti + ph):.15f},1.0"
                 for r, ph in ((1, 0.0), (2, 2.0)) for ti in t]
        rows = "run,t,w,torque\n" + "\n".join(lines) + "\n"
    (tmp_path / "log.csv").write_text(rows)
    (tmp_path / "log.toml").write_text(_meta(rows.splitlines()[0], extra) + derive)
    return tmp_path / "log.csv"


# -- derived acceleration ------------------------------------------------------------------------
def test_derived_acceleration_matches_the_analytic_derivative(tmp_path):
    """Savitzky–Golay, window 7, order 3, at 100 samples per period: within 1e-5 of the peak inside
    each trajectory, 1e-3 at its first and last 3 samples; never across the trajectory boundary
    (the phase jumps by 2 rad there: a filter across it would be off by ~1)."""
    ds = load_dataset(_sine_log(tmp_path, "[derive.acceleration]\nwindow = 7\norder = 3\n"))
    t, run = ds["time"].values, ds["run"].values
    exact = 2 * np.pi * np.cos(2 * np.pi * t + np.where(run == 1, 0.0, 2.0))
    err = np.abs(ds["acceleration"].values - exact) / (2 * np.pi)
    ends = np.zeros(t.size, dtype=bool)
    for start in (0, 197, 200, 397):
        ends[start:start + 3] = True
    assert err[~ends].max() < 1e-5 and err[ends].max() < 1e-3
    assert ds["acceleration"].attrs["units"] == "rad/s**2" and ds["acceleration"].attrs["role"] == "input"
    assert "Savitzky–Golay" in ds.attrs["derived"] and "window 7" in ds.attrs["derived"]
    assert "order 3" in ds.attrs["derived"] and "trajectory 'run'" in ds.attrs["derived"]


def test_ball_screw_acceleration_derived_from_velocity_matches_the_given_column(tmp_path):
    """The example's velocity differentiated (window 7, order 3, 50 Hz) is within 0.5 % of the peak
    of its exact acceleration inside each run, 5 % at the 3 samples of each end."""
    meta = _acceleration_as_aux()
    (tmp_path / "ball_screw.toml").write_text(meta + "\n[derive.linear_acceleration]\nwindow = 7\norder = 3\n")
    (tmp_path / "ball_screw.csv").write_bytes((EXAMPLE / "ball_screw.csv").read_bytes())
    ds = load_dataset(tmp_path / "ball_screw.csv")
    err = np.abs(ds["linear_acceleration"].values - ds["a"].values) / np.abs(ds["a"].values).max()
    inner = np.ones(err.size, dtype=bool)
    for start in range(0, err.size, 300):
        inner[start:start + 3] = inner[start + 297:start + 300] = False
    assert err[inner].max() < 5e-3 and err.max() < 5e-2


@pytest.mark.parametrize(("derive", "extra", "rows", "mentions"), [
    ("[derive.acceleration]\n", 'trajectory = "run"', "run,t,torque\n1,0,1\n", ["[derive.acceleration]", "'velocity'"]),
    ("[derive.linear_acceleration]\n", 'trajectory = "run"', None, ["[derive.linear_acceleration]",
                                                                    "'linear_velocity'"]),
    ("[derive.acceleration]\n", "", "w,torque\n1,1\n", ["[derive.acceleration]", "'time'"]),
    ("[derive.acceleration]\nwindow = 6\n", "", None, ["[derive.acceleration] window", "odd"]),
    ("[derive.acceleration]\nmethod = \"gradient\"\n", "", None, ["[derive.acceleration] method"]),
    ("[derive.acceleration]\n", "", None, ["[derive.acceleration]", "time does not increase"]),
    ("[derive.jerk]\n", "", None, ["[derive.jerk]", "derivable"]),
    ("[derive.acceleration]\nwindow = 9\n", 'trajectory = "run"',
     "run,t,w,torque\n" + "".join(f"1,{0.01 * i:.2f},{i},1\n" for i in range(8)),
     ["window", "trajectory 1 has 8 rows, fewer than the window"]),
    ("[derive.acceleration]\n", 'trajectory = "run"',
     "run,t,w,torque\n" + "".join(f"1,{0.01 * i + (0.005 if i == 5 else 0):.3f},{i},1\n" for i in range(20)),
     ["[derive.acceleration]", "not evenly sampled"]),
])
def test_bad_derivation_is_one_line_naming_the_key(tmp_path, derive, extra, rows, mentions):
    path = _sine_log(tmp_path, derive, extra, rows)
    assert_user_error(["data", "check", str(path)], tmp_path, ["log.toml", *mentions])


def test_inertia_on_data_without_acceleration_names_the_entry_and_the_input(tmp_path):
    meta = _acceleration_as_aux()
    (tmp_path / "ball_screw.toml").write_text(meta)
    (tmp_path / "ball_screw.csv").write_bytes((EXAMPLE / "ball_screw.csv").read_bytes())
    (tmp_path / "s.toml").write_text('[study]\nname = "s"\ntitle = "t"\nquestion = "q"\n[data]\n'
                                     'dataset = "ball_screw.csv"\n[noise]\nkind = "normal"\n[[laws]]\n'
                                     'name = "coulomb_viscous"\nlabel = "cvi"\nadd = ["inertia"]\n')
    assert_user_error(["study", "s.toml"], tmp_path, ["s.toml", "laws[0] (cvi)", "linear_acceleration"])


# -- terms ---------------------------------------------------------------------------------------
def test_inertia_is_J_on_torque_data_and_M_in_kg_on_force_data():
    law = vary(get_law("coulomb_viscous"), add=["inertia"])
    assert law.params["J"].unit == "kg*m**2" and "acceleration" in law.inputs
    moved = vary(law, motion="translational")
    assert moved.params["M"].unit == "kg" and "J" not in moved.params
    assert moved.params["M"].prior.scaled_by == {"response": 1, "linear_acceleration": -1}
    fixed = vary(law, motion="translational", fixed={"M": 2.0})
    v, a = np.array([0.5, -0.5]), np.array([1.0, 3.0])
    got = fixed.mean({"linear_velocity": v, "linear_acceleration": a}, {"T_C": 1.0, "c_v": 4.0})
    np.testing.assert_allclose(got, np.sign(v) * 1.0 + 4.0 * v + 2.0 * a)


def test_gravity_by_hand_and_refused_on_force_data():
    law = vary(get_law("coulomb"), add=["gravity", "inertia"])
    q, w, a = np.array([0.0, np.pi / 2, 1.0]), np.array([1.0, 1.0, -1.0]), np.array([0.0, 2.0, -1.0])
    got = law.mean({"velocity": w, "angle": q, "acceleration": a}, {"T_C": 2.0, "G_c": 3.0, "G_s": -1.5, "J": 0.5})
    np.testing.assert_allclose(got, 2.0 * np.sign(w) + 3.0 * np.cos(q) - 1.5 * np.sin(q) + 0.5 * a)
    assert float(law.derived_values({"G_c": 3.0, "G_s": 4.0})["G"]) == pytest.approx(5.0)
    with pytest.raises(VariantError, match="add 'offset' instead"):
        vary(law, motion="translational")


def test_every_static_law_takes_inertia_and_offset_on_force_data():
    steady = [w for w in map(get_law, ("coulomb", "coulomb_viscous", "stribeck", "armstrong_helouvry",
                                        "helical_gear", "joint_tribological")) if not w.trajectory]
    for base in steady:
        law = vary(base, add=["inertia", "offset"], motion="translational")
        assert {"M", "offset"} <= set(law.params) and "linear_acceleration" in law.inputs, base.name


# -- normal force --------------------------------------------------------------------------------
def test_normal_force_is_an_input_that_amontons_scales_with_and_no_preload(tmp_path):
    from bayesfric.model import build_program

    (tmp_path / "tribo.csv").write_text("v,fn,f\n0.01,5,0.5\n-0.01,5,-0.5\n0.01,10,1.0\n-0.02,10,-1.0\n")
    (tmp_path / "tribo.toml").write_text(
        '[dataset]\nprovenance = "simulated"\nsource = "test"\n[columns.v]\nrole = "input"\n'
        'quantity = "linear_velocity"\nunit = "m/s"\n[columns.fn]\nrole = "input"\nquantity = "normal_force"\n'
        'unit = "N"\n[columns.f]\nrole = "response"\nquantity = "force"\nunit = "N"\n')
    ds = load_dataset(tmp_path / "tribo.csv")
    law = get_law("amontons")
    np.testing.assert_allclose(law.mean({"linear_velocity": ds["linear_velocity"].values,
                                         "normal_force": ds["normal_force"].values}, {"mu": 0.1}),
                               [0.5, -0.5, 1.0, -1.0])
    program = build_program(law, ds)
    assert program.resolved["mu"].args["scale"] == pytest.approx(1.0 / 10.0)  # R / F_N,max
    with_viscous = vary(law, add=["viscous"], asymmetric=["mu"])
    assert with_viscous.params["c_v"].unit == "N*s/m" and {"mu_pos", "mu_neg"} <= set(with_viscous.params)
    assert "preload" not in program.law.inputs and "preload" not in ds.coords  # Dahl's preload stays off


# -- the simulated ball-screw drive --------------------------------------------------------------
def test_ball_screw_files_are_what_the_generator_writes(tmp_path):
    gen = _generator()
    assert gen.TRUTH == TRUTH
    gen.main(tmp_path)
    for name in ("ball_screw.csv", "ball_screw.toml"):
        assert (tmp_path / name).read_bytes() == (EXAMPLE / name).read_bytes(), name


@pytest.mark.slow  # ~25 s on the 2-core machine (2 chains x 500 draws, compilation included)
def test_ball_screw_study_entry_recovers_inertia_and_friction():
    """The study's truth-form entry, fitted with default priors: the gate passes and M and every
    friction coefficient lie within their 90 % intervals."""
    from bayesfric.compare import verdict_of
    from bayesfric.inference import fit
    from bayesfric.study import load_study

    study = load_study(EXAMPLE / "study.toml")
    spec = next(s for s in study.laws if s.name == "cv_inertia_asym")
    dt = fit(spec.build(), load_dataset(study.dataset), draws=500, tune=500, chains=2, seed=1)
    assert verdict_of(dt).passed, verdict_of(dt).problems
    post = dt["posterior"].to_dataset()
    for name, value in TRUTH.items():
        low, high = np.quantile(np.asarray(post[name]).ravel(), [0.05, 0.95])
        assert low <= value <= high, f"{name}: truth {value} outside [{low:.4g}, {high:.4g}]"
