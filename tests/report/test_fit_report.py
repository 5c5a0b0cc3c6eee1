"""`bayesfric fit` prints the noise model it used: its kind, form and parameters."""

import json

import numpy as np
import pytest
import xarray as xr

from bayesfric.laws import get_law
from bayesfric.report.tables import noise_text

LAW = get_law("coulomb_viscous")


def tree(kind: str, values: dict[str, float], **noise) -> xr.DataTree:
    """A fit-shaped tree whose noise draws are v ± 1 % alternating: mean v, sd 1.0025 % of v."""
    sign = np.where(np.arange(200) % 2 == 0, 1.0, -1.0).reshape(2, 100)
    post = {k: (("chain", "draw"), v * (1 + 0.01 * sign)) for k, v in values.items()}
    post["T_C"] = (("chain", "draw"), 5.0 + sign)
    dt = xr.DataTree.from_dict({"posterior": xr.Dataset(post)})
    dt.attrs["noise"] = json.dumps({"kind": kind, "group": None, "sigma": None} | noise)
    return dt


@pytest.mark.parametrize(("kind", "values", "said"), [
    ("normal", {"sigma": 0.2}, ["noise model: normal (Gaussian residuals, sd sigma)", "sigma = 0.2000 ± 0.0020 N·m"]),
    ("student_t", {"sigma": 0.2, "nu": 4.0}, ["Student-t", "sigma = 0.2000 ± 0.0020 N·m", "nu = 4.00 ± 0.04"]),
    ("proportional", {"sigma_rel": 0.05, "sigma_floor": 0.01},
     ["sqrt((sigma_rel · mean)² + sigma_floor²)", "sigma_rel = 0.0500 ± 0.0005",
      "sigma_floor = 0.01000 ± 0.00010 N·m"]),
    ("ar1", {"sigma": 0.2, "rho": 0.8}, ["AR(1)", "rho = 0.800 ± 0.008", "sigma = 0.2000 ± 0.0020 N·m"]),
])
def test_each_kind_states_its_form_and_parameters(kind, values, said):
    text = noise_text(tree(kind, values), LAW)
    assert text.startswith(f"noise model: {kind}")
    for part in said:
        assert part in text
    assert "T_C" not in text  # law parameters are not noise


def test_known_sigma_and_groups_are_said():
    text = noise_text(tree("normal", {"group_sd": 0.1}, sigma=0.3, group="series"), LAW)
    assert "partial-pooled offsets per series" in text and "sigma = 0.3 N·m (known, not sampled)" in text
    assert "group_sd = 0.1000 ± 0.0010" in text
