"""Claims of a source paper, declared in the study file and checked against the posterior.

A study's ``[[claims]]`` entries state what the paper says in a small declarative vocabulary
(``kind``):

``ratio``
    The relative difference ``of / to − 1`` of two predictions of mean-function torque (or
    force): the numerator is ``law`` at the point ``at`` (minus its value at ``minus``: a
    chord, i.e. a slope times a span), optionally with some parameters or constants ``fixed``
    (e.g. a catalogue coefficient instead of the posterior); the denominator is ``reference``
    (default: ``law``) at ``reference_at`` / ``reference_minus`` (default: ``at`` / ``minus``)
    from its posterior. ``expect`` is the claimed range of the relative difference (−0.35 =
    35 % below).
``parameter``
    A posterior parameter (or constant-free derived quantity) of ``law``: ``parameter``,
    ``expect`` its claimed range in SI units.
``score``
    A row of the law × metric table (:mod:`bayesfric.study.scores`): ``law``, ``metric``,
    ``scheme``; ``expect`` the claimed range of its estimate. With ``reference``, the claim is
    about the difference ``law − reference`` of that score (e.g. "i = 2 fits are less accurate
    than i = 1": ``expect = [-inf, 0]``); for ``elpd_loo`` and ``elpd_cv`` its standard error is
    the paired one, ``sqrt(n · var(elpd_i(law) − elpd_i(reference)))`` over the points both score.
``best``
    ``law`` is the best reliable law under ``metric`` / ``scheme``.

``law`` (and ``reference``) name a candidate of the study by its entry's label, so a claim may
be about a variant (``fixed``, ``offset``, ``add``, ``asymmetric``). Predictions go through the
fit's own program: the law, variant and constants that were fitted, rebuilt from the fit's
provenance (:func:`bayesfric.compare.refit.program_from_fit`), never a law looked up again by
its base name.

``basis`` says what a verdict can mean. ``"pipeline check"``: the claim's number was used to
build the data set (a RECONSTRUCTED data set calibrated to the paper's statements, see its
README), so "reproduced" checks the reconstruction and the pipeline, not the paper; the
reports mark it "pipeline check, not evidence". ``"evidence"``: the number was not used to
build the data. On reconstructed data every claim must say which (:func:`basis_problem`, checked
when the study runs, against the data set's provenance); elsewhere it defaults to evidence.

Each claim gets a :class:`ClaimResult`: the posterior median and 90 % equal-tailed interval (or
the estimate ± standard error), and a verdict: ``reproduced`` when the posterior median (or
estimate, or winner) falls within the claimed range, ``not reproduced`` when it does not, and
``not testable`` with the reason (a law not fitted, a fit that failed the diagnostics gate, a
score not computed). The claimed range is the study author's reading of the paper (the papers
state no uncertainty); the study file says how it was chosen.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
import numpy as np

from bayesfric.study import scores as sc
from bayesfric.study.claimspec import (
    BASES,
    KINDS,
    Claim,
    ClaimError,
    ClaimResult,
    basis_problem,
    check_claim,
    make_claim,
)

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr

# KINDS, BASES, Claim, ClaimError, ClaimResult, make_claim, check_claim, basis_problem: the claim
# specification and its result type (bayesfric.study.claimspec), re-exported here.
__all__ = ["KINDS", "BASES", "Claim", "ClaimError", "ClaimResult", "make_claim", "check_claim", "basis_problem",
           "evaluate_claims", "mean_draws", "VERDICTS"]

VERDICTS = ("reproduced", "not reproduced", "not testable")
#: Equal-tailed posterior interval shown with each claim.
INTERVAL = (0.05, 0.95)


# -- predictions through the fit's own program ----------------------------------------------------
def mean_draws(fit: xr.DataTree, points: Mapping[str, float], fixed: Mapping[str, float] | None = None) -> np.ndarray:
    """Mean-function draws, shaped (chain · draw,), of a fit at one operating point.

    Through the fit's own program (:func:`bayesfric.model.program_of_fit`) at the point
    (:meth:`~bayesfric.model.Program.at`): the variant that was fitted (recipe, ``fixed`` values,
    added terms) with the constants it was fitted with. ``fixed`` parameters or constants replace
    the posterior's (a fully fixed law gives one value for every draw); a partial-pooled group
    offset is not applied (the population mean).
    """
    from bayesfric.model import program_of_fit

    fixed = dict(fixed or {})
    program = program_of_fit(fit)
    program = program.at({k: np.asarray([points[k]], dtype=float) for k in program.law.operating_inputs})
    post = fit["posterior"].to_dataset()
    s = post.sizes["chain"] * post.sizes["draw"]
    params = {k: jnp.full((s,), fixed[k]) if k in fixed else
              jnp.asarray(np.asarray(post[k].values, dtype=float).reshape(s, *post[k].shape[2:]))
              for k in program.law.params}
    constants = program.constants | {k: v for k, v in fixed.items() if k in program.law.constants}
    inputs = {k: jnp.asarray(v) for k, v in program.inputs.items()}
    mu = jax.vmap(lambda p: program.law.mean(inputs, p, constants or None))(params)
    return np.asarray(mu, dtype=float).reshape(s, -1)[:, 0]


def _term(fit, at, minus, fixed) -> np.ndarray:
    value = mean_draws(fit, at, fixed)
    return value - mean_draws(fit, minus, fixed) if minus else value


def _interval(draws: np.ndarray) -> tuple[float, float, float]:
    lo, mid, hi = np.quantile(draws, [INTERVAL[0], 0.5, INTERVAL[1]])
    return float(mid), float(lo), float(hi)


def _verdict(claim: Claim, value: float) -> str:
    return "reproduced" if claim.expect[0] <= value <= claim.expect[1] else "not reproduced"


def _pointwise(tree: xr.DataTree, name: str, metric: str, scheme: str) -> np.ndarray | None:
    """Pointwise elpd of a law under ``elpd_loo`` / ``elpd_cv`` (NaN where not scored), else None."""
    node = tree["pointwise"].to_dataset()
    criterion = metric if metric == "elpd_loo" else f"{metric}[{scheme}]" if metric == "elpd_cv" else None
    if criterion is None or criterion not in node["criterion"].values:
        return None
    elpd = np.asarray(node["elpd"].sel(criterion=criterion, law=name).values, dtype=float)
    return None if not np.isfinite(elpd).any() else elpd


def _score(claim: Claim, tree: xr.DataTree, table: pd.DataFrame) -> ClaimResult:
    """A score, or with ``reference`` the difference of two scores (paired se for elpd)."""
    rows = [(name, sc.value(table, name, claim.metric, claim.scheme)) for name in (claim.law, claim.reference) if name]
    for name, row in rows:
        if row is None:
            return ClaimResult(claim, "not testable", why=f"{claim.metric} {claim.scheme} was not computed for {name}")
        if not row["reliable"]:
            return ClaimResult(claim, "not testable", value=float(row["estimate"]), why=f"{name}: {row['reason']}")
    est, se = float(rows[0][1]["estimate"]), float(rows[0][1]["se"])
    if claim.reference:
        est -= float(rows[1][1]["estimate"])
        a, b = (_pointwise(tree, n, claim.metric, claim.scheme) for n in (claim.law, claim.reference))
        if a is not None and b is not None and (both := np.isfinite(a) & np.isfinite(b)).sum() > 1:
            d = a[both] - b[both]
            se = float(np.sqrt(d.size * np.var(d)))
        else:
            se = math.hypot(se, float(rows[1][1]["se"]))
    return ClaimResult(claim, _verdict(claim, est), est, est - se, est + se)


def _untestable(claim: Claim, tree: xr.DataTree) -> ClaimResult | None:
    """``not testable`` when a posterior the claim reads comes from a fit that failed the gate."""
    if claim.kind not in ("ratio", "parameter"):
        return None
    from bayesfric.model import program_of_fit

    law = program_of_fit(tree[f"fits/{claim.law}"]).law
    used = [claim.law] if set(law.params) - set(claim.fixed) else []  # posterior read?
    if claim.kind == "ratio":
        used.append(claim.reference or claim.law)
    passed = tree["diagnostics"]["passed"]
    for name in dict.fromkeys(used):
        if not bool(passed.sel(law=name)):
            return ClaimResult(claim, "not testable", why=f"the fit of {name} failed the diagnostics gate")
    return None


def _evaluate(claim: Claim, tree: xr.DataTree, table: pd.DataFrame) -> ClaimResult:
    if (untestable := _untestable(claim, tree)) is not None:
        return untestable
    if claim.kind == "ratio":
        num = _term(tree[f"fits/{claim.law}"], claim.at, claim.minus, claim.fixed)
        den = _term(tree[f"fits/{claim.reference or claim.law}"], claim.reference_at, claim.reference_minus, {})
        mid, lo, hi = _interval(num / den - 1.0)
        return ClaimResult(claim, _verdict(claim, mid), mid, lo, hi)
    if claim.kind == "parameter":
        draws = np.asarray(tree[f"fits/{claim.law}/posterior"][claim.parameter].values, dtype=float).ravel()
        mid, lo, hi = _interval(draws)
        return ClaimResult(claim, _verdict(claim, mid), mid, lo, hi)
    if claim.kind == "score":
        return _score(claim, tree, table)
    winner = sc.best(table, claim.metric, claim.scheme)
    if winner is None:
        return ClaimResult(claim, "not testable", why="no law could be ranked under this criterion")
    if winner != claim.law and _form(tree, winner) == _form(tree, claim.law):
        return ClaimResult(claim, "reproduced", winner=winner,
                           why=f"by {winner}, the same law with coefficients varying between groups (vary_by)")
    return ClaimResult(claim, "reproduced" if winner == claim.law else "not reproduced", winner=winner)


def _form(tree: xr.DataTree, label: str) -> dict:
    """A fitted law's functional form: its recipe without group terms (a law's claim is about its
    curve; ``vary_by`` only lets its coefficients differ between runs or units)."""
    if "fits" not in tree.children or label not in tree["fits"].children:
        return {"label": label}
    attrs = tree[f"fits/{label}"].attrs
    recipe = json.loads(attrs.get("law_recipe") or "{}") or {"base": str(attrs.get("law", label))}
    return {k: v for k, v in recipe.items() if k not in ("vary_by", "trend", "trend_form")}


def evaluate_claims(claims: list[Claim], tree: xr.DataTree) -> list[ClaimResult]:
    """Every claim checked against a study's result tree alone (:mod:`bayesfric.study.tree`): the
    posteriors and programs of ``/fits/<law>``, the gate's verdicts in ``/diagnostics``, the law ×
    metric table in ``/scores`` and the pointwise elpd in ``/pointwise``. A saved ``results.nc``
    gives the same results as the run that wrote it.

    Parameters
    ----------
    claims : list of Claim
        The study's ``[[claims]]`` (:func:`make_claim`).
    tree : xarray.DataTree
        The study's result tree, in memory or opened from ``results.nc``.

    Returns
    -------
    list of ClaimResult
        One per claim, in order.
    """
    table = sc.table_of(tree["scores"].to_dataset())
    return [_evaluate(c, tree, table) for c in claims]
