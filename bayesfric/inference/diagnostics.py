"""The diagnostics gate: one place for the thresholds a posterior must pass to be ranked.

The statistics are arviz-stats' (rank-normalised split R-hat, bulk and tail ESS, E-BFMI). It is
imported on first use, not with this module: it brings scipy.stats along (0.4-0.5 s of the 2 s
a ``bayesfric fit`` spends importing), and a fit needs it only once its chains are sampled. The
NUTS engine calls :func:`import_statistics` right after it hands its programs to the background
compilation threads, so the import runs while they compile, or read the programs back from the
cache (:mod:`bayesfric.exported`), instead of before.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from types import ModuleType

import numpy as np
import xarray as xr

__all__ = ["GATE", "Gate", "Verdict", "check", "check_folds", "verdict_of", "import_statistics", "unmixed", "MIXING",
           "mixing_only", "with_predictions", "resolve_fold"]

#: The gate's problems about mixing between chains only (R-hat, ESS).
MIXING = ("R-hat", "bulk ESS", "tail ESS")


def import_statistics() -> ModuleType:
    """arviz-stats, the gate's statistics library (imported on first call; see the module notes)."""
    import arviz_stats

    return arviz_stats


#: Rows of the pointwise log-likelihood read to tell unidentified parameters from an unconverged
#: fit (:attr:`Verdict.predictions_note`): evenly spaced over the data beyond this many, with the
#: total log-likelihood over every row beside them (approximate: the extremes over the other rows
#: are not seen). arviz-stats' R-hat and bulk ESS cost about 5 ms a row (4 × 1000 draws), so at
#: most 0.5 s, only on a fit whose chains did not mix.
LOGLIK_ROWS = 100


@dataclass(frozen=True)
class Gate:
    """Thresholds of the diagnostics gate (Vehtari et al. 2021 for R-hat/ESS; Betancourt 2016 E-BFMI)."""

    rhat_max: float = 1.01
    ess_bulk_min: float = 400.0
    ess_tail_min: float = 400.0
    divergences_max: int = 0
    ebfmi_min: float = 0.3
    # emcee: healthy affine-invariant ensembles accept ~20-50 % (Foreman-Mackey et al. 2013)
    acceptance_min: float = 0.15


GATE = Gate()


