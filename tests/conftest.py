"""Shared fixtures: in-memory datasets with the loader's layout."""

import pytest

import bayesfric  # noqa: F401  (enables x64)
from bayesfric.datasets.synthetic import make_dataset, simulate


@pytest.fixture
def dataset_factory():
    """``make_dataset(inputs, response, ...)`` (see bayesfric.datasets.synthetic)."""
    return make_dataset


@pytest.fixture
def simulator():
    """``simulate(law, inputs, params, sigma=..., seed=...)`` (see bayesfric.datasets.synthetic)."""
    return simulate
