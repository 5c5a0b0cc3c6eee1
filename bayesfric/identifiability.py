"""What the data can determine of a stateful law, checked before fitting.

Each hysteresis law's notes (:mod:`bayesfric.laws.hysteresis`, :mod:`bayesfric.laws.slip`) say
what identifies its parameters: "F_c, F_ratio, v_s need steady data spanning v_s", "σ1 needs
fast, finely sampled reversals", "γ needs ≥ 2 preloads" ... This module makes those sentences
checks on a data set: :data:`REQUIREMENTS` maps a law family to its :class:`Requirement` s, each
naming the parameters it concerns, what it needs, and a check that *measures* the data
(:class:`Motion`: speeds, travel per sample, reversals, preloads) against the law's prior medians
on this data (its data-scaled priors, :func:`bayesfric.model.build_program`). The measures are
design checks: they say whether the data *could* pin a parameter, not whether the posterior did
(a law whose true Stribeck drop is nil leaves v_s open on any design).

What is measured:

* **steady speeds** -- rows whose speed changes by at most :data:`STEADY_CHANGE` (5 %) from the
  row before, in the same direction; their 5–95 % range. The Gaussian Stribeck factor
  e^(−(v/v_s)²) falls from 0.9 to 0.1 over a factor 4.7 in speed, and v_s is not known to within
  that before fitting, so F_c, F_s and v_s need steady speeds over :data:`STRIBECK_SPAN` (a
  decade); σ2 needs them to vary by :data:`VISCOUS_SPAN` (2×), else σ2·v is collinear with F_c.
* **samples within the pre-sliding deflection after each reversal** -- the rows whose travel
  since the last reversal (or trajectory start) is within F_c/σ0 at the prior medians (LuGre,
  elasto-plastic: ≥ :data:`PRESLIDING_SAMPLES`) or within the elements' largest break-away
  deflection Δ_N (Maxwell-slip, GMS: ≥ :data:`PRESLIDING_SAMPLES` per element); median over the
  reversals.
* **strokes** -- travel between reversals against Dahl's knee x_c (saturating loops: ≥ 10 x_c).
* **preloads** -- distinct values of the ``preload`` input (γ, κ: ≥ 2).

:func:`assess` returns one :class:`Check` per requirement whose parameters the law (as it runs
on the data) still samples; :func:`reduction` gives the fixed values of the law's *reduced
variant* where a requirement with a reduction failed (LuGre and elasto-plastic with F_s = F_c,
GMS with F_s − F_c ≈ 0 -- v_s then has no effect and is fixed at its prior median --; γ, κ = 0 at
one preload), which a study adds as a companion entry (:mod:`bayesfric.study.plan`);
:func:`checks_dataset` stores the checks as the result tree's ``/identifiability`` node.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import xarray as xr
from scipy import stats

from bayesfric.datasets.views import trajectory_starts
from bayesfric.laws.base import Law
from bayesfric.priors import Prior

__all__ = ["Requirement", "Check", "Motion", "REQUIREMENTS", "requirements_for", "assess", "reduction",
           "checks_dataset", "checks_of", "describe", "companions_of", "unidentified", "prior_median",
           "STEADY_CHANGE", "STRIBECK_SPAN", "VISCOUS_SPAN", "PRESLIDING_SAMPLES"]

STEADY_CHANGE = 0.05  # a steady row's speed differs by at most 5 % from the row before
STRIBECK_SPAN = 10.0  # steady speeds over a decade: F_c, F_s, v_s
VISCOUS_SPAN = 2.0  # steady speeds varying by 2x: σ2 apart from F_c
PRESLIDING_SAMPLES = 5  # samples within the pre-sliding deflection after a reversal (per element)
SATURATION = 10.0  # Dahl: strokes of 10 x_c saturate (the law's notes: ±10 x_c)
RATIO_ONE = 1.0 - 1e-9  # F_c/F_s of the reduced variant: F_s = F_c to 1e-9 (exactly 1 divides by 0 in σ1)


@dataclass(frozen=True)
class Motion:
    """What the checks read from a data set (:meth:`of`): per row, |speed| (NaN where the data
    have none), |travel| since the row before, whether a reversal (or a trajectory start) is at
    the row, whether the row slides steadily, and the distinct preloads."""

    speed: np.ndarray
    step: np.ndarray
    reversal: np.ndarray
    steady: np.ndarray
    preloads: np.ndarray
    position_unit: str  # "m" or "rad"
    has_motion: bool

    @classmethod
    def of(cls, ds: xr.Dataset) -> Motion:
        """The motion of ``ds`` (inputs as coordinates named by quantity; trajectories from attrs)."""
        n = int(ds.sizes["obs"])
        starts = trajectory_starts(ds)
        rotary = "velocity" in ds.coords or "angle" in ds.coords
        v = _coord(ds, "velocity" if rotary else "linear_velocity")
        x = _coord(ds, "angle" if rotary else "displacement")
        t = _coord(ds, "time")
        if x is not None:
            signed = np.where(starts, 0.0, np.diff(x, prepend=x[:1]))
        elif v is not None and t is not None:
            signed = np.where(starts, 0.0, 0.5 * (v + np.r_[v[:1], v[:-1]]) * np.diff(t, prepend=t[:1]))
        else:
            signed = np.zeros(n)
        if v is None and x is not None and t is not None:
            dt = np.diff(t, prepend=t[:1])
            v = np.where(starts | (dt <= 0), np.nan, signed / np.where(dt > 0, dt, 1.0))
        speed = np.abs(v) if v is not None else np.full(n, np.nan)
        direction = np.sign(signed)
        last = _carried(direction)  # the direction of the last move before each row
        reversal = starts | ((direction != 0) & (np.r_[0.0, last[:-1]] != 0) & (direction != np.r_[0.0, last[:-1]]))
        before = np.r_[np.nan, speed[:-1]]
        steady = ~starts & (speed > 0) & (np.abs(speed - before) <= STEADY_CHANGE * speed) & (direction != 0)
        preload = _coord(ds, "preload")
        preloads = np.unique(np.round(preload, 9)) if preload is not None else np.array([])
        return cls(speed, np.abs(signed), reversal, steady, preloads, "rad" if rotary else "m",
                   bool(np.any(signed != 0)))

    def steady_range(self) -> tuple[float, float] | None:
        """5 % and 95 % quantiles of the steady rows' speeds (None: fewer than 3 steady rows)."""
        s = self.speed[self.steady & np.isfinite(self.speed)]
        return (float(np.quantile(s, 0.05)), float(np.quantile(s, 0.95))) if s.size >= 3 else None

    def samples_within(self, deflection: float) -> tuple[float, int]:
        """Median number of rows within ``deflection`` of travel after each reversal, and the
        number of reversals."""
        segment = np.cumsum(self.reversal)
        since = self.step.copy()
        since[self.reversal] = 0.0
        travelled = _segment_cumsum(since, segment)
        counts = np.bincount(segment, weights=((travelled <= deflection) & ~self.reversal).astype(float))[1:]
        return (float(np.median(counts)) if counts.size else 0.0), int(counts.size)

    def strokes(self) -> np.ndarray:
        """Travel between successive reversals (each trajectory's last, unfinished one left out
        when there are others)."""
        segment = np.cumsum(self.reversal)
        total = np.bincount(segment, weights=np.where(self.reversal, 0.0, self.step))[1:]
        return total[total > 0]