@dataclass
class Verdict:
    """Outcome of the gate. ``passed`` is False if any check failed; ``problems`` says which.

    A **multimodal** verdict (:mod:`bayesfric.inference.modes`) is the third state: the chains
    disagree (``problems`` keeps the mixing problems of the chains as sampled) but each chain is
    healthy on its own and the chains sit in distinct regions, so the fit is *used*: ``passed``
    is True, ``multimodal`` True, ``modes`` the chains of each mode, ``weights`` the stacking
    weight of each mode, ``mode_ranges`` each variable's 5-95 % range per mode, and the fit's
    ``posterior`` holds the combined draws (the chains as sampled are kept in
    ``posterior_chains``). ``mode_note`` says why a fit whose chains disagree was *not* taken
    as multimodal (empty otherwise).
    """

    passed: bool
    rhat_max: float
    ess_bulk_min: float
    ess_tail_min: float
    divergences: int | None
    ebfmi_min: float | None
    acceptance_mean: float | None
    problems: list[str] = field(default_factory=list)
    #: When the chains did not mix (R-hat or bulk ESS failed): the largest R-hat and the smallest
    #: bulk ESS of the pointwise log-likelihood (one per data row), and whether both pass the gate.
    loglik_rhat_max: float | None = None
    loglik_ess_bulk_min: float | None = None
    predictions_converged: bool | None = None
    multimodal: bool = False
    modes: tuple[tuple[int, ...], ...] = ()
    weights: tuple[float, ...] = ()
    mode_ranges: dict[str, list[list[float]]] = field(default_factory=dict)
    mode_note: str = ""
    #: Posterior variables the chains did not mix along although the fit to every row converged
    #: (:func:`bayesfric.inference.modes.resolve`): the fit is used, its chains pooled.
    unidentified: tuple[str, ...] = ()

    @property
    def mode_summary(self) -> str:
        """``"multimodal: 2 modes, weights 0.62, 0.38 (chains 0,1 | 2,3)"``; ``""`` for one mode."""
        if not self.multimodal:
            return ""
        chains = " | ".join(",".join(str(c) for c in m) for m in self.modes)
        weights = ", ".join(f"{w:.2f}" for w in self.weights)
        return f"multimodal: {len(self.modes)} modes, stacking weights {weights} (chains {chains})"

    @property
    def unidentified_summary(self) -> str:
        """``"not identified by the data: v_s, F_c (...)"``; ``""`` when every variable mixed."""
        if not self.unidentified:
            return ""
        return (f"not identified by the data: {', '.join(self.unidentified)} (the chains did not mix along "
                f"them, R-hat max {self.rhat_max:.3f}, but agree on the fit to every row: pointwise "
                f"log-likelihood R-hat max {self.loglik_rhat_max:.3f}, bulk ESS min {self.loglik_ess_bulk_min:.0f}); "
                "used as the chains pooled: predictions on the tested rows converged, these parameters' "
                "ranges and answers that depend on them beyond the tested envelope did not")

    @property
    def predictions_note(self) -> str:
        """Why the chains did not mix, said from the pointwise log-likelihood: the fit to the data
        converged and only the parameters are unidentified, or the fit itself did not converge
        (``""`` when the gate passed or the chains mixed)."""
        if self.passed or self.predictions_converged is None:
            return ""
        stats = (f"pointwise log-likelihood R-hat max {self.loglik_rhat_max:.3f}, bulk ESS min "
                 f"{self.loglik_ess_bulk_min:.0f}")
        if self.predictions_converged:
            return (f"{stats}: the chains agree on the fit to every row, so the parameters are not identified "
                    "from these data (a ridge or interchangeable terms: see the pair plot), not the predictions")
        return f"{stats}: the chains disagree on the fit to the data itself (separate modes or unconverged), " \
               "not only on the parameters"

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @staticmethod
    def from_json(text: str) -> Verdict:
        return Verdict.from_dict(json.loads(text))

    @staticmethod
    def from_dict(values: dict) -> Verdict:
        """A verdict from :func:`dataclasses.asdict`'s dict, or its JSON read back (lists to tuples)."""
        values = dict(values)
        values["modes"] = tuple(tuple(int(c) for c in m) for m in values.get("modes", ()))
        values["weights"] = tuple(float(w) for w in values.get("weights", ()))
        values["unidentified"] = tuple(str(v) for v in values.get("unidentified", ()))
        return Verdict(**values)

    def __str__(self) -> str:
        head = ("MULTIMODAL" if self.multimodal else "UNIDENTIFIED" if self.unidentified
                else "PASSED" if self.passed else "FAILED")
        parts = [f"R-hat max {self.rhat_max:.3f}", f"ESS bulk min {self.ess_bulk_min:.0f}",
                 f"ESS tail min {self.ess_tail_min:.0f}"]
        if self.divergences is not None:
            parts.append(f"divergences {self.divergences}")
        if self.ebfmi_min is not None:
            parts.append(f"E-BFMI min {self.ebfmi_min:.2f}")
        if self.acceptance_mean is not None:
            parts.append(f"acceptance {self.acceptance_mean:.2f}")
        text = f"{head}: " + ", ".join(parts)
        if self.problems:
            text += " -- " + "; ".join(self.problems)
        if note := self.predictions_note:
            text += f" ({note})"
        if self.multimodal:
            text += f" ({self.mode_summary})"
        elif self.unidentified:
            text += f" ({self.unidentified_summary})"
        elif self.mode_note:
            text += f" (not multimodal: {self.mode_note})"
        return text


def _per_fold(ds: xr.Dataset, reduce, fold: str | None) -> np.ndarray:
    """``reduce`` (nanmin or nanmax) over each variable's entries, then over variables, per ``fold``.

    Without a fold dimension the result has one element. A variable whose entries are all NaN
    gives NaN (and so fails the gate), without numpy's "All-NaN slice" warning: the verdict says it."""
    per_var = []
    for v in ds.data_vars.values():
        if not v.size:
            continue
        values = np.asarray(v.transpose(fold, ...).values if fold else v.values, dtype=float)
        rows = values.reshape(values.shape[0] if fold else 1, -1)
        some = ~np.isnan(rows).all(axis=1)
        reduced = np.full(rows.shape[0], np.nan)
        reduced[some] = reduce(rows[some], axis=1)
        per_var.append(reduced)
    if not per_var:
        return np.full(ds.sizes.get(fold, 1) if fold else 1, np.nan)
    return np.max(per_var, axis=0) if reduce is np.nanmax else np.min(per_var, axis=0)


