"""The validated study as plain types: :class:`Study` with its :class:`LawSpec` and
:class:`BlockedSpec` entries, and :class:`StudyError`.

What a study file may say and how it is checked: :mod:`bayesfric.study.config` (which re-exports
these names), with the schema tables of :mod:`bayesfric.study.sections`. These types sit below the
claims' evaluation, the law × metric table and the result tree, which all read a :class:`Study`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bayesfric.errors import UserError
from bayesfric.inference.config import SamplerConfig
from bayesfric.laws import Law, get_law
from bayesfric.laws.plugins import load_modules
from bayesfric.laws.variants import vary
from bayesfric.model import Noise
from bayesfric.priors import Prior
from bayesfric.sizing.points import SizingQuestion
from bayesfric.study.claimspec import Claim

__all__ = ["StudyError", "LawSpec", "BlockedSpec", "Study"]


class StudyError(UserError):
    """A study file error: one line naming the file and key."""


@dataclass(frozen=True)
class LawSpec:
    """A candidate law with its overrides and variant options (:mod:`bayesfric.laws.variants`).

    ``name`` is the entry's label -- what fits, tables and the result tree call it (the law's
    name unless the entry gives ``label``); ``law`` is the registered law it is built from.
    """

    name: str
    priors: dict[str, Prior] = field(default_factory=dict)
    constants: dict[str, float] = field(default_factory=dict)
    law: str = ""
    fixed: dict[str, float] = field(default_factory=dict)
    add: tuple[str, ...] = ()
    asymmetric: tuple[str, ...] = ()
    vary_by: dict[str, tuple[str, ...]] = field(default_factory=dict)  # group terms (bayesfric.hierarchy)
    trend: dict[str, tuple[str, ...]] = field(default_factory=dict)  # trends over campaigns (bayesfric.trend)
    trend_form: str | None = None
    metric: str | None = None  # this law's NUTS mass matrix, over [sampler] metric
    modules: tuple[str, ...] = ()  # the study's law files (absolute): loaded before the name is resolved
    companion_of: str = ""  # added by the study: the reduced variant of this entry (bayesfric.identifiability)

    def config(self, study: SamplerConfig) -> SamplerConfig:
        """The sampler configuration this law runs with: the study's, with the entry's own metric."""
        return study if self.metric is None else study.replace(metric=self.metric)

    def build(self) -> Law:
        """The entry's law: the registered law with its options applied, named by the label.

        Built once per process and kept on the entry: the study's checks, claims, unit keys and
        every unit of the law use the same :class:`~bayesfric.laws.Law` object. The entry's
        ``constants`` and ``fixed`` values enter here only (held as the law's constants). A
        pickled entry (sent to a ``main --jobs`` process or a Dask worker) carries its recipe,
        not the law: the study's law files are loaded there first (once per process) and the law
        is built again from them.
        """
        built = self.__dict__.get("_built")
        if built is None:
            load_modules(self.modules)
            built = vary(get_law(self.law or self.name), name=self.name, add=self.add,
                         asymmetric=self.asymmetric, fixed=self.constants | self.fixed, vary_by=self.vary_by,
                         trend=self.trend, trend_form=self.trend_form)
            object.__setattr__(self, "_built", built)  # a cache, not a field: frozen otherwise
        return built

    def __getstate__(self) -> dict[str, Any]:
        """The recipe without the built law: a law's functions may come from a law file that
        the receiving process has not loaded yet (:meth:`build` loads it)."""
        return {k: v for k, v in self.__dict__.items() if k != "_built"}


@dataclass(frozen=True)
class BlockedSpec:
    """A blocked extrapolation fold along an operating input."""

    axis: str
    direction: str = "upper"
    threshold: float | None = None
    quantile: float | None = None
    label: str = ""
    future: bool = False  # leave-future-out: split inside each trajectory (compare.folds)

    def describe(self) -> str:
        cut = f"{self.threshold:g}" if self.threshold is not None else f"q{self.quantile:g}"
        arrow = "train ≤ cut, score above" if self.direction == "upper" else "train ≥ cut, score below"
        if self.future:
            arrow = "each trajectory's past trains, its future beyond the cut is scored"
        return self.label or f"{self.axis} {cut} ({arrow})"


@dataclass
class Study:
    """A validated study (``sampler``: every setting of the chosen sampler, defaults filled)."""

    path: Path
    name: str
    title: str
    question: str
    dataset: str
    select: dict[str, Any]
    noise: Noise
    sampler: dict[str, Any]
    laws: list[LawSpec]
    loo: bool = True
    kfold: int = 0
    grouped: str | None = None
    forecast: str | None = None  # leave-future-out over campaigns (compare.forecast_masks)
    forecast_first: int = 2
    evidence: bool = True
    smc: bool = False  # opt-in reference: tempered SMC costs 3-13x the fit (bench_evidence.py)
    smc_particles: int = 300  # tempered SMC: within ~0.1 nat of bridge sampling at ~1/5 the cost of 1000
    smc_runs: int = 3
    blocked: list[BlockedSpec] = field(default_factory=list)
    include_failed: bool = False
    failed_fits: str = "skip"  # a law whose full fit failed the gate: "skip" its CV and evidence, or "run" them
    sizing: list[SizingQuestion] = field(default_factory=list)
    claims: list[Claim] = field(default_factory=list)
    raw: dict[str, Any] = field(default_factory=dict)
    every: int = 1  # [data] every: keep every n-th row (datasets.views.thin)
    max_levels: int = 100  # [data] max_levels: most levels of a group column run without being confirmed
    companions: bool = True  # [compare] companions: add a reduced variant where the data do not identify a law
    identifiability: list = field(default_factory=list)  # identifiability.Check per law, filled by study.plan

    @property
    def sampler_config(self) -> SamplerConfig:
        """The study's sampler configuration: its ``[sampler]`` table, checked when the file loaded."""
        return SamplerConfig.from_table(self.sampler)
