"""Thinning a large log (``[data] every``, ``bayesfric.Study(every=...)``, ``datasets.views.thin``):
one row in n, counted within each trajectory from its first row, which is always kept."""

from __future__ import annotations

import numpy as np
import pytest

import bayesfric
from bayesfric.datasets.synthetic import make_dataset
from bayesfric.datasets.views import thin, trajectory_starts
from bayesfric.study.config import StudyError, study_from_raw
from bayesfric.study.plan import load_study_data


def test_thin_keeps_one_row_in_n_from_each_trajectory_start():
    ds = make_dataset({"velocity": np.arange(10.0)}, np.ones(10), groups={"loop": np.repeat([0, 1], [4, 6])},
                      trajectory="loop")
    out = thin(ds, 3)
    assert out["velocity"].values.tolist() == [0.0, 3.0, 4.0, 7.0]  # loop 0: rows 0, 3; loop 1 from row 4
    assert trajectory_starts(out).tolist() == [True, False, True, False]
    assert "one row in 3" in out.attrs["selection"]
    assert thin(ds, 1) is ds

def test_a_study_thins_its_data_and_refuses_a_bad_every(tmp_path):
    raw = {"study": {"name": "s"}, "data": {"dataset": "robot_joint", "every": 4}, "laws": [{"name": "coulomb"}]}
    study = study_from_raw(tmp_path / "s.toml", raw)
    assert study.every == 4
    assert load_study_data(study).sizes["obs"] == 28  # 111 rows (no trajectories): rows 0, 4, ..., 108
    raw["data"]["every"] = 0
    with pytest.raises(StudyError, match=r"\[data\] every: must be an integer ≥ 1"):
        study_from_raw(tmp_path / "s.toml", raw)
    assert bayesfric.Study("t", "robot_joint", laws=["coulomb"], every=2).every == 2
