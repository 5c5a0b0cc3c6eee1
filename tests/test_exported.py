"""Traced programs kept on disk (bayesfric.exported): read back only for the same content, and
then the very same program; unreadable files and the off switch fall back to tracing."""

import json
import os
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

import bayesfric.exported as exported
from bayesfric.datasets.synthetic import simulate
from bayesfric.inference.engine import NutsEngine
from bayesfric.laws import get_law
from bayesfric.model import build_program

SMALL = dict(draws=100, tune=150, chains=2, seed=3)


@pytest.fixture(scope="module")
def data():
    law = get_law("coulomb_viscous")
    return simulate(law, {"velocity": np.linspace(-2, 2, 24)}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.05, seed=4)


@pytest.fixture
def cache(monkeypatch, tmp_path):
    monkeypatch.setenv("BAYESFRIC_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("BAYESFRIC_NO_CACHE", raising=False)
    exported.forget_compiled()  # each test starts as a new process would, with an empty cache
    return tmp_path / "exported"


def _engine(ds, **settings):
    """An engine as a new process would build it: nothing compiled in this one is reused."""
    exported.forget_compiled()
    return NutsEngine.build(build_program(get_law("coulomb_viscous"), ds), **(SMALL | settings))


def test_within_a_process_an_equal_program_reuses_the_compiled_function(cache, data):
    """A second engine on equal content (a law's units rebuild its program from the stored
    fit) gets the function compiled for the first: no trace, no disk read, no compilation."""
    first = _engine(data)
    files = sorted(cache.glob(f"*{exported.SUFFIX}"))
    second = NutsEngine.build(build_program(get_law("coulomb_viscous"), data.copy(deep=True)), **SMALL)
    assert second.loaded and second.kernel.sampler.advance is first.kernel.sampler.advance
    assert first.compilations == 1 and second.compilations == 1  # the second counts its reuse
    assert sorted(cache.glob(f"*{exported.SUFFIX}")) == files
    exported.forget_compiled()  # between laws (release_compiled_code): read back from disk
    third = NutsEngine.build(build_program(get_law("coulomb_viscous"), data), **SMALL)
    assert third.loaded and third.kernel.sampler.advance is not first.kernel.sampler.advance


def test_an_engine_on_equal_content_reads_the_same_program_back(cache, data):
    first = _engine(data)
    assert not first.loaded and first.compilations == 1
    assert list(cache.glob(f"*{exported.SUFFIX}"))
    second = _engine(data.copy(deep=True))  # a new program object with the same content
    assert second.loaded and second.compilations == 1
    a, b = first.fit(data), second.fit(data)
    np.testing.assert_array_equal(a["posterior"]["T_C"].values, b["posterior"]["T_C"].values)
    assert second.compilations == 1  # reading it back was its one compilation; nothing was traced


def test_other_data_or_settings_trace_a_program_of_their_own(cache, data):
    _engine(data)
    shifted = data.copy(deep=True)
    shifted["torque"] = shifted["torque"] + 0.1
    assert not _engine(shifted).loaded
    assert not _engine(data, draws=120).loaded


def test_an_unreadable_file_is_traced_again_and_replaced(cache, data):
    _engine(data)
    for path in cache.glob(f"*{exported.SUFFIX}"):
        path.write_bytes(path.read_bytes()[:100])  # truncated, as by a full disk
    again = _engine(data)
    assert not again.loaded and again.compilations == 1
    assert _engine(data).loaded  # the replacement is whole


def test_the_off_switch_keeps_nothing(monkeypatch, tmp_path, data):
    monkeypatch.setenv("BAYESFRIC_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("BAYESFRIC_NO_CACHE", "1")
    engine = _engine(data)
    assert not engine.loaded and engine.compilations == 1  # plain jax.jit, traced (lowered ahead) here
    engine.fit(data)
    assert engine.compilations == 1 and engine.kernel.sampler.fallbacks == 0
    assert not (tmp_path / "exported").exists()


def test_program_functions_give_what_plain_jit_gives(cache, data):
    density = build_program(get_law("coulomb_viscous"), data).density()
    x = np.random.default_rng(0).normal(size=(5, density.dim))
    np.testing.assert_allclose(density.log_joint_batch(x), jax.jit(jax.vmap(density.log_joint))(x), rtol=1e-12)
    np.testing.assert_allclose(density.log_joint_batch(x[:3]), jax.jit(jax.vmap(density.log_joint))(x[:3]),
                               rtol=1e-12)  # another batch size: another exported program
    inside = jax.jit(jax.vmap(lambda row: density.log_joint_batch(row[None])[0]))(x)  # e.g. tempered SMC
    np.testing.assert_allclose(inside, jax.vmap(density.log_joint)(x), rtol=1e-12)  # inlined: no exported call
    value, grad = density.neg_value_and_grad(x[0])
    np.testing.assert_allclose(grad, -jax.grad(density.log_joint)(x[0]), rtol=1e-12)
    assert float(value) == pytest.approx(-float(density.log_joint(x[0])), rel=1e-12)


def test_the_folder_stays_under_its_bound(cache, data, monkeypatch):
    density = build_program(get_law("coulomb_viscous"), data).density()
    for n in (2, 3, 4):
        density.log_joint_batch(np.zeros((n, density.dim)))
    files = sorted(cache.glob(f"*{exported.SUFFIX}"), key=lambda p: p.stat().st_mtime)
    os.utime(files[0], (1, 1))  # the least recently used
    limit = sum(p.stat().st_size for p in files)  # one more file must push the oldest out
    monkeypatch.setattr(exported, "EXPORTED_MAX_BYTES", limit)
    density.log_joint_batch(np.zeros((5, density.dim)))
    left = set(cache.glob(f"*{exported.SUFFIX}"))
    assert files[0] not in left and len(left - set(files)) == 1  # the oldest went, the new one stays
    assert sum(p.stat().st_size for p in left) <= limit


def test_a_file_another_process_evicted_meanwhile_is_skipped(tmp_path, monkeypatch):
    """Processes share the folder: a file listed but gone before its ``stat`` (the CI failure of
    2026-11-26, pytest workers evicting at once) is skipped, and the rest is still evicted."""
    for i, name in enumerate(("a", "b", "c")):
        (tmp_path / f"{name}{exported.SUFFIX}").write_bytes(b"x" * 100)
        os.utime(tmp_path / f"{name}{exported.SUFFIX}", (i + 1, i + 1))
    gone = tmp_path / f"b{exported.SUFFIX}"
    real_glob = type(tmp_path).glob

    def glob_then_evict(self, pattern):  # lists b, then "another process" removes it
        listed = list(real_glob(self, pattern))
        gone.unlink()
        return listed

    monkeypatch.setattr(type(tmp_path), "glob", glob_then_evict)
    monkeypatch.setattr(exported, "EXPORTED_MAX_BYTES", 100)
    exported._evict(tmp_path, keep=tmp_path / f"c{exported.SUFFIX}")
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"c{exported.SUFFIX}"]


PROBE = textwrap.dedent("""
    import json, jax.monitoring
    traces = []
    jax.monitoring.register_event_duration_secs_listener(
        lambda name, secs, **kw: traces.append(secs) if name.endswith("jaxpr_trace_duration") else None)
    import numpy as np
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.inference import fit
    from bayesfric.laws import get_law
    law = get_law("coulomb_viscous")
    ds = simulate(law, {"velocity": np.linspace(-2, 2, 30)}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.1, seed=1)
    dt = fit(law, ds, draws=100, tune=150, chains=2, seed=5)
    print(json.dumps(dict(trace_seconds=sum(traces), T_C=dt["posterior"]["T_C"].values.ravel().tolist())))
""")


@pytest.mark.slow
def test_a_second_process_traces_almost_nothing(tmp_path):
    """The second fit in a new process reads the sampler and the draw tables back instead of tracing them."""
    def run():
        out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, check=True, timeout=600,
                             env=os.environ | {"BAYESFRIC_CACHE_DIR": str(tmp_path)})
        return json.loads(out.stdout.strip().splitlines()[-1])

    first, second = run(), run()
    assert second["T_C"] == first["T_C"]  # the same program, the same draws
    assert second["trace_seconds"] < 0.25 * first["trace_seconds"], (first["trace_seconds"], second["trace_seconds"])


