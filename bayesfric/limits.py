"""Upper bounds of size-like settings, from the memory they imply: one rule, checked before any work.

Every setting that sizes an array — draws, warm-up steps, chains or walkers, thinning, SMC
particles and runs, and the processes of ``--workers`` and ``--jobs`` — is bounded here, by the
memory it implies on this machine, not by a fixed number: ``fit`` checks its options, a study its
``[sampler]`` and ``[compare]`` tables (:func:`bayesfric.study.runner.validate_against_data`), the
command line its ``--workers`` and ``--jobs``, all before anything is sampled or written. A value
that passes cannot take the machine's memory; one that does not is refused in one line naming
its key, what it would need and the largest value that fits.

The memory of a fit (NUTS or emcee, and every refit of a fold, which is no larger): the compiled
sampler keeps every step of every chain, warm-up included (its position and :data:`STEP_STATS`
statistics: emcee stores its burn-in and every step before thinning too), and every kept draw
holds the parameters and derived quantities; the pointwise groups (:func:`pointwise_bytes`)
hold, while chains × kept × rows ≤ ``pointwise.FULL_NUMBERS``, per draw and data row the
log-likelihood, the posterior-predictive draw and a transient copy while they are computed
(:data:`ROW_NUMBERS`), and above it a bounded amount whatever the rows (thinned draws in
chunks: :mod:`bayesfric.inference.pointwise`)::

    bytes = 8 · chains · [(tune + draws) · (parameters + STEP_STATS) + kept · parameters] + pointwise_bytes

with ``kept = draws`` (NUTS) or ``draws // thin`` (emcee, whose chains are its walkers). SMC keeps
every particle of every run, with every row of each (``chains = runs``, ``kept = particles``,
``8 · ROW_NUMBERS · rows`` per particle: it has no thinned storage). A fit may
claim at most :data:`SHARE` of the memory available now (:func:`available_memory`). A process
(a study of ``--jobs``, a Dask worker of ``--workers``) takes :data:`PROCESS_BYTES`, and
:data:`RESERVED_BYTES` stay with the rest of the machine (the same budget
:func:`bayesfric.pipeline.mainjob.default_jobs` uses).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = [
    "STEP_STATS", "ROW_NUMBERS", "FULL_NUMBERS", "STORED_NUMBERS", "CHUNK_NUMBERS", "INIT_NUMBERS",
    "LOO_SUBSAMPLE_ROWS", "LOO_SUBSAMPLE_SIZE",
    "SHARE", "PROCESS_BYTES", "RESERVED_BYTES", "available_memory", "physical_memory",
    "fit_bytes", "pointwise_bytes", "program_size", "sampler_problem", "smc_problem", "max_processes",
    "process_problem", "LOAD_FACTOR", "load_problem", "PREDICT_NUMBERS", "predict_problem",
]

#: Numbers kept per chain and step besides the position: divergence, energy, tree size, acceptance ...
STEP_STATS = 8
#: Numbers per kept draw and data row: log-likelihood, posterior predictive, a transient copy.
ROW_NUMBERS = 3
#: Draws × rows (all chains) up to which a fit keeps every draw of its pointwise groups in
#: float64 (:mod:`bayesfric.inference.pointwise`, which uses these three numbers).
FULL_NUMBERS = 2**24
#: Numbers one pointwise group may hold above :data:`FULL_NUMBERS` (128 MiB as float32).
STORED_NUMBERS = 2**25
#: Numbers computed per chunk (draws × rows): 32 MiB of float64 per intermediate array.
CHUNK_NUMBERS = 2**22
#: Pathfinder's budget (``init = "pathfinder"``, :mod:`bayesfric.inference.init`): log-density
#: evaluations at once × data rows, in every stage (its L-BFGS paths, the ELBO draws of each
#: iterate, the draws resampled for the starts). XLA's buffer sizes (``memory_analysis``) of LuGre
#: on 800 rows: 100 bytes per row of a value, 330 of a gradient, so at most ~0.2 GB of values (the
#: 8 paths' gradients take 8 × rows × 330 bytes: 26 MB at 10⁴ rows). blackjax's approximation
#: evaluated 8 paths × 101 iterates × 200 draws at once (13 GB of values at 800 rows; a LuGre
#: study peaked at 16.7 GB that way). At 10⁴ rows all paths and 200 draws still run side by side; above 2²¹ rows
#: one evaluation exceeds it and the chains start at prior medians, with a warning.
INIT_NUMBERS = 2**21
#: Data rows above which PSIS-LOO is subsampled (:mod:`bayesfric.compare.loo_subsample`), and
#: the rows it then scores exactly. PSIS fits a Pareto tail per row, whatever the draws: measured
#: on 2 cores, 18 s for 10⁴ rows × 2000 draws and 262 s (0.9 GB peak) for 10⁵ rows × 308 draws,
#: per law and pass; a study makes several passes (LOO, LOO-PIT, ranking sensitivity at two prior
#: powers): in a 3-law study at 10⁴ rows (benchmarks/bench_scale_study.py, loaded machine) LOO
#: took 337 s and the checks 603 s of 1726 s. Above 5000 rows arviz-stats' ``loo_subsample``
#: scores 2000 rows exactly and the rest by a point-estimate (plpd) approximation, with its
#: subsampling standard error reported, and the checks read the same rows. The seed studies
#: (at most 521 rows) lie far below.
LOO_SUBSAMPLE_ROWS = 5_000
LOO_SUBSAMPLE_SIZE = 2_000
#: Share of the available memory one fit may claim.
SHARE = 0.5
#: Memory of one study process or Dask worker: the seed studies peaked at 1.3-1.7 GB resident each
#: (``/usr/bin/time -v``), rounded up; and what is left to the rest of the machine.
PROCESS_BYTES = 2 * 1024**3
RESERVED_BYTES = 2 * 1024**3
#: Memory per byte of CSV text while a table is parsed into cells and columns (measured 18: 10⁶
#: rows × 2 columns, 19 MB of text, 340 MB resident above the interpreter), rounded up. A data set
#: has no row limit of its own: loading is bounded by this, a fit by :func:`fit_bytes`.
LOAD_FACTOR = 20
#: Numbers per posterior draw and log row a prediction holds (``predict``, ``score``): each law's
#: mean and noise scale, kept for every law until the model average is formed, and two working
#: arrays of the quantiles and densities. Measured: 23 kB per row for one law at 1000 draws
#: (1.38 GB above the interpreter at 6·10⁴ rows); this rule says 32 kB.
PREDICT_NUMBERS = {"per_law": 2, "working": 2}
#: Settings a memory problem may be blamed on, with their usual values (the one furthest above
#: its usual value is named).
_USUAL = {"draws": 1000, "tune": 1000, "chains": 4, "walkers": 32}


def physical_memory() -> int | None:
    """Bytes of physical memory (None where the system does not say)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # not POSIX, or not reported
        return None


