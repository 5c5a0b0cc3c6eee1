"""What a fit keeps per data row, computed in bounded memory.

A fit's pointwise groups -- ``log_likelihood`` and ``posterior_predictive`` (a number per kept
posterior draw and data row) and ``prior_predictive`` (per prior draw and row) -- are the only
parts of it that grow with draws × rows. Which draws it keeps, and in which precision, is
:func:`storage`'s rule:

* **Small fits, as before.** While chains × draws × rows ≤ :data:`FULL_NUMBERS` (2²⁴: 128 MiB
  of float64 per group; 4 chains × 1000 draws up to 4194 rows) a fit keeps every draw in
  float64, computed in one compiled program over all draws (``datatree._draw_tables``): the
  seed studies' fits do not change.
* **Large fits, thinned.** Above it each group holds at most :data:`STORED_NUMBERS` (2²⁵)
  numbers: every ``every``-th draw of each chain, ``every`` the smallest stride that fits
  (the ``draw`` coordinate keeps the draws' own indices, so the groups line up with the
  ``posterior``), and min(500, kept draws) prior-predictive draws. They are computed from the
  posterior draws and the program by :func:`thinned_tables`, a scan over chunks of at most
  :data:`CHUNK_NUMBERS` numbers, so no array of all draws × rows is ever formed, and stored as
  float32 where the numbers allow it: where rounding to float32 moves no log-likelihood value
  by more than :data:`LOG_LIKELIHOOD_TOLERANCE` nats and no predictive draw by more than
  :data:`PREDICTIVE_TOLERANCE` of its row's predictive standard deviation (else that group is
  float64, twice the bytes). Each kept draw's values are the ones the full computation gives
  that draw (its predictive draw uses the same random key), rounded.

The choice is recorded in the fit's ``attrs["pointwise_storage"]`` (JSON: rows, chains, draws,
``every``, kept draws, prior-predictive draws, each group's dtype and the rule).

Reading a thinned fit. ``arviz`` opens it as any fit and ``az.loo(fit)`` runs on the draws it
holds (its relative efficiency, though, comes from the whole posterior); :func:`stored_draws`
gives the fit restricted to those draws and in float64, which is what the consumers in
:mod:`bayesfric.compare` pass to arviz-stats (PSIS-LOO, LOO-PIT, power-scaling sensitivity).
:func:`log_likelihood` computes the pointwise log-likelihood of every posterior draw on demand
for chosen rows (in chunks, from the fit's program), for a PSIS-LOO over all draws by blocks
of rows.

>>> info = storage(rows=100_000, chains=4, draws=1000)   # doctest: +SKIP
>>> info.every, info.kept_total                           # doctest: +SKIP
(13, 308)
"""

from __future__ import annotations

import ctypes
import ctypes.util
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
from numpyro.handlers import mask, seed, substitute, trace
from numpyro.infer import log_likelihood as numpyro_log_likelihood

from bayesfric.errors import UserError
from bayesfric.exported import program_jit
from bayesfric.limits import CHUNK_NUMBERS, FULL_NUMBERS, STORED_NUMBERS
from bayesfric.model import OBS_SITE, Program, program_from_fit

__all__ = [
    "FULL_NUMBERS", "STORED_NUMBERS", "CHUNK_NUMBERS", "LOG_LIKELIHOOD_TOLERANCE", "PREDICTIVE_TOLERANCE",
    "Storage", "storage", "storage_of", "thinned_tables_jit", "thinned_tables", "stored_draws", "log_likelihood",
    "log_mean_likelihood", "trim_memory",
]

# FULL_NUMBERS, STORED_NUMBERS and CHUNK_NUMBERS are declared in bayesfric.limits (the memory
# rule reads them too), re-exported here.
#: Largest change (nats) rounding to float32 may make to a stored log-likelihood value.
LOG_LIKELIHOOD_TOLERANCE = 1e-4
#: Largest change rounding to float32 may make to a predictive draw, in its row's predictive sd.
PREDICTIVE_TOLERANCE = 1e-3
#: Groups of the thinned tables that may be stored as float32.
GROUPS = ("log_likelihood", "posterior_predictive", "prior_predictive")

RULE = ("every draw in float64 while chains × draws × rows ≤ 2^24; above, at most 2^25 numbers per group: "
        "every `every`-th draw of each chain, min(500, kept) prior-predictive draws, float32 where rounding moves "
        "no log-likelihood by more than 1e-4 nats and no predictive draw by more than 1e-3 of its row's sd")