def _coord(ds: xr.Dataset, name: str) -> np.ndarray | None:
    return np.asarray(ds[name].values, dtype=float) if name in ds.coords else None


def _carried(direction: np.ndarray) -> np.ndarray:
    """Each row's last nonzero direction up to and including it (0 before the first move)."""
    idx = np.where(direction != 0, np.arange(direction.size), -1)
    idx = np.maximum.accumulate(idx)
    return np.where(idx >= 0, direction[np.maximum(idx, 0)], 0.0)


def _segment_cumsum(values: np.ndarray, segment: np.ndarray) -> np.ndarray:
    total = np.cumsum(values)
    first = np.r_[0, np.flatnonzero(np.diff(segment)) + 1]
    offset = np.repeat(total[first] - values[first], np.diff(np.r_[first, values.size]))
    return total - offset


def prior_median(prior: Prior) -> float:
    """The median of an absolute (resolved) prior."""
    a = prior.args
    known = {"LogNormal": lambda: math.exp(a["loc"]), "HalfNormal": lambda: 0.6744897501960817 * a["scale"],
             "Normal": lambda: a["loc"], "Uniform": lambda: 0.5 * (a["low"] + a["high"]),
             "Beta": lambda: stats.beta.median(a["concentration1"], a["concentration0"]),
             "Gamma": lambda: stats.gamma.median(a["concentration"], scale=1.0 / a["rate"])}
    if prior.dist in known:
        return float(known[prior.dist]())
    import jax  # only for a distribution without a closed-form median above

    draws = np.asarray(prior.to_numpyro().sample(jax.random.PRNGKey(0), (4001,)))
    return float(np.median(draws.reshape(4001, -1)[:, 0]))