def check(dt: xr.DataTree, var_names: list[str] | None = None, gate: Gate = GATE) -> Verdict:
    """Apply the gate to a fit's posterior (all sampled and derived variables by default)."""
    post = dt["posterior"].to_dataset()
    stats = dt["sample_stats"].to_dataset() if "sample_stats" in dt.children else xr.Dataset()
    verdict = check_folds(post, stats, var_names, gate, fold=None)[0]
    mixed = verdict.rhat_max <= gate.rhat_max and verdict.ess_bulk_min >= gate.ess_bulk_min
    if mixed or "log_likelihood" not in dt.children:
        return verdict
    return with_predictions(verdict, dt["log_likelihood"].to_dataset(), gate)


def with_predictions(verdict: Verdict, loglik: xr.Dataset, gate: Gate) -> Verdict:
    """``verdict`` with the largest R-hat and smallest bulk ESS of the pointwise log-likelihood
    (:data:`LOGLIK_ROWS` rows and the total over all rows): the convergence of the fit to the
    data, which a law whose parameters are not identified (a ridge, interchangeable elements)
    reaches although its parameters' chains disagree."""
    arviz_stats = import_statistics()
    rows = [d for d in loglik.dims if d not in ("chain", "draw")]
    total = sum(v.sum([d for d in v.dims if d not in ("chain", "draw")], skipna=False)  # a NaN row: NaN
                for v in loglik.data_vars.values())
    for dim in rows:  # at most LOGLIK_ROWS rows, evenly spaced: bounded cost on large data
        if loglik.sizes[dim] > LOGLIK_ROWS:
            loglik = loglik.isel({dim: np.linspace(0, loglik.sizes[dim] - 1, LOGLIK_ROWS).astype(int)})
    loglik = loglik.assign(total_log_likelihood=total)
    rhat = float(np.nanmax(_per_fold(arviz_stats.rhat(loglik), np.nanmax, None)))
    ess = float(np.nanmin(_per_fold(arviz_stats.ess(loglik, method="bulk"), np.nanmin, None)))
    converged = bool(rhat <= gate.rhat_max and ess >= gate.ess_bulk_min)
    return replace(verdict, loglik_rhat_max=rhat, loglik_ess_bulk_min=ess, predictions_converged=converged)


def mixing_only(verdict: Verdict, chains: int) -> bool:
    """The gate failed on the chains' mixing alone (R-hat, ESS): no divergence, no low E-BFMI, at
    least two chains of NUTS (an emcee ensemble has an acceptance rate instead)."""
    return (not verdict.passed and all(any(p.startswith(m) for m in MIXING) for p in verdict.problems)
            and verdict.acceptance_mean is None and chains >= 2)


def resolve_fold(verdict: Verdict, posterior: xr.Dataset, loglik: Callable[[], xr.Dataset],
                 gate: Gate = GATE) -> Verdict:
    """A cross-validation fold's verdict under the rule a full fit follows
    (:func:`bayesfric.inference.modes.resolve`, *unidentified, not failed*).

    A fold that failed on its chains' mixing alone (:func:`mixing_only`) and whose pointwise
    log-likelihood converged (``loglik()``: ``(chain, draw, obs)`` over every row, trained on
    and held out, so both the fit to its training rows and the predictions it is scored on) is
    used: passed, with the variables that did not mix named in ``unidentified``. Otherwise the
    verdict as given (with the log-likelihood's figures where it was computed). ``loglik`` is
    called only for such a fold: it evaluates the law over the fold's draws.

    Examples
    --------
    >>> v = Verdict(True, 1.0, 900.0, 900.0, 0, 0.9, None)
    >>> resolve_fold(v, xr.Dataset(), lambda: xr.Dataset()) is v
    True
    """
    if not mixing_only(verdict, posterior.sizes.get("chain", 0)):
        return verdict
    checked = with_predictions(verdict, loglik(), gate)
    if not checked.predictions_converged:
        return checked
    return replace(checked, passed=True, unidentified=unmixed(posterior, gate),
                   mode_note="a fold's chains did not mix along these variables but agree on every row")


def unmixed(posterior: xr.Dataset, gate: Gate = GATE) -> tuple[str, ...]:
    """The posterior variables whose R-hat or bulk ESS fails ``gate`` (``group_offset`` aside).

    >>> rng = np.random.default_rng(0)
    >>> post = xr.Dataset({"a": (("chain", "draw"), rng.normal(size=(4, 500))),
    ...                    "b": (("chain", "draw"), rng.normal(size=(4, 500)) + np.arange(4)[:, None])})
    >>> unmixed(post)
    ('b',)
    """
    arviz_stats = import_statistics()
    # a constant variable (fixed values hold it) has no R-hat and is not unmixed: left out, as the gate does
    post = posterior.drop_vars([v for v in posterior.data_vars if v == "group_offset" or _constant(posterior[v])])
    rhat, ess = arviz_stats.rhat(post), arviz_stats.ess(post, method="bulk")

    def failed(name: str) -> bool:  # a variable constant in some of its elements (NaN statistics there)
        r, e = np.asarray(rhat[name], dtype=float).ravel(), np.asarray(ess[name], dtype=float).ravel()
        return bool(np.any(r[~np.isnan(r)] > gate.rhat_max) or np.any(e[~np.isnan(e)] < gate.ess_bulk_min))

    return tuple(str(name) for name in post.data_vars if post[name].size and failed(str(name)))


