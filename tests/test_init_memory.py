"""Pathfinder within its memory budget (issue 29 item 2): the plan's invariant, the same numbers as
blackjax's unbounded approximation, and the fall-back to prior medians above the budget."""

import blackjax
import jax
import numpy as np
import pytest

from bayesfric.datasets.synthetic import simulate
from bayesfric.density import median_starts, start_seeds
from bayesfric.inference import init
from bayesfric.laws import get_law
from bayesfric.limits import INIT_NUMBERS
from bayesfric.model import build_program


@pytest.fixture(scope="module")
def program():
    v = np.linspace(-3, 3, 30)
    ds = simulate(get_law("coulomb_viscous"), {"velocity": v}, {"T_C": 2.0, "c_v": 0.5}, sigma=0.1, seed=3)
    return build_program(get_law("coulomb_viscous"), ds)


@pytest.mark.parametrize("budget", [INIT_NUMBERS, 2**10, 1000, 1])
@pytest.mark.parametrize("paths", [1, 8, 16])
def test_no_stage_evaluates_more_rows_at_once_than_the_budget(budget, paths):
    for rows in (1, 7, 30, 800, 10_000, 10**5, 10**6, 10**7):
        chosen = init.plan(rows, paths, budget)
        if rows > budget:
            assert chosen is None
            continue
        assert 1 <= chosen.paths_at_once <= paths and 1 <= chosen.draws_at_once
        assert chosen.draws_at_once <= max(init.ELBO_DRAWS, init.DRAWS_PER_PATH)
        assert chosen.paths_at_once * rows <= budget and chosen.draws_at_once * rows <= budget
        # as many at once as the budget allows: one more would exceed it, or there is no more
        assert chosen.draws_at_once == max(init.ELBO_DRAWS, init.DRAWS_PER_PATH) or (
            (chosen.draws_at_once + 1) * rows > budget)


def test_the_budget_holds_every_path_at_once_up_to_ten_thousand_rows():
    """The declared budget runs issue 29's sizes without a fall-back, all paths side by side."""
    for rows in (800, 10_000):
        chosen = init.plan(rows)
        assert chosen is not None and chosen.paths_at_once == init.PATHS


def test_bounded_pathfinder_gives_blackjax_numbers(program):
    """Evaluated a few points at a time (7 of 30 rows each), every path's draws and importance
    weights equal those of ``blackjax.vi.pathfinder.approximate`` + ``sample`` run all at once."""
    density = program.density(0)
    starts = median_starts(program, start_seeds(0, init.PATHS))
    keys = jax.random.split(jax.random.PRNGKey(0), init.PATHS)

    def reference(key, x0):
        k_fit, k_draw = jax.random.split(key)
        state, _ = blackjax.vi.pathfinder.approximate(k_fit, density.log_joint, x0, maxiter=init.MAXITER,
                                                      num_samples=init.ELBO_DRAWS)
        draws, log_q = blackjax.vi.pathfinder.sample(k_draw, state, init.DRAWS_PER_PATH)
        return draws, jax.vmap(density.log_joint)(draws) - log_q

    expected = jax.jit(jax.vmap(reference))(keys, starts)
    chosen = init.plan(program.n_obs, init.PATHS, budget=7 * program.n_obs)
    assert chosen == init.Plan(7, 7)  # neither 8 paths nor 200 or 100 draws divide by 7: remainders too
    got = jax.jit(init.multipath(density.log_joint, chosen))(keys, starts)
    np.testing.assert_allclose(got[0], expected[0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got[1], expected[1], rtol=1e-9, atol=1e-9)


def test_data_above_the_budget_start_at_prior_medians_and_say_so(program):
    with pytest.warns(UserWarning, match=r"Pathfinder skipped .* 30 rows exceeds .* budget of 29 row evaluations"):
        starts = init.pathfinder_starts(program, 3, seed=1, budget=29)
    expected = median_starts(program, start_seeds(1, init.PATHS))[:3]
    np.testing.assert_array_equal(starts, expected)
