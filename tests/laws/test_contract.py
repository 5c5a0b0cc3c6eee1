"""Registry-wide contract test: every registered law satisfies the same declaration contract.

The checks live in :mod:`bayesfric.testing` (``check_law`` runs them on a user's own law); this
file runs each of them over every registered law, once on rotary (torque) data and, unless the
law declares itself rotary-only, once more on translational (force) data at tribometer scale.
"""

from __future__ import annotations

import pytest

from bayesfric import testing
from bayesfric.laws import all_laws
from bayesfric.laws.variants import translation_problem

LAWS = all_laws()
N_DRAWS = 64
#: (law, motion kind) for every law on rotary data and every law that also runs translationally.
CASES = [(w, "rotary") for w in LAWS] + [(w, "translational") for w in LAWS if translation_problem(w) is None]


@pytest.fixture(scope="module", params=CASES, ids=[f"{w.name}-{m}" for w, m in CASES])
def law_case(request):
    """(the law as it runs on the case's data, its program, prior draws of its parameters)."""
    law, motion = request.param
    ds = testing.contract_dataset(law, motion)
    program, params = testing.prior_draws(law, ds, N_DRAWS)
    assert program.law.response == ds.attrs["response"]
    return program.law, program, params


def test_registry_is_populated():
    assert len(LAWS) >= 7
    assert {"coulomb", "coulomb_viscous", "stribeck", "armstrong_helouvry", "joint_tribological",
            "prestressed_roller_bearing", "helical_gear"} <= {w.name for w in LAWS}


def test_declaration_complete(law_case):
    testing.check_declaration(law_case[0])


def _run(check, law_case):
    _, program, params = law_case
    if (why := check(program, params)) is not None:
        pytest.skip(why)


def test_mean_finite_and_jittable(law_case):
    _run(testing.check_mean, law_case)


def test_gradient_finite(law_case):
    _run(testing.check_gradient, law_case)


def test_broadcasting(law_case):
    _run(testing.check_broadcasting, law_case)


def test_prior_predictive_sign(law_case):
    _run(testing.check_prior_sign, law_case)


def test_odd_in_velocity(law_case):
    _run(testing.check_odd, law_case)


def test_group_terms(law_case):
    _run(testing.check_group_terms, law_case)


def test_translational_form_follows_the_rotary_declaration():
    """Units map N·m → N and rad → m, the response to force, the inputs to their counterparts."""
    for law in LAWS:
        testing.check_translational_form(law)


def test_rotary_only_laws_say_why():
    """Laws that cannot run translationally give a reason (declared, or read from their inputs)."""
    for law in LAWS:
        problem = translation_problem(law)
        assert problem is None or problem.strip(), law.name
        if law.family in ("bearing", "thermal", "drum"):
            assert problem, f"{law.name}: a geometry-specific rotary law must stay rotary-only"
