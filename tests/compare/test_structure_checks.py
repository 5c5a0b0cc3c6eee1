"""Residual-structure checks (issue 47 item 4): quiet on data from the law's own model, loud on a
run offset, blind neither to autocorrelation nor to a law's misfit along its inputs.

The rates are measured by simulation on the statistic alone (:func:`structure_tests`), with the
residuals a fit would give: the exact least-squares fit of Coulomb + viscous (linear in T_C and
c_v, so the posterior mean under flat priors; noise sd its residual sd). Each rate bound is the
target plus a one-sided 99 % binomial margin, 2.33 √(0.05 · 0.95 / N); the measured rates are
printed (``pytest -s``) and stated in the README. One module-scoped NUTS fit checks the residuals
a real fit gives and the whole path from fit to flag; the fake study checks the summary.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bayesfric.compare.structure import (
    Column,
    checks_of,
    columns_to_test,
    fit_residuals,
    residual_structure,
    stack_structure,
    structure_dataset,
    structure_tests,
)
from bayesfric.datasets import load_dataset, resolve
from bayesfric.laws import get_law

SIGMA = 0.1


def _bound(n: int, rate: float = 0.05) -> float:
    return rate + 2.33 * math.sqrt(rate * (1 - rate) / n)


def _least_squares(v: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of the exact Coulomb + viscous fit and its noise sd per row."""
    x = np.column_stack([np.sign(v), v])
    r = y - x @ np.linalg.lstsq(x, y, rcond=None)[0]
    return r, np.full(y.size, math.sqrt(r @ r / (y.size - 2)))


def _runs(rng: np.random.Generator, spread_sd: float = 0.0, n: int = 20):
    """3 runs over the same speeds, Coulomb level 1, 1 + spread/2, 1 + spread (in noise sd), and
    columns that have no effect: an angle, a drifting temperature, the time."""
    v = np.tile(np.linspace(-2.0, 2.0, n), 3)
    run = np.repeat([1, 2, 3], n)
    y = (1.0 + spread_sd * SIGMA * (run - 1) / 2) * np.sign(v) + 0.8 * v + rng.normal(0.0, SIGMA, v.size)
    columns = [Column("run", "group", run), Column("angle", "trend", rng.uniform(0.0, 2 * np.pi, v.size), "angle"),
               Column("temperature", "trend", 20 + 10 * np.linspace(0, 1, v.size) + rng.normal(0, 1, v.size),
                      "temperature"),
               Column("time", "trend", np.arange(v.size, dtype=float), "time")]
    r, s = _least_squares(v, y)
    return structure_tests(r, s, {"velocity": v}, columns)


def _rate(replicate, n: int, seed: int, **kw) -> float:
    rng = np.random.default_rng(seed)
    return float(np.mean([any(c.flagged for c in replicate(rng, **kw)) for _ in range(n)]))


def test_quiet_on_iid_data_from_the_laws_own_model():
    n = 400
    rate = _rate(_runs, n, seed=0)
    print(f"\nfalse alarm, i.i.d. data, 3 runs + 3 unread columns: {rate:.3f} of {n} (bound {_bound(n):.3f})")
    assert rate <= _bound(n)


def test_fires_on_a_run_offset_of_three_noise_sd():
    n = 200
    rng = np.random.default_rng(1)
    results = [_runs(rng, spread_sd=3.0, n=12) for _ in range(n)]
    rate = np.mean([c[0].flagged for c in results])
    print(f"\ndetection, 3 runs x 24 rows, Coulomb levels 3 noise sd apart: {rate:.3f} of {n}")
    assert rate >= 0.95
    # the effect: Coulomb levels 0.3 N·m apart, read at the same speed (each direction)
    assert abs(np.mean([c[0].effect for c in results]) - 3 * SIGMA) < 0.05
    assert all(c[0].column == "run" and c[0].kind == "group" for c in results)


