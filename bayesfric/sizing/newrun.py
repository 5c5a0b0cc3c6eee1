"""Answers for a new run when the runs differ: never from a law blind to a group the data flagged.

A study's residual-structure check (:mod:`bayesfric.compare.structure`) tests each law's
residuals against every group column (run, series, unit) at the same operating point. When it
flags a column on a law that does not model it (no ``vary_by`` on it, no ``[noise] group``),
that law describes an average over the tested runs, and its band is the band of that average:
the next run lies off it by the between-run difference the check measured. An answer for a new
run (the default of sizing, ``predict`` and ``score``) then follows one rule, :func:`rule`:

``aware``
    Some law that models every flagged column passed the gate (or is used as multimodal or
    unidentified): the new-run answer comes from those laws only; the blind ones are shown,
    with weight 0.
``cannot``
    Laws that model the column were fitted, and every one FAILED the gate: the answer says that
    it CANNOT answer for a new run, before any number; the numbers below it are the pooled laws
    widened as under ``widened``, marked as such.
``widened``
    No law models the column: each pooled law's draws are widened by the between-group spread
    its check measured, one factor per draw, ``exp(t · r · √(1 + 1/G))`` with ``t`` Student-t
    with ``G − 1`` degrees of freedom (the textbook prediction interval of a new group's mean
    from ``G`` group means: with two runs the spread itself is known to one degree of freedom,
    so the band is wide) and ``r`` the check's between-group sd relative to the data's mean
    ``|response|`` (factors cut at :data:`MAX_LOG_FACTOR`). Approximation: the spread is taken
    as a factor common to every operating point (a run whose Coulomb level and viscous
    coefficient differ by the same factor); a run effect that grows beyond the data faster than
    the friction does is not covered.

Every answer for a new run says which, first (:attr:`NewRun.statement`).

Examples
--------
>>> from bayesfric.compare.structure_stats import StructureCheck
>>> flag = StructureCheck("run", "group", 2, 0.3, 6.0, 1e-6, 0.05, True, "", "N*m", "velocity", 0.0, 1, 0.2)
>>> pooled = LawGroups("coulomb_viscous", frozenset(), True, (flag,), 2.0)
>>> by_run = LawGroups("cv_by_run", frozenset({"run"}), True, (), 2.0)
>>> r = rule([pooled, by_run])
>>> r.mode, r.aware, r.names(["coulomb_viscous", "cv_by_run"])
('aware', ('cv_by_run',), ['cv_by_run'])
"""

from __future__ import annotations

import json
import math
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

#: Largest |log| of a widening factor: the Student-t with one degree of freedom (two levels) has
#: draws beyond any float's range; factors beyond 10⁶ are cut there (with two levels 20 % apart,
#: quantiles above about 99.4 % reach the cut: an answer the statement already calls no answer).
MAX_LOG_FACTOR = math.log(1e6)

__all__ = ["MAX_LOG_FACTOR", "LawGroups", "NewRun", "rule", "law_groups", "modelled_columns", "widen_draws",
           "relative_spread"]


@dataclass(frozen=True)
class LawGroups:
    """What the new-run rule needs of one law: the group columns it models, whether it may be
    used (its gate), its residual-structure checks and the data's mean ``|response|``."""

    name: str
    models: frozenset[str]
    usable: bool
    checks: tuple = ()
    response_scale: float = math.nan

    def flagged(self) -> dict[str, object]:
        """Its flagged group columns that it does not model, column -> check."""
        return {c.column: c for c in self.checks
                if c.kind == "group" and c.flagged and c.column not in self.models}


def modelled_columns(attrs: Mapping) -> frozenset[str]:
    """The group columns a fit models, from its attrs: ``vary_by`` columns of its law's recipe
    and its noise model's ``group``."""
    recipe = json.loads(attrs.get("law_recipe") or "{}")
    noise = json.loads(attrs.get("noise") or "{}").get("group")
    return frozenset(recipe.get("vary_by", {})) | ({str(noise)} if noise else set())


def law_groups(name: str, fit, usable: bool, checks: Sequence = ()) -> LawGroups:
    """:class:`LawGroups` of a fit (its attrs and observed response)."""
    scale = math.nan
    if "observed_data" in getattr(fit, "children", {}):
        observed = fit["observed_data"].to_dataset()
        if observed.data_vars:
            values = np.abs(np.asarray(next(iter(observed.data_vars.values())).values, dtype=float))
            scale = float(np.nanmean(values)) if values.size else math.nan
    return LawGroups(name, modelled_columns(fit.attrs), bool(usable), tuple(checks), scale)


def relative_spread(check, response_scale: float) -> float:
    """A flagged group column's between-group sd relative to the mean ``|response|`` (the
    check's range over √2 where it kept no sd: a result written before it did)."""
    sd = float(getattr(check, "between_sd", math.nan))
    if not math.isfinite(sd):
        sd = float(check.effect) / math.sqrt(2.0)
    return sd / response_scale if response_scale > 0 else math.nan


