"""Cross-validation on the compiled, masked NUTS engine of a law.

Cross-validation needs many refits of the same program on subsets of the data. They run on
:class:`bayesfric.inference.engine.NutsEngine` -- the very compiled sampler that makes the full
fit (its all-true mask) -- so a fold is one more call of compiled code (``RefitEngine`` is the
same class, by its older name). Given the full fit, folds that drop a few points start from its
draws and mass matrix with a 250-step warm-up (``engine.warm_started(fit)``): a 10-fold refit
then costs about 1.7× one full fit against 2.2× cold (``benchmarks/bench_refit.py``).
numpyro's ``MCMC(jit_model_args=True)`` was measured as the alternative for folds and was an
order of magnitude slower per fold.

Every fold fit goes through the diagnostics gate; a fold that fails is *flagged* in the result,
and scores computed from it are reported with the flag, never silently used as if healthy.

>>> engine = RefitEngine.build(build_program(law, ds))                 # doctest: +SKIP
>>> result = cross_validate(engine, kfold_masks(ds, k=10))             # doctest: +SKIP
>>> result.elpd, result.se, result.failed_folds                       # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from bayesfric.compare.foldmodes import resolve_folds
from bayesfric.compare.folds import Folds
from bayesfric.compare.heldout import HeldOut, heldout_predictive
from bayesfric.errors import UserError
from bayesfric.exported import program_options
from bayesfric.inference.diagnostics import Verdict
from bayesfric.inference.engine import FoldFits, NutsEngine
from bayesfric.model import program_from_fit  # re-exported: it lives below compare, in model

#: The compiled NUTS engine of a law, by the name the comparison code has always used.
RefitEngine = NutsEngine

__all__ = [
    "RefitEngine", "FoldFits", "CVResult", "cross_validate", "pointwise_lpd", "program_from_fit", "joint_lpd",
    "group_coverage",
]


def pointwise_lpd(log_lik: np.ndarray) -> np.ndarray:
    """Log pointwise predictive density ``log mean_s p(y_i | θ_s)`` of draws ``(..., S, n)``.

    The leading axes are flattened into the draw axis ``S`` (chains × draws).
    """
    ll = jnp.asarray(log_lik)
    ll = ll.reshape((-1, ll.shape[-1]))
    return np.asarray(jax.scipy.special.logsumexp(ll, axis=0) - jnp.log(ll.shape[0]))


@dataclass
class CVResult:
    """Cross-validated predictive performance of one law under one fold scheme.

    Attributes
    ----------
    law, scheme : str
        Law name and the fold scheme's description (:attr:`Folds.scheme`).
    elpd, se : float
        ``Σ_i log mean_s p(y_i | θ_s^(fold(i)))`` over held-out points, and
        ``sqrt(n · var(elpd_i))``.
    elpd_i : ndarray
        ``(n_obs,)``; NaN where a point is never held out.
    heldout : ndarray
        ``(n_obs,)`` bool, the points scored.
    verdicts : list of Verdict
        Gate verdict per fold; :attr:`failed_folds` lists those that failed.
    predictive : HeldOut or None
        Thinned fold-posterior mean-function draws and noise variance at the held-out points
        (:mod:`bayesfric.compare.heldout`), kept when asked (blocked schemes: sizing measures
        the model-form error from them).
    coverage : dict or None
        Grouped schemes scored jointly: the share of held-out rows inside the central 50 % and
        90 % bands of their fold's predictive (``{"50": …, "90": …}``) -- how well the answers
        for a *new* group held on the groups left out (:func:`group_coverage`).
    elpd_new_group : ndarray or None
        Blocked schemes of a study with a group column: each run's held-out rows scored jointly
        as a NEW run's (:mod:`bayesfric.compare.newgroup`), one value per run.
    """

    law: str
    scheme: str
    elpd: float
    se: float
    elpd_i: np.ndarray
    heldout: np.ndarray
    verdicts: list[Verdict]
    seconds: float
    settings: dict = field(default_factory=dict)
    predictive: HeldOut | None = None
    coverage: dict[str, float] | None = None  # joint (grouped) schemes: central 50/90 % bands' share of rows
    elpd_fold: np.ndarray | None = None  # joint schemes: each fold's held-out rows' joint log density
    elpd_new_group: np.ndarray | None = None  # blocked, a group column: each run's rows jointly, as a new run's
    too_few: str = ""  # a grouped scheme with too few groups to tell laws apart for a new group: why

    @property
    def failed_folds(self) -> list[int]:
        return [i for i, v in enumerate(self.verdicts) if not v.passed]

    @property
    def reliable(self) -> bool:
        """True when every fold's posterior passed the gate and the scheme has enough groups."""
        return not self.failed_folds and not self.too_few

    @property
    def unidentified(self) -> tuple[str, ...]:
        """Variables some fold's chains did not mix along although they agree on every row (the
        fold is used: :mod:`bayesfric.compare.foldmodes`); ``()`` when every fold mixed."""
        return tuple(sorted({name for v in self.verdicts for name in v.unidentified}))

    @property
    def modes_note(self) -> str:
        """Which folds were multimodal and combined by stacking (``"fold 1 of 3: multimodal: 2
        modes, stacking weights 0.23, 0.77 (chains 0,2,3 | 1)"``); ``""`` when none was."""
        return "; ".join(f"fold {i + 1} of {len(self.verdicts)}: {v.mode_summary}"
                         for i, v in enumerate(self.verdicts) if v.multimodal)

    @property
    def n_heldout(self) -> int:
        return int(self.heldout.sum())

    @property
    def failure(self) -> str:
        """Which folds failed the gate and why, numbered from 1 (``"fold 2 of 4 failed the
        diagnostics gate (R-hat 1.05 > 1.01)"``); ``""`` when every fold passed."""
        failed = self.failed_folds
        if not failed:
            return self.too_few
        why = [(f"fold {i + 1}: " if len(failed) > 1 else "") + (self.verdicts[i].problems or ["failed"])[0]
               for i in failed]
        which = ("its only fold" if len(self.verdicts) == 1 else
                 f"{'fold' if len(failed) == 1 else 'folds'} {', '.join(str(i + 1) for i in failed)} of "
                 f"{len(self.verdicts)}")
        return f"{which} failed the diagnostics gate ({'; '.join(why)})" + (f"; {self.too_few}" if self.too_few else "")

    def __str__(self) -> str:
        flag = "" if self.reliable else f"  [FLAGGED: {self.failure}]"
        if self.reliable and self.unidentified:
            flag = f"  [UNIDENTIFIED in a fold: {', '.join(self.unidentified)}; predictions converged]"
        if self.reliable and self.modes_note:
            flag += f"  [{self.modes_note}]"
        return (f"{self.law} / {self.scheme}: elpd {self.elpd:.2f} ± {self.se:.2f} "
                f"on {self.n_heldout} held-out points{flag}")