def _constant(values: xr.DataArray) -> bool:
    """Every draw of every chain (and fold) holds the same value."""
    v = np.asarray(values.values, dtype=float)
    return bool(v.size) and bool(np.all(v == v.flat[0]))


def check_folds(posterior: xr.Dataset, sample_stats: xr.Dataset, var_names: list[str] | None = None,
                gate: Gate = GATE, fold: str | None = "fold") -> list[Verdict]:
    """The gate for every fold of draws with a ``fold`` dimension, in one pass of arviz-stats.

    ``posterior`` and ``sample_stats`` have dimensions ``(fold, chain, draw, ...)``; the
    statistics are computed over ``chain`` and ``draw`` and kept per fold (arviz-stats keeps
    every other dimension), so K folds cost one call per statistic instead of K. ``fold=None``:
    draws without a fold dimension (one verdict).
    """
    arviz_stats = import_statistics()
    names = var_names or [v for v in posterior.data_vars if v != "group_offset"]
    # a derived quantity that fixed values hold constant (σ1 = 0 where ρ1 = 0) has no R-hat: left out
    # (unless nothing moves at all: that stays a failure)
    names = [v for v in names if not _constant(posterior[v])] or names if var_names is None else names
    sub = posterior[names]
    rhat = _per_fold(arviz_stats.rhat(sub), np.nanmax, fold)
    ess_bulk = _per_fold(arviz_stats.ess(sub, method="bulk"), np.nanmin, fold)
    ess_tail = _per_fold(arviz_stats.ess(sub, method="tail"), np.nanmin, fold)
    n = rhat.size
    divergences = ebfmi = acceptance = [None] * n
    if "diverging" in sample_stats:
        div = sample_stats["diverging"]
        divergences = [int(x) for x in np.atleast_1d(div.sum([d for d in div.dims if d != fold]).values)]
    if "energy" in sample_stats:
        energy = xr.DataTree.from_dict({"sample_stats": sample_stats[["energy"]]})
        ebfmi = [float(x) for x in _per_fold(arviz_stats.bfmi(energy).to_dataset(), np.nanmin, fold)]
    if "acceptance_fraction" in sample_stats:
        acc = sample_stats["acceptance_fraction"]
        acceptance = [float(x) for x in np.atleast_1d(acc.mean([d for d in acc.dims if d != fold]).values)]
    return [_verdict(float(rhat[i]), float(ess_bulk[i]), float(ess_tail[i]), divergences[i], ebfmi[i],
                     acceptance[i], gate) for i in range(n)]


def _verdict(rhat: float, ess_bulk: float, ess_tail: float, divergences: int | None, ebfmi: float | None,
             acceptance: float | None, gate: Gate) -> Verdict:
    problems = []
    if not rhat <= gate.rhat_max:
        problems.append(f"R-hat {rhat:.3f} > {gate.rhat_max}")
    if not ess_bulk >= gate.ess_bulk_min:
        problems.append(f"bulk ESS {ess_bulk:.0f} < {gate.ess_bulk_min:.0f}")
    if not ess_tail >= gate.ess_tail_min:
        problems.append(f"tail ESS {ess_tail:.0f} < {gate.ess_tail_min:.0f}")
    if divergences is not None and divergences > gate.divergences_max:
        problems.append(f"{divergences} divergent transitions")
    if ebfmi is not None and not ebfmi >= gate.ebfmi_min:
        problems.append(f"E-BFMI {ebfmi:.2f} < {gate.ebfmi_min}")
    if acceptance is not None and not acceptance >= gate.acceptance_min:
        problems.append(f"acceptance {acceptance:.2f} < {gate.acceptance_min}")
    return Verdict(not problems, rhat, ess_bulk, ess_tail, divergences, ebfmi, acceptance, problems)


def verdict_of(dt: xr.DataTree) -> Verdict:
    """The verdict stored with a fit (attrs ``diagnostics``)."""
    return Verdict.from_json(dt.attrs["diagnostics"])
