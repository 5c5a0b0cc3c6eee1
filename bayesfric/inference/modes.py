"""Multimodal fits: tell chains that found separate modes from a failed fit, and combine them.

On data that leave a law's posterior with several separated modes (hysteresis loops that do not
span the Stribeck speed give LuGre, elasto-plastic and GMS two arms), NUTS chains started apart
land in different modes and stay there: split R-hat over all chains fails although every chain
sampled its own mode well. :func:`resolve` tells that case from a failed fit and combines the chains
by **stacking** (Yao, Vehtari & Gelman 2022, "Stacking for non-mixing Bayesian computations", JMLR 23).

**Detection** (:func:`detect`), on a fit whose gate failed:

1. the gate's problems are about mixing only (R-hat, bulk or tail ESS): no divergent transition
   after the retry, no low E-BFMI, at least two chains, NUTS (not an emcee ensemble);
2. every chain is healthy on its own (:func:`chain_health`): split R-hat of the chain alone (its
   two halves, each split again by arviz-stats) at most :attr:`ModeGate.chain_rhat_max`, bulk
   and tail ESS at least the gate's minimum divided by the number of chains, no divergence;
3. the chains fall into k ≥ 2 groups (:func:`group_chains`): two chains are one mode when no
   variable's chain means (posterior variables and the total log-likelihood) differ by more
   than :attr:`ModeGate.link` pooled within-chain standard deviations (single linkage), and
   every two modes are at least :attr:`ModeGate.separation` apart.

Otherwise the fit fails as before, with :attr:`~bayesfric.inference.diagnostics.Verdict.mode_note`
saying which condition did not hold, **unless the chains agree on the fit to every row** (failed
on mixing alone, and the pointwise log-likelihood converged: ``predictions_converged``). Then the
chains wander along directions the data do not determine (a ridge, interchangeable elements, an
arm a chain visits and leaves); stacking them (Yao et al. 2022) weighs each alike, as each
predicts every row alike, so the fit is used as its chains pooled, its verdict passed with
``unidentified`` naming the variables that did not mix: predictions on the tested rows are
converged, those variables' ranges and answers resting on them beyond the tested envelope not.

**Combination.** Each mode's pointwise PSIS-LOO predictive density log p_k(y_i | y_-i) is
computed from its chains' pointwise log-likelihood (arviz-stats ``loo``; chains of one mode are
pooled: they agree by construction, and stacking exchangeable chains would split their weight
arbitrarily). The stacking weights maximise Σ_i log Σ_k w_k p_k(y_i | y_-i) over the simplex
(:func:`stacking_weights`, EM fixed point: the objective is concave), with one pseudo-observation
shared by the modes' chain counts (:func:`chain_prior`: a Dirichlet prior on w) so that modes that
predict alike keep the share of chains that found them instead of an arbitrary corner. The fit's ``posterior``,
``sample_stats``, ``log_prior``, ``log_likelihood`` and ``posterior_predictive`` are then
replaced by draws resampled from each mode in proportion to its weight (same shape, fixed seed;
a draw keeps its own log-likelihood and predictive draw, and a thinned fit's kept draws are
resampled from kept draws, so the groups stay aligned); the chains as sampled stay in the group
``posterior_chains``. How each estimator reads such a fit:

- PSIS-LOO, LOO-PIT, power-scaling, residual checks, sizing, claims: the combined draws, i.e.
  the stacked predictive distribution. Its LOO is slightly optimistic: the weights were chosen on
  the same LOO densities (k − 1 free weights; Yao et al. 2022 §4).
- Exact refits (LOO's high-k̂ points, K-fold) warm-start from the combined draws; grouped and
  blocked folds start cold. A refit is judged by the fold gate, so a fold whose chains split over
  the modes is a failed fold, not combined (not yet done per fold).
- Bridge sampling (:func:`by_mode`): per mode, on that mode's own chains with a proposal fitted
  to them, log Z = log Σ_k Z_k (the posterior mass of each mode, not its stacking weight), valid
  while the modes are disjoint and every mode was found by some chain.
- Laplace importance sampling centres its proposal on one mode: marked approximate
  (:func:`single_mode_note`); it misses the other modes' mass, so it tends to be low and may
  disagree with bridge sampling, which then withholds the evidence ranking. SMC tempers from the
  prior and reaches every mode; it is used as it is.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import xarray as xr

from bayesfric.inference import pointwise
from bayesfric.inference.diagnostics import GATE, MIXING, Gate, Verdict, import_statistics, mixing_only, unmixed

__all__ = ["ModeGate", "MODE_GATE", "ChainHealth", "chain_health", "group_chains", "detect", "loo_by_mode",
           "stacking_weights", "chain_prior", "combine", "resolve", "mode_ranges", "by_mode", "single_mode_note",
           "is_multimodal"]

#: Groups holding every posterior draw, and those holding the kept draws of a thinned fit.
ALL_DRAWS = ("posterior", "sample_stats", "log_prior")
KEPT_DRAWS = ("log_likelihood", "posterior_predictive")


@dataclass(frozen=True)
class ModeGate:
    """Thresholds of :func:`detect` (the gate's own thresholds are in :class:`~.diagnostics.Gate`).

    ``chain_rhat_max``: split R-hat of one chain alone (its halves split again: four pieces of a
    quarter chain each, noisier than the gate's four chains, hence the pre-2021 1.05).
    ``link``: chains whose means differ by at most this many pooled within-chain sds in every
    variable are one mode (at the gate's ESS, ~7 Monte Carlo standard errors). ``separation``:
    every two modes' closest chains differ by at least this many sds in some variable (chains
    between ``link`` and ``separation`` apart are drifting, not in distinct regions: failed).
    """

    chain_rhat_max: float = 1.05
    link: float = 0.5
    separation: float = 1.0


MODE_GATE = ModeGate()


@dataclass(frozen=True)
class ChainHealth:
    """One chain's own diagnostics (:func:`chain_health`)."""

    rhat: float
    ess_bulk: float
    ess_tail: float
    divergences: int
    healthy: bool


def _features(post: xr.Dataset) -> tuple[list[str], np.ndarray]:
    """Every scalar element of every posterior variable (``group_offset`` aside, as the gate)
    as columns: names and an array ``(chain, draw, feature)``."""
    names, columns = [], []
    for name, v in post.data_vars.items():
        if name == "group_offset" or not v.size:
            continue
        values = np.asarray(v.transpose("chain", "draw", ...).values, dtype=float)
        flat = values.reshape(values.shape[:2] + (-1,))
        names += [str(name)] if flat.shape[2] == 1 else [f"{name}[{i}]" for i in range(flat.shape[2])]
        columns.append(flat)
    return names, np.concatenate(columns, axis=2)


def chain_health(posterior: xr.Dataset, sample_stats: xr.Dataset, gate: Gate = GATE,
                 mode_gate: ModeGate = MODE_GATE) -> list[ChainHealth]:
    """Each chain's split R-hat, bulk and tail ESS (worst over the variables) and divergences.

    A chain is healthy when its R-hat is at most ``mode_gate.chain_rhat_max``, its bulk and tail
    ESS at least the gate's minimum over the number of chains, and it has no divergence.

    >>> post = xr.Dataset({"a": (("chain", "draw"), np.random.default_rng(0).normal(size=(2, 800)))})
    >>> [h.healthy for h in chain_health(post, xr.Dataset())]
    [True, True]
    """
    stats = import_statistics()
    x = _features(posterior)[1]
    # a feature constant in every draw (a derived quantity fixed values hold, as the gate leaves out) has no R-hat
    moving = ~np.all(x == x[:1, :1], axis=(0, 1))
    x = x[..., moving] if moving.any() else x
    n_chains, n_draws = x.shape[:2]
    half = n_draws // 2
    dims = ("fold", "chain", "draw", "feature")
    halves = xr.Dataset({"x": (dims, x[:, :2 * half].reshape(n_chains, 2, half, -1))})
    whole = xr.Dataset({"x": (dims, x[:, None])})
    rhat = np.nanmax(stats.rhat(halves)["x"].values, axis=-1)
    ess_bulk = np.nanmin(stats.ess(whole, method="bulk")["x"].values, axis=-1)
    ess_tail = np.nanmin(stats.ess(whole, method="tail")["x"].values, axis=-1)
    div = (sample_stats["diverging"].sum("draw").values.astype(int) if "diverging" in sample_stats
           else np.zeros(n_chains, int))
    out = []
    for c in range(n_chains):
        ok = (rhat[c] <= mode_gate.chain_rhat_max and ess_bulk[c] >= gate.ess_bulk_min / n_chains
              and ess_tail[c] >= gate.ess_tail_min / n_chains and div[c] == 0)
        out.append(ChainHealth(float(rhat[c]), float(ess_bulk[c]), float(ess_tail[c]), int(div[c]), bool(ok)))
    return out


def _distances(means: np.ndarray, sds: np.ndarray) -> np.ndarray:
    """Pairwise chain distances: the largest |Δ mean| / pooled within-chain sd over the features."""
    diff = np.abs(means[:, None] - means[None])
    pooled = np.sqrt((sds[:, None] ** 2 + sds[None] ** 2) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(pooled > 0, diff / pooled, np.where(diff > 0, np.inf, 0.0))
    return ratio.max(axis=-1)


def group_chains(means: np.ndarray, sds: np.ndarray, link: float = MODE_GATE.link
                 ) -> tuple[tuple[tuple[int, ...], ...], np.ndarray]:
    """Chains grouped into modes by single linkage at ``link`` (``means``, ``sds``: chain × feature).

    Returns the groups (sorted by their first chain) and the distance matrix.

    >>> group_chains(np.array([[0.0], [0.1], [5.0]]), np.ones((3, 1)))[0]
    ((0, 1), (2,))
    """
    d = _distances(np.asarray(means, float), np.asarray(sds, float))
    label = list(range(d.shape[0]))
    for i in range(d.shape[0]):
        for j in range(i + 1, d.shape[0]):
            if d[i, j] <= link and label[i] != label[j]:
                old, new = max(label[i], label[j]), min(label[i], label[j])
                label = [new if lab == old else lab for lab in label]
    groups = tuple(tuple(c for c in range(len(label)) if label[c] == g) for g in sorted(set(label)))
    return groups, d


def _chain_summary(fit: xr.DataTree) -> tuple[np.ndarray, np.ndarray]:
    """Each chain's mean and sd of every posterior feature and of the total log-likelihood."""
    x = _features(fit["posterior"].to_dataset())[1]
    means, sds = x.mean(axis=1), x.std(axis=1)
    if "log_likelihood" in fit.children:
        ll = fit["log_likelihood"].to_dataset()
        total = sum(np.asarray(v.transpose("chain", "draw", ...).values, float).reshape(
            v.sizes["chain"], v.sizes["draw"], -1).sum(-1) for v in ll.data_vars.values())
        means = np.column_stack([means, total.mean(axis=1)])
        sds = np.column_stack([sds, total.std(axis=1)])
    return means, sds


def detect(fit: xr.DataTree, verdict: Verdict, gate: Gate = GATE, mode_gate: ModeGate = MODE_GATE
           ) -> tuple[tuple[tuple[int, ...], ...], str]:
    """The chains of each mode when ``fit`` (whose gate gave ``verdict``) is multimodal, else
    ``()`` and why not (see the module notes for the conditions)."""
    if verdict.passed:
        return (), ""
    if not _only_mixing(fit, verdict):
        other = [p for p in verdict.problems if not any(p.startswith(m) for m in MIXING)]
        return (), f"{'; '.join(other) or 'needs two or more NUTS chains'} (not only the chains' mixing)"
    post = fit["posterior"].to_dataset()
    stats = fit["sample_stats"].to_dataset() if "sample_stats" in fit.children else xr.Dataset()
    health = chain_health(post, stats, gate, mode_gate)
    sick = [f"chain {c} (R-hat {h.rhat:.3f}, bulk ESS {h.ess_bulk:.0f}, tail ESS {h.ess_tail:.0f}, "
            f"{h.divergences} divergences)" for c, h in enumerate(health) if not h.healthy]
    if sick:
        return (), "not converged within " + "; ".join(sick)
    groups, d = group_chains(*_chain_summary(fit), link=mode_gate.link)
    if len(groups) < 2:
        return (), "the chains disagree but lie in one region"
    apart = min(d[np.ix_(a, b)].min() for i, a in enumerate(groups) for b in groups[i + 1:])
    if apart < mode_gate.separation:
        return (), f"the chains' groups lie {apart:.2f} sd apart (< {mode_gate.separation}): drifting, not modes"
    return groups, ""


def _only_mixing(fit: xr.DataTree, verdict: Verdict) -> bool:
    """The gate failed on mixing alone (:func:`~bayesfric.inference.diagnostics.mixing_only`)."""
    return mixing_only(verdict, fit["posterior"].sizes["chain"])


def loo_by_mode(fit: xr.DataTree, modes: Sequence[Sequence[int]]) -> np.ndarray:
    """Each mode's pointwise PSIS-LOO log predictive density log p_k(y_i | y_-i), ``(mode, obs)``,
    from the pooled pointwise log-likelihood of its chains (the kept draws of a thinned fit)."""
    stats = import_statistics()
    view = pointwise.stored_draws(fit, ("log_likelihood",))
    ll = view["log_likelihood"].to_dataset()
    name = next(iter(ll.data_vars))
    out = []
    for chains in modes:
        part = xr.DataTree.from_dict({"posterior": view["posterior"].to_dataset().isel(chain=list(chains)),
                                      "log_likelihood": ll.isel(chain=list(chains))})
        with warnings.catch_warnings():  # high k̂ is about a mode's LOO, not the stacking
            warnings.simplefilter("ignore")
            elpd = stats.loo(part, pointwise=True, var_name=name)
        out.append(np.asarray(elpd.elpd_i, dtype=float).ravel())
    return np.array(out)


def stacking_weights(lpd: np.ndarray, prior: np.ndarray | None = None, *, iterations: int = 10_000,
                     tol: float = 1e-12) -> np.ndarray:
    """Weights w on the simplex maximising Σ_i log Σ_k w_k exp(lpd[k, i]) + Σ_k prior_k log w_k
    (``lpd``: mode × obs; ``prior``: pseudo-counts, a Dirichlet(1 + prior) on w; none by default).

    The EM fixed point for mixture proportions, w_k ← (Σ_i w_k p_ki / Σ_j w_j p_ji + prior_k) /
    (n + Σ prior): the objective is concave in w, so it converges to its maximum from the uniform
    start.

    >>> lpd = np.log([[0.9, 0.9, 0.1], [0.1, 0.1, 0.9]])
    >>> np.round(stacking_weights(lpd), 3)
    array([0.66, 0.34])
    """
    lpd = np.asarray(lpd, dtype=float)
    prior = np.zeros(lpd.shape[0]) if prior is None else np.asarray(prior, dtype=float)
    p = np.exp(lpd - lpd.max(axis=0))  # a per-row scale cancels in the responsibilities
    w = np.full(lpd.shape[0], 1.0 / lpd.shape[0])
    for _ in range(iterations):
        r = w[:, None] * p
        new = ((r / r.sum(axis=0)).sum(axis=1) + prior) / (lpd.shape[1] + prior.sum())
        done = np.max(np.abs(new - w)) < tol
        w = new
        if done:
            break
    return w


def chain_prior(modes: Sequence[Sequence[int]]) -> np.ndarray:
    """The pseudo-counts :func:`resolve` gives :func:`stacking_weights`: one observation's worth,
    shared by the modes' numbers of chains. Modes that predict the data alike (a sign ambiguity,
    interchangeable terms) leave the stacking objective flat up to Monte Carlo noise, which would
    push all weight onto one of them; this keeps them in the proportion the chains found them,
    and moves weights by at most ~1/n where the modes predict differently."""
    counts = np.array([len(m) for m in modes], dtype=float)
    return counts / counts.sum()


def _allocate(weights: np.ndarray, n: int) -> np.ndarray:
    """``n`` draws shared by ``weights`` (largest remainders)."""
    exact = np.asarray(weights) * n
    counts = np.floor(exact).astype(int)
    counts[np.argsort(counts - exact)[: n - counts.sum()]] += 1
    return counts


def _resample_index(modes, weights, n_chains: int, n_draws: int, kept: np.ndarray, seed: int) -> np.ndarray:
    """New position (chain, draw) → old flat position: each mode's draws in proportion to its
    weight, shuffled over the chains; kept positions of a thinned fit take kept draws only."""
    rng = np.random.default_rng(seed)
    positions = np.arange(n_chains * n_draws).reshape(n_chains, n_draws)
    is_kept = np.isin(np.arange(n_draws), kept)
    new = np.empty(n_chains * n_draws, dtype=int)
    for stratum, source in ((is_kept, is_kept), (~is_kept, np.ones(n_draws, bool))):
        targets = positions[:, stratum].ravel()
        if not targets.size:
            continue
        picks = [rng.choice(pool, count, replace=count > pool.size)
                 for chains, count in zip(modes, _allocate(weights, targets.size), strict=True)
                 for pool in [positions[list(chains)][:, source].ravel()]]
        new[rng.permutation(targets)] = np.concatenate(picks)
    return new.reshape(n_chains, n_draws)


def _take(ds: xr.Dataset, chain: np.ndarray, draw: np.ndarray) -> xr.Dataset:
    """``ds`` with its (chain, draw) entries taken at the index arrays ``chain``, ``draw``."""
    data = {}
    for name, v in ds.data_vars.items():
        v = v.transpose("chain", "draw", ...)
        data[name] = xr.Variable(v.dims, np.asarray(v.values)[chain, draw], v.attrs)
    return xr.Dataset(data, coords=ds.coords, attrs=ds.attrs)


def combine(fit: xr.DataTree, modes, weights, seed: int) -> xr.DataTree:
    """``fit`` with its draws resampled from the modes in proportion to ``weights`` (a shallow
    copy; the original posterior kept as ``posterior_chains``)."""
    post = fit["posterior"].to_dataset()
    n_chains, n_draws = post.sizes["chain"], post.sizes["draw"]
    kept = (np.asarray(fit["log_likelihood"]["draw"].values) if "log_likelihood" in fit.children
            else np.arange(n_draws))
    index = _resample_index(modes, np.asarray(weights), n_chains, n_draws, kept, seed)
    out = fit.copy(deep=False)
    for group in ALL_DRAWS:
        if group in fit.children:
            out[group] = _take(fit[group].to_dataset(), index // n_draws, index % n_draws)
    at_kept = index[:, kept]
    for group in KEPT_DRAWS:
        if group in fit.children:
            out[group] = _take(fit[group].to_dataset(), at_kept // n_draws, np.searchsorted(kept, at_kept % n_draws))
    out["posterior_chains"] = post
    return out


def mode_ranges(posterior: xr.Dataset, modes, low: float = 0.05, high: float = 0.95) -> dict[str, list[list[float]]]:
    """Each scalar variable's [5 %, 95 %] quantiles within each mode (name → one pair per mode)."""
    names, x = _features(posterior)
    q = [np.quantile(x[list(chains)].reshape(-1, x.shape[2]), [low, high], axis=0) for chains in modes]
    return {name: [[float(m[0, j]), float(m[1, j])] for m in q] for j, name in enumerate(names)}


def resolve(fit: xr.DataTree, verdict: Verdict, seed: int, gate: Gate = GATE,
            mode_gate: ModeGate = MODE_GATE) -> tuple[xr.DataTree, Verdict]:
    """The fit and verdict to keep: a multimodal fit combined by stacking with its multimodal
    verdict, else ``fit`` and ``verdict`` as given (with the reason in ``mode_note`` when the
    chains disagreed). ``seed``: the fit's seed (the resampling's is derived from it)."""
    modes, why = detect(fit, verdict, gate, mode_gate)
    if not modes and _only_mixing(fit, verdict) and verdict.predictions_converged:
        unidentified = unmixed(fit["posterior"].to_dataset(), gate)
        return fit, replace(verdict, passed=True, unidentified=unidentified, mode_note=why)
    if not modes:
        return fit, replace(verdict, mode_note=why)
    weights = stacking_weights(loo_by_mode(fit, modes), chain_prior(modes))
    ranges = mode_ranges(fit["posterior"].to_dataset(), modes)
    combined = combine(fit, modes, weights, seed + 7919)
    return combined, replace(verdict, passed=True, multimodal=True, modes=modes,
                             weights=tuple(float(w) for w in weights), mode_ranges=ranges)


def is_multimodal(fit: xr.DataTree) -> bool:
    """Whether ``fit``'s stored verdict is multimodal (and its chains as sampled are kept)."""
    return ("diagnostics" in fit.attrs and "posterior_chains" in fit.children
            and Verdict.from_json(fit.attrs["diagnostics"]).multimodal)


def by_mode(fit: xr.DataTree, estimate: Callable[[xr.DataTree], object]):
    """A log-evidence estimate of a multimodal fit: ``estimate`` (a fit → an ``Evidence``-like
    frozen dataclass with ``log_z``, ``error``, ``diagnostics``) run on each mode's own chains,
    summed: Z = Σ_k Z_k, relative error √Σ (Z_k/Z · error_k)². Valid while the modes are disjoint
    and each mode's proposal puts no mass in another mode."""
    verdict = Verdict.from_json(fit.attrs["diagnostics"])
    chains = fit["posterior_chains"].to_dataset()
    parts = [estimate(xr.DataTree.from_dict({"posterior": chains.isel(chain=list(m))})) for m in verdict.modes]
    log_z = np.array([p.log_z for p in parts])
    total = float(np.logaddexp.reduce(log_z))
    share = np.exp(log_z - total)
    error = float(np.sqrt(np.sum((share * np.array([p.error for p in parts])) ** 2)))
    diagnostics = {"combination": "sum over modes of each mode's estimate on its own chains",
                   "mode_log_z": log_z.tolist(), "mode_error": [p.error for p in parts],
                   "modes": [list(m) for m in verdict.modes], "per_mode": [p.diagnostics for p in parts]}
    return dataclasses.replace(parts[0], log_z=total, error=error, diagnostics=diagnostics)


def single_mode_note(fit: xr.DataTree) -> str:
    """For an estimator that centres one proposal on one mode (Laplace importance sampling): the
    note that marks it approximate on a multimodal fit (``""`` otherwise)."""
    if not is_multimodal(fit):
        return ""
    k = len(Verdict.from_json(fit.attrs["diagnostics"]).modes)
    return (f"approximate: the fit has {k} modes and the proposal is centred on one, "
            "so the other modes' mass is missed (low in expectation)")
