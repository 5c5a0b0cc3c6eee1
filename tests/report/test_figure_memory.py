"""The report's figures on large fits: computed in bounded chunks, with the one-call numbers."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from bayesfric.report import study_figures


def _fit_and_data(rows: int) -> tuple[xr.DataTree, xr.Dataset]:
    rng = np.random.default_rng(3)
    pp = rng.normal(size=(2, 300, rows)).astype(np.float32)  # stored as a thinned fit keeps it
    fit = xr.DataTree.from_dict({"posterior_predictive": xr.Dataset({"response": (("chain", "draw", "obs"), pp)})})
    # a unit conversion, so that the display transform is not the identity
    ds = xr.Dataset({"torque": ("obs", rng.normal(size=rows), {"quantity": "torque", "original_unit": "mN*m"})})
    return fit, ds


@pytest.mark.parametrize("chunk", [1, 7 * study_figures.MAX_DRAWS, 2**22])
def test_predictive_band_in_chunks_equals_the_one_call_quantiles(monkeypatch, chunk):
    fit, ds = _fit_and_data(rows=53)
    expected = np.quantile(study_figures._shown(ds, "torque", study_figures._draws(fit, "posterior_predictive",
                                                                                    "response")),
                           [0.05, 0.5, 0.95], axis=0)  # the figures' numbers before chunking
    monkeypatch.setattr(study_figures, "CHUNK_NUMBERS", chunk)
    band = study_figures._band(ds, "torque", fit)
    assert band.shape == (3, 53)
    np.testing.assert_array_equal(band, expected)  # bit-identical, whatever the chunk
