"""Law variants (issue 13): hand-computed values of the asymmetric, offset, added, fixed, optional-input
and translational forms, and their equivalence with the registered laws they reproduce."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bayesfric.datasets import DataError
from bayesfric.datasets.synthetic import make_dataset
from bayesfric.laws import get_law
from bayesfric.laws.base import TRAJECTORY_START
from bayesfric.laws.hysteresis import dahl_torque
from bayesfric.laws.variants import (
    VariantError,
    build,
    describe,
    for_data,
    law_of_fit,
    translational_unit,
    vary,
)
from bayesfric.model import build_program
from bayesfric.priors import DataScale

V = np.array([-2.0, -0.5, 0.5, 2.0])


@pytest.mark.parametrize("rotary, translational", [
    ("N*m", "N"), ("N*m*s/rad", "N*s/m"), ("N*m/rad", "N/m"), ("rad", "m"), ("rad/s", "m/s"),
    ("1", "1"), ("N", "N"), ("K", "K"), ("s", "s"),
])
def test_translational_unit(rotary, translational):
    assert translational_unit(rotary) == translational


def test_asymmetric_offset_viscous_by_hand():
    law = vary(get_law("stribeck"), name="s", add=["viscous"], offset=True, asymmetric=["T_C", "offset"],
               fixed={"delta": 1.0})
    assert list(law.params) == ["T_C_pos", "T_C_neg", "dT_s", "v_s", "c_v", "offset_pos", "offset_neg"]
    assert law.constants["delta"].value == 1.0 and law.name == "s"
    p = dict(T_C_pos=1.0, T_C_neg=2.0, dT_s=0.5, v_s=1.0, c_v=0.1, offset_pos=0.3, offset_neg=-0.2)
    # T = sign(v)[T_C(dir) + dT_s e^(-|v|/v_s)] + c_v v + offset(dir), by hand at each speed
    expected = [-(2.0 + 0.5 * math.exp(-2.0)) - 0.2 - 0.2, -(2.0 + 0.5 * math.exp(-0.5)) - 0.05 - 0.2,
                1.0 + 0.5 * math.exp(-0.5) + 0.05 + 0.3, 1.0 + 0.5 * math.exp(-2.0) + 0.2 + 0.3]
    np.testing.assert_allclose(law.mean({"velocity": V}, p), expected, rtol=1e-12)
    # the derived static level is reported per side
    assert law.derived_values(p) == {"T_s_pos": 1.5, "T_s_neg": 2.5}
    assert "direction-dependent T_C, offset" in describe(law)


def test_offset_term_by_hand():
    law = vary(get_law("coulomb"), offset=True)
    np.testing.assert_allclose(law.mean({"velocity": V}, {"T_C": 2.0, "offset": -0.5}), [-2.5, -2.5, 1.5, 1.5])
    assert law.params["offset"].unit == "N*m" and law.params["offset"].prior.scaled_by == {"response": 1}
    assert not law.sign_definite  # an offset may push friction across zero


def test_added_viscous_is_armstrong_helouvry():
    """Stribeck + viscous composed from parts equals the registered Armstrong-Hélouvry law."""
    p = {"T_C": 1.0, "dT_s": 0.4, "v_s": 0.3, "delta": 0.7, "c_v": 0.2}
    composed = vary(get_law("stribeck"), add=["viscous"])
    np.testing.assert_allclose(composed.mean({"velocity": V}, p),
                               get_law("armstrong_helouvry").mean({"velocity": V}, p), rtol=1e-12)
    assert composed.params["c_v"] == get_law("armstrong_helouvry").params["c_v"]


def test_clashing_part_parameters_are_renamed():
    law = vary(get_law("coulomb"), add=["coulomb_viscous"])
    assert list(law.params) == ["T_C", "T_C_coulomb_viscous", "c_v"]
    np.testing.assert_allclose(law.mean({"velocity": V}, {"T_C": 1.0, "T_C_coulomb_viscous": 0.5, "c_v": 0.1}),
                               np.sign(V) * 1.5 + 0.1 * V)


def _loops(n=60, amplitude=0.02):
    angle = amplitude * np.sin(np.linspace(0, 4 * np.pi, n))
    start = np.zeros(n, dtype=bool)
    start[0] = True
    return angle, start


def test_fixed_exponent_and_the_alias_users_type():
    """dahl with fixed i = 1.5 is Dahl's torque function at i = 1.5; ``dahl_i1p5`` is that alias."""
    angle, start = _loops()
    preload = np.full(angle.size, 60.0)
    inputs = {"angle": angle, "preload": preload, TRAJECTORY_START: start}
    p = {"F_c0": 0.01, "gamma": 0.8, "x_c0": 4e-3}
    fixed = vary(get_law("dahl"), fixed={"i": 1.5})
    assert "i" not in fixed.params and fixed.constants["i"].value == 1.5
    direct = dahl_torque(angle, preload, start, i=1.5, kappa=0.0, P_ref=get_law("dahl").constants["P_ref"].value,
                         F_start=1.0, **p)
    np.testing.assert_allclose(fixed.mean(inputs, p), direct, rtol=1e-12)
    alias = get_law("dahl_i1p5")
    assert alias.recipe == {"base": "dahl", "fixed": {"i": 1.5}} and list(alias.params) == list(fixed.params)
    np.testing.assert_allclose(alias.mean(inputs, p), direct, rtol=1e-12)