def joint_lpd(program, samples: dict[str, np.ndarray], rows: np.ndarray) -> float:
    """``log mean_s Π_{i ∈ rows} p(y_i | θ_s)``: the rows scored *together*, as one new group.

    ``samples`` are one fold's constrained draws ``(chain, draw, ...)``. Leaving a whole run out
    and scoring its rows one by one (``Σ_i log mean_s p(y_i | θ_s)``) treats every row as if it
    came from its own new run; a model whose runs differ then looks as good as one that folds the
    runs' differences into its noise. The joint density is that of the new run's rows as a whole
    (the held-out level's values are shared by its rows). Draws are evaluated in chunks of at
    most ``limits.CHUNK_NUMBERS`` draws × rows.
    """
    from bayesfric.limits import CHUNK_NUMBERS

    density = program.density()
    s = int(np.prod(next(iter(samples.values())).shape[:2]))
    flat = {k: np.asarray(v).reshape((s,) + np.shape(v)[2:]) for k, v in samples.items()}
    pointwise = jax.jit(jax.vmap(density.pointwise), compiler_options=program_options(program.n_obs, optimised=False))
    size = max(1, CHUNK_NUMBERS // max(1, program.n_obs))
    sums = np.concatenate([np.asarray(pointwise({k: v[a:a + size] for k, v in flat.items()}))[:, rows].sum(axis=1)
                           for a in range(0, s, size)])
    return float(jax.scipy.special.logsumexp(sums) - np.log(s))


def group_coverage(program, kept: HeldOut, response: np.ndarray) -> dict[str, float]:
    """Share of held-out rows inside the central 50 % and 90 % bands of their fold's predictive.

    Each row's PIT is ``mean_s Φ((y − μ_s) / sqrt(v))`` over the kept mean-function draws ``μ_s``
    (a held-out group's levels drawn from the group distribution: a new group) with ``v`` the
    fold's mean noise variance at the row -- a normal approximation of the noise (exact for normal
    noise up to the spread of its variance over draws). Rows of one group are correlated, so the
    shares scatter more between studies than a binomial count of rows would.
    """
    from scipy.stats import norm

    if kept.mu.size == 0:
        return {"50": float("nan"), "90": float("nan")}
    y = np.asarray(response, dtype=float)[kept.index]
    pit = norm.cdf((y[None, :] - kept.mu) / np.sqrt(kept.noise_var)[None, :]).mean(axis=0)
    return {"50": float(np.mean(np.abs(pit - 0.5) <= 0.25)), "90": float(np.mean(np.abs(pit - 0.5) <= 0.45))}


def cross_validate(engine: RefitEngine, folds: Folds, *, seed: int = 0, predictive: bool = False,
                   joint: bool = False, new_groups: tuple[str, np.ndarray] | None = None,
                   min_groups: int = 0) -> CVResult:
    """Refit on every fold's training mask and score its held-out points.

    Parameters
    ----------
    engine : RefitEngine
        Compiled sampler of the law on the full dataset.
    folds : Folds
        From :mod:`bayesfric.compare.folds`; each point may be held out at most once.
    seed : int
        Seed of the fold fits.
    predictive : bool
        Also keep the held-out predictive draws (:attr:`CVResult.predictive`).
    joint : bool
        Score each fold's held-out rows together (:func:`joint_lpd`): leave-one-group-out, where
        a fold holds out one run, series or unit. ``elpd`` is then the sum over folds of the
        joint densities and ``se = sqrt(K · var)`` over the K folds; ``elpd_i`` stays pointwise.
    new_groups : (str, ndarray), optional
        A group column and each row's level: also score each fold's held-out rows per level, jointly,
        as a new level's (:func:`bayesfric.compare.newgroup.new_group_lpd`; a blocked scheme).
    min_groups : int
        A joint scheme that leaves out fewer groups is not reliable (:attr:`CVResult.too_few`):
        leave-one-group-out with two groups trains each fold on one, which cannot estimate the
        spread between groups (:data:`bayesfric.compare.newgroup.MIN_GROUPS`).

    Returns
    -------
    CVResult
        ``elpd = Σ_heldout log mean_s p(y_i | θ_s)`` (log-sum-exp over the fold's draws) with
        ``se = sqrt(n · var(elpd_i))``, and the per-fold gate verdicts.
    """
    counts = folds.heldout.sum(axis=0)
    if counts.max() > 1:
        raise UserError(f"scheme {folds.scheme!r} holds some points out more than once", "folds")
    # a fold whose chains did not mix is judged as a full fit would be (unidentified, multimodal)
    fits = resolve_folds(engine, engine.run(folds.train, seed=seed), folds.train, seed)
    elpd_i = np.full(engine.program.n_obs, np.nan)
    for k in range(folds.n_folds):
        elpd_i[folds.heldout[k]] = fits.lpd[k, folds.heldout[k]]
    heldout = counts == 1
    scored = elpd_i[heldout]
    if joint:  # one value per fold: its held-out rows as one new group
        scored = np.array([joint_lpd(engine.program, {n: v[k] for n, v in fits.samples.items()}, folds.heldout[k])
                           for k in range(folds.n_folds) if folds.heldout[k].any()])
    kept = heldout_predictive(engine.program, fits.samples, folds.heldout) if predictive or joint else None
    fresh = None
    if new_groups is not None:
        from bayesfric.compare.newgroup import new_group_lpd

        column, levels = new_groups
        fresh = np.concatenate([new_group_lpd(engine.program, {n: v[k] for n, v in fits.samples.items()},
                                              folds.heldout[k], np.asarray(levels), column, seed=seed)
                                for k in range(folds.n_folds) if folds.heldout[k].any()])
    return CVResult(
        law=engine.program.law.name,
        scheme=folds.scheme,
        elpd=float(scored.sum()),
        se=float(np.sqrt(scored.size * scored.var())),
        elpd_i=elpd_i,
        heldout=heldout,
        verdicts=fits.verdicts,
        seconds=fits.seconds,
        settings=engine.settings | {"fold_target_accept": [float(t) for t in fits.target_accept],
                                    "scored": "each held-out group's rows jointly" if joint else "pointwise"},
        predictive=kept if predictive else None,
        coverage=group_coverage(engine.program, kept, engine.program.response) if joint else None,
        elpd_fold=scored if joint else None,
        elpd_new_group=fresh,
        too_few=_too_few(int(folds.heldout.any(axis=1).sum()), min_groups) if joint else "",
    )


def _too_few(groups: int, least: int) -> str:
    """Why a joint scheme of ``groups`` held-out groups cannot tell laws apart (``""``: it can)."""
    if groups >= least:
        return ""
    return (f"{groups} groups left out one at a time, each fold trained on {groups - 1}: too few to estimate the "
            f"spread between groups, so this scheme cannot tell laws apart for a new group (it needs {least})")

