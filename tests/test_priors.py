"""Prior specs: printing, serialisation, overrides and the data-scaling rule."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bayesfric.datasets.synthetic import make_dataset
from bayesfric.laws import get_law
from bayesfric.model import build_program
from bayesfric.priors import DataScale, Prior, PriorError


def test_prints_cleanly():
    assert str(Prior("LogNormal", loc=0.0, scale=0.5)) == "LogNormal(loc=0, scale=0.5)"
    assert str(Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "velocity": -1})) == (
        "HalfNormal(scale=1) × R·X[velocity]^-1"
    )


def test_round_trip_dict():
    p = Prior("TruncatedNormal", loc=1.0, scale=2.0, low=0.0, high=5.0, scaled_by={"response": 1})
    assert Prior.from_dict(p.to_dict()) == p


@pytest.mark.parametrize(
    "bad", [dict(dist="Nope", scale=1.0), dict(dist="Normal", loc=0.0), dict(dist="HalfNormal", scale=math.inf), {}]
)
def test_invalid_specs_raise(bad):
    with pytest.raises(PriorError):
        Prior.from_dict(bad)


def test_scaling_rule_hand_computed():
    # R = 20 N·m (largest |response|), X[velocity] = 4 rad/s (largest |velocity|)
    scale = DataScale.of(np.array([-20.0, 5.0, np.nan]), {"velocity": np.array([-4.0, 0.5])})
    assert scale.response == 20.0 and scale.inputs["velocity"] == 4.0
    viscous = Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "velocity": -1}).resolve(scale)
    assert viscous.args["scale"] == pytest.approx(20.0 / 4.0)
    lognormal = Prior("LogNormal", loc=-3.0, scale=1.5, scaled_by={"velocity": 1}).resolve(scale)
    assert lognormal.args["loc"] == pytest.approx(-3.0 + math.log(4.0))  # median 0.05 × 4 rad/s
    assert lognormal.args["scale"] == 1.5
    rate = Prior("Exponential", rate=2.0, scaled_by={"response": 1}).resolve(scale)
    assert rate.args["rate"] == pytest.approx(2.0 / 20.0)


def test_all_zero_column_scales_to_one():
    scale = DataScale.of(np.zeros(3), {"velocity": np.zeros(3)})
    assert scale.response == 1.0 and scale.inputs["velocity"] == 1.0


@given(factor=st.floats(min_value=1e-3, max_value=1e6))
def test_scaling_is_equivariant(factor):
    """Rescaling the response by c rescales a response-scaled prior's scale by c."""
    base = Prior("HalfNormal", scale=1.0, scaled_by={"response": 1})
    a = base.resolve(DataScale(2.0, {}))
    b = base.resolve(DataScale(2.0 * factor, {}))
    assert b.args["scale"] == pytest.approx(a.args["scale"] * factor, rel=1e-12)


def test_override_by_name_and_unknown_name():
    ds = make_dataset({"velocity": np.linspace(-1, 1, 5)}, np.linspace(-1, 1, 5))
    law = get_law("coulomb")
    program = build_program(law, ds, priors={"T_C": {"dist": "LogNormal", "loc": 0.0, "scale": 0.3}})
    assert str(program.resolved["T_C"]) == "LogNormal(loc=0, scale=0.3)"
    with pytest.raises(PriorError, match="unknown parameter 'nope'"):
        build_program(law, ds, priors={"nope": Prior("HalfNormal", scale=1.0)})
