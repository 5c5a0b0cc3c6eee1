"""Actuator sizing from stored fits: predictive torque (or force) at operating points nobody
tested, the capacity a drive needs at a confidence level, and how much the answer leans on
extrapolation. Pure computation: fits + weights in, a :class:`SizingResult` out; the reports,
``sizing.csv``, the fan figure and the CLI only render it.

Per law and point
    The fit's program (:func:`bayesfric.model.program_of_fit`) is moved to the query points
    (:meth:`bayesfric.model.Program.at`) and the law's **mean function** is evaluated per posterior draw
    (``jax.vmap``): its spread is *parameter uncertainty*. With partial-pooled group offsets a
    new, unseen unit (series, blade, run) is sized: one offset per draw from N(0, group_sd),
    multiplying the mean function at every point of the question (``mu · exp(b)``, as in the
    model). **With noise** adds one draw of the fit's observation noise per posterior draw, from
    the fit's own program (:meth:`bayesfric.model.Program.observation`: the likelihood's
    distribution; ar1 at its stationary marginal ``σ / sqrt(1 − ρ²)``).
    A trajectory (stateful) law is evaluated by its **steady state at constant speed**
    (:mod:`bayesfric.sizing.steady`): no transient, and the answer says so (``LawAnswer.steady``).

Magnitudes
    Friction opposes motion, so the drive must overcome ``|T|`` whichever the direction: every
    quantile, the required capacity and ``P(|T| > capacity)`` are of the magnitude. The
    **required capacity** at confidence ``c`` is the ``c``-quantile of ``|T|`` with noise. The
    Monte Carlo error of ``P`` is binomial, ``sqrt(p (1 − p) / S_eff)`` with ``S_eff`` the
    effective sample size of the exceedance indicator over the fit's chains (arviz ``ess``,
    "mean"); when no draw (or every draw) exceeds, the error is 0 and the one-sided 95 % bound
    ``3 / S`` (rule of three) is given instead.

Model average
    Laws are mixed by the weights of the question's basis (:mod:`bayesfric.sizing.basis`:
    stacking on the blocked folds that extrapolate in its direction, else LOO stacking),
    renormalised over the laws sizing may use; LOO stacking weights give a second average for
    comparison. A law whose full fit failed the diagnostics gate is *excluded* (its predictions
    may not be used) and listed with the reason, never mixed in; nothing else excludes a law (an
    unreliable evidence estimate is no reason about its predictions). The mixture is evaluated
    exactly rather than by resampling: its quantiles invert the weighted empirical CDF of all
    laws' draws (each draw of law k weighs ``w_k / S_k``), ``P`` is ``Σ w_k p_k`` with error
    ``sqrt(Σ w_k² se_k²)``. The variance of ``|T|`` splits by the law of total variance into
    *parameter* ``Σ w_k Var_k(|mu|)``, *noise* ``Σ w_k E_k[noise variance]`` and *between-law*
    ``Σ w_k (E_k|mu| − Σ_j w_j E_j|mu|)²``. The noise variance is the noise model's (exact for
    ``T`` away from zero); a Student-t draw with ``nu ≤ 2`` has infinite variance: such draws
    are left out of the noise term and the result says what fraction that was.

Calibrated answers
    Every law's answer and the average exist twice: within-model (parameter and noise
    uncertainty of the law as fitted) and *calibrated*, with the model-form error the blocked
    folds measured added to each draw (:mod:`bayesfric.sizing.calibration`).

Extrapolation distance
    Per input: 0 inside the tested ``[lo, hi]``, ``(x − hi) / (hi − lo)`` above and
    ``(lo − x) / (hi − lo)`` below (a single tested value: 0 there, infinite elsewhere); a
    warning when any distance exceeds :data:`EXTRAPOLATION_WARN`.

Energy (pitch drives, seed 000 §1)
    The friction energy of one rotation through ``θ`` at constant load and speed is
    ``E = ∫ |T| dθ = |T| · θ`` per draw, *assuming the torque does not depend on the angle*; its
    quantiles are those of ``|T|`` times ``θ`` (in J). With noise, the scatter is taken to last
    the whole rotation (conservative: it does if it is a block offset, averages out if it is
    fast vibration).
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import jax.numpy as jnp
import numpy as np
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.inference.diagnostics import import_statistics
from bayesfric.sizing.basis import LOO, Basis
from bayesfric.sizing.calibration import Miss
from bayesfric.sizing.points import SizingError, SizingQuestion

__all__ = [
    "EXTRAPOLATION_WARN", "FAN_POINTS", "LEVELS", "LawSource", "Draws", "Spread", "LawAnswer", "Mixture",
    "Fan", "Answer", "SizingResult", "extrapolation_distance", "tested_ranges", "predict", "weighted_quantiles",
    "mixture", "variance_split", "law_answer", "levels",
]

#: A point more than this many tested ranges beyond the data (along any input) carries a warning.
EXTRAPOLATION_WARN = 0.5
#: Points along the fan figure's axis.
FAN_POINTS = 61
#: Quantile levels reported besides the question's confidence level.
LEVELS = (0.05, 0.5, 0.95)


@dataclass(frozen=True)
class LawSource:
    """What sizing needs of one law: its fit, weights, measured misses and why it is excluded.

    ``weights``: weighting key (:data:`bayesfric.sizing.basis.LOO` or a blocked scheme's label)
    -> stacking weight (NaN: not computed); ``misses``: blocked label -> the law's measured miss
    there (:mod:`bayesfric.sizing.calibration`); ``penalties``: blocked label -> extrapolation
    penalty (nats per held-out point); ``excluded``: why its predictions may not be used (a
    failed diagnostics gate; None: used); ``weight_note``: why a weighting gave it 0;
    ``checks``: its residual-structure checks (:class:`~bayesfric.compare.structure_stats.StructureCheck`,
    which group columns the data show it is blind to: :mod:`bayesfric.sizing.newrun`).
    """

    name: str
    fit: xr.DataTree
    weights: Mapping[str, float] = field(default_factory=dict)
    excluded: str | None = None
    weight_note: str = ""
    misses: Mapping[str, Miss] = field(default_factory=dict)
    penalties: Mapping[str, float] = field(default_factory=dict)
    checks: tuple = ()


@dataclass
class Draws:
    """Predictive draws of one law at ``n`` points, shaped (chain, draw, n)."""

    mu: np.ndarray  # mean function (new-unit offset included), signed
    y: np.ndarray  # with observation noise, signed
    noise_var: np.ndarray  # noise-model variance per draw and point (inf: Student-t with nu <= 2)
    steady: str = ""  # a trajectory law's steady state at constant speed: what the answer is (sizing.steady)

    @property
    def n_draws(self) -> int:
        return int(self.mu.shape[0] * self.mu.shape[1])


@dataclass(frozen=True)
class Spread:
    """Quantiles (level -> array over points) and mean of a predictive of ``|T|``."""

    quantiles: dict[float, np.ndarray]
    mean: np.ndarray

    def q(self, level: float) -> np.ndarray:
        """The kept quantile at ``level``: the question's levels only (any level in (0, 1) from the
        draws: :meth:`bayesfric.sizing.result.SizingAnswer.q`)."""
        if level not in self.quantiles:
            kept = ", ".join(f"{k:g}" for k in self.quantiles)
            raise UserError(f"level: {level!r} is not one of the kept levels ({kept}); "
                            "SizingAnswer.q(p) gives any level in (0, 1) from the draws")
        return self.quantiles[level]


@dataclass
class LawAnswer:
    """One law's answer at every point of a question (arrays over points)."""

    name: str
    weight: float  # in the average (renormalised over the laws used; 0 if excluded)
    weight_raw: float  # the basis's weight, as computed (before renormalisation)
    weight_loo: float  # the study's LOO stacking weight, as computed
    excluded: str | None
    weight_note: str
    mean_fn: Spread  # |mu|: parameter uncertainty only
    noisy: Spread  # |T| with observation noise
    required: np.ndarray  # confidence-quantile of |T| with noise
    p_exceed: np.ndarray  # P(|T| > capacity); NaN without a capacity
    p_se: np.ndarray  # binomial MC error with S_eff; 0 when p is 0 or 1
    p_bound: np.ndarray  # 3/S where no draw (p = 0) or every draw (p = 1) exceeds, else NaN
    ess: np.ndarray  # S_eff of the exceedance indicator (NaN without a capacity)
    var_param: np.ndarray
    var_noise: np.ndarray
    infinite_noise: float  # fraction of draws whose noise variance is infinite (Student-t nu <= 2)
    n_draws: int
    rel_sd: np.ndarray | None = None  # relative sd of the model-form discrepancy per point (calibrated only)
    calibrated: LawAnswer | None = None  # the same answer with the measured model-form error added
    steady: str = ""  # "" or, from a trajectory law's steady state, what the answer is (sizing.steady)