def _misfit(rng: np.random.Generator, naive: bool = False):
    """A Stribeck truth fitted by Coulomb + viscous; each run covers other speeds (overlapping)."""
    parts = [(0.02, 0.6), (0.2, 1.2), (0.6, 2.0)]
    v = np.concatenate([np.r_[np.geomspace(a, b, 10), -np.geomspace(a, b, 10)] for a, b in parts])
    run = np.repeat([1, 2, 3], 20)
    y = np.sign(v) * (1 + 1.5 * np.exp(-(np.abs(v) / 0.2) ** 2)) + 0.8 * v + rng.normal(0.0, SIGMA, v.size)
    r, s = _least_squares(v, y)
    basis = np.column_stack([np.ones(v.size), np.sign(v)]) if naive else None
    return structure_tests(r, s, {"velocity": v}, [Column("run", "group", run)], basis=basis)


def test_a_misfit_along_speed_is_not_read_as_a_run_effect():
    n = 300
    rate, naive = _rate(_misfit, n, seed=2), _rate(_misfit, 50, seed=2, naive=True)
    print(f"\nfalse alarm, law misfit + runs over other speeds: {rate:.3f} of {n}; without the speed basis {naive:.2f}")
    assert rate <= _bound(n)
    assert naive > 0.5  # what conditioning on the operating point prevents


def _trajectories(rng: np.random.Generator, rho: float = 0.8, whiten: bool = True):
    """4 ordered trajectories of 150 rows, AR(1) noise (ρ = 0.8) along each; the run and the
    angle (the integral of speed: smooth, unread) have no effect."""
    k, m = 4, 150
    t = np.arange(m) * 0.02
    v = np.concatenate([(1 + 0.3 * j) * np.sin(2 * np.pi * t / 1.5) for j in range(k)])
    angle = np.concatenate([np.cumsum(v[j * m:(j + 1) * m]) * 0.02 for j in range(k)])
    run = np.repeat(np.arange(k), m)
    e = np.zeros(k * m)
    for j in range(k):
        x = rng.normal(0.0, SIGMA / math.sqrt(1 - rho**2))
        for i in range(m):
            x = rho * x + rng.normal(0.0, SIGMA) if i else x
            e[j * m + i] = x
    r, s = _least_squares(v, np.sign(v) + 0.8 * v + e)
    starts = np.r_[True, run[1:] != run[:-1]]
    columns = [Column("run", "group", run), Column("angle", "trend", angle, "angle")]
    return structure_tests(r, s, {"velocity": v}, columns, starts=starts if whiten else None)


def test_autocorrelated_trajectories_do_not_false_alarm():
    n = 300
    rate, iid = _rate(_trajectories, n, seed=3), _rate(_trajectories, 50, seed=3, whiten=False)
    print(f"\nfalse alarm, AR(1) rho 0.8 along 4 trajectories: {rate:.3f} of {n}; as if i.i.d. {iid:.2f}")
    assert rate <= _bound(n)
    assert iid > 0.5  # what the prewhitening prevents
    rhos = [c.rho for c in _trajectories(np.random.default_rng(4))]
    assert all(0.65 < rho < 0.9 for rho in rhos)


def test_a_trend_in_an_unread_column_is_found_and_named():
    rng = np.random.default_rng(5)
    v = np.tile(np.linspace(-2.0, 2.0, 30), 2)
    angle = rng.uniform(0.0, 2 * np.pi, v.size)
    found = []
    for _ in range(100):
        y = np.sign(v) + 0.8 * v + 3 * SIGMA * np.cos(angle) + rng.normal(0.0, SIGMA, v.size)
        r, s = _least_squares(v, y)
        c, = structure_tests(r, s, {"velocity": v}, [Column("angle", "trend", angle, "angle")], unit="N*m",
                             suggestions={"angle": "gravity"})
        found.append(c)
    assert np.mean([c.flagged for c in found]) >= 0.95
    assert "trends with 'angle'" in found[0].sentence() and "N·m" in found[0].sentence()


def test_a_column_spanned_by_the_laws_inputs_is_not_testable():
    v = np.repeat([0.5, 1.0, 2.0], 10)
    r = np.random.default_rng(6).normal(size=v.size)
    c, = structure_tests(r, np.ones(v.size), {"velocity": v}, [Column("setting", "group", v.astype(int))])
    assert c.df == 0 and math.isnan(c.p_value) and not c.flagged


