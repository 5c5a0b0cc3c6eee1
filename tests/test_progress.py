"""Progress inside a fit (issue 29 item 4): the chains run in chunks of one compiled step function
with the same draws as one call; ``bayesfric fit`` prints plain progress lines when stderr is not a
terminal; the study's time left comes from per-law costs; reused units keep their cost."""

import io
import math

import jax
import numpy as np
import pytest
import xarray as xr

from bayesfric.datasets.synthetic import simulate
from bayesfric.inference.adaptation import chain_start, chain_steps, nuts_chain, sampling_schedule, step_keys
from bayesfric.inference.engine import NutsEngine
from bayesfric.inference.progress import SamplingProgress, reporting
from bayesfric.laws import get_law
from bayesfric.model import build_program
from bayesfric.study.executor import CostModel, Progress
from bayesfric.study.store import RunStore
from bayesfric.study.units import Unit
from tests.test_study import data_csv  # noqa: F401 - the fixture is used by name

SMALL = dict(draws=100, tune=150, chains=2, seed=3)
META = """
[dataset]
name = "bench"
title = "test bench"
provenance = "measured"
source = "unit test"

[columns.speed]
role = "input"
quantity = "velocity"
unit = "rad/s"

[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"
"""


@pytest.fixture(scope="module")
def data():
    law = get_law("coulomb_viscous")
    return simulate(law, {"velocity": np.linspace(-2, 2, 24)}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.05, seed=4)


def test_a_chain_in_slices_draws_what_one_scan_draws():
    """nuts_chain = chain_start + chain_steps over consecutive slices of the schedule and keys."""
    precision = np.array([[2.0, 0.5], [0.5, 1.0]])

    def logdensity(x):
        return -0.5 * x @ precision @ x

    schedule = sampling_schedule(150, 60)
    key, z0, imm = jax.random.PRNGKey(5), np.array([1.0, -1.0]), np.ones(2)
    whole = jax.jit(lambda: nuts_chain(key, z0, logdensity, schedule, imm, 0.8, 6))()
    carry, keys, parts = chain_start(z0, logdensity, imm), step_keys(key, schedule.shape[0]), []
    step = jax.jit(lambda c, k, rows: chain_steps(c, k, rows, logdensity, 0.8, 6))
    for lo, hi in ((0, 70), (70, 71), (71, 210)):
        carry, out = step(carry, keys[lo:hi], schedule[lo:hi])
        parts.append(out.position)
    # the same arithmetic in two compiled programs: XLA may fuse the whole scan differently from its
    # slices (jax 0.12.1 differs in the last bits, 1e-9 relative after 210 steps); a wrong slice
    # boundary (a key or schedule row skipped or repeated) changes the draws at order one
    np.testing.assert_allclose(np.concatenate(parts), whole.position, rtol=1e-7, atol=1e-9)


def test_chunked_engine_draws_equal_one_call(data):
    """Chunks of 37 rows (the last padded with idle rows) give the draws, statistics and lpd of
    the whole schedule in one call, for a cold fit and warm-started folds; one compilation each."""
    program = build_program(get_law("coulomb_viscous"), data)
    chunked = NutsEngine.build(program, chunk_steps=37, **SMALL)
    whole = NutsEngine.build(program, chunk_steps=10**6, **SMALL)
    assert chunked.kernel.sampler.chunk == 37 and whole.kernel.sampler.chunk == 250
    masks = np.ones((2, program.n_obs), dtype=bool)
    masks[1, :5] = False
    a, b = chunked.run(masks, seed=2), whole.run(masks, seed=2)
    for name in a.samples:
        np.testing.assert_array_equal(a.samples[name], b.samples[name])
    for name in a.stats:
        np.testing.assert_array_equal(a.stats[name], b.stats[name])
    np.testing.assert_allclose(a.lpd, b.lpd, rtol=1e-12)
    fit = whole.fit(data)
    warm_a, warm_b = chunked.warm_started(fit, 120).run(masks), whole.warm_started(fit, 120).run(masks)
    np.testing.assert_array_equal(warm_a.samples["T_C"], warm_b.samples["T_C"])
    assert chunked.compilations == 1 and whole.compilations == 1 and chunked.kernel.sampler.fallbacks == 0