@dataclass
class Mixture:
    """A model-averaged predictive (arrays over points) with its variance split."""

    basis: str  # which weights
    weights: dict[str, float]
    mean_fn: Spread
    noisy: Spread
    required: np.ndarray
    p_exceed: np.ndarray
    p_se: np.ndarray
    p_bound: np.ndarray  # Σ w_k 3/S_k where no draw of any law (or every draw) exceeds, else NaN
    var_param: np.ndarray
    var_noise: np.ndarray
    var_between: np.ndarray
    calibrated: Mixture | None = None  # the same average of the laws' calibrated answers

    @property
    def var_total(self) -> np.ndarray:
        return self.var_param + self.var_noise + self.var_between


@dataclass
class Fan:
    """Predictive bands along one input (the fan figure), other inputs at the question's values."""

    axis: str
    x: np.ndarray  # SI
    tested: tuple[float, float]
    laws: dict[str, dict[str, np.ndarray]]  # law -> {"curve": median |mu|, "lo", "hi": 5/95 % of |T| with noise}
    excluded: list[str]  # laws drawn for reference only
    average: dict[str, np.ndarray] | None  # {"curve", "lo", "hi", "required"} of the average, and its
    # calibrated friction-curve band and required capacity {"cal_lo", "cal_hi", "cal_required"} when measured
    measured: tuple[np.ndarray, np.ndarray] | None = None  # (axis values, |response|) of the data, SI