def test_columns_of_the_builtin_data_sets():
    robot = load_dataset(resolve("robot_joint"))
    assert [c.name for c in columns_to_test(robot, get_law("coulomb_viscous"))] == ["series"]  # not torque_normalised
    unwinder = load_dataset(resolve("unwinder"))
    blind = [c.name for c in columns_to_test(unwinder, get_law("coulomb_viscous"))]
    thermal = [c.name for c in columns_to_test(unwinder, get_law("thermal_viscous_quadratic"))]
    assert blind == ["temperature", "setup", "cycle", "time"] and thermal == ["setup", "cycle", "time"]
    dahl = load_dataset(resolve("dahl_duplex"))
    blind = {c.name: c.kind for c in columns_to_test(dahl, get_law("coulomb_viscous"))}
    assert blind == {"loop": "group", "condition": "group", "preload": "trend", "time": "trend", "angle": "trend"}
    assert not {"preload", "preload_group"} & {c.name for c in columns_to_test(dahl, get_law("dahl"))}


def _same(a, b) -> bool:
    """Checks equal field by field, NaN equal to NaN (a numeric column has no between-group sd)."""
    return len(a) == len(b) and all(
        x == y or (isinstance(x, float) and np.isnan(x) and np.isnan(y))
        for ca, cb in zip(a, b, strict=True) for x, y in zip(dataclasses.astuple(ca), dataclasses.astuple(cb),
                                                             strict=True))


def test_checks_round_trip_through_a_dataset_and_a_stack():
    checks = _runs(np.random.default_rng(7), spread_sd=3.0)
    ds = structure_dataset(checks)
    assert _same(checks_of(ds), checks)
    stacked = stack_structure([("a", ds), ("b", structure_dataset(checks[:1]))])
    assert _same(checks_of(stacked.sel(law="a")), checks) and _same(checks_of(stacked.sel(law="b")), checks[:1])


# -- through a real fit ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def offset_fit():
    """Coulomb + viscous fitted (NUTS, small) to 3 runs whose Coulomb levels are 3 noise sd
    apart, with an unread angle that has no effect."""
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.inference import fit

    rng = np.random.default_rng(8)
    v = np.tile(np.linspace(-2.0, 2.0, 20), 3)
    run = np.repeat([1, 2, 3], 20)
    law = get_law("coulomb_viscous")
    ds = simulate(law, {"velocity": v, "angle": rng.uniform(0, 6.0, v.size)}, {"T_C": 1.0, "c_v": 0.8},
                  sigma=SIGMA, seed=9, groups={"run": run})
    ds["torque"] = ds["torque"] + 1.5 * SIGMA * (run - 1) * np.sign(v)
    return ds, fit(law, ds, seed=1, draws=300, tune=300, chains=2)


def test_residuals_are_the_data_minus_the_posterior_mean_of_the_mean_function(offset_fit):
    ds, f = offset_fit
    post = f["posterior"]
    tc, cv, sigma = (post[k].values.reshape(-1) for k in ("T_C", "c_v", "sigma"))
    v, y = ds["velocity"].values, ds["torque"].values
    by_hand = y - (tc[:, None] * np.sign(v) + cv[:, None] * v).mean(axis=0)
    r, s = fit_residuals(f, draws=tc.size)  # every draw: the exact posterior mean
    np.testing.assert_allclose(r, by_hand, atol=1e-9)
    np.testing.assert_allclose(s, math.sqrt(np.mean(sigma**2)), rtol=1e-9)


def test_a_fit_flags_the_run_offset_and_not_the_angle(offset_fit):
    ds, f = offset_fit
    found = residual_structure(f, ds)
    checks = {c.column: c for c in found if c.kind != "curvature"}
    assert set(checks) == {"run", "angle"}
    assert checks["run"].flagged and not checks["angle"].flagged
    # along its own input the law (the truth, up to the run offset) shows no lack of fit
    (bend,) = [c for c in found if c.kind == "curvature"]
    assert bend.column == "velocity" and not bend.flagged and "bend" in bend.sentence()
    assert 0.2 < checks["run"].effect < 0.4  # Coulomb levels 0.3 N·m apart
    assert "vary_by = { run = [\"T_C\"] }" in checks["run"].suggestion
    with pytest.raises(ValueError, match="rows"):
        residual_structure(f, ds.isel(obs=slice(0, 30)))