def test_plain_progress_lines_per_chain(data):
    """Off a terminal: lines at most one per interval (here every chunk), the last at the end; a
    run shorter than the interval prints nothing."""
    stream = io.StringIO()
    engine = NutsEngine.build(build_program(get_law("coulomb_viscous"), data), chunk_steps=50,
                              retry_target_accept=None, **SMALL)
    with reporting("cv fit", stream=stream, live=False, interval=0):
        engine.run(np.ones((1, data.sizes["obs"]), dtype=bool))
    lines = stream.getvalue().splitlines()
    assert len(lines) == 10, lines  # 5 chunks of 50 rows per chain, 2 chains
    assert lines[0].startswith("[cv fit] chain 1 ") and "chain 2 " in lines[0] and "0 divergent" in lines[0]
    assert "warm-up 50/150" in lines[0] and "s left" in lines[-2]
    assert lines[-1].endswith(", done") and "chain 1 draws 100/100 · chain 2 draws 100/100" in lines[-1]
    quiet = io.StringIO()
    with reporting("cv fit", stream=quiet, live=False, interval=1e9):
        engine.run(np.ones((1, data.sizes["obs"]), dtype=bool))
    assert quiet.getvalue() == ""


def test_progress_line_text_and_live_rewrite():
    """Warm-up and draws per chain, folds done, divergences and time left; a terminal rewrites one line."""
    stream = io.StringIO()
    with reporting("law cv", stream=stream, live=True):
        from bayesfric.inference.progress import current

        shown = SamplingProgress(current(), folds=3, chains=2, idle=10, tune=100, draws=200)
    shown.update(range(0, 1), range(0, 2), 60, np.zeros((1, 2)))
    shown.first = (shown.first[0] - 10, 0)  # 10 s ago nothing was done
    text = shown.line(shown.first[0] + 10, 100)
    assert "folds done 0/3" in text and "fold 1 chain 1 warm-up 50/100" in text
    assert "~" in text and "s left" in text
    shown.update(range(0, 1), range(0, 2), 310, np.array([[1, 2]]))
    assert shown.divergent.sum() == 3 and "3 divergent" in shown.line(shown.first[0] + 20, 600)
    assert stream.getvalue().startswith("\r[law cv]")


def test_fit_command_prints_progress_off_a_terminal(tmp_path, capsys, data, monkeypatch):
    """``bayesfric fit`` without --quiet: plain progress lines on stderr (not a terminal here)."""
    from bayesfric.cli import main

    monkeypatch.setenv("BAYESFRIC_PROGRESS_S", "0")  # every chunk reports
    csv = tmp_path / "bench.csv"
    csv.write_text("speed,torque\n" + "\n".join(f"{v},{t}" for v, t in zip(
        data["velocity"].values, data["torque"].values, strict=True)) + "\n")
    (tmp_path / "bench.toml").write_text(META)
    code = main(["fit", str(csv), "coulomb_viscous", "--out", str(tmp_path / "fit.nc"),
                 "--draws", "100", "--tune", "150", "--chains", "2"])
    err = capsys.readouterr().err
    assert code == 0
    lines = [line for line in err.splitlines() if line.startswith("[coulomb_viscous fit]")]
    assert len(lines) >= 3, err
    assert "warm-up" in err and "chain 2 draws 100/100" in lines[-1] and lines[-1].endswith(", done")


def _unit(law, stage, key):
    return Unit(law, stage, stage, key)


