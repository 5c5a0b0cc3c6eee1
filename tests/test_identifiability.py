"""Identifiability from the data before fitting, companion entries, and no LOO refit on a failed fit
(issue 50 items 2 and 3)."""

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from bayesfric import identifiability as idf
from bayesfric.compare.loo import psis_loo
from bayesfric.datasets.synthetic import make_dataset, simulate
from bayesfric.datasets.views import travel
from bayesfric.inference import SamplerConfig, fit
from bayesfric.laws import get_law
from bayesfric.laws.variants import for_data
from bayesfric.model import Noise, build_program
from bayesfric.report.content import _identifiability
from bayesfric.report.view import TreeView
from bayesfric.study import lawresult, units
from bayesfric.study.config import study_from_raw
from bayesfric.study.plan import with_identifiability
from bayesfric.study.spec import LawSpec
from bayesfric.study.tree import study_tree

PER_STROKE = 40


def _loops(speeds, stroke=0.004, preloads=(None,)):
    """Triangle-drive loops (rotary): one trajectory per (speed, preload), each two strokes of
    ``stroke`` rad at that constant speed, ``PER_STROKE`` samples a stroke."""
    v, t, run, p = [], [], [], []
    for k, (speed, preload) in enumerate((s, q) for s in speeds for q in preloads):
        h = stroke / speed / PER_STROKE
        sign = np.r_[np.ones(PER_STROKE), -np.ones(PER_STROKE), np.ones(PER_STROKE)]
        v.append(speed * sign)
        t.append(np.arange(sign.size) * h)
        run.append(np.full(sign.size, k))
        p.append(np.full(sign.size, preload if preload is not None else np.nan))
    v, t, run = np.concatenate(v), np.concatenate(t), np.concatenate(run)
    inputs = {"velocity": v, "time": t, "angle": travel(v, t, np.r_[True, run[1:] != run[:-1]])}
    if preloads[0] is not None:
        inputs["preload"] = np.concatenate(p)
    torque = 0.5 * np.sign(v) + 0.1 * v  # the checks read the inputs; the response only scales priors
    return make_dataset(inputs, torque, groups={"run": run}, trajectory="run", name="loops")


def _checks(name, ds, priors=None):
    law = for_data(get_law(name), ds)
    return idf.assess(law, name, ds, build_program(law, ds, priors=priors or {}, noise=Noise()).resolved)


def _by_params(checks):
    return {c.params: c for c in checks}


def _study(laws, companions=None):
    compare = {"kfold": 0, "evidence": False} | ({"companions": companions} if companions is not None else {})
    return study_from_raw(Path("loops.toml"), {"data": {"dataset": "loops.csv"}, "laws": laws, "compare": compare})


def test_loops_at_one_speed_do_not_identify_the_stribeck_part():
    checks = _by_params(_checks("lugre", _loops([0.5])))
    stribeck = checks[("F_c", "F_ratio", "v_s")]
    assert stribeck.holds is False
    assert "steady speeds 500 mrad/s–500 mrad/s (×1" in stribeck.measured and "below them" in stribeck.measured
    assert stribeck.reduce["F_ratio"] == idf.RATIO_ONE and stribeck.reduce["rho1"] == 0.0
    assert stribeck.reduce["v_s"] == pytest.approx(0.5 * np.exp(-2.0))  # its prior median on these data
    assert checks[("sigma2",)].holds is False  # σ2·v constant: collinear with F_c
    assert checks[("sigma0", "rho1")].holds is True  # 40 samples a stroke: reversals finely sampled
    assert ("gamma", "kappa") not in checks and ("gamma",) not in checks  # no preload input: γ fixed


def test_a_prior_far_above_the_tested_speed_is_named():
    prior = {"v_s": {"dist": "LogNormal", "loc": float(np.log(50.0)), "scale": 0.5}}
    from bayesfric.priors import Prior

    checks = _by_params(_checks("lugre", _loops([0.5]), {k: Prior.from_dict(v) for k, v in prior.items()}))
    assert "v_s prior median 50 rad/s above them" in checks[("F_c", "F_ratio", "v_s")].measured


def test_loops_over_two_decades_of_speed_identify_it():
    checks = _by_params(_checks("elastoplastic", _loops(np.geomspace(0.01, 1.0, 5))))
    stribeck = checks[("F_c", "F_ratio", "v_s")]
    assert stribeck.holds is True and "×1e+02" in stribeck.measured and not stribeck.reduce
    assert checks[("sigma2",)].holds is True