def test_dahl_without_preload_holds_it_at_the_reference():
    """Without a preload input the law equals Dahl at P = P_ref (factor 1); γ, κ are not sampled."""
    angle, start = _loops()
    dahl = get_law("dahl")
    lean = vary(dahl, without=["preload"])
    assert "preload" not in lean.inputs and "gamma" not in lean.params
    assert lean.constants["gamma"].value == 0.0
    p = {"F_c0": 0.01, "x_c0": 4e-3, "i": 1.3}
    p_ref = dahl.constants["P_ref"].value
    full = dahl.mean({"angle": angle, "preload": np.full(angle.size, p_ref), TRAJECTORY_START: start},
                     p | {"gamma": 1.7})
    np.testing.assert_allclose(lean.mean({"angle": angle, TRAJECTORY_START: start}, p), full, rtol=1e-12)


def test_translational_dahl_is_the_same_function_in_metres():
    angle, start = _loops()
    moved = vary(get_law("dahl"), without=["preload"], motion="translational")
    assert moved.inputs == ("displacement", TRAJECTORY_START) and moved.response == "force"
    assert moved.params["F_c0"].unit == "N" and moved.params["x_c0"].unit == "m"
    assert moved.derived["sigma_ref"].unit == "N/m"
    p = {"F_c0": 0.01, "x_c0": 4e-3, "i": 1.3}
    np.testing.assert_allclose(moved.mean({"displacement": angle, TRAJECTORY_START: start}, p),
                               vary(get_law("dahl"), without=["preload"]).mean(
                                   {"angle": angle, TRAJECTORY_START: start}, p), rtol=1e-12)
    # the knee prior follows the loops' scale: median 5 % of the largest displacement
    resolved = moved.params["x_c0"].prior.resolve(DataScale(1e-3, {"displacement": 20e-6}))
    assert math.isclose(math.exp(resolved.args["loc"]), 0.05 * 20e-6, rel_tol=1e-9)


def _force_data(inputs, trajectory=False):
    n = len(next(iter(inputs.values())))
    groups = {"run": np.zeros(n, dtype=int)} if trajectory else None
    return make_dataset(inputs, np.full(n, 1e-3), response_quantity="force", groups=groups,
                        trajectory="run" if trajectory else None)


def test_for_data_picks_motion_and_optional_inputs():
    x = 20e-6 * np.sin(np.linspace(0, 4 * np.pi, 40))
    law = for_data(get_law("dahl"), _force_data({"displacement": x}, trajectory=True))
    assert law.recipe == {"base": "dahl", "without": ["preload"], "motion": "translational"}
    program = build_program(get_law("dahl"), _force_data({"displacement": x}, trajectory=True))
    assert program.law.name == "dahl" and set(program.inputs) == {"displacement", TRAJECTORY_START}
    with pytest.raises(DataError, match="rotary .torque. data only"):
        for_data(get_law("thermal_mass2_viscous"), _force_data({"linear_velocity": x}))
    with pytest.raises(DataError, match="no input 'time' \\(time since"):
        build_program(get_law("lugre"), _force_data({"linear_velocity": x}, trajectory=True))


def test_recipe_round_trip_through_fit_attrs():
    law = vary(get_law("stribeck"), name="asym", offset=True, asymmetric=["T_C"], motion="translational")
    again = law_of_fit({"law": "asym", "law_recipe": json.dumps(law.recipe)})
    assert again.name == "asym" and list(again.params) == list(law.params)
    assert law_of_fit({"law": "stribeck", "law_recipe": ""}) is get_law("stribeck")
    p = {"T_C_pos": 1.0, "T_C_neg": 0.5, "dT_s": 0.2, "v_s": 0.1, "delta": 1.0, "offset": 0.1}
    np.testing.assert_allclose(again.mean({"linear_velocity": V}, p), law.mean({"linear_velocity": V}, p))


def test_variant_errors_name_their_option():
    with pytest.raises(VariantError) as err:
        vary(get_law("coulomb"), fixed={"T_C": -1.0})
    assert err.value.key == "fixed.T_C" and "outside the support" in err.value.problem
    with pytest.raises(VariantError) as err:
        vary(get_law("dahl"), asymmetric=["F_c0"])
    assert err.value.key == "asymmetric"
    with pytest.raises(VariantError, match="unknown variant key"):
        build({"base": "coulomb", "mirror": True})


def test_cli_fix_builds_the_fixed_variant():
    from bayesfric.commands import parse_fix

    law = parse_fix(["i=1.5", "F_start=0"], get_law("dahl"))
    assert law.constants["i"].value == 1.5 and law.constants["F_start"].value == 0.0 and "i" not in law.params
    assert parse_fix(None, get_law("dahl")) is get_law("dahl")


def test_study_entry_builds_its_variant(tmp_path):
    from bayesfric.study import load_study

    (tmp_path / "s.toml").write_text(
        '[data]\ndataset = "robot_joint"\n[compare]\nevidence = false\n'
        '[[laws]]\nname = "stribeck"\n'
        '[[laws]]\nname = "stribeck"\nlabel = "stribeck_plus"\nadd = "viscous"\noffset = true\n'
        'asymmetric = "T_C"\nfixed = { delta = 1.0 }\nconstants = {}\n')
    a, b = load_study(tmp_path / "s.toml").laws
    assert (a.name, a.law, a.build()) == ("stribeck", "stribeck", get_law("stribeck"))
    law = b.build()
    assert law.name == "stribeck_plus" and b.law == "stribeck"
    assert law.recipe == {"base": "stribeck", "add": ["viscous", "offset"], "asymmetric": ["T_C"],
                          "fixed": {"delta": 1.0}}