@dataclass
class Answer:
    """The answer to one sizing question."""

    question: SizingQuestion
    grid: dict[str, np.ndarray]  # input -> SI values at every point
    tested: dict[str, tuple[float, float]]  # input -> tested [lo, hi] (SI)
    distance: dict[str, np.ndarray]  # input -> extrapolation distance at every point
    laws: list[LawAnswer]  # every law, excluded ones marked
    average: Mixture | None
    average_loo: Mixture | None
    no_average: str  # why there is no average ("" when there is)
    governing: int  # point of the largest required capacity (average, else the largest over laws)
    energy_levels: tuple[float, ...]
    warnings: list[str] = field(default_factory=list)
    fan: Fan | None = None
    basis: Basis | None = None  # which weights and measured misses answer it (None: a single fit)
    undetected: str = ""  # laws the blocked folds cannot tell from the truth here, and by how much ("": none)
    bend: str = ""  # the data bend away from every weighted law along an extrapolated axis (sizing.shape; "": not)
    bend_upward: bool = False  # that bend is upward: the band is NOT calibrated for the shape the data show
    draws: dict[str, Draws] = field(default_factory=dict)  # law -> its draws at the points (kept: q(p) of any p)
    calibrated_draws: dict[str, Draws] = field(default_factory=dict)  # law -> with the model-form error added

    @property
    def n_points(self) -> int:
        return len(next(iter(self.grid.values())))

    @property
    def used(self) -> list[LawAnswer]:
        return [w for w in self.laws if w.excluded is None]

    def energy(self, spread: Spread, level: float) -> np.ndarray:
        """Friction energy (J) of one rotation at a quantile of ``spread`` (|T| · θ, see the module)."""
        return spread.q(level) * self.question.energy_rotation.lo


