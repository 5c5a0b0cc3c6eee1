"""Hostile speed/time columns for the derived position scale (issue 29): a data set with velocity
and time but no angle gives GMS's break-away deflections the largest excursion of ∫v dt as their
prior's scale (:func:`bayesfric.datasets.views.data_scale`). Whatever the columns hold, loading and
resolving that prior either work with a finite positive scale or fail in one line naming the row or
column."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayesfric.datasets import load_dataset
from bayesfric.datasets.views import data_scale
from bayesfric.errors import UserError
from bayesfric.laws import get_law

SIDECAR = ('[dataset]\nname = "h"\ntitle = "hostile speed/time"\nprovenance = "simulated"\nsource = "test"\n'
           'trajectory = "run"\n'
           '[columns.v]\nrole = "input"\nquantity = "velocity"\nunit = "rad/s"\n'
           '[columns.t]\nrole = "input"\nquantity = "time"\nunit = "s"\n'
           '[columns.run]\nrole = "group"\n'
           '[columns.T]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n')

CASES = {
    # time that never advances or runs backwards: the loader refuses it at the row, so travel never
    # sees it
    "time stands still": ([1.0, 2.0, -1.0, 0.5], [0.0, 0.0, 0.0, 0.0], "time must strictly increase"),
    "time runs backwards": ([1.0, 1.0, 1.0, 1.0], [3.0, 2.0, 1.0, 0.0], "time must strictly increase"),
    # speed zero everywhere: no travel, the scale falls back to 1 (DataScale.of's rule)
    "no motion": ([0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 2.0, 3.0], 1.0),
    # a reversal: the excursion is the largest |∫v dt|, 1.5 rad at the second row's end
    "reversal": ([1.0, 2.0, -2.0, -1.0], [0.0, 1.0, 2.0, 3.0], 1.5),
    # the largest speed and time the loader accepts (SCALE_RANGE): 1e24 rad, far inside float64
    "largest speed and time": ([1e12, 1e12, 1e12, 1e12], [0.0, 2.5e11, 5e11, 1e12], 1e24),
    # beyond it: refused in one line naming the column
    "time beyond the scale range": ([1.0, 1.0, 1.0, 1.0], [0.0, 1e12, 2e12, 3e12], "column 't'"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_derived_scale_is_finite_or_one_line(tmp_path, case):
    speed, time, expected = CASES[case]
    rows = "\n".join(f"{v!r},{t!r},1,{0.1 * (i + 1)!r}" for i, (v, t) in enumerate(zip(speed, time, strict=True)))
    (tmp_path / "h.csv").write_text("v,t,run,T\n" + rows + "\n")
    (tmp_path / "h.toml").write_text(SIDECAR)
    if isinstance(expected, str):
        with pytest.raises(UserError) as refused:
            load_dataset(tmp_path / "h.csv")
        assert expected in str(refused.value) and "\n" not in str(refused.value), case
        return
    scale = data_scale(load_dataset(tmp_path / "h.csv"))
    resolved = get_law("gms").params["dx"].prior.resolve(scale)
    assert scale.inputs["angle"] == pytest.approx(expected, rel=1e-12), case
    assert math.isfinite(resolved.args["loc"]) and np.isfinite(scale.factor({"angle": 1})), case
