"""Study files: parse and validate a study TOML into a :class:`Study`.

A study names a data set, candidate laws (with prior overrides and constants), the noise model,
sampler settings, comparison methods and extrapolation folds::

    [study]
    name = "robot_joint"
    title = "Stäubli RX90 joint 1"
    question = "Which law, fitted on 0-0.5 rad/s, predicts the torque above 0.5 rad/s?"

    [data]
    dataset = "robot_joint"            # built-in name or a CSV path (relative to the study file)
    select = { series = [1, 2, 3] }    # optional row selection on coordinates

    [noise]
    kind = "normal"                    # normal | student_t | proportional
    group = "series"                   # optional partial-pooled offsets

    [sampler]
    draws = 1000
    tune = 1000
    chains = 4
    seed = 0

    [[laws]]
    name = "armstrong_helouvry"
    priors = { delta = { dist = "LogNormal", loc = -1.1, scale = 0.3 } }

    [compare]
    loo = true
    kfold = 10                         # 0 disables
    grouped = "series"                 # optional leave-one-group-out
    evidence = true                    # bridge sampling + tempered SMC (two estimators)
    smc_particles = 300                # SMC particles per run (default 300)
    smc_runs = 3                       # independent SMC runs; their spread gives the MC error

    [[compare.blocked]]
    axis = "velocity"                  # any input coordinate of the data
    threshold = 0.5                    # SI units; or quantile = 0.7
    direction = "upper"                # train below, score above; "lower" for high -> low

Every error is a :class:`StudyError` with one line naming the file and the key.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bayesfric.errors import UserError
from bayesfric.laws import get_law
from bayesfric.model import NOISE_PRIORS, Noise
from bayesfric.priors import Prior, PriorError

__all__ = ["StudyError", "Study", "LawSpec", "BlockedSpec", "load_study"]


class StudyError(UserError):
    """A study file error: one line naming the file and key."""


@dataclass(frozen=True)
class LawSpec:
    """A candidate law with its overrides."""

    name: str
    priors: dict[str, Prior] = field(default_factory=dict)
    constants: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class BlockedSpec:
    """A blocked extrapolation fold along an operating input."""

    axis: str
    direction: str = "upper"
    threshold: float | None = None
    quantile: float | None = None
    label: str = ""

    def describe(self) -> str:
        cut = f"{self.threshold:g}" if self.threshold is not None else f"q{self.quantile:g}"
        arrow = "train ≤ cut, score above" if self.direction == "upper" else "train ≥ cut, score below"
        return self.label or f"{self.axis} {cut} ({arrow})"


@dataclass
class Study:
    """A validated study."""

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
    evidence: bool = True
    smc_particles: int = 300  # tempered SMC: within ~0.1 nat of bridge sampling at ~1/5 the cost of 1000
    smc_runs: int = 3
    blocked: list[BlockedSpec] = field(default_factory=list)
    include_failed: bool = False
    raw: dict[str, Any] = field(default_factory=dict)


_TOP = {"study", "data", "noise", "sampler", "laws", "compare"}
_SAMPLER = {"name", "draws", "tune", "chains", "seed", "target_accept"}
_COMPARE = {"loo", "kfold", "grouped", "evidence", "blocked", "include_failed", "smc_particles", "smc_runs"}


def _check_keys(where: str, table: dict, allowed: set[str]) -> None:
    for key in table:
        if key not in allowed:
            raise StudyError(f"{where}: unknown key {key!r} (allowed: {', '.join(sorted(allowed))})")


def load_study(path: str | Path) -> Study:
    """Parse and validate a study file (data-dependent checks happen in the runner).

    Raises
    ------
    StudyError
        Invalid TOML, unknown keys, unknown law, unknown parameter in an override, bad values.
    """
    path = Path(path)
    if not path.exists():
        raise StudyError(f"{path}: study file not found")
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{path}: invalid TOML: {exc}") from None
    _check_keys(str(path), raw, _TOP)
    meta = raw.get("study", {})
    _check_keys(f"{path}: [study]", meta, {"name", "title", "question"})
    data = raw.get("data")
    if not data or "dataset" not in data:
        raise StudyError(f"{path}: [data] dataset is required")
    _check_keys(f"{path}: [data]", data, {"dataset", "select"})
    dataset = data["dataset"]
    if dataset.endswith(".csv"):
        dataset = str((path.parent / dataset).resolve())

    noise_raw = raw.get("noise", {})
    _check_keys(f"{path}: [noise]", noise_raw, {"kind", "group"})
    try:
        noise = Noise(kind=noise_raw.get("kind", "normal"), group=noise_raw.get("group"))
    except ValueError as exc:
        raise StudyError(f"{path}: [noise] kind: {exc}") from None

    sampler = raw.get("sampler", {})
    _check_keys(f"{path}: [sampler]", sampler, _SAMPLER)
    if sampler.get("name", "nuts") not in ("nuts", "emcee"):
        raise StudyError(f"{path}: [sampler] name {sampler['name']!r} must be 'nuts' or 'emcee'")

    laws = []
    if not raw.get("laws"):
        raise StudyError(f"{path}: at least one [[laws]] entry is required")
    for i, entry in enumerate(raw["laws"]):
        where = f"{path}: laws[{i}]"
        _check_keys(where, entry, {"name", "priors", "constants"})
        if "name" not in entry:
            raise StudyError(f"{where}: 'name' is required")
        try:
            law = get_law(entry["name"])
        except KeyError as exc:
            raise StudyError(f"{where}.name: {exc.args[0]}") from None
        known = set(law.params) | set(NOISE_PRIORS)
        priors = {}
        for pname, spec in entry.get("priors", {}).items():
            if pname not in known:
                raise StudyError(
                    f"{where}.priors.{pname}: law {law.name!r} has no parameter {pname!r} "
                    f"(parameters: {', '.join(law.params)}; noise: {', '.join(NOISE_PRIORS)})"
                )
            try:
                priors[pname] = Prior.from_dict(spec)
            except (PriorError, TypeError) as exc:
                raise StudyError(f"{where}.priors.{pname}: {exc}") from None
        constants = entry.get("constants", {})
        for cname in constants:
            if cname not in law.constants:
                raise StudyError(f"{where}.constants.{cname}: law {law.name!r} has no constant {cname!r}")
        laws.append(LawSpec(law.name, priors, {k: float(v) for k, v in constants.items()}))
    names = [w.name for w in laws]
    if len(set(names)) != len(names):
        raise StudyError(f"{path}: laws: a law is listed twice")

    compare = raw.get("compare", {})
    _check_keys(f"{path}: [compare]", compare, _COMPARE)
    blocked = []
    for i, b in enumerate(compare.get("blocked", [])):
        where = f"{path}: compare.blocked[{i}]"
        _check_keys(where, b, {"axis", "direction", "threshold", "quantile", "label"})
        if "axis" not in b:
            raise StudyError(f"{where}: 'axis' is required")
        if ("threshold" in b) == ("quantile" in b):
            raise StudyError(f"{where}: give exactly one of 'threshold' or 'quantile'")
        if b.get("direction", "upper") not in ("upper", "lower"):
            raise StudyError(f"{where}.direction: must be 'upper' or 'lower'")
        if "quantile" in b and not 0 < b["quantile"] < 1:
            raise StudyError(f"{where}.quantile: must lie in (0, 1)")
        blocked.append(BlockedSpec(b["axis"], b.get("direction", "upper"), b.get("threshold"),
                                   b.get("quantile"), b.get("label", "")))
    kfold = int(compare.get("kfold", 0))
    if kfold == 1 or kfold < 0:
        raise StudyError(f"{path}: compare.kfold: must be 0 (off) or ≥ 2")
    return Study(
        path=path,
        name=meta.get("name", path.stem),
        title=meta.get("title", path.stem),
        question=meta.get("question", ""),
        dataset=dataset,
        select=data.get("select", {}),
        noise=noise,
        sampler={"name": "nuts", **sampler},
        laws=laws,
        loo=bool(compare.get("loo", True)),
        kfold=kfold,
        grouped=compare.get("grouped"),
        evidence=bool(compare.get("evidence", True)),
        smc_particles=int(compare.get("smc_particles", 300)),
        smc_runs=int(compare.get("smc_runs", 3)),
        blocked=blocked,
        include_failed=bool(compare.get("include_failed", False)),
        raw=raw,
    )