@dataclass
class SizingResult:
    """Every question's answer, with what the renderings need to say where the numbers come from."""

    answers: list[Answer]
    response: str  # torque | force
    response_unit: str  # display unit (data's own, or the capacity's)
    response_scale: float  # SI = scale * display
    provenance: str  # the data's provenance label
    source: str  # "study <name>" or "fit <file>"


# -- small pieces ----------------------------------------------------------------------------------
def extrapolation_distance(x, lo: float, hi: float) -> np.ndarray:
    """How far ``x`` lies beyond the tested ``[lo, hi]``, in tested ranges (0 inside)."""
    x = np.asarray(x, dtype=float)
    width = hi - lo
    if width <= 0:
        return np.where(x == lo, 0.0, np.inf)
    return np.where(x > hi, (x - hi) / width, np.where(x < lo, (lo - x) / width, 0.0))


def tested_ranges(ds: xr.Dataset, inputs: Sequence[str]) -> dict[str, tuple[float, float]]:
    """Tested [min, max] (SI) of each input in the data (an xarray Dataset or the fit's constant_data)."""
    return {k: (float(np.min(ds[k].values)), float(np.max(ds[k].values))) for k in inputs if k in ds}


def weighted_quantiles(values: np.ndarray, weights: np.ndarray, levels: Sequence[float]) -> dict[float, np.ndarray]:
    """Quantiles per column of ``values`` (S, n) under draw ``weights`` (S,): the smallest value
    whose weighted CDF reaches the level (the inverse of the weighted empirical CDF)."""
    order = np.argsort(values, axis=0, kind="stable")
    sorted_values = np.take_along_axis(values, order, axis=0)
    cdf = np.cumsum(weights[order], axis=0) / weights.sum()
    out = {}
    for level in levels:
        idx = np.minimum((cdf < level - 1e-12).sum(axis=0), values.shape[0] - 1)
        out[level] = sorted_values[idx, np.arange(values.shape[1])]
    return out