def available_memory() -> int | None:
    """Bytes of memory available now: ``MemAvailable`` (Linux), within the cgroup's limit if one is
    set, else the physical memory (None where neither is known)."""
    found = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                found.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit != "max":
            found.append(int(limit) - int(Path("/sys/fs/cgroup/memory.current").read_text()))
    except (OSError, ValueError):
        pass
    return min(found) if found else physical_memory()


def pointwise_bytes(*, chains: int, kept: int, rows: int) -> int:
    """Memory of a fit's pointwise groups (:mod:`bayesfric.inference.pointwise`): every draw
    and row, :data:`ROW_NUMBERS` float64 numbers each, up to ``FULL_NUMBERS``; above it three
    groups of at most ``STORED_NUMBERS``, in the worst case both as float32 and again as float64
    (values that float32 would round too far), plus the chunks being computed (four arrays of
    ``CHUNK_NUMBERS`` in float64)."""
    if chains * kept * rows <= FULL_NUMBERS:
        return 8 * ROW_NUMBERS * chains * kept * rows
    return (4 + 8) * 3 * STORED_NUMBERS + 8 * 4 * CHUNK_NUMBERS


def fit_bytes(*, chains: int, tune: int, draws: int, kept: int, params: int, rows: int) -> int:
    """Memory of a fit (module docstring); exact integers, whatever the sizes."""
    return (8 * chains * ((tune + draws) * (params + STEP_STATS) + kept * params)
            + pointwise_bytes(chains=chains, kept=kept, rows=rows))


def program_size(program) -> tuple[int, int]:
    """(parameters, rows) of a :class:`~bayesfric.model.Program`: every sampled and derived value
    kept per draw (vector parameters count their entries; one offset per group), and data rows."""
    params = sum(math.prod(p.shape) if p.shape else 1 for p in program.law.params.values())
    params += len(program.law.derived) + len(program.noise.sites()) + len(program.group_labels)
    return params, program.n_obs


def _gib(n: float) -> str:
    return f"{n / 1024**3:.3g} GiB"


def _budget(memory: int | None) -> int | None:
    memory = available_memory() if memory is None else memory
    return None if memory is None else int(memory * SHARE)


