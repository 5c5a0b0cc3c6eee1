"""The public Python API (issue 31, item 3): bayesfric.load_data / law / fit / compare_laws / size /
Study / run. Arguments are checked where they are given, errors name the argument, a capacity is
never dropped; the CLI's `size` and the API give the same answer; a Study built in Python is the
study its TOML file gives. Fast tests use fits made by hand or one small fixture of two real fits
(2 x 100 draws); a study run, the docstring examples and example (a) are slow."""

from __future__ import annotations

import doctest
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import bayesfric
from bayesfric.errors import UserError
from bayesfric.inference import save_fit
from tests.sizing_helpers import hand_fit

REPO = Path(__file__).resolve().parents[1]
V = np.linspace(0.1, 2.0, 10)


@pytest.fixture(scope="module")
def handmade():
    """A coulomb_viscous fit with known draws (T = 5 + 2 v, sigma 0.2), no sampling."""
    draws = {"T_C": np.full((2, 50), 5.0), "c_v": np.full((2, 50), 2.0), "sigma": np.full((2, 50), 0.2)}
    return hand_fit("coulomb_viscous", draws, {"velocity": V})


@pytest.fixture(scope="module")
def fits():
    """Two small real fits of the built-in robot_joint data (about 15 s)."""
    return {name: bayesfric.fit(name, "robot_joint", draws=100, tune=100, chains=2)
            for name in ("coulomb_viscous", "stribeck")}


def test_import_is_cheap_and_the_api_loads_on_first_use():
    code = ("import sys, bayesfric; assert 'bayesfric.api' not in sys.modules; "
            "assert 'fit' in dir(bayesfric); bayesfric.size; assert 'bayesfric.api' in sys.modules; "
            "import jax; assert not jax.config.jax_enable_x64")  # nothing process-wide changed
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        bayesfric.nope  # noqa: B018


@pytest.mark.parametrize(("kwargs", "fragment"), [
    ({"at": {"velocity": (2, "rad/s")}, "capacity": 40}, 'capacity: 40 has no unit; give it as (40, "N*m")'),
    ({"at": {"velocity": (2, "rad/s")}, "capacity": "40"}, "capacity: '40' has no unit"),
    ({"at": {"velocity": (2, "rad/s")}, "capacity": (3, "kN")}, "capacity: '3 kN': unit 'kN' has dimension"),
    ({"at": {"velocity": (2, "rad/s")}, "capacity": (-40, "N*m")}, "capacity: '-40 N*m': a capacity is"),
    ({"at": {"velocity": 2}}, 'at.velocity: 2 has no unit; give it as (2, "rad/s")'),
    ({"at": {"velocity": (2, "m")}}, "at.velocity: '2 m': unit 'm' has dimension"),
    ({"at": {"temperature": (20, "degC")}}, "at.temperature: 'temperature' is not an input of law 'coulomb_viscous'"),
    ({"at": {"speed": (2, "rad/s")}}, "at.speed: 'speed' is not an operating quantity"),
    ({"at": {"velocity": (6, 0.5, "rad/s")}}, "at.velocity: range '6..0.5 rad/s' must go from the smaller"),
    ({"at": {"velocity": (2, "rad/s")}, "confidence": 1.5}, "confidence: must be in (0, 1), got 1.5"),
    ({"at": {"velocity": (2, "rad/s")}, "confidence": math.nan}, "confidence: must be in (0, 1)"),
    ({"at": {"velocity": (2, "rad/s")}, "confidence": "high"}, "confidence: must be a number in (0, 1)"),
    ({"capacity": (40, "N*m")}, "capacity: applies only with at"),
    ({"confidence": 0.9}, "confidence: applies only with at"),
    ({}, "at: required with a fit"),
    ({"at": ["velocity"]}, "at: expected a dict of input -> value"),
])
def test_bad_sizing_arguments_raise_one_line_naming_the_argument(handmade, kwargs, fragment):
    with pytest.raises(UserError) as info:
        bayesfric.size(handmade, **kwargs)
    message = str(info.value)
    assert fragment in message and "\n" not in message


def test_size_of_a_fit_keeps_the_capacity_and_matches_the_cli(handmade, tmp_path, capsys):
    from bayesfric.cli import main
    from bayesfric.report.sizing import text_report

    result = bayesfric.size(handmade, at={"velocity": (3, "rad/s")}, capacity=(11.2, "N*m"), confidence=0.95)
    answer = result.dataset.sel(law="coulomb_viscous", point=0)
    assert float(answer["capacity"]) == 11.2  # parsed, not dropped
    # T = 5 + 2 * 3 = 11 N*m with noise sd 0.2: P(|T| > 11.2) = P(z > 1) = 0.159, here from 100 draws
    assert 0.05 < answer["p_exceed"] < 0.35 and 0 < answer["p_exceed_se"] < 0.05
    save_fit(handmade, tmp_path / "fit.nc")
    assert main(["size", str(tmp_path / "fit.nc"), "--at", "velocity=3 rad/s", "--capacity", "11.2 N*m",
                 "--confidence", "0.95"]) == 0
    cli = capsys.readouterr().out
    from_file = bayesfric.size(tmp_path / "fit.nc", at="velocity=3 rad/s", capacity="11.2 N*m", confidence=0.95)
    assert text_report(from_file) + "\n" == cli  # the CLI prints what the API returns
    assert f"{float(answer['required']):.4g}" in cli


