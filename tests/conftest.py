"""Shared fixtures: in-memory datasets with the loader's layout."""

import pytest

from bayesfric.datasets.synthetic import make_dataset, simulate
from bayesfric.inference import release_compiled_code
from bayesfric.runtime import configure

configure()  # x64 (and the persistent compilation cache) before any test builds an array


@pytest.fixture
def dataset_factory():
    """``make_dataset(inputs, response, ...)`` (see bayesfric.datasets.synthetic)."""
    return make_dataset


@pytest.fixture
def simulator():
    """``simulate(law, inputs, params, sigma=..., seed=...)`` (see bayesfric.datasets.synthetic)."""
    return simulate


@pytest.fixture(autouse=True, scope="module")
def free_compiled_code_per_module():
    """Free compiled JAX code after each test module (see ``release_compiled_code``).

    Without it the suite passed ``vm.max_map_count`` near its 460th test and XLA aborted
    mid-compilation (the CI crash of 2026-11-21).
    """
    yield
    release_compiled_code()
