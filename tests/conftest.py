"""Shared fixtures: in-memory datasets with the loader's layout."""

import pytest

from bayesfric.datasets.synthetic import make_dataset, simulate
from bayesfric.inference import release_compiled_code
from bayesfric.runtime import configure

configure()  # x64 (and the persistent compilation cache) before any test builds an array

#: The ``make test-fast`` tier (``-m fast``): the files whose tests run no MCMC to convergence and
#: compile little -- declarations, priors, numerics, folds, weights, PIT, typesetting, rendering from
#: fakes, the data sets' loaders, the structure checks and the hostile-input corpora. Chosen from a
#: whole-suite ``--durations=0`` run (2026-11-26: each file under 35 s of test time at load 14,
#: together 5 % of the suite's test seconds); ``make test`` runs them with everything else. The
#: tier's wall time is stated in benchmarks/README.md.
FAST_FILES = frozenset(f"tests/{name}.py" for name in (
    "laws/test_declaration", "laws/test_classical", "laws/test_variants", "laws/test_ball_loads",
    "compare/test_folds", "compare/test_pit", "compare/test_weights", "compare/test_future", "compare/test_loo",
    "compare/test_checks", "compare/test_foldmodes",
    "report/test_verdicts", "report/test_scores", "report/test_fit_report", "report/test_typeset",
    "report/test_distrust", "report/test_render",
    "datasets/test_robot_joint", "datasets/test_unwinder", "datasets/test_dahl_duplex", "datasets/test_drum_rollout",
    "datasets/test_pitch_bearing",
    "hostile/test_links_corpus", "hostile/test_variant_corpus", "hostile/test_data_corpus",
    "hostile/test_study_corpus", "hostile/test_loader_properties", "hostile/test_derived_scale",
    "hostile/test_third_round",
    "test_example_studies", "test_priors", "test_sizing_misfit", "test_sizing_basis", "test_numerics",
    "test_sizing_truth", "test_asymmetry", "test_drive_dynamics", "test_structure", "test_density", "test_errors",
    "test_fingerprint", "test_readme", "test_thin", "test_modes", "test_drum_campaigns_data", "test_identifiability",
    "test_sampler_config",
    "test_sizing_distance",
    "test_sizing_result", "test_new_run", "test_docs_figures",
))


def pytest_configure(config):
    config.addinivalue_line("markers", "fast: the make test-fast tier (tests/conftest.py FAST_FILES)")


def pytest_collection_modifyitems(config, items):
    """Mark the tests of :data:`FAST_FILES` ``fast`` (those marked ``slow`` excepted).

    The files keep xdist's default order (most tests first). Running the files with the most test
    seconds first was measured and dropped (2026-11-26, warm cache, quiet machine): the long files
    then ran beside each other, each using more than one core, and their test time rose from 2291
    to 2569 s (pytest 1281 → 1333 s).
    """
    for item in items:
        if item.nodeid.split("::")[0] in FAST_FILES and item.get_closest_marker("slow") is None:
            item.add_marker(pytest.mark.fast)


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
