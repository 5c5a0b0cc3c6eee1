"""A declaration that disagrees with its function, the vocabulary or the unit registry fails."""

import jax.numpy as jnp
import pytest

from bayesfric.laws.base import REGISTRY, LawDeclarationError, Param, law
from bayesfric.priors import Prior

P = Param("N*m", Prior("HalfNormal", scale=1.0), "a level", "test")


def _declare(fn, **overrides):
    spec = dict(name=f"test_{fn.__name__}", family="test", inputs=("velocity",), response="torque",
                source="test", params={"T": P})
    spec.update(overrides)
    try:
        return law(**spec)(fn)
    finally:
        REGISTRY.pop(spec["name"], None)


def test_signature_mismatch():
    def f(velocity, wrong):
        """Doc."""
        return velocity * wrong

    with pytest.raises(LawDeclarationError, match="signature"):
        _declare(f)


def test_unknown_input():
    def f(speed, T):
        """Doc."""
        return speed * T

    with pytest.raises(LawDeclarationError, match="unknown input 'speed'"):
        _declare(f, inputs=("speed",))


@pytest.mark.parametrize("unit", ["", "furlongs_per_fortnight_squared_x"])
def test_missing_or_bad_unit(unit):
    def f(velocity, T):
        """Doc."""
        return jnp.sign(velocity) * T

    with pytest.raises(LawDeclarationError, match="unit"):
        _declare(f, params={"T": Param(unit, Prior("HalfNormal", scale=1.0), "m", "s")})


def test_missing_source():
    def f(velocity, T):
        """Doc."""
        return jnp.sign(velocity) * T

    with pytest.raises(LawDeclarationError, match="meaning and a source"):
        _declare(f, params={"T": Param("N*m", Prior("HalfNormal", scale=1.0), "m", "")})


def test_duplicate_name():
    def coulomb(velocity, T):
        """Doc."""
        return velocity * T

    with pytest.raises(LawDeclarationError, match="already registered"):
        law(name="coulomb", family="x", inputs=("velocity",), response="torque", source="s",
            params={"T": P})(coulomb)


def test_prior_scaled_by_unread_input():
    def f(velocity, T):
        """Doc."""
        return velocity * T

    bad = Param("N*m", Prior("HalfNormal", scale=1.0, scaled_by={"temperature": 1}), "m", "s")
    with pytest.raises(LawDeclarationError, match="does not read"):
        _declare(f, params={"T": bad})