def variance_split(weights: Sequence[float], means: np.ndarray, var_param: np.ndarray,
                   var_noise: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Law of total variance over a weighted mixture of laws (arrays shaped (laws, n)):
    parameter ``Σ w Var_param``, noise ``Σ w E[noise var]``, between-law ``Σ w (m − Σ w m)²``."""
    w = np.asarray(weights, dtype=float)[:, None]
    w = w / w.sum()
    grand = (w * means).sum(axis=0)
    return (w * var_param).sum(axis=0), (w * var_noise).sum(axis=0), (w * (means - grand) ** 2).sum(axis=0)


def levels(confidence: float) -> tuple[float, ...]:
    return tuple(sorted(set(LEVELS) | {confidence}))


# -- prediction ----------------------------------------------------------------------------------
def predict(fit: xr.DataTree, grid: Mapping[str, np.ndarray], seed: int = 0, group: str | None = None) -> Draws:
    """Mean-function and noisy predictive draws of a fit at the points ``grid`` (input -> SI values).

    With group terms (``vary_by``, ``[noise] group``) the answer is for a new run / unit unless
    ``group`` names an existing level (:func:`bayesfric.hierarchy.mean_draws`).

    A trajectory (stateful) law answers from its steady state at constant speed
    (:func:`bayesfric.sizing.steady.sizing_law`), evaluated with the fit's posterior; the draws say
    so (``Draws.steady``).

    Raises
    ------
    SizingError
        The fit's law is a trajectory (stateful) law without a steady state, or ``grid`` lacks an
        input it reads.
    """
    from bayesfric.hierarchy import mean_draws
    from bayesfric.model import program_of_fit
    from bayesfric.sizing.steady import sizing_law, steady_note

    program = program_of_fit(fit)
    fitted, law = program.law, sizing_law(program.law)
    missing = [k for k in law.operating_inputs if k not in grid]
    if missing:
        raise SizingError("", f"law {law.name!r} reads {', '.join(missing)}, which the point does not give")
    n = len(next(iter(grid.values())))
    # a new unit of a grouped fit; with ar1 noise each point its own trajectory (stationary marginal)
    program = dataclasses.replace(program, law=law).at({k: grid[k] for k in law.operating_inputs})
    post = fit["posterior"].to_dataset()
    chains, draws = post.sizes["chain"], post.sizes["draw"]
    s = chains * draws

    def flat(name: str) -> np.ndarray:
        v = np.asarray(post[name].values, dtype=float)
        return v.reshape((s,) + v.shape[2:])

    mu = mean_draws(program, post, group=group, seed=zlib.crc32(law.name.encode()) + seed)
    _check_magnitude(law, grid, mu)
    shape, note = (chains, draws, n), steady_note(fitted, law)
    if law.response != fitted.response:  # a coast-down's torque: the fit's noise is on its speed
        return Draws(mu.reshape(shape), mu.reshape(shape), np.zeros(shape), note)
    rng = np.random.default_rng([seed, zlib.crc32(law.name.encode())])
    # The fit's own observation distribution (Program.observation: the likelihood's, ar1 at its
    # stationary marginal). One standardised noise draw per posterior draw, shared by the
    # question's points (common random numbers): each point's distribution is unchanged, and
    # curves along a range are smooth.
    values = {k: jnp.asarray(flat(k))[:, None] for k in program.noise.sites() if k != "group_sd"}
    obs = program.observation(jnp.asarray(mu), values)
    loc, scale = np.asarray(obs.loc, dtype=float), np.broadcast_to(np.asarray(obs.scale, dtype=float), (s, n))
    if program.noise.kind == "student_t":
        y = loc + scale * rng.standard_t(np.asarray(obs.df, dtype=float)[:, :1])
    else:
        y = loc + scale * rng.normal(size=(s, 1))
    var = np.asarray(jnp.broadcast_to(obs.variance, (s, n)), dtype=float)
    var = np.where(np.isfinite(var), var, np.inf)
    return Draws(mu.reshape(shape), y.reshape(shape), np.asarray(var, dtype=float).reshape(shape), note)


def _check_magnitude(law, grid: Mapping[str, np.ndarray], mu: np.ndarray) -> None:
    """The law's mean function at every asked point is finite and within the largest magnitude of
    an operating value (:data:`bayesfric.quantities.SCALE_RANGE`), so noise, quantiles and energies
    computed from it stay finite; else a :class:`SizingError` naming the point."""
    from bayesfric.quantities import QUANTITIES, SCALE_RANGE

    peak = np.max(np.where(np.isnan(mu), np.inf, np.abs(mu)), axis=0)
    if np.all(peak <= SCALE_RANGE[1]):
        return
    j = int(np.argmax(peak))
    point = ", ".join(f"{k} = {grid[k][j]:.4g}" for k in law.operating_inputs)
    unit = QUANTITIES[law.response].unit
    raise SizingError("", f"at the asked point {point} (SI) law {law.name!r} predicts |{law.response}| up to "
                          f"{peak[j]:.3g} {unit}, beyond the {SCALE_RANGE[1]:g} {unit} any friction stays below: "
                          "the point lies where the law cannot be used")


def _spread(values: np.ndarray, levels: Sequence[float]) -> Spread:
    flat = values.reshape(-1, values.shape[-1])
    return Spread({q: np.quantile(flat, q, axis=0) for q in levels}, flat.mean(axis=0))


def _exceedance(y_abs: np.ndarray, capacity: float | None) -> tuple[np.ndarray, ...]:
    """P(|T| > capacity) per point, its MC error, the rule-of-three bound and S_eff."""
    n = y_abs.shape[-1]
    if capacity is None:
        nan = np.full(n, np.nan)
        return nan, nan, nan, nan
    s = y_abs.shape[0] * y_abs.shape[1]
    hit = (y_abs > capacity).astype(float)
    p = hit.mean(axis=(0, 1))
    ess = np.full(n, float(s))
    bound = np.full(n, np.nan)
    for j in range(n):
        if 0 < p[j] < 1:
            enough = hit.shape[0] > 1 or hit.shape[1] > 3
            e = float(import_statistics().ess(hit[:, :, j], method="mean")) if enough else float(s)
            ess[j] = e if math.isfinite(e) and e > 0 else float(s)
        else:
            bound[j] = 3.0 / s
    se = np.sqrt(p * (1 - p) / ess)
    return p, se, bound, ess


def law_answer(source: LawSource, draws: Draws, question: SizingQuestion, levels,
                exceedance: bool = True) -> LawAnswer:
    mu_abs, y_abs = np.abs(draws.mu), np.abs(draws.y)
    mean_fn, noisy = _spread(mu_abs, levels), _spread(y_abs, levels)
    capacity = question.capacity.lo if question.capacity is not None and exceedance else None
    p, se, bound, ess = _exceedance(y_abs, capacity)
    var = draws.noise_var.reshape(-1, draws.noise_var.shape[-1])
    finite = np.isfinite(var)
    infinite = float(1.0 - finite[:, 0].mean()) if var.size else 0.0
    var_noise = np.where(finite.any(axis=0), np.nanmean(np.where(finite, var, np.nan), axis=0), np.inf)
    return LawAnswer(
        name=source.name, weight=0.0, weight_raw=math.nan, weight_loo=source.weights.get(LOO, math.nan),
        excluded=source.excluded,
        weight_note=source.weight_note, mean_fn=mean_fn, noisy=noisy, required=noisy.q(question.confidence),
        p_exceed=p, p_se=se, p_bound=bound, ess=ess, var_param=mu_abs.reshape(-1, mu_abs.shape[-1]).var(axis=0),
        var_noise=var_noise, infinite_noise=infinite, n_draws=draws.n_draws, steady=draws.steady,
    )


def mixture(answers: Sequence[LawAnswer], draws: Mapping[str, Draws], weights: Mapping[str, float],
            confidence: float, levels: Sequence[float], basis: str) -> Mixture:
    """The model average of ``answers`` under ``weights`` (law -> weight > 0; see the module)."""
    names = [a.name for a in answers if weights.get(a.name, 0.0) > 0]
    total = sum(weights[k] for k in names)
    w = {k: weights[k] / total for k in names}
    picked = [a for a in answers if a.name in w]
    mu = np.concatenate([np.abs(draws[a.name].mu).reshape(-1, draws[a.name].mu.shape[-1]) for a in picked])
    y = np.concatenate([np.abs(draws[a.name].y).reshape(-1, draws[a.name].y.shape[-1]) for a in picked])
    per_draw = np.concatenate([np.full(a.n_draws, w[a.name] / a.n_draws) for a in picked])
    mean_fn = Spread(weighted_quantiles(mu, per_draw, levels), per_draw @ mu)
    noisy = Spread(weighted_quantiles(y, per_draw, levels), per_draw @ y)
    ws = np.array([w[a.name] for a in picked])
    p = sum(w[a.name] * a.p_exceed for a in picked)
    se = np.sqrt(sum(w[a.name] ** 2 * a.p_se**2 for a in picked))
    edge = (p == 0) | (p == 1)
    bound = np.where(edge, sum(w[a.name] * 3.0 / a.n_draws for a in picked), np.nan)
    param, noise, between = variance_split(ws, np.array([a.mean_fn.mean for a in picked]),
                                           np.array([a.var_param for a in picked]),
                                           np.array([a.var_noise for a in picked]))
    return Mixture(basis, w, mean_fn, noisy, noisy.q(confidence), p, se, bound, param, noise, between)
