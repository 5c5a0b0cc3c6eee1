"""Study results without sampling, for fast report tests: posterior draws are drawn around given
values with numpy (not a posterior of the data — stated here, used only to exercise renderings).

A fake run (:class:`FakeRun`) holds each law's compare-layer results (:class:`FakeLaw`) the way
the runner holds them between its units and its result tree; :func:`tree_of` flattens them with
the runner's own functions (:func:`bayesfric.study.lawresult.law_result`,
:func:`bayesfric.study.tree.study_tree`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import xarray as xr

from bayesfric.compare import CVResult, EstimatorAgreement, Evidence, LooResult, Penalty, RankingSensitivity
from bayesfric.datasets.synthetic import simulate
from bayesfric.inference.datatree import provenance
from bayesfric.inference.diagnostics import Verdict
from bayesfric.laws import get_law
from bayesfric.laws.base import Law
from bayesfric.model import build_program
from bayesfric.report.summary import write_reports
from bayesfric.study.claims import evaluate_claims
from bayesfric.study.lawresult import Weight, law_result
from bayesfric.study.plan import QuickRun
from bayesfric.study.spec import Study
from bayesfric.study.tree import run_attrs, study_tree
from bayesfric.study.units import checks_dataset
from tests.bench_data import write_bench

OK = Verdict(True, 1.0, 1000.0, 1000.0, 0, 1.0, 0.9)
BAD = Verdict(False, 1.2, 50.0, 40.0, 12, 0.2, 0.9, problems=["R-hat 1.2 > 1.01"])


def data(n: int = 40) -> xr.Dataset:
    """Simulated Coulomb + viscous torque over ±4 rad/s (sigma 0.2 N·m)."""
    speeds = np.geomspace(0.005, 4.0, n // 2)
    v = np.concatenate([-speeds[::-1], speeds])
    return simulate(get_law("coulomb_viscous"), {"velocity": v}, {"T_C": 5.0, "c_v": 2.0}, sigma=0.2, seed=5)


def fake_fit(name: str, ds: xr.Dataset, centre: dict[str, float], sd: float = 0.05, seed: int = 0) -> xr.DataTree:
    """A DataTree laid out like a fit: posterior draws N(centre, sd·|centre|), 2 chains × 200."""
    law = get_law(name)
    rng = np.random.default_rng(seed)
    post = {k: (("chain", "draw"), c + sd * abs(c) * rng.standard_normal((2, 200))) for k, c in centre.items()}
    post["sigma"] = (("chain", "draw"), 0.2 + 0.01 * rng.standard_normal((2, 200)))
    v = ds["velocity"].values
    mean = np.asarray(law.mean({"velocity": v[None, None, :]}, {k: post[k][1][..., None] for k in law.params}))
    pp = mean + 0.2 * rng.standard_normal(mean.shape)
    tree = xr.DataTree.from_dict({
        "posterior": xr.Dataset(post),
        "posterior_predictive": xr.Dataset({"response": (("chain", "draw", "obs"), pp)}),
    })
    tree.attrs.update(provenance(build_program(law, ds), ds, "nuts", {}, 0))  # the attrs of a real fit
    return tree


def loo_result(name: str, elpd: float, se: float, n: int = 40, reliable: bool = True) -> LooResult:
    """A PSIS-LOO result with the given estimate (pointwise values spread evenly; p_loo 2, k̂ ≤ 0.3)."""
    return LooResult(law=name, elpd=elpd, se=se, p_loo=2.0, elpd_i=np.full(n, elpd / n),
                     pareto_k=np.linspace(0.0, 0.3, n), k_threshold=0.7, high_k=np.array([], dtype=int),
                     handling="none above threshold", refit_failed=[], fit_passed=True, elpd_data=None,
                     refitted=reliable)


def cv_result(name: str, scheme: str, elpd: float, se: float, heldout: np.ndarray, reliable: bool = True) -> CVResult:
    """A cross-validation result with the given estimate; ``reliable=False``: fold 0 failed the gate."""
    elpd_i = np.where(heldout, elpd / max(int(heldout.sum()), 1), np.nan)
    return CVResult(law=name, scheme=scheme, elpd=elpd, se=se, elpd_i=elpd_i, heldout=heldout,
                    verdicts=[OK if reliable else BAD], seconds=0.0)


def evidence(log_z: float, error: float, method: str) -> Evidence:
    return Evidence(log_z, error, method, {"reliable": True})


def checks(pvalue: float = 0.4, ok: bool = True, ci_prob: float = 0.94, pit=None, band=None) -> xr.Dataset:
    """A checks unit's Dataset (no prior-predictive or power-scaling findings)."""
    return checks_dataset(float("nan"), pvalue, ok, ci_prob, [], pit, band)