def test_compile_threads_run_side_by_side_up_to_the_setting():
    """Two background compilations overlap with two threads and queue with one (a barrier both
    must reach); the main job's study processes share the cores (one thread each on two cores)."""
    import threading

    def both_at_once(threads: int) -> bool:
        exported.set_compile_threads(threads)
        barrier = threading.Barrier(2, timeout=2.0)
        futures = [exported._compiler().submit(barrier.wait) for _ in range(2)]
        try:
            return all(f.exception() is None for f in futures)
        finally:
            exported.finish_compilations()

    try:
        assert both_at_once(2)
        assert not both_at_once(1)
        with pytest.raises(ValueError, match="at least 1"):
            exported.set_compile_threads(0)
    finally:
        exported.set_compile_threads(exported.COMPILE_THREADS)


def test_once_run_programs_of_small_data_compile_at_level_zero_and_sampler_inputs_at_the_default():
    """The compile options by program: a once-run program over a small data set at level 0, a
    looped or sampler-steering one (and every program above ONE_SHOT_ROWS rows) at XLA's default."""
    assert exported.program_options(111, optimised=False) is exported.ONE_SHOT
    assert exported.program_options(111, optimised=True) is exported.LOOPED
    assert exported.program_options(exported.ONE_SHOT_ROWS + 1, optimised=False) is exported.LOOPED
    assert exported.ONE_SHOT["xla_backend_optimization_level"] == 0
    assert exported.LOOPED["xla_backend_optimization_level"] == 2


def test_programs_steering_the_sampler_compile_at_the_default_level(data):
    """Prior-median starts, Pathfinder's draws, the warm-start transform and emcee's density are
    compiled at XLA's default level (a chain's trajectory follows the last bits of its start);
    a fit's tables and the checks' curves at level 0 on this small data set."""
    from bayesfric.density import _median_starts_jit
    from bayesfric.inference.datatree import draw_tables_jit

    program = build_program(get_law("coulomb_viscous"), data)
    density = program.density(0)
    assert _median_starts_jit(program)._options is exported.LOOPED
    assert density.log_joint_batch._options is exported.LOOPED
    assert density.neg_value_and_grad._options is exported.LOOPED
    assert draw_tables_jit(program)._options is exported.ONE_SHOT


def test_once_run_tables_at_level_zero_agree_with_the_default_level(cache, data):
    """A fit's tables compiled at level 0 agree with the default level's to rounding."""
    from functools import partial

    from bayesfric.inference.datatree import _draw_tables, draw_tables_jit

    program = build_program(get_law("coulomb_viscous"), data)
    rng = np.random.default_rng(0)
    flat = {"T_C": rng.uniform(0.9, 1.1, 200), "c_v": rng.uniform(0.4, 0.6, 200), "sigma": rng.uniform(0.04, 0.06, 200)}
    key = jax.random.PRNGKey(1)
    ours = draw_tables_jit(program, 50)(flat, key, key)
    plain = jax.jit(partial(_draw_tables, program, 50))(flat, key, key)
    for a, b in zip(jax.tree.leaves(ours), jax.tree.leaves(plain), strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-12)
