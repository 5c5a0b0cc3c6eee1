"""Both log-evidence estimators against the closed-form evidence of a linear-Gaussian law.

``coulomb_viscous`` (T = sign(v) T_C + c_v v) is linear in (T_C, c_v); with Normal priors on both
and a known noise sd the marginal likelihood is N(y; X m0, σ² I + X S0 Xᵀ), X = [sign(v), v].
"""

import arviz as az
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from bayesfric.compare.evidence import (
    Evidence,
    bridge_log_evidence,
    compare_estimators,
    smc_log_evidence,
)
from bayesfric.inference import fit
from bayesfric.laws import get_law
from bayesfric.model import Noise, build_program
from bayesfric.priors import Prior

SIGMA = 0.1
PRIOR_MEAN = np.array([0.5, 0.0])  # T_C, c_v
PRIOR_SD = np.array([1.0, 1.0])


def _case(simulator, seed):
    law = get_law("coulomb_viscous")
    velocity = np.linspace(-2.0, 2.0, 20)
    ds = simulator(law, {"velocity": velocity}, {"T_C": 1.0, "c_v": 0.5}, sigma=SIGMA, seed=seed)
    priors = {"T_C": Prior("Normal", loc=PRIOR_MEAN[0], scale=PRIOR_SD[0]),
              "c_v": Prior("Normal", loc=PRIOR_MEAN[1], scale=PRIOR_SD[1])}
    noise = Noise(sigma=SIGMA)
    program = build_program(law, ds, priors=priors, noise=noise)
    design = np.column_stack([np.sign(velocity), velocity])
    cov = SIGMA**2 * np.eye(velocity.size) + design @ np.diag(PRIOR_SD**2) @ design.T
    exact = multivariate_normal(design @ PRIOR_MEAN, cov).logpdf(program.response)
    return law, ds, priors, noise, program, float(exact)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_both_estimators_match_the_analytic_evidence(simulator, seed):
    law, ds, priors, noise, program, exact = _case(simulator, seed)
    dt = fit(law, ds, priors=priors, noise=noise, seed=seed, draws=1000, tune=500, chains=2)
    bridge = bridge_log_evidence(program, dt, seed=seed)
    smc = smc_log_evidence(program, seed=seed)
    for estimate in (bridge, smc):
        assert abs(estimate.log_z - exact) <= 0.1, (str(estimate), exact)
        assert 0 < estimate.error < 0.1, str(estimate)
    assert compare_estimators(bridge, smc).agree


def test_compare_estimators_flags_but_never_averages():
    a = Evidence(-10.0, 0.02, "bridge")
    b = Evidence(-10.7, 0.03, "smc")
    flagged = compare_estimators(a, b, threshold=0.5)
    assert not flagged.agree and flagged.difference == pytest.approx(0.7)
    assert (flagged.a, flagged.b) == (a, b)
    assert compare_estimators(a, Evidence(-10.3, 0.03, "smc")).agree


def test_bridge_rejects_a_fit_without_the_programs_sites(simulator):
    law, ds, priors, _, _, _ = _case(simulator, 1)
    rng = np.random.default_rng(0)
    dt = az.from_dict({"posterior": {"T_C": rng.normal(1, 0.01, (2, 100)),
                                     "c_v": rng.normal(0.5, 0.01, (2, 100))}})
    other = build_program(law, ds, priors=priors)  # sampled sigma: a site the fit does not have
    with pytest.raises(ValueError, match="sigma"):
        bridge_log_evidence(other, dt)