def test_coarse_reversals_fail_the_presliding_check():
    ds = _loops([0.5], stroke=2.0)  # 50 mrad per sample against F_c/σ0 ≈ 0.7 mrad at the prior medians
    check = _by_params(_checks("lugre", ds))[("sigma0", "rho1")]
    assert check.holds is False and "0 samples" in check.measured


def test_one_preload_leaves_gamma_open_two_identify_it():
    one = _by_params(_checks("dahl", _loops([0.5], preloads=(80.0,))))
    two = _by_params(_checks("dahl", _loops([0.5], preloads=(40.0, 160.0))))
    assert one[("gamma",)].holds is False and one[("gamma",)].reduce == {"gamma": 0.0}
    assert "1 preload (80 N)" in one[("gamma",)].measured
    assert two[("gamma",)].holds is True and "2 preloads (40 N–160 N)" in two[("gamma",)].measured
    assert idf.requirements_for("dahl_i1p5") == idf.REQUIREMENTS["dahl"]
    assert idf.requirements_for("gms_n6") == idf.REQUIREMENTS["gms"]
    assert idf.requirements_for("stribeck") == [] and idf.requirements_for("lugre_custom") == []


def test_the_companion_entry_is_added_named_and_ranked_like_any_law():
    ds = _loops([0.5])
    study = with_identifiability(_study([{"name": "lugre"}, {"name": "dahl"}]), ds)
    names = [spec.name for spec in study.laws]
    assert names == ["lugre", "dahl", "lugre_Fs_eq_Fc"]  # after the study's own entries
    companion = study.laws[-1]
    assert companion.companion_of == "lugre" and companion.law == "lugre"
    assert set(companion.build().params) == {"sigma0", "sigma2", "F_c", "gamma"}
    assert set(for_data(companion.build(), ds).params) == {"sigma0", "sigma2", "F_c"}
    # the companion is an entry like any other: it gets its own job and units
    job = units.make_job(companion, Noise(), ds, SamplerConfig(draws=10, tune=10, chains=1))
    fit_unit, rest = units.plan_law(job, study, [])
    assert fit_unit.law == "lugre_Fs_eq_Fc" and [u.stage for u in rest] == ["loo", "checks"]
    lines = idf.describe(study.identifiability, idf.companions_of(study.laws))
    assert len(lines) == 3 and lines[0].startswith("lugre: F_c, F_ratio, v_s not determined")
    assert lines[0].endswith("-> companion lugre_Fs_eq_Fc added")
    # Dahl's loops of 4 mrad do not saturate against its knee's prior median (4 mrad): no reduced variant
    assert lines[1].startswith("dahl: F_c0, x_c0, i not determined: median stroke 3.8 mrad = 0.95 x_c")
    assert "companion" not in lines[1]
    # the companion is checked too: at one speed its σ2 is still collinear with F_c (no further companion)
    assert lines[2] == "lugre_Fs_eq_Fc: sigma2 not determined: steady speeds vary ×1 (needs ×2)"
    node = idf.checks_dataset(study.identifiability, idf.companions_of(study.laws))
    rows = idf.checks_of(node)
    assert {r["law"] for r in rows} == {"lugre", "dahl", "lugre_Fs_eq_Fc"}
    assert {r["companion"] for r in rows if r["law"] == "lugre"} == {"lugre_Fs_eq_Fc"}


def test_the_opt_out_keeps_the_checks_and_adds_no_companion():
    ds = _loops([0.5])
    study = with_identifiability(_study([{"name": "lugre"}], companions=False), ds)
    assert [spec.name for spec in study.laws] == ["lugre"]
    assert any(c.holds is False for c in study.identifiability)
    spanning = with_identifiability(_study([{"name": "lugre"}]), _loops(np.geomspace(0.01, 1.0, 5)))
    assert [spec.name for spec in spanning.laws] == ["lugre"]  # identified: no companion


def test_a_label_already_taken_or_a_grouped_parameter_gets_no_companion():
    ds = _loops([0.5], preloads=(80.0,))
    taken = with_identifiability(_study([{"name": "lugre"}, {"name": "lugre", "label": "lugre_Fs_eq_Fc_gamma0",
                                                             "fixed": {"F_ratio": 0.5}}]), ds)
    assert [s.name for s in taken.laws][:2] == ["lugre", "lugre_Fs_eq_Fc_gamma0"]
    assert sum(s.companion_of == "lugre" for s in taken.laws) == 0
    grouped = with_identifiability(_study([{"name": "dahl", "vary_by": {"run": ["F_c0"]}}]), ds)
    assert [s.name for s in grouped.laws] == ["dahl", "dahl_gamma0"]


