"""Actuator sizing (issue #10): hand-computed pieces, predictions from hand-made fits, study-file
questions, and one tiny study end to end (report sections, sizing.csv, fan figure, `bayesfric size`)."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from bayesfric import sizing
from bayesfric.laws import get_law
from bayesfric.model import Noise
from bayesfric.sizing import SizingError, make_question
from tests.bench_data import write_bench
from tests.sizing_helpers import hand_fit

C, D = 4, 500
TESTED = {"velocity": np.linspace(0.1, 2.0, 12)}


def const(value: float) -> np.ndarray:
    return np.full((C, D), float(value))


# -- hand-computed pieces ---------------------------------------------------------------------------
def test_extrapolation_distance_by_hand():
    d = sizing.extrapolation_distance([1.0, 2.0, 4.0, 6.0, 8.0, 12.0], 2.0, 6.0)
    np.testing.assert_allclose(d, [0.25, 0.0, 0.0, 0.0, 0.5, 1.5])
    np.testing.assert_array_equal(sizing.extrapolation_distance([3.0, 3.5], 3.0, 3.0), [0.0, np.inf])


def test_variance_split_by_hand_and_by_the_law_of_total_variance():
    # two laws, weights 1/4 and 3/4; means 10 and 14; parameter variances 1 and 3; noise 4 and 2
    param, noise, between = sizing.variance_split([1.0, 3.0], np.array([[10.0], [14.0]]), np.array([[1.0], [3.0]]),
                                                  np.array([[4.0], [2.0]]))
    assert param[0] == pytest.approx(0.25 * 1 + 0.75 * 3)  # 2.5
    assert noise[0] == pytest.approx(0.25 * 4 + 0.75 * 2)  # 2.5
    assert between[0] == pytest.approx(0.25 * (10 - 13) ** 2 + 0.75 * (14 - 13) ** 2)  # 3.0
    rng = np.random.default_rng(1)  # the three terms add up to the variance of the mixture
    n = 400_000
    law = rng.random(n) < 0.75
    mu = np.where(law, 14 + rng.normal(0, math.sqrt(3), n), 10 + rng.normal(0, 1, n))
    y = mu + rng.normal(0, 1, n) * np.where(law, math.sqrt(2), 2.0)
    assert y.var() == pytest.approx(param[0] + noise[0] + between[0], rel=0.01)


def test_weighted_quantiles_invert_the_weighted_cdf():
    values = np.array([[1.0], [2.0], [3.0]])
    q = sizing.weighted_quantiles(values, np.array([0.3, 0.5, 0.2]), [0.1, 0.3, 0.31, 0.8, 0.81, 1.0])
    assert [float(q[k][0]) for k in (0.1, 0.3, 0.31, 0.8, 0.81, 1.0)] == [1.0, 1.0, 2.0, 2.0, 3.0, 3.0]
    x = np.random.default_rng(0).normal(size=(1001, 2))
    equal = sizing.weighted_quantiles(x, np.ones(1001), [0.05, 0.5])
    np.testing.assert_allclose(equal[0.5], np.quantile(x, 0.5, axis=0, method="inverted_cdf"))


def test_exclusion_reasons_come_from_the_verdicts_boolean():
    assert sizing.exclusion(True) is None
    assert sizing.exclusion(True, "R-hat 1.02 > 1.01") is None  # the boolean decides, not the text
    assert sizing.exclusion(False, "R-hat 1.02 > 1.01") == "failed the diagnostics gate (R-hat 1.02 > 1.01)"
    assert sizing.exclusion(False) == "failed the diagnostics gate"
    # an unreliable evidence estimate is no reason about a law's predictions: exclusion() does not
    # even take it (issue #28); the basis keeps it in /diagnostics evidence_agree, shown only


# -- parsing questions ------------------------------------------------------------------------------
def test_values_ranges_and_units():
    assert sizing.parse_value("8 MN*m", "bending_moment").lo == pytest.approx(8e6)
    assert sizing.parse_value("5 °C", "temperature").lo == pytest.approx(278.15)
    v = sizing.parse_value("0.5..6 rad/s", "velocity")
    assert v.is_range and (v.lo, v.hi) == (0.5, 6.0) and len(v.points()) == sizing.RANGE_POINTS
    rpm = sizing.parse_value("1.04 rpm", "velocity")
    assert rpm.lo == pytest.approx(1.04 * 2 * math.pi / 60) and float(rpm.display(rpm.lo)) == pytest.approx(1.04)
    q = make_question({"velocity": "0.5..6 rad/s"}, 0.9, capacity="40 N*m", energy_rotation="90 deg")
    assert q.axis == "velocity" and q.energy_rotation.lo == pytest.approx(math.pi / 2)


@pytest.mark.parametrize(("at", "kwargs", "fragment"), [
    ({"bending_moment": "8 kN"}, {}, "at.bending_moment: '8 kN': unit 'kN' has dimension"),
    ({"velocity": "6..0.5 rad/s"}, {}, "must go from the smaller to the larger"),
    ({"temperature": "-300 degC"}, {}, "outside the physical bound of temperature (> 0 K)"),
    ({"velocity": "fast"}, {}, "cannot read 'fast'"),
    ({"velocity": "8"}, {}, "has no unit"),
    ({"velocity": 8}, {}, "give the value with its unit as a string"),
    ({"speed": "2 rad/s"}, {}, "'speed' is not an operating quantity"),
    ({"velocity": "1..2 rad/s", "temperature": "1..2 degC"}, {}, "at most one input may be a range"),
    ({"velocity": "2 rad/s"}, {"capacity": "40 rpm"}, "capacity: '40 rpm' is neither a torque"),
    ({"velocity": "2 rad/s"}, {"energy_rotation": "0..90 deg"}, "a single value is needed here"),
])
def test_bad_questions_name_the_key(at, kwargs, fragment):
    with pytest.raises(SizingError) as info:
        make_question(at, 0.9, **kwargs)
    assert fragment in str(info.value) and "\n" not in str(info.value)


def test_cli_point_syntax():
    assert sizing.parse_at("bending_moment=8 MN*m, velocity=1.04 rpm") == {"bending_moment": "8 MN*m",
                                                                            "velocity": "1.04 rpm"}
    for bad, fragment in (("velocity 2 rad/s", "expected INPUT=VALUE"), ("velocity=1 rpm, velocity=2 rpm", "twice"),
                          ("=2 rpm", "name is missing")):
        with pytest.raises(SizingError, match=fragment):
            sizing.parse_at(bad)


# -- predictions from hand-made fits ----------------------------------------------------------------
BLOCKED = sizing.Scheme("blocked", "velocity", "upper")


def _answer(question, sources, data=None, schemes=(BLOCKED,)):
    question = sizing.check_question(question, ["velocity"], ["velocity"], "torque")
    return sizing.answer_question(question, sources, data or {"velocity": np.array([0.1, 2.0])}, schemes=schemes,
                                  seed=3)


def _weights(blocked: float, loo: float) -> dict[str, float]:
    return {"blocked": blocked, sizing.LOO: loo}


def test_per_law_quantiles_exceedance_average_and_split_on_known_draws():
    rng = np.random.default_rng(0)
    truth = hand_fit("coulomb_viscous", {"T_C": const(5), "c_v": const(2), "sigma": const(0.5)}, TESTED)
    spread = hand_fit("coulomb", {"T_C": 8 + 0.3 * rng.normal(size=(C, D)), "sigma": const(0.5)}, TESTED)
    failed = hand_fit("coulomb", {"T_C": const(50), "sigma": const(0.5)}, TESTED)
    q = make_question({"velocity": "4 rad/s"}, 0.9, capacity="12 N*m", energy_rotation="90 deg")
    a = _answer(q, [sizing.LawSource("coulomb_viscous", truth, _weights(0.56, 0.5)),
                    sizing.LawSource("coulomb", spread, _weights(0.24, 0.5)),
                    sizing.LawSource("failed_law", failed, _weights(0.2, 0.0), excluded="failed the diagnostics gate")])
    cv, co, bad = a.laws
    assert bad.excluded and bad.weight == 0 and [w.name for w in a.used] == ["coulomb_viscous", "coulomb"]
    assert cv.mean_fn.q(0.05)[0] == pytest.approx(13.0) and cv.mean_fn.q(0.95)[0] == pytest.approx(13.0)
    assert cv.var_param[0] == pytest.approx(0.0, abs=1e-20) and cv.var_noise[0] == pytest.approx(0.25)
    assert cv.noisy.q(0.95)[0] == pytest.approx(13 + 1.645 * 0.5, abs=0.06)  # normal quantile, MC error
    assert cv.required[0] == pytest.approx(13 + 1.2816 * 0.5, abs=0.06)
    z = 4 * cv.p_se[0]  # P(|T| > 12) = P(Z > -2) = 0.977
    assert cv.p_exceed[0] == pytest.approx(0.97725, abs=max(z, 0.005)) and 0 < cv.p_se[0] < 0.01
    assert co.p_exceed[0] == 0 and co.p_bound[0] == pytest.approx(3 / (C * D))  # no draw exceeds
    # the average: renormalised weights 0.7 / 0.3, the failed law never mixed in
    mix = a.average
    assert mix.weights == pytest.approx({"coulomb_viscous": 0.7, "coulomb": 0.3})
    assert mix.p_exceed[0] == pytest.approx(0.7 * cv.p_exceed[0])
    m = np.array([13.0, co.mean_fn.mean[0]])
    assert mix.var_between[0] == pytest.approx(0.7 * 0.3 * (m[0] - m[1]) ** 2)
    assert mix.var_param[0] == pytest.approx(0.3 * co.var_param[0]) and mix.var_noise[0] == pytest.approx(0.25)
    assert a.average_loo.weights == pytest.approx({"coulomb_viscous": 0.5, "coulomb": 0.5})
    assert a.energy(cv.noisy, 0.9)[0] == pytest.approx(cv.required[0] * math.pi / 2)
    # 4 rad/s is (4 - 2) / 1.9 = 1.05 tested ranges beyond the data: warned
    assert a.distance["velocity"][0] == pytest.approx(2 / 1.9)
    assert any("rests on extrapolation" in w for w in a.warnings)
    assert a.fan is not None and a.fan.axis == "velocity" and a.fan.x[-1] == pytest.approx(4.0)


def test_noise_models_and_a_new_units_group_offset():
    x = {"velocity": np.array([1.0, 3.0])}
    rng = np.random.default_rng(2)
    nu = np.where(rng.random((C, D)) < 0.25, 1.5, 10.0)
    fit = hand_fit("coulomb", {"T_C": const(10), "sigma": const(1.0), "nu": nu}, TESTED, noise=Noise("student_t"))
    draws = sizing.predict(fit, x)
    inf = ~np.isfinite(draws.noise_var[..., 0])
    assert inf.mean() == pytest.approx(0.25, abs=0.03) and np.all(draws.noise_var[~inf] == pytest.approx(1.25))
    fit = hand_fit("coulomb", {"T_C": const(10), "sigma_rel": const(0.1), "sigma_floor": const(0.3)}, TESTED,
                   noise=Noise("proportional"))
    np.testing.assert_allclose(sizing.predict(fit, x).noise_var, 0.1**2 * 100 + 0.09)
    fit = hand_fit("coulomb", {"T_C": const(10), "sigma": const(0.1), "group_sd": const(0.2),
                               "group_z": np.zeros((C, D, 2))}, TESTED, noise=Noise(group="series"))
    mu = sizing.predict(fit, x).mu
    assert np.log(mu[..., 0]).std() == pytest.approx(0.2, rel=0.08)  # a new unit: offset ~ N(0, group_sd)
    np.testing.assert_allclose(mu[..., 0], mu[..., 1])  # the same unit at every point


def test_ar1_noise_sizes_through_the_programs_own_observation_model():
    """Issue #28: sizing draws noise from the fit's Program (the likelihood's distribution), not a
    restatement: ar1 is sized at its stationary marginal sd σ / sqrt(1 − ρ²) (it raised
    KeyError('sigma_rel') when it fell into a proportional branch)."""
    fit = hand_fit("coulomb", {"T_C": const(10), "sigma": const(0.6)}, TESTED)
    fit.attrs["noise"] = '{"kind": "ar1", "group": null, "sigma": null}'  # hand_fit's data have no trajectories
    fit["posterior"] = fit["posterior"].to_dataset().assign(rho=fit["posterior"]["sigma"] * 0 + 0.8)
    draws = sizing.predict(fit, {"velocity": np.array([1.0, 3.0])})
    np.testing.assert_allclose(draws.noise_var, 0.6**2 / (1 - 0.8**2))
    assert np.std(draws.y[..., 0] - draws.mu[..., 0]) == pytest.approx(0.6 / math.sqrt(1 - 0.64), rel=0.05)


def test_a_law_with_unidentified_parameters_is_used_and_said_so():
    """A fit whose chains did not mix along parameters the data do not determine, while they agree
    on every row (verdict UNIDENTIFIED: passed), is sized, and the answer names the parameters."""
    from bayesfric.inference.diagnostics import Verdict

    fit = hand_fit("coulomb_viscous", {"T_C": const(5), "c_v": const(2), "sigma": const(0.5)}, TESTED)
    fit.attrs["diagnostics"] = Verdict(True, 1.16, 17.0, 7.0, 0, 0.7, None, ["R-hat 1.160 > 1.01"], 1.004, 2572.0,
                                       True, unidentified=("c_v",)).to_json()
    a = _answer(make_question({"velocity": "1 rad/s"}, 0.9), [sizing.LawSource("coulomb_viscous", fit)], schemes=())
    assert [w.name for w in a.used] == ["coulomb_viscous"]
    assert any(w.startswith("coulomb_viscous: c_v not identified by the data") for w in a.warnings)
    fit.attrs["diagnostics"] = Verdict(True, 1.001, 2000.0, 2000.0, 0, 0.9, None).to_json()
    again = _answer(make_question({"velocity": "1 rad/s"}, 0.9), [sizing.LawSource("coulomb_viscous", fit)],
                    schemes=())
    assert not any("not identified" in w for w in again.warnings)


def test_student_t_with_infinite_variance_is_reported():
    nu = np.where(np.random.default_rng(4).random((C, D)) < 0.1, 1.2, 30.0)
    fit = hand_fit("coulomb", {"T_C": const(10), "sigma": const(1.0), "nu": nu}, TESTED, noise=Noise("student_t"))
    a = _answer(make_question({"velocity": "1 rad/s"}, 0.99), [sizing.LawSource("coulomb", fit)], schemes=())
    assert a.laws[0].infinite_noise == pytest.approx(0.1, abs=0.02)
    assert np.isfinite(a.laws[0].var_noise[0]) and any("nu ≤ 2" in w for w in a.warnings)


def test_trajectory_laws_are_sized_by_their_steady_state():
    """Dahl at constant speed is F_c0 (P/P_ref)^γ sgn v (tests/test_steady_state.py checks every
    stateful law against its long run); the angle is no input of its steady state."""
    from bayesfric.laws.steady import STEADY_NOTE

    draws = {"F_c0": const(2.0), "gamma": const(1.0), "x_c0": const(0.01), "i": const(1.5), "sigma": const(0.1)}
    fit = hand_fit("dahl", draws, {"angle": np.linspace(0, 1, 6), "preload": np.full(6, 50.0)})
    d = sizing.predict(fit, {"velocity": np.array([-1.0, 2.0]), "preload": np.array([100.0, 25.0])})
    p_ref = get_law("dahl").constants["P_ref"].value
    np.testing.assert_allclose(d.mu[0, 0], 2.0 * np.array([-100.0, 25.0]) / p_ref, rtol=1e-12)
    assert d.steady == STEADY_NOTE
    with pytest.raises(SizingError, match="reads velocity"):
        sizing.predict(fit, {"angle": np.array([0.1]), "preload": np.array([10.0])})


# -- study files --------------------------------------------------------------------------------------
@pytest.fixture
def bench(tmp_path):
    """A small simulated data set (CSV + sidecar): coulomb_viscous truth, 0.1-2 rad/s."""

    write_bench(tmp_path, np.geomspace(0.1, 2.0, 24))
    return tmp_path


SIZING = '[[sizing]]\nlabel = "top speed"\nat = { velocity = "1..4 rad/s" }\nconfidence = 0.9\ncapacity = "12 N*m"\n'


def tiny_study(sizing_text=SIZING, laws=("coulomb", "coulomb_viscous")):
    return ('[study]\nname = "tiny"\n[data]\ndataset = "bench.csv"\n'
            # four chains: with two, the cold-started blocked fold's split R-hat (4 half-chains)
            # scatters around the 1.01 gate (1.012 measured Nov 2026) and drops the law's weight
            '[sampler]\ndraws = 800\ntune = 300\nchains = 4\n'
            + "".join(f'[[laws]]\nname = "{w}"\n' for w in laws)
            + '[compare]\nloo = true\nevidence = false\n'
            '[[compare.blocked]]\naxis = "velocity"\nthreshold = 1.2\nlabel = "above 1.2"\n' + sizing_text)


@pytest.mark.parametrize(("text", "fragment"), [
    ('[[sizing]]\nat = { velocity = "2 m" }\n', "sizing[0].at.velocity: '2 m': unit 'm' has dimension"),
    ('[[sizing]]\nat = { velocity = "2 rad/s" }\nconfidence = 1.5\n', "sizing[0].confidence: must be a number > 0"),
    ('[[sizing]]\nat = { velocity = "2 rad/s" }\ncapacity = "3 kg"\n', "sizing[0].capacity: '3 kg' is neither"),
    ('[[sizing]]\nat = { velocity = "2 rad/s" }\nmargin = 2\n', "sizing[0]: unknown key 'margin'"),
    ('[[sizing]]\nconfidence = 0.9\n', "sizing[0].at: is required"),
    ('[[sizing]]\nat = { temperature = "20 degC" }\n', "sizing[0].at.temperature: 'temperature' is not an input of "
                                                      "the data"),
    ('[[sizing]]\nat = { velocity = "2 rad/s" }\ncapacity = "3 N"\n', "sizing[0].capacity: '3 N': unit 'N' has "
                                                                     "dimension"),
])
def test_sizing_entries_are_validated_before_anything_is_written(bench, text, fragment):
    from bayesfric.study import StudyError, load_study
    from bayesfric.study.plan import _prepare

    path = bench / "s.toml"
    path.write_text(tiny_study(text))
    with pytest.raises(StudyError) as info:
        load_study(path)
        _prepare(path, bench / "reports", quick=False)
    assert fragment in str(info.value) and str(info.value).startswith(str(path)) and "\n" not in str(info.value)
    assert not (bench / "reports").exists()


def test_every_input_a_law_reads_is_required(tmp_path):
    from bayesfric.study import StudyError, load_study
    from bayesfric.study.runner import load_study_data, sizing_questions

    text = (tiny_study('[[sizing]]\nat = { velocity = "1.04 rpm" }\n', laws=("rothe_erde", "palmgren"))
            .replace('"bench.csv"', '"pitch_bearing"').replace('threshold = 1.2', 'threshold = 0.09'))
    (tmp_path / "s.toml").write_text(text)
    study = load_study(tmp_path / "s.toml")
    with pytest.raises(StudyError, match=r"sizing\[0\].at: give a value for every input the laws read: missing "
                                         "bending_moment"):
        sizing_questions(study, load_study_data(study))


def test_shipped_sizing_questions():
    from bayesfric.study import STUDIES_DIR, load_study

    asked = {name: load_study(STUDIES_DIR / f"{name}.toml").sizing for name in
             ("pitch_bearing", "robot_joint", "unwinder")}
    (pitch,) = asked["pitch_bearing"]
    assert pitch.at["bending_moment"].lo == pytest.approx(8e6) and pitch.energy_rotation.lo == pytest.approx(np.pi / 2)
    assert asked["robot_joint"][0].axis == "velocity" and asked["robot_joint"][0].at["velocity"].hi == 6.0
    assert asked["unwinder"][0].at["temperature"].lo == pytest.approx(278.15)


def test_tiny_study_end_to_end_and_size_without_refitting(bench, monkeypatch, capsys):
    """The runner writes the sizing basis into results.nc, sizing.csv, the fan figure and the sections; `bayesfric size`
    answers the same question from the stored fits (the samplers are disabled) with the same numbers,
    and a single fit answers --at."""
    import functools

    from bayesfric import compare, inference
    from bayesfric.cli import main
    from bayesfric.pipeline.runner import run_study

    (bench / "s.toml").write_text(tiny_study())
    folder = run_study(bench / "s.toml", out_root=bench / "reports")
    assert not (folder / "weights.json").exists()  # the basis lives in results.nc, not in a JSON file
    basis = sizing.read_basis(folder)
    assert sizing.basis_schemes(basis) == [sizing.Scheme("above 1.2", "velocity", "upper", False)]
    node = basis["sizing_basis"]
    assert set(node["law"].values) == {"coulomb", "coulomb_viscous"}
    assert (node["miss_n"].sel(scheme="above 1.2") > 0).all() and (node["miss_rate"] >= 0).all()
    assert list(node["fit"].values) == ["fits/coulomb.nc", "fits/coulomb_viscous.nc"]
    with (folder / "sizing.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == sizing.RANGE_POINTS * 4  # two laws, the blocked-weight average and the LOO one
    top = [r for r in rows if r["governing"] == "True" and r["role"] == "average"]
    assert len(top) == 1 and float(top[0]["velocity"]) == pytest.approx(4.0)
    assert float(top[0]["distance[velocity]"]) == pytest.approx((4 - 2) / 1.9)
    assert float(top[0]["var_between"]) >= 0 and 0 <= float(top[0]["p_exceed"]) <= 1
    assert top[0]["basis"] == "stacking 'above 1.2'"  # the blocked fold that extrapolates this way
    cal = {k: float(top[0][k]) for k in ("calibrated_q5", "calibrated_q50", "calibrated_q95", "calibrated_required")}
    assert cal["calibrated_q5"] <= float(top[0]["mean_fn_q5"]) + 1e-9  # widened, never narrowed
    assert cal["calibrated_q95"] >= float(top[0]["mean_fn_q95"]) - 1e-9
    assert cal["calibrated_required"] >= float(top[0]["required"]) - 1e-9
    assert 0 <= float(top[0]["calibrated_p_exceed"]) <= 1
    assert (folder / "figures" / "sizing_1.png").stat().st_size > 10_000
    summary = (folder / "summary.md").read_text()
    assert "## Sizing" in summary and "MODEL AVERAGE" in summary and "between-law disagreement" in summary
    assert "figures/sizing_1.png" in summary and "rests on extrapolation" in summary
    assert "- Sizing 'top speed': required \\|torque\\| **" in summary  # the headline among the findings
    assert "calibrated for model-form error" in summary  # the headline quotes the calibrated number
    # the recommendation names the basis sizing uses (one object, chosen once per question)
    assert "Sizing uses, per question: 'top speed' by stacking 'above 1.2'" in summary
    assert "the recommendation's weights" in summary
    assert "<h2>Sizing</h2>" in (folder / "report.html").read_text()

    @functools.wraps(inference.SAMPLERS["nuts"])  # keeps the signature the schema reads defaults from
    def no_sampling(*args, **kwargs):
        raise AssertionError("size refitted a law")

    monkeypatch.setitem(inference.SAMPLERS, "nuts", no_sampling)
    monkeypatch.setattr(compare.RefitEngine, "run", no_sampling)
    capsys.readouterr()
    assert main(["size", str(bench / "s.toml"), "--reports", str(bench / "reports")]) == 0
    out = capsys.readouterr().out
    assert "MODEL AVERAGE" in out and "variance split" in out and "Extrapolation distance" in out
    required = f"{float(top[0]['required']):.4g}"
    assert required in out  # the same number as the study's sizing.csv: same fits, weights and seed
    fit = folder / "fits" / "coulomb_viscous.nc"
    assert main(["size", str(fit), "--at", "velocity=3 rad/s", "--capacity", "12 N*m", "--confidence", "0.95"]) == 0
    out = capsys.readouterr().out
    assert "coulomb_viscous" in out and "MODEL AVERAGE" not in out and "P(|torque| > 12 N·m)" in out
    assert "weight" not in out.split("coulomb_viscous", 1)[1].split("\n")[0]  # one fit: no weight columns
    assert "no calibrated numbers" in out