def test_size_of_a_real_fit_gives_a_finite_exceedance(fits):
    result = bayesfric.size(fits["stribeck"], at={"velocity": (0.5, 6, "rad/s")}, capacity=(20, "N*m"))
    answer = result.dataset.sel(law="stribeck")
    p, required = answer["p_exceed"].values, answer["required"].values
    assert p.shape == (25,) and np.isfinite(p).all()
    assert np.all((p >= 0) & (p <= 1)) and np.all(required > 0)
    assert result.response_unit == "N*m" and result.dataset.attrs["response_unit"] == "N*m"
    assert len(result.to_dataframe()) == 25 and bool((result.q(0.999).sel(law="stribeck") >= required).all())


def test_compare_laws_ranks_the_fits(fits):
    table = bayesfric.compare_laws(fits, "robot_joint")
    assert list(table.columns) == ["elpd_loo", "se", "elpd_diff", "subsampling_se", "p_loo", "high_k", "weight",
                                   "reliable", "reason"]
    assert table["subsampling_se"].isna().all()  # 111 rows: every row scored
    assert sorted(table.index) == sorted(fits) and table["elpd_diff"].iloc[0] == 0
    assert table["elpd_loo"].is_monotonic_decreasing
    for law, row in table.iterrows():  # a law without a weight says why
        assert (not math.isnan(row["weight"])) or row["reason"], law
    assert bayesfric.compare_laws(list(fits.values())).index.tolist() == table.index.tolist()
    with pytest.raises(UserError, match=r"fits\['x'\]: not a fit"):
        bayesfric.compare_laws({"x": fits["stribeck"].posterior})


@pytest.mark.parametrize(("kwargs", "fragment"), [
    ({"law": "nope"}, "law: unknown law 'nope'"),
    ({"draws": 0}, "draws: must be an integer ≥ 1"),
    ({"chains": 2, "walkers": 8}, "walkers: applies only to sampler emcee"),
    ({"draws": 10**12}, "draws: 1000000000000 needs about"),
    ({"noise": "gauss"}, "noise: noise kind 'gauss' not one of"),
    ({"noise": {"kind": "normal", "group": "run"}}, "noise: group 'run' is not a coordinate of the data"),
    ({"priors": {"X": {"dist": "HalfNormal", "scale": 1}}}, "priors.X: law 'stribeck' has no parameter 'X'"),
    ({"priors": {"T_C": {"dist": "HalfNormal", "scale": -1}}}, "priors.T_C: scale:"),
    ({"data": 3}, "data: expected a built-in data set name"),
])
def test_fit_checks_its_arguments_before_sampling(kwargs, fragment):
    args = {"law": "stribeck", "data": "robot_joint"} | kwargs
    with pytest.raises(UserError) as info:
        bayesfric.fit(args.pop("law"), args.pop("data"), **args)
    assert fragment in str(info.value)


def test_law_and_load_data(tmp_path):
    import jax.numpy as jnp

    assert bayesfric.law("stribeck") is bayesfric.law(bayesfric.law("stribeck"))
    assert bayesfric.load_data("robot_joint", select={"series": [1, 2]}).sizes["obs"] == 74

    def api_test_smooth(velocity, T_C, v_eps=0.01):
        return T_C * jnp.tanh(velocity / v_eps)

    mine = bayesfric.law(api_test_smooth, units={"T_C": "N*m", "v_eps": "rad/s"})
    assert mine.inputs == ("velocity",) and list(mine.params) == ["T_C"]
    with pytest.raises(UserError, match="units: a law given as a function needs"):
        bayesfric.law(api_test_smooth)
    with pytest.raises(UserError, match="priors: applies only to a law given as a function"):
        bayesfric.law("stribeck", priors={"T_C": {"dist": "HalfNormal", "scale": 1}})
    study = bayesfric.Study("s", "robot_joint", laws=[mine])  # not registered: found by name in this process
    assert study.laws[0].build() is mine and study.laws[0].modules == ()  # declared in a function: no file
    # worker processes could not load it: refused before anything runs, naming the law
    with pytest.raises(UserError, match="workers: law 'api_test_smooth' is declared in this process only"):
        bayesfric.run(study, tmp_path, workers=2)
    assert not any(tmp_path.iterdir())
    assert bayesfric.api.studies.process_local_laws(bayesfric.Study("r", "robot_joint", laws=["stribeck"])) == []