@dataclass
class FakeLaw:
    """One law's results as the runner holds them before its result tree (fakes, not sampled)."""

    law: Law
    fit: xr.DataTree | None
    verdict: Verdict
    loo: LooResult | None = None
    cv: dict[str, CVResult] = field(default_factory=dict)
    penalty: dict[str, float] = field(default_factory=dict)
    penalty_se: dict[str, float] = field(default_factory=dict)
    evidence: dict[str, Evidence] = field(default_factory=dict)
    agreement: EstimatorAgreement | None = None
    checks: xr.Dataset | None = None
    weights: dict[str, Weight] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.law.name

    def result(self) -> xr.Dataset:
        """The law's result Dataset, as the runner flattens it."""
        penalty = {k: Penalty(self.name, k, v, self.penalty_se.get(k, float("nan")), 1, True)
                   for k, v in self.penalty.items()}
        return law_result(self.law, f"fits/{self.name}.nc", self.verdict, loo=self.loo, cv=self.cv, penalty=penalty,
                          evidence=self.evidence, agreement=self.agreement, checks=self.checks,
                          weights=self.weights, timings=self.timings)


@dataclass
class FakeRun:
    """A study's fake results: its laws, its schemes' held-out rows and its sensitivity."""

    study: Study
    data: xr.Dataset | None
    laws: list[FakeLaw]
    heldout: dict[str, np.ndarray] = field(default_factory=dict)  # scheme label -> held-out rows (all blocked)
    sensitivity: RankingSensitivity | None = None
    quick: QuickRun | None = None

    @property
    def blocked(self) -> list[str]:
        return list(self.heldout)

    @property
    def schemes(self) -> list[tuple]:
        return [(label, SimpleNamespace(heldout=held[None, :]), "blocked") for label, held in self.heldout.items()]


def tree_of(run: FakeRun) -> xr.DataTree:
    """The run's result tree, built as the runner builds one."""
    return study_tree(run.study, run.data, run.schemes, [w.result() for w in run.laws],
                      {w.name: w.fit for w in run.laws}, sensitivity=run.sensitivity, quick=run.quick)


def outcome(study, tmp: Path, *, failed: str | None = None) -> FakeRun:
    """Two laws (coulomb, coulomb_viscous) with LOO, one blocked scheme and stacking weights;
    ``failed`` names a law whose fit failed the gate."""
    ds = data()
    label = study.blocked[0].describe() if study.blocked else "blocked"
    held = np.abs(ds["velocity"].values) > 1.0
    laws = []
    for name, centre, loo, cv, pen, w in (("coulomb", {"T_C": 6.3}, -90.0, -160.0, 15.0, 0.0),
                                          ("coulomb_viscous", {"T_C": 5.0, "c_v": 2.0}, 9.0, -4.0, 0.5, 1.0)):
        laws.append(FakeLaw(
            law=get_law(name), fit=fake_fit(name, ds, centre), verdict=BAD if name == failed else OK,
            loo=loo_result(name, loo, 3.0, n=held.size), cv={label: cv_result(name, label, cv, 2.0, held)},
            penalty={label: pen}, weights={f"stacking {label}": Weight(w), "stacking LOO": Weight(w)},
            checks=checks(0.4)))
    return FakeRun(study=study, data=ds, laws=laws, heldout={label: held})


def write_outcome(out: FakeRun, folder: Path, seconds: float = 0.0) -> xr.DataTree:
    """The report of ``out`` written as the runner writes one: the run's result tree with the
    run's seconds, the study's claims evaluated from that tree, the data set and each law's fit
    (no sizing question)."""
    tree = tree_of(out)
    tree.attrs.update(run_attrs(seconds, None))
    claims = evaluate_claims(out.study.claims, tree)
    return write_reports(tree, folder, out.data, {w.name: w.fit for w in out.laws}, claims)


def write_bench_study(folder: Path, capacity: str | None = None) -> Path:
    """A real small study in ``folder`` (SIMULATED coulomb_viscous bench, 40 speeds; NUTS 2 × 700,
    LOO, a blocked fold above 1 rad/s, a parameter claim, a sizing question with ``capacity``):
    the study file's path. Shared by the browser and re-rendering tests."""
    speeds = np.geomspace(0.005, 4.0, 20)
    write_bench(folder, np.concatenate([-speeds[::-1], speeds]))
    cap = f'capacity = "{capacity}"\n' if capacity else ""
    (folder / "s.toml").write_text(
        '[study]\nname = "tiny"\nquestion = "Trained below 1 rad/s, which law predicts above?"\n'
        '[data]\ndataset = "bench.csv"\n[sampler]\ndraws = 700\ntune = 400\nchains = 2\n'
        '[[laws]]\nname = "coulomb"\n[[laws]]\nname = "coulomb_viscous"\n[compare]\nevidence = false\n'
        '[[compare.blocked]]\naxis = "velocity"\nthreshold = 1.0\nlabel = "outside"\n'
        '[[claims]]\ntext = "viscous coefficient 2 N·m·s/rad"\nsource = "simulation"\nkind = "parameter"\n'
        'law = "coulomb_viscous"\nparameter = "c_v"\nexpect = [1.8, 2.2]\n'
        '[[sizing]]\nlabel = "beyond the tested speeds"\nat = { velocity = "4..6 rad/s" }\n' + cap)
    return folder / "s.toml"

