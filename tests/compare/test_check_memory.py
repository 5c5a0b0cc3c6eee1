"""The checks on large fits read the stored draws in bounded chunks, with the one-call numbers."""

from __future__ import annotations

import gc

import arviz as az
import numpy as np
import pandas as pd
import pytest
import xarray as xr

from bayesfric.compare import loo_subsample, prior_sensitivity
from bayesfric.compare.checks import power_scaled_loo


def _fit(rows: int = 37, chains: int = 2, draws: int = 60) -> xr.DataTree:
    """A fit-shaped tree: two parameters, their log prior, a log-likelihood that depends on them."""
    rng = np.random.default_rng(11)
    dims = ("chain", "draw")
    a, b = rng.normal(2.0, 0.1, (chains, draws)), rng.normal(0.5, 0.05, (chains, draws))
    x = rng.uniform(0.1, 3.0, rows)
    y = 2.0 + 0.5 * x + rng.normal(0, 0.1, rows)
    ll = -0.5 * ((y - a[..., None] - b[..., None] * x) / 0.1) ** 2 - np.log(0.1 * np.sqrt(2 * np.pi))
    return xr.DataTree.from_dict({
        "posterior": xr.Dataset({"T_C": (dims, a), "c_v": (dims, b)}),
        "log_prior": xr.Dataset({"T_C": (dims, -0.5 * (a - 1.5) ** 2), "c_v": (dims, -0.5 * (b / 2) ** 2)}),
        "log_likelihood": xr.Dataset({"response": (dims + ("obs",), ll)}),
        "observed_data": xr.Dataset({"response": ("obs", y)}),
    })


@pytest.mark.parametrize("chunk", [1, 7 * 37, 2**22])
def test_prior_sensitivity_in_chunks_equals_psense_on_the_whole_group(monkeypatch, chunk):
    dt = _fit()
    expected = az.psense_summary(dt, var_names=["T_C", "c_v"], threshold=0.05)  # what the check called before
    monkeypatch.setattr(loo_subsample, "CHUNK_NUMBERS", chunk)
    view = loo_subsample.rows_summed(dt)
    assert view["log_likelihood"]["response"].dims == ("chain", "draw")
    np.testing.assert_array_equal(view["log_likelihood"]["response"].values,
                                  dt["log_likelihood"]["response"].sum("obs").values)
    pd.testing.assert_frame_equal(prior_sensitivity(dt), expected)  # bit-identical, whatever the chunk
    assert "log_likelihood" in dt.children and dt["log_likelihood"]["response"].dims == ("chain", "draw", "obs")


def _trees() -> int:
    return sum(isinstance(o, xr.DataTree) for o in gc.get_objects())


@pytest.mark.parametrize("large", [True, False])
def test_views_of_a_large_fit_leave_memory_on_return(monkeypatch, large):
    """A view of a fit is a DataTree, a reference cycle: on a large fit the checks collect it on
    return (with the cyclic collector off, it would otherwise stay, with its float64 copies)."""
    dt, rows = _fit(), np.arange(0, 37, 3)
    expected = power_scaled_loo(dt, 0.5, rows)
    monkeypatch.setattr(loo_subsample, "CHUNK_NUMBERS", dt["log_likelihood"]["response"].size if large else 2**40)
    gc.collect()
    gc.disable()
    try:
        before = _trees()
        got = power_scaled_loo(dt, 0.5, rows)
        left = _trees() - before
    finally:
        gc.enable()
    assert (left == 0) == large
    np.testing.assert_array_equal(got.elpd_i, expected.elpd_i)
    assert got.elpd == expected.elpd