@dataclass(frozen=True)
class Check:
    """One requirement on one law and data set: ``holds`` (None: not measurable on this data),
    the ``measured`` reason, and the values the reduced variant fixes where it fails."""

    law: str
    params: tuple[str, ...]
    needs: str
    holds: bool | None
    measured: str
    reduce: Mapping[str, float] = field(default_factory=dict)
    suffix: str = ""


Measure = Callable[[Motion, Mapping[str, float], str], tuple[bool | None, str]]


@dataclass(frozen=True)
class Requirement:
    """What identifies ``params`` (``needs``, from the law's notes), how the data are measured
    against it (``measure(motion, medians, unit)`` → (holds, measured text)), and the reduced
    variant's fixed values where it fails (``reduce(medians)``, named by ``suffix``); it applies
    while the law samples one of ``applies`` (default: one of ``params``)."""

    params: tuple[str, ...]
    needs: str
    measure: Measure
    reduce: Callable[[Mapping[str, float]], dict[str, float]] | None = None
    suffix: str = ""
    applies: tuple[str, ...] = ()  # it applies only while one of these is sampled (default: any of params)


def _si(value: float, unit: str) -> str:
    """``value`` in ``unit`` with an SI prefix (µm, mm/s, mrad)."""
    if not math.isfinite(value) or value == 0:
        return f"{value:.3g} {unit}"
    for factor, prefix in ((1.0, ""), (1e-3, "m"), (1e-6, "µ"), (1e-9, "n")):
        if abs(value) >= factor:
            return f"{value / factor:.3g} {prefix}{unit}"
    return f"{value:.3g} {unit}"


def _stribeck(motion: Motion, med: Mapping[str, float], unit: str) -> tuple[bool | None, str]:
    span = motion.steady_range()
    vs = med.get("v_s", math.nan)
    if span is None:
        return (None if not motion.has_motion else False), "no steady sliding rows (speed constant within 5 %)"
    lo, hi = span
    held = hi >= STRIBECK_SPAN * lo
    where = "below" if vs < lo else ("above" if vs > hi else "inside")
    return held, (f"steady speeds {_si(lo, unit + '/s')}–{_si(hi, unit + '/s')} (×{hi / lo:.2g}; needs ×"
                  f"{STRIBECK_SPAN:g}), v_s prior median {_si(vs, unit + '/s')} {where} them"
                  + ("" if held else ": the Stribeck part does not change across them"))


def _viscous(motion: Motion, med: Mapping[str, float], unit: str) -> tuple[bool | None, str]:
    span = motion.steady_range()
    if span is None:
        return (None if not motion.has_motion else False), "no steady sliding rows"
    lo, hi = span
    return hi >= VISCOUS_SPAN * lo, f"steady speeds vary ×{hi / lo:.2g} (needs ×{VISCOUS_SPAN:g})"


def _presliding(deflection: Callable[[Mapping[str, float]], float], per: Callable[[Mapping[str, float]], int],
                what: str) -> Measure:
    def measure(motion: Motion, med: Mapping[str, float], unit: str) -> tuple[bool | None, str]:
        if not motion.has_motion:
            return None, "the data record no motion"
        z, need = deflection(med), PRESLIDING_SAMPLES * per(med)
        count, reversals = motion.samples_within(z)
        spacing = f", one per {_si(z / count, unit)}" if count > 0 else ""
        plural = "" if count == 1 else "s"
        return count >= need, (f"{count:.3g} sample{plural} (median over {reversals} reversals) within {what} "
                               f"{_si(z, unit)} after a reversal{spacing} (needs ≥ {need})")
    return measure