@dataclass(frozen=True)
class Storage:
    """Which draws a fit keeps in its pointwise groups (see the module).

    Attributes
    ----------
    rows, chains, draws : int
        Data rows, chains (emcee: walkers) and draws per chain of the fit.
    every : int
        Stride of the kept draws within each chain (1: every draw).
    full : bool
        Every draw in float64, computed as before (small fits).
    n_prior : int
        Prior draws of the fit (their parameters are all kept).
    """

    rows: int
    chains: int
    draws: int
    every: int
    full: bool
    n_prior: int

    @property
    def kept(self) -> int:
        """Draws kept per chain."""
        return len(range(0, self.draws, self.every))

    @property
    def kept_total(self) -> int:
        return self.chains * self.kept

    @property
    def n_prior_predictive(self) -> int:
        """Prior draws whose predictive draws are kept (the first ones)."""
        return self.n_prior if self.full else min(self.n_prior, self.kept_total)

    def draw_index(self) -> np.ndarray:
        """Indices of the kept draws within a chain (the ``draw`` coordinate of the groups)."""
        return np.arange(0, self.draws, self.every)

    def flat_index(self) -> np.ndarray:
        """Indices of the kept draws among all draws flattened chain by chain."""
        return (np.arange(self.chains)[:, None] * self.draws + self.draw_index()[None, :]).ravel()

    @property
    def chunk(self) -> int:
        """Draws per chunk: the largest divisor of the kept draws with at most
        :data:`CHUNK_NUMBERS` numbers per chunk (1 at least)."""
        return _largest_divisor(self.kept_total, max(1, CHUNK_NUMBERS // max(self.rows, 1)))

    def to_json(self, dtypes: Mapping[str, str]) -> str:
        """The ``pointwise_storage`` attr (``dtypes``: group -> dtype name)."""
        return json.dumps({"rows": self.rows, "chains": self.chains, "draws": self.draws, "every": self.every,
                           "kept_draws": self.kept_total, "prior_predictive_draws": self.n_prior_predictive,
                           "thinned": not self.full, "dtypes": dict(dtypes), "rule": RULE})


def _largest_divisor(n: int, most: int) -> int:
    return max(d for d in range(1, min(n, most) + 1) if n % d == 0)


def storage(rows: int, chains: int, draws: int, n_prior: int = 500) -> Storage:
    """The pointwise storage of a fit of ``chains`` × ``draws`` on ``rows`` rows (module rule)."""
    rows, chains, draws = int(rows), int(chains), int(draws)
    if chains * draws * rows <= FULL_NUMBERS:
        return Storage(rows, chains, draws, 1, True, int(n_prior))
    per_chain = max(1, STORED_NUMBERS // (chains * rows))
    every = max(1, math.ceil(draws / per_chain))
    return Storage(rows, chains, draws, every, False, int(n_prior))


def storage_of(fit: xr.DataTree) -> dict[str, Any] | None:
    """The fit's ``pointwise_storage`` attr (None: a fit from before it, which keeps every draw)."""
    text = fit.attrs.get("pointwise_storage")
    return json.loads(text) if text else None


# -- the thinned tables ---------------------------------------------------------------------------
def _pointwise_ll(program: Program, draw: Mapping[str, Any]) -> jax.Array:
    """Pointwise log-likelihood ``(rows,)`` of one draw (numpyro's ``log_likelihood`` of it)."""
    batched = {k: jnp.asarray(v)[None] for k, v in draw.items()}
    return numpyro_log_likelihood(program.model, batched, **program.model_kwargs)[OBS_SITE][0]


def _predict(program: Program, key: jax.Array, draw: Mapping[str, Any]) -> dict[str, jax.Array]:
    """The sites numpyro's ``Predictive`` returns for one draw and its key (``draw`` empty: a
    prior draw), as it computes them."""
    def fixed(msg):
        return draw.get(msg["name"]) if msg["type"] != "deterministic" else None

    model = substitute(mask(program.model, mask=False), substitute_fn=fixed)
    tr = trace(seed(model, key)).get_trace(**dict(program.model_kwargs, response=None))
    return {k: s["value"] for k, s in tr.items()
            if (s["type"] == "sample" and k not in draw) or s["type"] == "deterministic"}


def _welford(carry: tuple, values: jax.Array) -> tuple:
    """Merge a chunk ``(B, rows)`` into per-row (count, mean, M2) (Chan et al.'s update)."""
    n, mean, m2 = carry
    b = values.shape[0]
    chunk_mean = values.mean(axis=0)
    chunk_m2 = ((values - chunk_mean) ** 2).sum(axis=0)
    delta = chunk_mean - mean
    total = n + b
    return total, mean + delta * (b / total), m2 + chunk_m2 + delta**2 * (n * b / total)


def _rounding(values: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``values`` as float32 and, per row, the largest change rounding made (0 where not finite)."""
    low = values.astype(jnp.float32)
    change = jnp.where(jnp.isfinite(values), jnp.abs(low.astype(values.dtype) - values), 0.0)
    return low, change.max(axis=0)


def _scan_rows(fn, xs: Any, n: int, chunk: int, low: bool, spread: bool) -> tuple[jax.Array, jax.Array]:
    """``fn`` (one element of ``xs`` -> ``(rows,)``) over the ``n`` leading elements of ``xs``,
    ``chunk`` at a time: ``(n, rows)`` values (float32 if ``low``) and how far float32 rounding
    moves them -- the largest change in absolute terms, or with ``spread`` in units of the
    row's standard deviation over the ``n`` elements (inf where that is 0 and a value moved)."""
    chunks = jax.tree.map(lambda a: a.reshape((n // chunk, chunk) + a.shape[1:]), xs)

    def step(carry, part):
        values = jax.vmap(fn)(*part) if isinstance(part, tuple) else jax.vmap(fn)(part)
        stats, worst = carry
        low_values, change = _rounding(values)
        stats = _welford(stats, values) if spread else stats
        return (stats, jnp.maximum(worst, change)), (low_values if low else values)

    rows = jax.eval_shape(fn, *jax.tree.map(lambda a: a[0], xs)) if isinstance(xs, tuple) else \
        jax.eval_shape(fn, jax.tree.map(lambda a: a[0], xs))
    zeros = jnp.zeros(rows.shape, rows.dtype)
    init = ((jnp.zeros((), rows.dtype), zeros, zeros), zeros)
    ((_, _, m2), worst), out = jax.lax.scan(step, init, chunks)
    out = out.reshape((n,) + rows.shape)
    if not spread:
        return out, worst.max()
    sd = jnp.sqrt(m2 / max(n - 1, 1))
    relative = jnp.where(worst == 0, 0.0, worst / jnp.where(sd > 0, sd, 0.0))
    return out, relative.max()


def _thinned_tables(program: Program, info: Storage, low: tuple[bool, bool, bool], flat: dict, key_pp, key_prior):
    """The pointwise tables of a thinned fit: log-likelihood and posterior-predictive draws of
    the kept draws, log prior of every draw, every prior draw's parameters and the first
    prior draws' predictive; with how far float32 rounding moves each group (module notes)."""
    n_all = info.chains * info.draws
    index = info.flat_index()
    kept = {k: v[index] for k, v in flat.items()}
    chunk = info.chunk
    ll, ll_moved = _scan_rows(partial(_pointwise_ll, program), kept, info.kept_total, chunk, low[0], spread=False)
    keys = _keys(key_pp, n_all)[index]  # each kept draw's key, as Predictive splits it over all draws
    pp, pp_moved = _scan_rows(lambda k, d: _predict(program, k, d)[OBS_SITE], (keys, kept), info.kept_total, chunk,
                              low[1], spread=True)

    def log_prior(draw):
        tr = trace(substitute(program.model, data=draw)).get_trace(**program.model_kwargs)
        return {name: site["fn"].log_prob(site["value"]).sum()
                for name, site in tr.items() if site["type"] == "sample" and not site["is_observed"]}

    big = max(1, CHUNK_NUMBERS // max(info.rows, 1))  # the model's mean function runs per draw
    prior_logs = jax.lax.map(log_prior, flat, batch_size=min(big, n_all))
    prior_keys = _keys(key_prior, info.n_prior)
    prior = jax.lax.map(lambda k: {s: v for s, v in _predict(program, k, {}).items() if s != OBS_SITE},
                        prior_keys, batch_size=min(big, info.n_prior))
    n_pp = info.n_prior_predictive
    prior_pp, prior_moved = _scan_rows(lambda k: _predict(program, k, {})[OBS_SITE], prior_keys[:n_pp], n_pp,
                                       _largest_divisor(n_pp, big), low[2], spread=True)
    return ll, prior_logs, pp, prior, prior_pp, jnp.stack([ll_moved, pp_moved, prior_moved])


def _keys(key: jax.Array, n: int) -> jax.Array:
    """One key per draw, as numpyro's ``Predictive`` makes them for ``n`` draws."""
    return jax.random.split(key, n) if n > 1 else jnp.reshape(key, (1,) + key.shape)


def thinned_tables_jit(program: Program, info: Storage, low: tuple[bool, bool, bool] = (True, True, True)):
    """The compiled program of a thinned fit's tables (:func:`_thinned_tables`); ``low`` says
    which groups (:data:`GROUPS`) come back as float32. Same arguments as
    ``datatree.draw_tables_jit``: ``(flat draws, key_pp, key_prior)``."""
    what = (f"thinned_tables n_prior={info.n_prior} chains={info.chains} draws={info.draws} every={info.every} "
            f"chunk={info.chunk} float32={''.join('1' if x else '0' for x in low)}")
    return program_jit(program, what, partial(_thinned_tables, program, info, tuple(low)))


def thinned_tables(program: Program, info: Storage, flat: dict, key_pp, key_prior, tables: Any = None):
    """Run the thinned tables and settle each group's dtype: float32 where the rounding stays
    within the tolerances, else that group again in float64. Returns the tables (as
    :func:`_thinned_tables`, without the rounding figures) and group -> dtype name.

    The C heap's free memory is given back first (:func:`trim_memory`): the tables are the
    fit's last large allocation, after the sampler's."""
    trim_memory()
    tables = thinned_tables_jit(program, info) if tables is None else tables
    ll, log_prior, pp, prior, prior_pp, moved = tables(flat, key_pp, key_prior)
    moved = np.asarray(moved)
    ok = (bool(moved[0] <= LOG_LIKELIHOOD_TOLERANCE), bool(moved[1] <= PREDICTIVE_TOLERANCE),
          bool(moved[2] <= PREDICTIVE_TOLERANCE))
    if not all(ok):  # rare: values too large for their spread; those groups again, in float64
        again = thinned_tables_jit(program, info, ok)(flat, key_pp, key_prior)
        ll, pp, prior_pp = (new if not fine else old for new, old, fine in zip(
            (again[0], again[2], again[4]), (ll, pp, prior_pp), ok, strict=True))
    dtypes = {g: "float32" if fine else "float64" for g, fine in zip(GROUPS, ok, strict=True)}
    return (ll, log_prior, pp, prior, prior_pp), dtypes


def trim_memory() -> bool:
    """Give the C heap's free pages back to the system (glibc's ``malloc_trim(0)``); False where
    there is no such call (not glibc).

    The compiled sampler's calls run on threads, and glibc keeps what they freed in each
    thread's own heap, where the main thread's next allocations do not reuse it: at 10⁶ rows
    (2 chains × 60 draws) a fit held 1.00 GB resident after sampling, 0.65 GB after
    the trim, and peaked at 1.16 GB instead of 1.69 GB while its tables were computed.
    """
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        return bool(libc.malloc_trim(0))
    except (OSError, AttributeError, TypeError):
        return False


# -- reading a fit --------------------------------------------------------------------------------
def stored_draws(fit: xr.DataTree, cast: tuple[str, ...] = ("log_likelihood", "posterior_predictive")
                 ) -> xr.DataTree:
    """The fit restricted to the draws its pointwise groups hold, those groups in float64.

    For a fit that keeps every draw (small fits, and fits from before thinning) this is ``fit``
    itself. For a thinned one, a shallow copy whose ``posterior``, ``sample_stats`` and
    ``log_prior`` hold only the kept draws and whose groups ``cast`` are float64 copies (the
    others as stored): what arviz-stats' ``loo`` (``cast=("log_likelihood",)``), ``loo_pit`` and
    ``psense`` need to see (their relative efficiency and weights computed on the same draws).
    """
    info = storage_of(fit)
    if info is None or not info.get("thinned"):
        return fit
    draws = fit["log_likelihood"]["draw"].values
    view = fit.copy(deep=False)
    for group in ("posterior", "sample_stats", "log_prior"):
        if group in fit.children:
            view[group] = fit[group].to_dataset().sel(draw=draws)
    for group in cast:
        if group in fit.children:
            view[group] = fit[group].to_dataset().astype(np.float64)
    return view


def log_likelihood(fit: xr.DataTree, ds: xr.Dataset | None = None, *, program: Program | None = None,
                   obs: Any = None) -> xr.DataArray:
    """Pointwise log-likelihood of every posterior draw of ``fit`` at rows ``obs``, on demand.

    Computed from the posterior draws through the fit's program (``program``, or rebuilt from
    the fit's attrs and its data ``ds``), in chunks of at most :data:`CHUNK_NUMBERS` numbers,
    in float64; the result is ``(chain, draw, obs)`` for the rows asked (default: all, which for
    a large fit is draws × rows: ask for blocks of rows). Each call evaluates every row of every
    draw (a law's row may depend on the rows before it) and keeps the ones asked, compiled once
    per block length. PSIS-LOO is pointwise, so a PSIS-LOO of a thinned fit over all its draws
    is ``az.loo`` over blocks of rows, each on ``xr.DataTree.from_dict({"posterior":
    fit["posterior"].to_dataset(), "log_likelihood": log_likelihood(fit, ds, obs=block).to_dataset()})``,
    with the blocks' ``elpd_i`` concatenated (``docs/data.md``, *Large data*).
    """
    if program is None:
        if ds is None:
            raise UserError("log_likelihood needs the fit's data (ds) or its program", "ds")
        program = program_from_fit(fit, ds)
    rows = np.arange(program.n_obs)[slice(None) if obs is None else obs]
    post = fit["posterior"]
    n_chain, n_draw = post.sizes["chain"], post.sizes["draw"]
    flat = {k: np.asarray(post[k].values).reshape((n_chain * n_draw,) + post[k].shape[2:]) for k in post.data_vars}
    chunk = min(max(1, CHUNK_NUMBERS // max(program.n_obs, 1)), n_chain * n_draw)

    def table(draws, at):
        return jax.lax.map(lambda d: _pointwise_ll(program, d)[at], draws, batch_size=chunk)

    # the rows are an argument: one compilation per block length, whichever rows
    values = np.asarray(program_jit(program, f"pointwise log_likelihood chunk={chunk}", table)(flat, rows))
    obs_coord = fit["log_likelihood"]["obs"].values[rows] if "log_likelihood" in fit.children else rows
    return xr.DataArray(values.reshape(n_chain, n_draw, rows.size), dims=("chain", "draw", "obs"),
                        coords={"chain": post["chain"].values, "draw": post["draw"].values, "obs": obs_coord},
                        name=OBS_SITE)


def log_mean_likelihood(pointwise: Any, flat: Mapping[str, jax.Array], rows: int) -> jax.Array:
    """``log mean_s p(y_i | θ_s)`` per row over the draws ``flat`` (leading axis ``s``), inside a
    traced function; ``pointwise`` maps one draw to its ``(rows,)`` log-likelihood.

    Up to :data:`CHUNK_NUMBERS` draws × rows it is the log-sum-exp of all draws at once (as it
    always was); above, a scan over chunks of draws with a running maximum and sum, so the
    sampler holds no array of draws × rows (the compiled NUTS engine's held-out scores).
    """
    n = next(iter(flat.values())).shape[0]
    chunk = _largest_divisor(n, max(1, CHUNK_NUMBERS // max(rows, 1)))
    if chunk == n:
        ll = jax.vmap(pointwise)(flat)
        return jax.scipy.special.logsumexp(ll, axis=0) - jnp.log(n)
    chunks = jax.tree.map(lambda a: a.reshape((n // chunk, chunk) + a.shape[1:]), flat)

    def step(carry, part):
        top, total = carry
        ll = jax.vmap(pointwise)(part)
        new_top = jnp.maximum(top, ll.max(axis=0))
        shift = jnp.where(jnp.isfinite(new_top), new_top, 0.0)
        total = total * jnp.exp(top - shift) + jnp.exp(ll - shift).sum(axis=0)
        return (new_top, total), None

    start = (jnp.full((rows,), -jnp.inf), jnp.zeros((rows,)))
    (top, total), _ = jax.lax.scan(step, start, chunks)
    return jnp.log(total) + jnp.where(jnp.isfinite(top), top, 0.0) - jnp.log(n)
