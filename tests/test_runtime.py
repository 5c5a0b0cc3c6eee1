"""Process-wide settings: nothing at import; x64 and the persistent compilation cache on first use."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from bayesfric.runtime import cache_dir

PROBE = textwrap.dedent("""
    import collections, json
    import jax, jax.monitoring
    events = collections.Counter()
    jax.monitoring.register_event_listener(lambda name, **kw: events.update([name.split("/")[-1]]))
    import numpy as np
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.inference import fit
    from bayesfric.laws import get_law
    law = get_law("coulomb_viscous")
    ds = simulate(law, {"velocity": np.linspace(-2, 2, 30)}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.1, seed=1)
    fit(law, ds, draws=100, tune=100, chains=2)
    print(json.dumps(dict(events)))
""")


def _run(code: str, **env) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env=os.environ | env, timeout=600)
    return out.stdout.strip().splitlines()[-1]


def test_importing_bayesfric_changes_no_process_setting():
    """x64 and the cache stay off, and the user's matplotlib backend (here svg) survives every import."""
    code = ("import jax, matplotlib; "
            "import bayesfric, bayesfric.cli, bayesfric.inference, bayesfric.compare, bayesfric.study, "
            "bayesfric.report.figures; "
            "print(jax.config.jax_enable_x64, jax.config.jax_compilation_cache_dir, matplotlib.get_backend())")
    assert _run(code, MPLBACKEND="svg") == "False None svg"  # figures.py used to force Agg at import


def test_cache_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("BAYESFRIC_CACHE_DIR", str(tmp_path / "c"))
    monkeypatch.delenv("BAYESFRIC_NO_CACHE", raising=False)
    assert cache_dir() == tmp_path / "c"
    monkeypatch.setenv("BAYESFRIC_NO_CACHE", "1")
    assert cache_dir() is None
    monkeypatch.delenv("BAYESFRIC_NO_CACHE")
    monkeypatch.delenv("BAYESFRIC_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "bayesfric" / "jax"


@pytest.mark.slow
def test_a_second_fit_in_a_new_process_compiles_nothing(tmp_path):
    """Two processes fit the same law to the same data: the second loads every program from disk."""
    first = json.loads(_run(PROBE, BAYESFRIC_CACHE_DIR=str(tmp_path)))
    second = json.loads(_run(PROBE, BAYESFRIC_CACHE_DIR=str(tmp_path)))
    assert first.get("cache_misses", 0) >= 10  # a fit is a few tens of programs (20 in Nov 2026), all written
    assert second.get("cache_misses", 0) == 0, second
    # every program the first process wrote, the second read back. (blackjax compiles one tiny
    # program at import, before bayesfric configures the cache: it counts as neither, in both.)
    assert second["cache_hits"] == first["cache_misses"], (first, second)


@pytest.mark.slow
def test_the_off_switch_writes_no_cache(tmp_path):
    events = json.loads(_run(PROBE, BAYESFRIC_CACHE_DIR=str(tmp_path / "c"), BAYESFRIC_NO_CACHE="1"))
    assert "cache_hits" not in events and "cache_misses" not in events
    assert not (tmp_path / "c").exists()


def test_the_fit_command_imports_only_what_it_uses():
    """``bayesfric fit`` needs no plotting, no ODE solver, no comparison or study-runner code;
    arviz-stats (with scipy.stats) waits until the engine has handed its programs to the
    compilation threads (see bayesfric.inference.diagnostics)."""
    code = ("import sys; import bayesfric.cli, bayesfric.inference, bayesfric.datasets, bayesfric.laws; "
            "from bayesfric.study.config import SAMPLER; "
            "print(sorted(m for m in ('matplotlib', 'arviz', 'arviz_plots', 'diffrax', 'bayesfric.study.runner', "
            "'bayesfric.pipeline.runner', 'bayesfric.compare', 'emcee', 'arviz_stats', 'scipy.stats') "
            "if m in sys.modules))")
    assert _run(code) == "[]"
    code = ("import sys; from bayesfric.report.tables import fit_report; "
            "print(sorted(m for m in ('matplotlib', 'arviz', 'diffrax', 'bayesfric.compare') if m in sys.modules))")
    assert _run(code) == "[]"


def test_importing_the_laws_starts_no_jax_backend():
    """Importing runs no JAX program. A law registered with a dropped part is fixed at import, and
    its support check used to run on a JAX array: it started the backend and compiled two programs.
    With an unknown platform, starting a backend raises (blackjax, imported by the inference
    package, evaluates ``jnp.log(2.0)`` at import itself, so it is left out)."""
    code = ("import bayesfric, bayesfric.cli, bayesfric.laws, bayesfric.model, bayesfric.datasets, "
            "bayesfric.priors; print('imported')")
    assert _run(code, JAX_PLATFORMS="no_such_platform") == "imported"


def test_unit_registry_uses_pints_cache_and_survives_a_broken_one(monkeypatch, tmp_path):
    """pint's parsed definitions are kept in ``<cache>/pint``; a truncated entry (a process
    killed while pint wrote it) costs a fresh parse and the folder, never an error."""
    from bayesfric.quantities import _unit_registry

    monkeypatch.setenv("BAYESFRIC_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("BAYESFRIC_NO_CACHE", raising=False)
    assert _unit_registry().parse_units("N*m") is not None
    entries = list((tmp_path / "pint").glob("*.pickle"))
    assert entries  # written by the first registry
    for entry in entries:
        entry.write_bytes(entry.read_bytes()[:10])
    registry = _unit_registry()
    assert not (tmp_path / "pint").exists()  # the broken cache was dropped; the next start writes it again
    assert registry.Quantity(1.0, "rpm").to("rad/s").magnitude == pytest.approx(0.10471975511965977)
    monkeypatch.setenv("BAYESFRIC_NO_CACHE", "1")
    assert _unit_registry().parse_units("N") is not None