def _saturation(motion: Motion, med: Mapping[str, float], unit: str) -> tuple[bool | None, str]:
    strokes = motion.strokes()
    if strokes.size == 0:
        return None, "no stroke between reversals"
    xc, stroke = med["x_c0"], float(np.median(strokes))
    return stroke >= SATURATION * xc, (f"median stroke {_si(stroke, unit)} = {stroke / xc:.3g} x_c at its prior "
                                       f"median {_si(xc, unit)} (saturating loops: ≥ {SATURATION:g} x_c)")


def _preloads(motion: Motion, med: Mapping[str, float], unit: str) -> tuple[bool | None, str]:
    p = motion.preloads
    if p.size == 0:
        return None, "no preload input"
    shown = _si(p[0], "N") if p.size == 1 else f"{_si(p[0], 'N')}–{_si(p[-1], 'N')}"
    return p.size >= 2, f"{p.size} preload{'s' if p.size > 1 else ''} ({shown})"


def _no_stribeck(med: Mapping[str, float]) -> dict[str, float]:
    out = {"F_ratio": RATIO_ONE, "rho1": 0.0, "dF_s": 1e-9 * med.get("F_c", 1.0), "v_s": med.get("v_s", 0.0)}
    return {k: v for k, v in out.items() if k in med}


_STRIBECK_NEEDS = ("steady sliding over a decade of speeds around v_s (at one speed only g(v) there is "
                   "identified: v_s below or above the tested speeds fit alike)")
_PRELOAD = Requirement(("gamma", "kappa"), "≥ 2 preloads (κ also resolved knees)", _preloads,
                       lambda med: {k: 0.0 for k in ("gamma", "kappa") if k in med}, "gamma0")


def _elements(med: Mapping[str, float]) -> int:
    return int(med.get("_elements", 1))


def _stateful(presliding: tuple[str, ...], stribeck: tuple[str, ...]) -> list[Requirement]:
    return [Requirement(stribeck, _STRIBECK_NEEDS, _stribeck, _no_stribeck, "Fs_eq_Fc", ("v_s",)),
            Requirement(("sigma2",), "steady speeds varying ≥ 2× (at one speed σ2·v is collinear with F_c)",
                        _viscous),
            Requirement(presliding, "fast, finely sampled reversals: samples within the pre-sliding deflection",
                        _presliding(lambda m: m["F_c"] / m["sigma0"], lambda m: 1, "F_c/σ0 at the prior medians")),
            _PRELOAD]


_ELEMENTS = Requirement(("dx", "w"), "reversals sampled finely enough to resolve the elements' kinks",
                        _presliding(lambda m: m["dx"] * _elements(m), _elements,
                                    "Δ_N (the elements' break-away deflection) at the prior medians"))

#: Law family -> its requirements (a law name's family: :func:`requirements_for`).
REQUIREMENTS: dict[str, list[Requirement]] = {
    "dahl": [Requirement(("F_c0", "x_c0", "i"), "loops that saturate (strokes ≥ 10 x_c); on smaller loops "
                         "mainly σ = F_c/x_c is identified", _saturation), _PRELOAD],
    "lugre": _stateful(("sigma0", "rho1"), ("F_c", "F_ratio", "v_s")),
    "elastoplastic": _stateful(("sigma0", "beta"), ("F_c", "F_ratio", "v_s")),
    "gms": [_stateful((), ("F_c", "dF_s", "v_s"))[0], _stateful((), ())[1], _ELEMENTS],
    "maxwell_slip": [_ELEMENTS],
}
_FAMILY = re.compile(r"(dahl)(_xc_preload)?(_i1|_i1p5|_i2)?|(lugre)|(elastoplastic)|(gms|maxwell_slip)(_n\d+)?")


def requirements_for(name: str) -> list[Requirement]:
    """The requirements of the registered law ``name`` (``gms_n6`` → GMS's, ``dahl_i1p5`` → Dahl's);
    [] for a law that declares none."""
    match = _FAMILY.fullmatch(name)
    return REQUIREMENTS[next(g for g in (match[1], match[4], match[5], match[6]) if g)] if match else []


def _medians(law: Law, resolved: Mapping[str, Prior]) -> dict[str, float]:
    out = {k: prior_median(p) for k, p in resolved.items() if k in law.params}
    shapes = [law.params[k].shape for k in ("dx", "w") if k in law.params]
    if shapes and shapes[0]:
        out["_elements"] = float(shapes[0][0])
    return out


