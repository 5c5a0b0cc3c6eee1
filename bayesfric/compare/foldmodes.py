"""Cross-validation folds under the full fit's rules for chains that do not mix.

A full fit whose gate failed on the chains' mixing alone is not necessarily failed
(:mod:`bayesfric.inference.modes`): its chains may agree on every row while wandering along a
direction the data do not determine (*unidentified*: used as the chains pooled), or each sample a
separate mode well (*multimodal*: combined by stacking, Yao, Vehtari & Gelman 2022). A fold refits
the same law on part of the data from the same chain starts, so it meets the same posterior and
the same two cases; a fold judged by the bare gate would drop such a law from the ranking of the
scheme although its full fit is used. :func:`resolve_folds` applies the full fit's rules to every
fold of one :meth:`~bayesfric.inference.engine.NutsEngine.run`:

* failed on mixing alone, the pointwise log-likelihood of its draws over every row (those it
  trained on and those it is scored on) converged: used as sampled, ``unidentified`` naming the
  variables that did not mix (:func:`bayesfric.inference.diagnostics.resolve_fold`);
* else, each chain healthy and the chains in separate regions (:func:`bayesfric.inference.modes.detect`,
  on the fold's draws and its training rows' log-likelihood): its modes are weighed by stacking
  their leave-one-out predictive densities on the *training* rows (the held-out rows stay unseen),
  its draws resampled from the modes in proportion to the weights
  (:func:`bayesfric.inference.modes.combine`), and every row's predictive density recomputed from
  the combined draws, so the fold's score, its held-out predictive and a grouped scheme's joint
  density are the combined posterior's;
* anything else (a divergence, an unhealthy chain, chains drifting apart) still fails.

Cost: nothing for a fold that passed; for one that failed on mixing, one evaluation of the law's
pointwise log-likelihood over its draws (the program's own compiled pointwise table), and for a
multimodal one a PSIS-LOO per mode on its training rows.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import xarray as xr
from scipy.special import logsumexp

from bayesfric.inference import modes
from bayesfric.inference.batching import FoldFits
from bayesfric.inference.diagnostics import Verdict, resolve_fold
from bayesfric.inference.pointwise import log_likelihood

__all__ = ["fold_posterior", "resolve_folds"]

#: Added to the run's seed (and the fold's index) for the multimodal resampling, as a full fit does.
RESAMPLE_SEED = 7919


def fold_posterior(engine, samples: dict[str, np.ndarray], k: int) -> xr.Dataset:
    """Fold ``k``'s draws ``(chain, draw, ...)`` as a posterior Dataset, dimensions named as a fit's."""
    site_dims = engine.program.site_dims()

    def dims(name: str, value: np.ndarray) -> tuple[str, ...]:
        return ("chain", "draw") + tuple(site_dims.get(name, [f"{name}_dim_{i}" for i in range(value.ndim - 2)]))

    values = {name: np.asarray(v[k]) for name, v in samples.items()}
    post = xr.Dataset({name: (dims(name, v), v) for name, v in values.items()})
    return post.assign_coords(chain=np.arange(post.sizes["chain"]), draw=np.arange(post.sizes["draw"]))


def _combined(engine, fits: FoldFits, k: int, post: xr.Dataset, loglik: xr.Dataset, train: np.ndarray,
              verdict: Verdict, seed: int) -> tuple[Verdict, xr.DataTree | None]:
    """Fold ``k`` as a multimodal fit (see the module): its verdict and its combined draws (with
    every row's log-likelihood), or its verdict with why not and None."""
    stats = xr.Dataset({"diverging": (("chain", "draw"), np.asarray(fits.stats["diverging"][k], dtype=bool))})
    stats = stats.assign_coords(chain=post["chain"].values, draw=post["draw"].values)
    trained = xr.DataTree.from_dict({"posterior": post, "sample_stats": stats,
                                     "log_likelihood": loglik.isel(obs=np.flatnonzero(train))})
    found, why = modes.detect(trained, verdict, engine.gate)
    if not found:
        return replace(verdict, mode_note=why), None
    weights = modes.stacking_weights(modes.loo_by_mode(trained, found), modes.chain_prior(found))
    every_row = xr.DataTree.from_dict({"posterior": post, "log_likelihood": loglik})
    combined = modes.combine(every_row, found, weights, seed + RESAMPLE_SEED + k)
    return replace(verdict, passed=True, multimodal=True, modes=found, weights=tuple(float(w) for w in weights),
                   mode_ranges=modes.mode_ranges(post, found)), combined


def resolve_folds(engine, fits: FoldFits, train: np.ndarray, seed: int) -> FoldFits:
    """``fits`` with every fold under the full fit's rules (see the module): the verdicts, and
    for a multimodal fold its draws and predictive densities, replaced (a new :class:`FoldFits`;
    ``fits`` is not changed). ``train``: the folds' training masks ``(K, n_obs)``; ``seed``: the
    run's seed."""
    verdicts, samples, lpd = list(fits.verdicts), None, None
    for k, verdict in enumerate(fits.verdicts):
        if verdict.passed:  # the common case: nothing to build
            continue
        post = fold_posterior(engine, fits.samples, k)
        kept: dict[str, xr.Dataset] = {}

        def loglik(post: xr.Dataset = post, kept: dict = kept) -> xr.Dataset:
            if "ll" not in kept:
                kept["ll"] = log_likelihood(xr.DataTree.from_dict({"posterior": post}),
                                            program=engine.program).to_dataset()
            return kept["ll"]

        verdicts[k] = resolve_fold(verdict, post, loglik, engine.gate)
        if verdicts[k].passed or verdicts[k].predictions_converged is not False:
            continue
        verdicts[k], combined = _combined(engine, fits, k, post, loglik(), train[k], verdicts[k], seed)
        if combined is None:
            continue
        if samples is None:
            samples, lpd = {n: np.array(v, copy=True) for n, v in fits.samples.items()}, np.array(fits.lpd, copy=True)
        for name in samples:
            samples[name][k] = combined["posterior"][name].transpose("chain", "draw", ...).values
        ll = next(iter(combined["log_likelihood"].to_dataset().data_vars.values())).values
        ll = ll.reshape(-1, ll.shape[-1])
        lpd[k] = logsumexp(ll, axis=0) - np.log(ll.shape[0])
    if samples is None:
        return replace(fits, verdicts=verdicts)
    return replace(fits, samples=samples, lpd=lpd, verdicts=verdicts)