STUDY_TOML = """[study]
name = "twin"
[data]
dataset = "robot_joint"
select = { series = [1, 2] }
[noise]
kind = "proportional"
[sampler]
draws = 200
tune = 200
chains = 2
[[laws]]
name = "coulomb_viscous"
[[laws]]
name = "stribeck"
label = "stribeck_fixed"
fixed = { delta = 1.0 }
priors = { T_C = { dist = "HalfNormal", scale = 20 } }
[compare]
evidence = false
[[compare.blocked]]
axis = "velocity"
threshold = 0.5
[[sizing]]
at = { velocity = "0.5..6 rad/s" }
capacity = "40 N*m"
confidence = 0.95
"""


def test_a_study_built_in_python_is_the_study_its_file_gives(tmp_path):
    (tmp_path / "twin.toml").write_text(STUDY_TOML)
    from_file = bayesfric.Study.from_toml(tmp_path / "twin.toml")
    built = bayesfric.Study(
        "twin", "robot_joint", select={"series": (1, 2)}, noise="proportional",
        laws=["coulomb_viscous", {"name": "stribeck", "label": "stribeck_fixed", "fixed": {"delta": 1.0},
                                  "priors": {"T_C": bayesfric.Prior("HalfNormal", scale=20)}}],
        sampler={"draws": 200, "tune": 200, "chains": 2},
        compare={"evidence": False, "blocked": [{"axis": "velocity", "threshold": 0.5}]},
        sizing=[{"at": {"velocity": (0.5, 6, "rad/s")}, "capacity": (40, "N*m"), "confidence": 0.95}])
    assert isinstance(built, bayesfric.Study) and isinstance(from_file, bayesfric.Study)
    skip = {"path", "raw"}
    assert {k: v for k, v in vars(built).items() if k not in skip} == \
        {k: v for k, v in vars(from_file).items() if k not in skip}
    assert str(built.path) == "Study('twin')"


@pytest.mark.parametrize(("kwargs", "fragment"), [
    ({"sampler": {"draws": 0}}, "Study('s'): [sampler] draws: must be an integer ≥ 1"),
    ({"sampler": {"walkers": 8}}, "Study('s'): [sampler] walkers: applies only to sampler emcee"),
    ({"laws": ["nope"]}, "Study('s'): laws[0].name: unknown law 'nope'"),
    ({"laws": [3]}, "Study('s'): laws[0]: expected a law name"),
    ({"sizing": [{"at": {"velocity": 3}}]}, "Study('s'): sizing[0].at.velocity: 3 has no unit"),
    ({"sizing": [{"at": {"velocity": (3, "rad/s")}, "capacity": 40}]}, "Study('s'): sizing[0].capacity: 40 has no"),
    ({"sizing": [{"at": {"velocity": "3 rad/s"}, "confidence": 2}]}, "Study('s'): sizing[0].confidence:"),
    ({"compare": {"kfold": 1}}, "Study('s'): [compare] kfold: must be 0 (off) or ≥ 2"),
    ({"noise": {"kind": "gauss"}}, "Study('s'): [noise] kind:"),
    ({"data": bayesfric.load_data("robot_joint")}, "Study('s'): [data] dataset: a study reads its data itself"),
    ({"name": "a/b"}, "Study: name: 'a/b' is not a plain name"),
])
def test_bad_study_arguments_name_the_key(kwargs, fragment):
    args = {"name": "s", "data": "robot_joint", "laws": ["stribeck"]} | kwargs
    with pytest.raises(UserError) as info:
        bayesfric.Study(args.pop("name"), args.pop("data"), **args)
    assert fragment in str(info.value) and "\n" not in str(info.value)


