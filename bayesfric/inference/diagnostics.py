"""The diagnostics gate: one place for the thresholds a posterior must pass to be ranked.

The statistics are arviz-stats' (rank-normalised split R-hat, bulk and tail ESS, E-BFMI). It is
imported on first use, not with this module: it brings scipy.stats along (0.4-0.5 s of the 2 s
a ``bayesfric fit`` spends importing), and a fit needs it only once its chains are sampled. The
NUTS engine calls :func:`import_statistics` right after it hands its programs to the background
compilation threads, so the import runs while they compile, or read the programs back from the
cache (:mod:`bayesfric.exported`), instead of before.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from types import ModuleType

import numpy as np
import xarray as xr

__all__ = ["GATE", "Gate", "Verdict", "check", "verdict_of", "import_statistics"]


def import_statistics() -> ModuleType:
    """arviz-stats, the gate's statistics library (imported on first call; see the module notes)."""
    import arviz_stats

    return arviz_stats


@dataclass(frozen=True)
class Gate:
    """Thresholds of the diagnostics gate (Vehtari et al. 2021 for R-hat/ESS; Betancourt 2016 E-BFMI)."""

    rhat_max: float = 1.01
    ess_bulk_min: float = 400.0
    ess_tail_min: float = 400.0
    divergences_max: int = 0
    ebfmi_min: float = 0.3
    # emcee: healthy affine-invariant ensembles accept ~20-50 % (Foreman-Mackey et al. 2013)
    acceptance_min: float = 0.15


GATE = Gate()


@dataclass
class Verdict:
    """Outcome of the gate. ``passed`` is False if any check failed; ``problems`` says which."""

    passed: bool
    rhat_max: float
    ess_bulk_min: float
    ess_tail_min: float
    divergences: int | None
    ebfmi_min: float | None
    acceptance_mean: float | None
    problems: list[str] = field(default_factory=list)

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @staticmethod
    def from_json(text: str) -> Verdict:
        return Verdict(**json.loads(text))

    def __str__(self) -> str:
        head = "PASSED" if self.passed else "FAILED"
        parts = [f"R-hat max {self.rhat_max:.3f}", f"ESS bulk min {self.ess_bulk_min:.0f}",
                 f"ESS tail min {self.ess_tail_min:.0f}"]
        if self.divergences is not None:
            parts.append(f"divergences {self.divergences}")
        if self.ebfmi_min is not None:
            parts.append(f"E-BFMI min {self.ebfmi_min:.2f}")
        if self.acceptance_mean is not None:
            parts.append(f"acceptance {self.acceptance_mean:.2f}")
        text = f"{head}: " + ", ".join(parts)
        if self.problems:
            text += " -- " + "; ".join(self.problems)
        return text


def _min_over(ds: xr.Dataset) -> float:
    vals = [np.nanmin(np.asarray(v.values, dtype=float)) for v in ds.data_vars.values() if v.size]
    return float(np.min(vals)) if vals else float("nan")


def _max_over(ds: xr.Dataset) -> float:
    vals = [np.nanmax(np.asarray(v.values, dtype=float)) for v in ds.data_vars.values() if v.size]
    return float(np.max(vals)) if vals else float("nan")


def check(dt: xr.DataTree, var_names: list[str] | None = None, gate: Gate = GATE) -> Verdict:
    """Apply the gate to a fit's posterior (all sampled and derived variables by default)."""
    arviz_stats = import_statistics()
    post = dt["posterior"].to_dataset()
    names = var_names or [v for v in post.data_vars if v != "group_offset"]
    sub = post[names]
    rhat = _max_over(arviz_stats.rhat(sub))
    ess_bulk = _min_over(arviz_stats.ess(sub, method="bulk"))
    ess_tail = _min_over(arviz_stats.ess(sub, method="tail"))
    problems = []
    if not rhat <= gate.rhat_max:
        problems.append(f"R-hat {rhat:.3f} > {gate.rhat_max}")
    if not ess_bulk >= gate.ess_bulk_min:
        problems.append(f"bulk ESS {ess_bulk:.0f} < {gate.ess_bulk_min:.0f}")
    if not ess_tail >= gate.ess_tail_min:
        problems.append(f"tail ESS {ess_tail:.0f} < {gate.ess_tail_min:.0f}")
    divergences = ebfmi = acceptance = None
    stats = dt["sample_stats"].to_dataset() if "sample_stats" in dt.children else xr.Dataset()
    if "diverging" in stats:
        divergences = int(stats["diverging"].sum())
        if divergences > gate.divergences_max:
            problems.append(f"{divergences} divergent transitions")
    if "energy" in stats:
        ebfmi = float(np.min(np.asarray(arviz_stats.bfmi(dt)["energy"].values)))
        if not ebfmi >= gate.ebfmi_min:
            problems.append(f"E-BFMI {ebfmi:.2f} < {gate.ebfmi_min}")
    if "acceptance_fraction" in stats:
        acceptance = float(stats["acceptance_fraction"].mean())
        if not acceptance >= gate.acceptance_min:
            problems.append(f"acceptance {acceptance:.2f} < {gate.acceptance_min}")
    return Verdict(not problems, rhat, ess_bulk, ess_tail, divergences, ebfmi, acceptance, problems)


def verdict_of(dt: xr.DataTree) -> Verdict:
    """The verdict stored with a fit (attrs ``diagnostics``)."""
    return Verdict.from_json(dt.attrs["diagnostics"])