# -- in a study's results and its summary ----------------------------------------------------------
def test_the_summary_leads_with_a_flagged_column(tmp_path):
    from bayesfric.study import load_study
    from bayesfric.study.units import checks_dataset
    from tests.report.fakes import outcome, write_outcome

    (tmp_path / "t.toml").write_text(
        '[study]\nname = "t"\n[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n[[laws]]\n'
        'name = "coulomb_viscous"\n[compare]\nevidence = false\n[[compare.blocked]]\naxis = "velocity"\n'
        'threshold = 1.0\nlabel = "outside"\n')
    out = outcome(load_study(tmp_path / "t.toml"), tmp_path)
    flagged = _runs(np.random.default_rng(10), spread_sd=3.0)
    flagged = (dataclasses.replace(flagged[0], suggestion='vary_by = { run = ["T_C"] }'), *flagged[1:])
    quiet = _runs(np.random.default_rng(11))
    assert flagged[0].flagged and not any(c.flagged for c in quiet)
    out.laws[0].checks = checks_dataset(float("nan"), 0.4, True, 0.94, [], structure=flagged)
    out.laws[1].checks = checks_dataset(float("nan"), 0.4, True, 0.94, [], structure=quiet[:2])
    folder = tmp_path / "report"
    folder.mkdir()
    tree = write_outcome(out, folder)
    assert bool(tree["checks"]["structure_flagged"].sel(law="coulomb", structure_column="run"))
    assert tree["checks"]["structure_kind"].sel(law="coulomb_viscous", structure_column="time").item() == ""
    md = (folder / "summary.md").read_text()
    new_run, first = md.split("## Summary")[1].split("\n- ")[1:3]
    # a new run's answer says first that no law models 'run' and that the pooled laws are widened
    assert new_run.startswith("FOR A NEW 'run'") and "no law models 'run'" in new_run
    assert first.startswith("RESIDUAL STRUCTURE in 'run' (1 of 2 laws (coulomb))")
    assert "differs between the 3 groups of 'run'" in first and "vary\\_by" in first
    assert "residual structure: the response differs" in tree["diagnostics"]["flags"].sel(law="coulomb").item()
    assert "*Residual structure: each law's residuals" in md and "Residual structure: each law" in (
        folder / "report.html").read_text()


def test_a_hysteresis_law_is_conditioned_on_its_direction_of_motion():
    """Dahl reads the angle, not the velocity: its two branches per angle differ by direction,
    which the basis takes from the recorded velocity, else from the angle's steps."""
    from bayesfric.compare.structure import DIRECTION, _operating_point
    from bayesfric.datasets.synthetic import make_dataset

    angle = np.r_[np.linspace(0, 1, 10), np.linspace(1, 0, 10)]
    run = np.repeat([0, 1], 10)
    starts = np.r_[True, run[1:] != run[:-1]]
    law = get_law("dahl")
    bare = make_dataset({"angle": angle}, np.zeros(20), groups={"run": run}, trajectory="run")
    point = _operating_point({"angle": angle}, law, bare, starts)
    np.testing.assert_array_equal(point[DIRECTION], np.repeat([1.0, -1.0], 10))
    rate = np.r_[np.full(10, 0.5), np.full(10, -0.5)]
    recorded = make_dataset({"angle": angle, "velocity": rate}, np.zeros(20), groups={"run": run}, trajectory="run")
    np.testing.assert_array_equal(_operating_point({"angle": angle}, law, recorded, starts)[DIRECTION], np.sign(rate))
    # the recorded velocity is then spanned by the operating point: not testable, not flagged
    c, = structure_tests(np.random.default_rng(12).normal(size=20), np.ones(20),
                         _operating_point({"angle": angle}, law, recorded, starts),
                         [Column("velocity", "trend", rate, "velocity")])
    assert c.df == 0 and not c.flagged