def test_time_left_scales_with_each_laws_fit_cost():
    """A law whose fit took 10× longer is expected to take 10× longer for its CV too."""
    units = [_unit("cheap", "fit", "a"), _unit("cheap", "cv", "b"), _unit("dear", "fit", "c"),
             _unit("dear", "cv", "d")]
    costs = CostModel(units)
    assert costs.left() is None
    costs.done(units[0], 2.0)
    costs.done(units[1], 6.0)  # cv = 3 × fit
    assert costs.left() == pytest.approx(2.0 + 6.0)  # dear's fit unknown: the median fit
    costs.done(units[2], 20.0)
    assert costs.left() == pytest.approx(60.0)


def test_a_reused_fit_reports_the_cost_it_saved(tmp_path):
    store = RunStore(tmp_path)
    store.put("k", "nc", xr.DataTree(xr.Dataset({"x": 1.0})))
    assert math.isnan(store.seconds("k", "nc"))  # stored by an older run
    store.put_seconds("k", "nc", 12.5)
    assert store.seconds("k", "nc") == 12.5
    stream = io.StringIO()
    progress = Progress(2, "s", stream, live=False, units=[_unit("law", "fit", "k"), _unit("law", "cv", "j")])
    progress.step(_unit("law", "fit", "k"), "reused", 0.0, 12.5)
    assert "reused (saved 12.5 s)" in stream.getvalue() and "~12 s left" in stream.getvalue()


STUDY = '''[study]
name = "timed"
[data]
dataset = "bench.csv"
[sampler]
draws = 200
tune = 200
chains = 2
[[laws]]
name = "coulomb_viscous"
[compare]
loo = true
evidence = false
'''


def test_a_resumed_study_reports_what_its_reused_units_cost(tmp_path, data_csv, monkeypatch):  # noqa: F811
    """Run, delete the report (the store stays), run again: every unit is reused, timings.csv has
    the seconds each took when computed (finite, the fit's included), the footer says so, and the
    plain lines show the chains' progress inside the fit."""
    import csv as csvmod
    import shutil

    from bayesfric.pipeline.runner import run_study

    (tmp_path / "s.toml").write_text(STUDY)
    monkeypatch.setenv("BAYESFRIC_PROGRESS_S", "0")  # every chunk reports
    out = io.StringIO()
    import contextlib

    with contextlib.redirect_stdout(out):
        first: list = []
        run_study(tmp_path / "s.toml", out_root=tmp_path / "reports", timings=first, live_progress=False)
    assert "[timed coulomb_viscous fit] chain 1 " in out.getvalue()
    computed = {r.stage: r.seconds for r in first}
    assert all(r.status == "computed" for r in first)
    shutil.rmtree(tmp_path / "reports" / "timed")
    again: list = []
    run_study(tmp_path / "s.toml", out_root=tmp_path / "reports", timings=again, live_progress=False)
    assert {r.status for r in again} == {"reused"}
    for row in again:
        assert row.seconds == 0.0 and row.stored_seconds == pytest.approx(computed[row.stage], rel=1e-6, abs=1e-3)
    with (tmp_path / "reports" / "timed" / "timings.csv").open(newline="") as fh:
        assert all(math.isfinite(float(r["stored_seconds"])) for r in csvmod.DictReader(fh))
    html = "".join(p.read_text() for p in (tmp_path / "reports" / "timed").glob("*.html"))
    assert "reused from earlier runs: 3 units" in html and "of computing saved" in html


def test_a_terminal_bar_shows_the_costed_time_left():
    stream = io.StringIO()
    units = [_unit("a", "fit", "k"), _unit("a", "cv", "j"), _unit("b", "fit", "m")]
    progress = Progress(3, "st", stream, live=True, units=units)
    progress.step(units[0], "computed", 3.0)
    progress.close()
    assert "st (~6 s left)" in stream.getvalue()  # a's cv (1 × its fit) and b's fit (the median fit)