def assess(law: Law, base: str, ds: xr.Dataset, resolved: Mapping[str, Prior]) -> list[Check]:
    """Every requirement of ``base``'s family that concerns a parameter ``law`` samples on ``ds``.

    Parameters
    ----------
    law : Law
        The law as it runs on the data (:func:`bayesfric.laws.variants.for_data`), named by its entry.
    base : str
        The registered law it was built from (its family's requirements apply).
    ds : xarray.Dataset
        The data set (as :func:`bayesfric.datasets.load_dataset` returns it).
    resolved : mapping
        The law's priors resolved on ``ds`` (``Program.resolved``): the checks compare the data
        with their medians.
    """
    motion, med = Motion.of(ds), _medians(law, resolved)
    unit = motion.position_unit
    out = []
    for req in requirements_for(base):
        params = tuple(p for p in req.params if p in law.params)
        if not params or not any(p in law.params for p in req.applies or req.params):
            continue
        holds, text = req.measure(motion, med, unit)
        reduce = req.reduce(med) if req.reduce is not None and holds is False else {}
        out.append(Check(law.name, params, req.needs, holds, text, reduce, req.suffix if reduce else ""))
    return out


def reduction(checks: Sequence[Check]) -> tuple[str, dict[str, float]]:
    """The reduced variant of the failed checks with a reduction: its label suffix and fixed values."""
    failed = [c for c in checks if c.holds is False and c.reduce]
    fixed = {k: v for c in failed for k, v in c.reduce.items()}
    return "_".join(c.suffix for c in failed), fixed


def unidentified(checks: Sequence[Check]) -> list[str]:
    """The parameters a failed check names, in order."""
    return list(dict.fromkeys(p for c in checks if c.holds is False for p in c.params))


def checks_dataset(checks: Sequence[Check], companions: Mapping[str, str]) -> xr.Dataset:
    """The checks as the result tree's ``/identifiability`` node, over ``requirement``: ``law``,
    ``params`` (comma-separated), ``needs``, ``status`` (held | failed | not measurable),
    ``measured`` and ``companion`` (the companion entry the study added for the law, or "")."""
    def col(values: list[str]) -> tuple[str, np.ndarray]:
        return "requirement", np.array(values, dtype=str).reshape(len(checks))

    status = ["held" if c.holds else ("not measurable" if c.holds is None else "failed") for c in checks]
    return xr.Dataset({"law": col([c.law for c in checks]), "params": col([", ".join(c.params) for c in checks]),
                       "needs": col([c.needs for c in checks]), "status": col(status),
                       "measured": col([c.measured for c in checks]),
                       "companion": col([companions.get(c.law, "") for c in checks])},
                      attrs={"description": "what the data can determine of each stateful law, measured before "
                                            "fitting (bayesfric.identifiability)"})


def checks_of(node: xr.Dataset | None) -> list[dict[str, str]]:
    """The rows of an ``/identifiability`` node as dicts ([] without one)."""
    if node is None or "law" not in node:
        return []
    keys = ("law", "params", "needs", "status", "measured", "companion")
    return [{k: str(node[k].values[i]) for k in keys} for i in range(node.sizes.get("requirement", 0))]


def describe(checks: Sequence[Check], companions: Mapping[str, str]) -> list[str]:
    """One line per law with a failed or unmeasurable check: which parameters the data do not
    determine and the measured reason, and the companion entry added for it."""
    lines = []
    for law in dict.fromkeys(c.law for c in checks):
        own = [c for c in checks if c.law == law and not c.holds]
        if not own:
            continue
        reasons = "; ".join(f"{', '.join(c.params)} "
                            f"{'not determined' if c.holds is False else 'not measurable'}: {c.measured}"
                            for c in own)
        companion = f" -> companion {companions[law]} added" if law in companions else ""
        lines.append(f"{law}: {reasons}{companion}")
    return lines


def companions_of(laws: Sequence) -> dict[str, str]:
    """Law label -> its companion's label, from a study's entries (``LawSpec.companion_of``)."""
    return {spec.companion_of: spec.name for spec in laws if getattr(spec, "companion_of", "")}
