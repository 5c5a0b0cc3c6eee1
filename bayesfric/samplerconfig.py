"""One frozen sampler configuration: what the command line, a study's ``[sampler]`` table,
``bayesfric.fit`` and the engine all read (a base module: it imports only :mod:`bayesfric.errors`,
so the command line checks ``fit``'s options before JAX loads; :mod:`bayesfric.inference.config`
re-exports it).

:class:`SamplerConfig` holds every setting of a fit: the backend and its seed, the draws, the NUTS
settings (target acceptance and its retry target, tree depth, metric, chain starts), the emcee
ones (walkers, thinning), and how the engine runs the chains (fold and chain batches, threads,
chunk length, progress), which never change a draw. It is checked when it is made: a bad value is
a :class:`~bayesfric.errors.UserError` whose key names the setting. A variation is a new object
(:meth:`SamplerConfig.replace`); nothing changes a configuration once made.

:meth:`SamplerConfig.from_table` is the one constructor from what a user writes: a study's
``[sampler]`` table, the ``fit`` command's options, ``bayesfric.fit``'s keywords. It refuses an
unknown key, and a key of the other backend, naming the key as its caller spells it (``--draws``).
:data:`RULES` states each setting's kind, range, choices and backend once; the study schema's
``[sampler]`` table (:data:`bayesfric.study.sections.SAMPLER`) is built from it.

>>> config = SamplerConfig.from_table({"draws": 500, "chains": 2})
>>> config.draws, config.tune, config.settings()["chains"]
(500, 1000, 2)
>>> config.replace(target_accept=0.95).target_accept
0.95
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from bayesfric.errors import UserError

__all__ = ["SamplerConfig", "Rule", "RULES", "BACKENDS", "METRICS", "INITS", "CHUNK_STEPS", "default_of", "described"]

#: Sampling backends (:data:`bayesfric.inference.SAMPLERS`).
BACKENDS = ("nuts", "emcee")
#: Mass matrices the NUTS warm-up can estimate.
METRICS = ("diag", "dense", "auto")
#: How NUTS chains that start cold are placed (:mod:`bayesfric.inference.init`).
INITS = ("median", "pathfinder")
#: Schedule rows per compiled call of the engine (:mod:`bayesfric.inference.chunked`): 100 rows of a
#: 1500-2000-row chain, a report every 5-7 % of a chain; a call costs about 0.3 ms.
CHUNK_STEPS = 100

#: Draws and warm-up per backend when not given.
_BACKEND_DEFAULTS = {"nuts": {"draws": 1000, "tune": 1000}, "emcee": {"draws": 2500, "tune": 2500}}


class Rule(NamedTuple):
    """What a setting a user may give must be: its kind (``int``, ``number``, ``str``), bounds
    (``min``/``max`` inclusive, ``gt``/``lt`` exclusive), ``choices``, the backends it applies to
    (``only``), and what it means (``doc``)."""

    kind: str
    doc: str
    min: float | None = None
    max: float | None = None
    gt: float | None = None
    lt: float | None = None
    choices: tuple | None = None
    only: tuple[str, ...] | None = None

    def describe(self) -> str:
        """What a valid value is, as the study schema says it (``an integer ≥ 1``)."""
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        text = {"int": "an integer", "number": "a number", "str": "a non-empty string"}[self.kind]
        low = f"≥ {_num(self.min)}" if self.min is not None else f"> {_num(self.gt)}" if self.gt is not None else ""
        high = f"≤ {_num(self.max)}" if self.max is not None else f"< {_num(self.lt)}" if self.lt is not None else ""
        return " ".join(p for p in (text, low, "and" if low and high else "", high) if p)

    def problem(self, value: Any) -> str | None:
        """Why ``value`` breaks this rule (None if it does not)."""
        numeric = isinstance(value, int | float) and not isinstance(value, bool)
        ok = {"int": isinstance(value, int) and not isinstance(value, bool),
              "number": numeric and math.isfinite(value),
              "str": isinstance(value, str) and value.strip() != ""}[self.kind]
        if ok and numeric:
            ok = not ((self.min is not None and value < self.min) or (self.max is not None and value > self.max)
                      or (self.gt is not None and value <= self.gt) or (self.lt is not None and value >= self.lt))
        if ok and self.choices is not None:
            ok = value in self.choices
        return None if ok else f"must be {self.describe()}, got {described(value)}"


NUTS, EMCEE = ("nuts",), ("emcee",)

#: The settings a user may give (a study's ``[sampler]`` table, ``fit``'s options and keywords).
RULES: dict[str, Rule] = {
    "name": Rule("str", "sampling backend", choices=BACKENDS),
    "seed": Rule("int", "seed of every random draw", min=0, max=2**32 - 1),
    "draws": Rule("int", "draws per chain (emcee: steps before thinning)", min=1),
    "tune": Rule("int", "warm-up draws (emcee: burn-in steps)", min=0),
    "chains": Rule("int", "NUTS chains", min=1, only=NUTS),
    "target_accept": Rule("number", "NUTS target acceptance probability", gt=0, lt=1, only=NUTS),
    "retry_target_accept": Rule("number", "draws with divergent transitions are sampled again at this target "
                                "acceptance (above target_accept); 0 switches the retry off", min=0, lt=1, only=NUTS),
    "metric": Rule("str", "mass matrix of the warm-up: auto (dense where the warm-up finds strong correlations, "
                   "else diagonal), diag, or dense", choices=METRICS, only=NUTS),
    "init": Rule("str", "chain starts: prior medians, or multi-path Pathfinder draws (posteriors with minor modes)",
                 choices=INITS, only=NUTS),
    "walkers": Rule("int", "emcee walkers: at least 2 × free parameters (default max(32, 4 × free parameters))",
                    min=2, only=EMCEE),
    "thin": Rule("int", "emcee thinning", min=1, only=EMCEE),
}
#: Settings of the engine only (not a study's): given in Python, checked, never in a unit's key.
_ENGINE_RULES: dict[str, Rule] = {
    "max_tree_depth": Rule("int", "largest NUTS tree depth (doublings)", min=1),
    "fold_batch": Rule("int", "folds sampled together in one vectorised call", min=1),
    "chain_batch": Rule("int", "chains vectorised in one call (a divisor of chains)", min=1),
    "threads": Rule("int", "calls of the compiled sampler run at once", min=1),
    "chunk_steps": Rule("int", "schedule rows per call of the compiled step", min=1),
}


@dataclass(frozen=True)
class SamplerConfig:
    """Every setting of a fit, checked when made; variations are new objects (:meth:`replace`).

    Parameters
    ----------
    name : {"nuts", "emcee"}
        The backend.
    seed : int
        Seed of every random draw (0 … 2**32 - 1).
    draws, tune : int, optional
        Draws and warm-up per chain (emcee: steps before thinning, burn-in); None: the backend's
        default (NUTS 1000 and 1000, emcee 2500 and 2500).
    chains, target_accept, retry_target_accept, max_tree_depth, metric, init
        NUTS: chains; target acceptance of the step-size adaptation; the target a fold with
        divergent transitions is sampled again at (0 or None: no retry); the largest tree depth;
        the warm-up's mass matrix; how chains that start cold are placed.
    walkers, thin
        emcee: walkers (None: ``max(32, 4 × free parameters)``) and thinning.
    fold_batch, chain_batch, threads, chunk_steps
        How the engine runs the chains (:class:`~bayesfric.inference.engine.NutsEngine`); the draws
        do not depend on them. ``chain_batch`` and ``threads`` None: chosen for the machine.
    progress : bool
        Show the chains' progress while sampling.

    Raises
    ------
    UserError
        A value of the wrong kind or out of range, keyed by the setting (``draws: must be an
        integer ≥ 1, got integer 0``); a retry target not above ``target_accept``.

    Examples
    --------
    A study's settings, then the same with a quicker warm-up (a new object; the first is unchanged):

    >>> study = SamplerConfig(draws=1000, tune=1000, chains=4, seed=0)
    >>> quick = study.replace(tune=300)
    >>> study.tune, quick.tune
    (1000, 300)
    >>> SamplerConfig(draws=0)
    Traceback (most recent call last):
    ...
    bayesfric.errors.UserError: draws: must be an integer ≥ 1, got integer 0
    """

    name: str = "nuts"
    seed: int = 0
    draws: int | None = None
    tune: int | None = None
    chains: int = 4
    target_accept: float = 0.9
    retry_target_accept: float | None = 0.99
    max_tree_depth: int = 10
    metric: str = "auto"
    init: str = "median"
    walkers: int | None = None
    thin: int = 10
    fold_batch: int = 1
    chain_batch: int | None = None
    threads: int | None = None
    chunk_steps: int = CHUNK_STEPS
    progress: bool = field(default=False, compare=False)

    def __post_init__(self):
        for key, rule in (RULES | _ENGINE_RULES).items():
            value = getattr(self, key)
            if value is not None and (problem := rule.problem(value)):
                raise UserError(problem, key)
        for key, default in _BACKEND_DEFAULTS[self.name].items():  # fills the backend's defaults once, here
            if getattr(self, key) is None:
                object.__setattr__(self, key, default)

    def replace(self, **changes: Any) -> SamplerConfig:
        """A new configuration with ``changes`` (checked as any new one); this one is unchanged."""
        return dataclasses.replace(self, **changes)

    @property
    def retry(self) -> float | None:
        """The retry target, None when the retry is off (0 or None) or not above ``target_accept``
        (a target raised to the default retry's 0.99 already: nothing to raise it to)."""
        r = self.retry_target_accept
        return float(r) if r and r > self.target_accept else None

    def settings(self) -> dict[str, Any]:
        """The backend's settings a user may give, as recorded with results and hashed into a
        unit's key: :data:`RULES` of this backend (no name, seed or unset value)."""
        return {k: getattr(self, k) for k, rule in RULES.items()
                if k not in ("name", "seed") and (rule.only is None or self.name in rule.only)
                and getattr(self, k) is not None}

    @classmethod
    def from_table(cls, table: Mapping[str, Any], key: Callable[[str], str] = str) -> SamplerConfig:
        """The configuration of a table of settings: a study's ``[sampler]``, ``fit``'s options
        (None: not given), ``bayesfric.fit``'s keywords.

        Parameters
        ----------
        table : mapping
            Setting -> value; keys of :data:`RULES` (and, from Python, the engine's own settings).
        key : callable
            Names a setting in errors (``--draws`` on the command line).

        Raises
        ------
        UserError
            An unknown setting, one of the other backend, or a bad value, keyed by ``key``.

        Examples
        --------
        >>> SamplerConfig.from_table({"name": "emcee", "walkers": 64}).settings()
        {'draws': 2500, 'tune': 2500, 'walkers': 64, 'thin': 10}
        >>> SamplerConfig.from_table({"walkers": 8}, key=lambda k: "--" + k)
        Traceback (most recent call last):
        ...
        bayesfric.errors.UserError: --walkers: applies only to sampler emcee (here 'nuts')
        """
        given = {k: v for k, v in table.items() if v is not None}
        name = given.get("name", "nuts")
        if problem := RULES["name"].problem(name):
            raise UserError(problem, key("name"))
        known = RULES | _ENGINE_RULES | {"progress": None}
        for k in given:
            if k not in known:
                raise UserError(f"unknown key {k!r} (allowed: {', '.join(RULES)})", key(k))
            only = known[k].only if known[k] is not None else None
            if only is not None and name not in only:
                raise UserError(f"applies only to sampler {' or '.join(only)} (here {name!r})", key(k))
        retry, target = given.get("retry_target_accept"), given.get("target_accept", cls.target_accept)
        numbers = all(isinstance(v, int | float) and not isinstance(v, bool) for v in (retry, target))
        if numbers and retry and retry <= target:  # asked for, and cannot raise the target: say so
            raise UserError(f"must be above target_accept ({target}) or 0 (off), got {retry}",
                            key("retry_target_accept"))
        try:
            return cls(**given)
        except UserError as exc:
            raise UserError(exc.problem, key(exc.key)) from None


def default_of(name: str, setting: str) -> Any:
    """The default of ``setting`` under backend ``name`` (the study schema's defaults)."""
    return getattr(SamplerConfig(name=name), setting)


def _num(value: float) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def described(value: Any) -> str:
    """A value as an error message names what it got (``integer 3``, ``string 'x'``, ``a table``)."""
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    if isinstance(value, int):
        return f"integer {value}"
    if isinstance(value, float):
        return f"number {value:g}"
    if isinstance(value, str):
        return f"string {value!r}" if len(value) <= 60 else f"string {value[:57]!r}..."
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, list):
        return "an array" if value else "an empty array"
    return type(value).__name__