def test_the_report_table_reads_the_tree_node():
    ds = _loops([0.5])
    study = with_identifiability(_study([{"name": "lugre"}]), ds)
    node = idf.checks_dataset(study.identifiability, idf.companions_of(study.laws))
    tree = study_tree(study, ds, [], [], {}, identifiability=node)
    table = _identifiability(TreeView(tree))
    assert table.header[-1] == "companion" and len(table.rows) == len(study.identifiability)
    failed = [table.rows[i] for i in table.warn]
    assert failed and all(r[3] == "failed" for r in failed)


# -- no exact LOO refit on a fit that failed the gate (issue 50 item 3) ----------------------------
SPEEDS = np.linspace(0.1, 4.0, 30)


@pytest.fixture(scope="module")
def outlier():
    """30 points of Coulomb + viscous friction, the last shifted by 8 sd (a high Pareto k), fitted."""
    law = get_law("coulomb_viscous")
    ds = simulate(law, {"velocity": SPEEDS}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.05, seed=2)
    torque = ds["torque"].values.copy()
    torque[-1] += 0.4
    ds = make_dataset({"velocity": SPEEDS}, torque, name="planted_outlier")
    return ds, fit(law, ds, noise=Noise(sigma=0.05), draws=500, tune=300, chains=2, seed=0)


def test_psis_loo_refits_nothing_when_told_why_not(outlier):
    _, dt = outlier

    def engine():
        raise AssertionError("no refit may start")

    result = psis_loo(dt, engine=engine, no_refit="the fit failed the gate")
    assert result.high_k.size and not result.refitted and not result.reliable
    assert result.handling.endswith("not refitted: the fit failed the gate (PSIS values kept)")


@pytest.mark.parametrize("failed_fits", ["skip", "run"])
def test_a_failed_fit_gets_psis_only_unless_the_study_runs_failed_fits(outlier, monkeypatch, failed_fits):
    ds, dt = outlier
    spec = LawSpec("coulomb_viscous", law="coulomb_viscous")
    job = units.make_job(spec, Noise(sigma=0.05), ds, SamplerConfig(draws=500, tune=300, chains=2))
    study = SimpleNamespace(loo=True, evidence=False, smc=False, failed_fits=failed_fits)
    loo_unit = units.plan_law(job, study, [])[1][0]
    verdict = units.compare.verdict_of(dt)
    assert loo_unit.stage == "loo" and loo_unit.params == ({"failed_fits": "run"} if failed_fits == "run" else {})
    monkeypatch.setattr(units.compare, "verdict_of", lambda fit: SimpleNamespace(passed=False))

    def engine(*args, **kwargs):
        raise RuntimeError("exact refit started")

    monkeypatch.setattr(units, "_engine", engine)
    if failed_fits == "run":  # the study asked for them: the refits start
        with pytest.raises(RuntimeError, match="exact refit started"):
            units.compute(job, loo_unit, dt)
        return
    result, _ = units.compute(job, loo_unit, dt)
    assert not result.attrs["refitted"] and units.NO_REFIT in result.attrs["handling"]
    loo = SimpleNamespace(reliable=False, fit_passed=False, refitted=False, n_high_k=1, handling="")
    values = {"skipped": "cv, bridge", "checked": False}
    failed = dataclasses.replace(verdict, passed=False, problems=["R-hat 1.02"])
    flags = lawresult._flags(values, failed, loo, {}, None, "skip")
    assert any("PSIS only, 1 high-k point(s) not refitted" in f for f in flags)


def test_a_derived_quantity_held_constant_by_the_reduction_does_not_fail_the_gate():
    """The companion lugre_Fs_eq_Fc fixes ρ1 = 0, so its derived σ1 is 0 in every draw: no R-hat
    exists for it, and it must not fail the gate (a smoke run's companion did: "R-hat nan")."""
    import xarray as xr

    from bayesfric.inference.diagnostics import check_folds

    rng = np.random.default_rng(0)
    post = xr.Dataset({"F_c": (("chain", "draw"), rng.normal(size=(4, 1000))),
                       "sigma1": (("chain", "draw"), np.zeros((4, 1000)))})
    verdict = check_folds(post, xr.Dataset(), fold=None)[0]
    assert verdict.passed and np.isfinite(verdict.rhat_max)
    stuck = check_folds(post[["sigma1"]], xr.Dataset(), fold=None)[0]  # nothing moves: still a failure
    assert not stuck.passed