@pytest.mark.slow  # a two-law study: 2 fits, 2 blocked refits, LOO, sizing, report (~60-90 s on the loaded machine)
def test_run_a_python_study_then_size_its_result(tmp_path):
    study = bayesfric.Study("api_run", "robot_joint", noise="proportional", laws=["coulomb_viscous", "stribeck"],
                            sampler={"draws": 200, "tune": 200, "chains": 2},
                            compare={"evidence": False, "failed_fits": "run",  # small fits may fail the gate
                                     "blocked": [{"axis": "velocity", "threshold": 0.5}]},
                            sizing=[{"at": {"velocity": (0.5, 6, "rad/s")}, "capacity": (40, "N*m")}])
    result = bayesfric.run(study, tmp_path)
    assert result.folder == tmp_path / "api_run" and (result.folder / "report.html").is_file()
    assert sorted(result.fits) == ["coulomb_viscous", "stribeck"]
    assert {"elpd_loo", "elpd_cv", "penalty"} <= set(result.scores["metric"])
    assert result.sizing is not None and np.isfinite(result.sizing["p_exceed"]).all()
    tree = result.tree  # results.nc: the same numbers as one DataTree
    assert sorted(tree["scores"].law.values) == ["coulomb_viscous", "stribeck"]
    assert tree["sizing"].sizes["row"] == len(result.sizing)
    np.testing.assert_array_equal(tree["sizing"]["p_exceed"].values, result.sizing["p_exceed"].to_numpy())
    own = bayesfric.size(result)  # the study's own question, from the stored fits
    asked = bayesfric.size(result, at={"velocity": (5, "rad/s")}, capacity=(30, "N*m"))
    assert set(own["capacity"].values) == {40.0} and set(asked["capacity"].values) == {30.0}
    assert np.isfinite(asked["p_exceed"].sel(law=["coulomb_viscous", "stribeck"]).values).all()
    # the study's sizing.csv is a rendering of the same object (computed once)
    from bayesfric.report.sizing import records

    np.testing.assert_array_equal([r["p_exceed"] for r in records(own)], result.sizing["p_exceed"].to_numpy())
    ran = result.sizing_answer  # the run's own object, of which sizing.csv is the table
    assert isinstance(ran, bayesfric.SizingAnswer)
    np.testing.assert_array_equal([r["p_exceed"] for r in records(ran)], result.sizing["p_exceed"].to_numpy())
    np.testing.assert_array_equal(ran["required"].values, own["required"].values)  # and what size() answers
    with pytest.raises(UserError, match="at.temperature: 'temperature' is not an input of the data"):
        bayesfric.size(result, at={"temperature": (20, "degC"), "velocity": (5, "rad/s")})
    with pytest.raises(UserError, match="no report of study 'api_run' in .*bayesfric.run"):
        bayesfric.size(study, at={"velocity": (5, "rad/s")}, reports=tmp_path / "elsewhere")
    again = bayesfric.run(study, tmp_path)  # unchanged: the report is returned as it is, read from its folder
    assert again.tree is not result.tree  # the first result was the run's own, in memory; this one is read back
    for table in ("scores", "ranking", "sizing"):  # the same tables either way, typed as pandas reads the CSV
        assert getattr(again, table).equals(getattr(result, table)), table
    np.testing.assert_array_equal(again.sizing_answer["required"].values, ran["required"].values)  # read back
    assert again.scores.equals(pd.read_csv(result.folder / "scores.csv", keep_default_na=False, na_values=[""]))
    assert again.ranking.equals(pd.read_csv(result.folder / "ranking.csv"))
    for name, fit in result.fits.items():
        np.testing.assert_array_equal(again.fits[name]["posterior"]["T_C"].values, fit["posterior"]["T_C"].values)
    copy = bayesfric.write_report(result, tmp_path / "copy" / "api_run")  # from the tree in memory alone
    for name in ("summary.md", "report.html", "scores.csv", "ranking.csv", "parameters.csv", "sizing.csv"):
        assert (copy / name).read_bytes() == (result.folder / name).read_bytes(), name
    with xr.open_datatree(copy / "results.nc") as saved:
        assert saved.attrs["study"] == "api_run" and "fits" in saved.children
    with pytest.raises(UserError, match="exists and is not empty"):
        bayesfric.write_report(again, copy)
    with pytest.raises(UserError, match="no stored report .*not a fit"):
        bayesfric.write_report(result.fits["stribeck"], tmp_path / "from_a_fit")
    assert not (tmp_path / "from_a_fit").exists()


@pytest.mark.slow  # every docstring example of the API, fits and a study run included (~2 min)
def test_docstring_examples_run():
    from bayesfric.api import fitfile, fitting, reports, sizing, studies

    for module in (fitting, fitfile, sizing, studies, reports):
        failed, tried = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
        assert tried > 0 and failed == 0, module.__name__


@pytest.mark.slow  # example (a): two fits (2 x 300 draws), compare, size (~60 s on the loaded machine)
def test_example_notebook_runs_in_at_most_30_lines_of_api(tmp_path):
    source = (REPO / "examples" / "notebook.py").read_text()
    body = source.split('"""', 2)[2]
    code = [line for line in body.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    assert len(code) <= 30, len(code)
    run = subprocess.run([sys.executable, str(REPO / "examples" / "notebook.py"), "--quick"], capture_output=True,
                         text=True, timeout=600, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "robot_joint: 111 points" in run.stdout and "elpd_loo" in run.stdout
    assert "N*m at 6 rad/s (99 % of |T|); P(|T| > 40 N*m) = " in run.stdout