def widen_draws(mu: np.ndarray, rel: float, levels: int, seed: int = 0, name: str = "") -> np.ndarray:
    """``mu`` (draws first) times one factor per draw, ``exp(t · rel · √(1 + 1/G))``, ``t``
    Student-t with ``G − 1`` degrees of freedom (the module's ``widened``); unchanged when ``rel``
    is not a positive number or fewer than two levels were seen.

    >>> mu = np.ones((4000, 3))
    >>> w = widen_draws(mu, 0.1, 5, seed=1)
    >>> bool(np.allclose(w[:, 0], w[:, 2])), 0.1 < float(np.std(np.log(w[:, 0]))) < 0.2
    (True, True)
    """
    if not (math.isfinite(rel) and rel > 0 and levels >= 2):
        return mu
    rng = np.random.default_rng([int(seed), zlib.crc32(("new run " + name).encode())])
    shape = mu.shape[:-1] + (1,)
    t = rng.standard_t(levels - 1, size=shape)
    return mu * np.exp(np.clip(t * rel * math.sqrt(1.0 + 1.0 / levels), -MAX_LOG_FACTOR, MAX_LOG_FACTOR))


@dataclass(frozen=True)
class NewRun:
    """The new-run rule for one set of laws (see the module): the flagged columns, the laws that
    model them (``aware``: usable; ``failed``: not), the blind usable ones, and each blind law's
    relative spread and level count per flagged column."""

    columns: tuple[str, ...] = ()
    levels: Mapping[str, int] = field(default_factory=dict)
    aware: tuple[str, ...] = ()
    failed: tuple[str, ...] = ()
    blind: tuple[str, ...] = ()
    spreads: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    effects: Mapping[str, str] = field(default_factory=dict)

    @property
    def mode(self) -> str:
        """``""`` (no flagged column), ``"aware"``, ``"cannot"`` or ``"widened"``."""
        if not self.columns:
            return ""
        return "aware" if self.aware else "cannot" if self.failed else "widened"

    def names(self, used: Sequence[str]) -> list[str]:
        """The laws of ``used`` a new-run answer may weigh: the aware ones under ``aware``."""
        return [n for n in used if n in self.aware] if self.mode == "aware" else list(used)

    def widened(self, name: str) -> bool:
        """Whether ``name``'s draws are widened for a new run (a blind law outside ``aware``)."""
        return self.mode in ("cannot", "widened") and name in self.spreads

    def widen(self, name: str, mu: np.ndarray, seed: int = 0) -> np.ndarray:
        """``name``'s draws widened by each flagged column's spread (unchanged if not :meth:`widened`)."""
        if not self.widened(name):
            return mu
        for column, rel in self.spreads[name].items():
            mu = widen_draws(mu, rel, self.levels[column], seed, f"{name} {column}")
        return mu

    @property
    def statement(self) -> str:
        """What a new-run answer says first (``""`` without a flagged column)."""
        if not self.columns:
            return ""
        cols = " and ".join(f"'{c}'" for c in self.columns)
        seen = "; ".join(f"{self.levels[c]} levels of '{c}' differ by up to {self.effects[c]}" for c in self.columns)
        found = f"the residual-structure check found that the tested {seen} at the same operating point"
        if self.mode == "aware":
            left = (f"; {', '.join(self.blind)} (blind to it) {'is' if len(self.blind) == 1 else 'are'} left out"
                    if self.blind else "")
            return (f"FOR A NEW {cols}: {found}; this answer comes only from the laws that model {cols} "
                    f"({', '.join(self.aware)}){left}")
        spread = "; ".join(f"{n}: {', '.join(f'{r:.1%} sd between the levels of {c!r}' for c, r in s.items())}"
                           for n, s in self.spreads.items())
        widened = (f"the pooled laws' draws are widened by that spread ({spread}; Student-t with levels − 1 degrees "
                   "of freedom, so two levels give a very wide band)")
        if self.mode == "cannot":
            return (f"CANNOT ANSWER FOR A NEW {cols}: {found}, and every law that models {cols} "
                    f"({', '.join(self.failed)}) FAILED the diagnostics gate; the numbers below are not an answer "
                    f"for a new {cols}: {widened}")
        return (f"FOR A NEW {cols}: {found}, and no law models {cols}: {widened}; "
                f"a law with `vary_by = {{ {self.columns[0]} = [...] }}` would model it")


def rule(laws: Sequence[LawGroups]) -> NewRun:
    """The new-run rule (see the module) over every law of a study or prediction.

    A column counts as flagged when at least half of the usable laws that do not model it have it
    flagged (a column only the worst law shows is that law's misfit, not a difference between
    runs the better laws missed); a law is *aware* when it models every flagged column.
    """
    flagged: dict[str, list] = {}
    for law in laws:
        if law.usable:
            for column, check in law.flagged().items():
                flagged.setdefault(column, []).append((law, check))
    blind = {c: sum(1 for law in laws if law.usable and c not in law.models and c in {k.column for k in law.checks})
             for c in flagged}
    flagged = {c: found for c, found in flagged.items() if 2 * len(found) >= blind[c]}
    if not flagged:
        return NewRun()
    columns = tuple(flagged)
    levels = {c: max(check.levels for _, check in found) for c, found in flagged.items()}
    effects = {c: f"{max(check.effect for _, check in found):.2g} {found[0][1].unit}".strip().replace("*", "·")
               for c, found in flagged.items()}
    modelling = [law for law in laws if set(columns) <= law.models]
    spreads = {}
    for law in laws:
        if law.usable and not set(columns) <= law.models:
            own = {c: check for c, check in law.flagged().items() if c in columns}
            spreads[law.name] = {c: relative_spread(check, law.response_scale) for c, check in own.items()}
            spreads[law.name] = {c: r for c, r in spreads[law.name].items() if math.isfinite(r)}
    return NewRun(columns, levels, tuple(w.name for w in modelling if w.usable),
                  tuple(w.name for w in modelling if not w.usable), tuple(spreads), spreads, effects)