def sampler_problem(sampler: str, settings: Mapping[str, Any], params: int, rows: int,
                    memory: int | None = None) -> tuple[str, str] | None:
    """``(key, problem)`` of sampler ``settings`` whose fit would not fit in memory, else None.

    Parameters
    ----------
    sampler : {"nuts", "emcee"}
    settings : mapping
        ``draws``, ``tune`` and ``chains`` (NUTS) or ``walkers`` (None: the default) and ``thin``.
    params, rows : int
        Of the program (:func:`program_size`).
    memory : int, optional
        Bytes available (default :func:`available_memory`).
    """
    sizes = {"draws": int(settings["draws"]), "tune": int(settings["tune"])}
    thin = int(settings.get("thin") or 1) if sampler == "emcee" else 1
    if sampler == "emcee":
        sizes["walkers"] = int(settings.get("walkers") or max(32, 4 * params))
    else:
        sizes["chains"] = int(settings["chains"])
    if sizes["draws"] // thin < 1:
        return "draws", f"{sizes['draws']} steps thinned by {thin} keep no draw; give at least {thin}"
    budget = _budget(memory)
    if budget is None:
        return None

    def need(s: dict[str, int]) -> int:
        chains = s.get("chains", s.get("walkers"))
        return fit_bytes(chains=chains, tune=s["tune"], draws=s["draws"], kept=s["draws"] // thin,
                         params=params, rows=rows)

    if need(sizes) <= budget:
        return None
    key = max(sizes, key=lambda k: sizes[k] / _USUAL[k])
    lo, hi = 0, sizes[key]  # the largest value of ``key`` that fits, the others as given
    while lo < hi:
        mid = (lo + hi + 1) // 2
        lo, hi = (mid, hi) if need(sizes | {key: mid}) <= budget else (lo, mid - 1)
    chains = "walkers" if sampler == "emcee" else "chains"
    return key, (f"{sizes[key]} needs about {_gib(need(sizes))} of memory ({sizes[chains]} {chains} × "
                 f"({sizes['tune']} warm-up + {sizes['draws']} draws), {params} parameters, {rows} data rows), more "
                 f"than {SHARE:.0%} of the {_gib(budget / SHARE)} available; at most {lo} with the other settings")


def smc_problem(particles: int, runs: int, params: int, rows: int, memory: int | None = None) -> tuple[str, str] | None:
    """``(key, problem)`` when tempered SMC with ``runs`` × ``particles`` would not fit in memory."""
    budget = _budget(memory)
    need = 8 * runs * particles * (2 * params + STEP_STATS + ROW_NUMBERS * rows)  # every row of every particle
    if budget is None or need <= budget:
        return None
    key = "smc_particles" if particles / 300 >= runs / 3 else "smc_runs"
    return key, (f"{runs} runs × {particles} particles need about {_gib(need)} of memory ({params} parameters, "
                 f"{rows} data rows), more than {SHARE:.0%} of the {_gib(budget / SHARE)} available")


def max_processes(memory: int | None = None) -> int | None:
    """Processes of :data:`PROCESS_BYTES` the machine holds besides :data:`RESERVED_BYTES`
    (at least 1; None where the memory is not known). Default: the physical memory."""
    memory = physical_memory() if memory is None else memory
    return None if memory is None else max(1, (memory - RESERVED_BYTES) // PROCESS_BYTES)


def process_problem(n: int, what: str = "processes") -> str | None:
    """Why ``n`` processes (``--workers``, ``--jobs``) are too many for this machine (None if not)."""
    most = max_processes()
    if most is None or n <= most:
        return None
    return (f"{n} {what} need about {_gib(n * PROCESS_BYTES)} of memory ({_gib(PROCESS_BYTES)} each), more than "
            f"this machine's {_gib(physical_memory())} less {_gib(RESERVED_BYTES)} kept for the rest; at most {most}")


def load_problem(path: Path, size: int) -> str | None:
    """Why a CSV file of ``size`` bytes cannot be loaded in the memory available now (None: it can)."""
    available = available_memory()
    need = LOAD_FACTOR * size
    if available is None or need <= SHARE * available:
        return None
    return (f"{path}: {_amount(size)} of text needs about {_amount(need)} of memory to load, more than half of "
            f"the {_amount(available)} available now; reduce it to steady-state segment means first "
            f"(bayesfric data reduce), or thin or split it")


def _amount(n: float) -> str:
    """Bytes for a message: kB, MB or GB (decimal)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n / 1e3:.0f} kB"


def predict_problem(laws: int, draws: int, rows: int, memory: int | None = None) -> str | None:
    """Why predicting ``rows`` log rows from ``laws`` laws of ``draws`` draws each would not fit in
    the memory available now (None: it fits; :data:`PREDICT_NUMBERS`, :data:`SHARE`)."""
    per_row = 8 * draws * (PREDICT_NUMBERS["per_law"] * laws + PREDICT_NUMBERS["working"])
    budget = _budget(memory)
    if budget is None or per_row * rows <= budget:
        return None
    return (f"{rows} rows × {draws} draws of {laws} law{'s' * (laws != 1)} need about {_gib(per_row * rows)} of "
            f"memory, more than {SHARE:.0%} of the {_gib(budget / SHARE)} available; split or thin the log (at most "
            f"{budget // per_row} rows at once)")
