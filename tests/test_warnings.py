"""No stray warnings on valid input: a study whose companion law holds a derived quantity constant
(LuGre's reduced variant fixes ρ1 = 0, so σ1 = 0 in every draw) printed numpy's "All-NaN slice
encountered" and arviz-stats' "invalid value encountered in scalar divide": the gate, the chains'
health check and the prior sensitivity computed statistics of a constant. They now leave a
constant out, as the gate did, and say nothing."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

from bayesfric.compare.checks import _parameters
from bayesfric.inference.diagnostics import check_folds
from bayesfric.inference.modes import chain_health


def _post() -> xr.Dataset:
    rng = np.random.default_rng(0)
    return xr.Dataset({"F_c": (("chain", "draw"), rng.normal(size=(4, 1000))),
                       "sigma1": (("chain", "draw"), np.zeros((4, 1000)))})


def test_a_constant_quantity_is_left_out_silently():
    post = _post()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert check_folds(post, xr.Dataset(), fold=None)[0].passed
        assert all(h.healthy for h in chain_health(post, xr.Dataset()))
    assert _parameters(xr.DataTree.from_dict({"posterior": post})) == ["F_c"]
    assert _parameters(xr.DataTree.from_dict({"posterior": post[["sigma1"]]})) == ["sigma1"]  # nothing else


def test_nothing_moving_fails_the_gate_without_numpys_all_nan_warning():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        assert not check_folds(_post()[["sigma1"]], xr.Dataset(), fold=None)[0].passed
    assert not [w for w in caught if "All-NaN" in str(w.message)]


@pytest.mark.slow  # a LuGre fit and its companion's, quick-sized
def test_a_small_valid_study_with_a_companion_warns_nothing(tmp_path):
    import bayesfric

    study = bayesfric.Study("quiet", "dahl_duplex", select={"condition": "new"}, laws=["lugre"],
                            sampler={"draws": 200, "tune": 200, "chains": 2},
                            compare={"evidence": False})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        result = bayesfric.run(study, tmp_path)
    assert "lugre_Fs_eq_Fc" in set(result.ranking["law"])  # the companion whose sigma1 is constant
    stray = [f"{w.filename}:{w.lineno}: {w.message}" for w in caught if issubclass(w.category, RuntimeWarning)]
    assert not stray, stray