def test_engines_of_other_warm_up_lengths_do_not_share_start_programs(monkeypatch, tmp_path, data):
    """The start program splits each chain's key into one key per schedule row: its disk key
    must say how many rows (the warm-up length is no argument shape of it)."""
    import bayesfric.exported as exported

    monkeypatch.setenv("BAYESFRIC_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("BAYESFRIC_NO_CACHE", raising=False)
    program = build_program(get_law("coulomb_viscous"), data)
    keys = np.zeros((1, 1, 2), dtype=np.uint32)
    for tune in (150, 200):
        exported.forget_compiled()
        engine = NutsEngine.build(program, **(SMALL | dict(tune=tune)))
        starts = np.asarray(engine.kernel.positions(engine.start))[:1]
        _, step = engine.kernel.sampler.start(keys, np.ones((1, program.n_obs), bool), program.response, starts,
                                              engine.start.inverse_mass)
        assert np.asarray(step).shape[2] == tune + SMALL["draws"]
    exported.forget_compiled()


def test_emcee_reports_its_ensemble_and_moves_as_run_mcmc_does(data):
    """emcee (the second backend) reports warm-up and kept steps of its one ensemble, without a
    divergence count; stepping it in reported slices gives run_mcmc's chain step for step."""
    import emcee

    from bayesfric.inference.ensemble import REPORT_EVERY, _steps, sample_emcee

    def log_prob(x):
        return -0.5 * np.sum(x**2, axis=-1)

    def sampler():
        s = emcee.EnsembleSampler(8, 2, log_prob, vectorize=True)
        s.random_state = np.random.RandomState(1).get_state()
        return s

    p0 = np.random.default_rng(0).standard_normal((8, 2))
    direct, sliced = sampler(), sampler()
    direct.run_mcmc(p0, 120)
    _steps(sliced, p0, 120, SamplingProgress(None, 1, 1, 0, 0, 120), 0)
    np.testing.assert_array_equal(direct.get_chain(), sliced.get_chain())
    stream = io.StringIO()
    program = build_program(get_law("coulomb_viscous"), data)
    with reporting("cv fit", stream=stream, live=False, interval=0):
        sample_emcee(program, data, draws=REPORT_EVERY, tune=2 * REPORT_EVERY, walkers=8, thin=10, seed=2)
    lines = stream.getvalue().splitlines()
    tune, draws = 2 * REPORT_EVERY, REPORT_EVERY
    assert lines[0].startswith(f"[cv fit] ensemble of 8 walkers warm-up {REPORT_EVERY}/{tune} · "), lines
    assert lines[1].startswith(f"[cv fit] ensemble of 8 walkers draws 0/{draws} · ")  # warm-up done
    assert lines[-1].startswith(f"[cv fit] ensemble of 8 walkers draws {draws}/{draws} · ")
    assert lines[-1].endswith(", done") and len(lines) == 3 and not any("divergent" in x for x in lines)


def test_a_unit_on_a_dask_worker_reports_its_chains(monkeypatch, capsys):
    """On a Dask worker a unit's chains report in plain lines on the worker's stderr, labelled with
    the study, law and unit (the executor submits compute_reporting, not compute)."""
    from types import SimpleNamespace

    from bayesfric.inference.progress import current
    from bayesfric.study import executor

    def fake_compute(job, unit, fit_payload, engines=None):
        shown = SamplingProgress(current(), folds=1, chains=2, idle=0, tune=10, draws=20)
        shown.update(range(1), range(2), 30, np.zeros((1, 2)))
        return b"payload", 1.5

    monkeypatch.setattr(executor, "compute", fake_compute)
    monkeypatch.setenv("BAYESFRIC_PROGRESS_S", "0")
    unit = SimpleNamespace(law="stribeck", label="fit")
    assert executor.compute_reporting("tiny", None, unit, None) == (b"payload", 1.5)
    err = capsys.readouterr().err.splitlines()
    assert err and err[-1].startswith("[tiny stribeck fit] chain 1 draws 20/20 · chain 2 draws 20/20")
    assert err[-1].endswith(", done")
