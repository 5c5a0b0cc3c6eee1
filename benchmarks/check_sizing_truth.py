"""Check the seed studies' sizing answers against the truth of the data generators.

Usage::

    .venv/bin/python benchmarks/check_sizing_truth.py [--reports DIR] [--studies NAME ...]

The shipped data sets are reconstructed: ``data/<name>/generate.py`` simulates them from a known
friction truth. A study with ``[[sizing]]`` questions writes ``<reports>/<study>/sizing.csv``
(SI units: inputs in rad/s, N·m, K; torque in N·m). For every sizing point of the model average
(rows with ``role == "average"``) this script evaluates the generator's noise-free MEAN friction
magnitude at that operating point and prints it next to

* the within-model 5-95 % band of the mean function (``mean_fn_q5``, ``mean_fn_q95``), and
* the calibrated 90 % band of the friction curve (``calibrated_q5``, ``calibrated_q95``, which
  carry the model-form error the blocked folds measured; older reports lack them: said so).

Where the generator simulates several series (robot_joint: three series with drift between
them), the truth is the mean over the series of the study's selection, and the min-max over
those series is printed too (a sizing answer is for a new unit). Before that, every truth
adapter is cross-checked against the shipped CSV in SI units as the study loads it: at each
tested point the measured mean should lie within the generator's own noise of the truth.

The generators are imported by path (``importlib.util.spec_from_file_location``); their numbers
are never copied here. Units are converted with :mod:`bayesfric.quantities` (pint).

A study whose questions all ask a time to exceed (``horizon``) is checked against its data set's
``truth.json`` instead: the generator's true crossing time inside the 90 % interval of the model
average that the study's ``results.nc`` keeps (``/service``).

Exit status: 2 if a study's ``sizing.csv`` is missing (or its data set has no truth adapter):
the check is incomplete; otherwise 1 if the truth lies outside the calibrated band at any point;
otherwise 0 (also when the calibrated columns are absent or NaN: printed as NOT CHECKED).
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import math
import sys
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script from anywhere: bayesfric from this checkout
    sys.path.insert(0, str(ROOT))

from bayesfric.datasets.loader import load_dataset  # noqa: E402
from bayesfric.datasets.views import select as select_rows  # noqa: E402
from bayesfric.quantities import conversion  # noqa: E402

DATA = ROOT / "data"
STUDIES = ROOT / "studies"
#: The sizing.csv role of the model average.
AVERAGE = "average"
#: Bands compared with the truth: name -> (lower, upper) column of sizing.csv.
BANDS = {"within-model": ("mean_fn_q5", "mean_fn_q95"), "calibrated": ("calibrated_q5", "calibrated_q95")}
#: The band whose miss fails the check.
GATE = "calibrated"


# -- generators and units ----------------------------------------------------------------------

@cache
def generator(dataset: str) -> ModuleType:
    """Import ``data/<dataset>/generate.py`` by path (once per process).

    Parameters
    ----------
    dataset : str
        Name of a shipped data set.

    Returns
    -------
    types.ModuleType
        The generator module (its ``main``/``write`` is not run).
    """
    path = DATA / dataset / "generate.py"
    spec = importlib.util.spec_from_file_location(f"_sizing_truth_{dataset}_generate", path)
    if spec is None or spec.loader is None:
        raise ImportError(f"{path}: cannot import")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def to_si(values: Any, unit: str, quantity: str) -> np.ndarray:
    """Values in ``unit`` converted to the SI unit of ``quantity`` (pint, affine for °C).

    Parameters
    ----------
    values : array_like
        Values in ``unit``.
    unit, quantity : str
        A pint unit (``"kN*m"``, ``"rpm"``, ``"degC"``) and a :data:`bayesfric.quantities.QUANTITIES` key.

    Returns
    -------
    numpy.ndarray
        The values in SI.
    """
    scale, offset = conversion(unit, quantity)
    return np.asarray(values, dtype=float) * scale + offset


def from_si(values: Any, unit: str, quantity: str) -> np.ndarray:
    """SI values of ``quantity`` converted to ``unit`` (the inverse of :func:`to_si`).

    Parameters
    ----------
    values : array_like
        Values in the SI unit of ``quantity``.
    unit, quantity : str
        Target pint unit and quantity name.

    Returns
    -------
    numpy.ndarray
        The values in ``unit``.
    """
    scale, offset = conversion(unit, quantity)
    return (np.asarray(values, dtype=float) - offset) / scale


# -- truth adapters ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Block:
    """A tested point of the shipped data: the measured mean there and the truth it estimates.

    Attributes
    ----------
    label : str
        Where (inputs in the data's own units, series).
    x : dict of str to float
        The point's inputs in SI.
    measured, truth, sd : float
        Mean of the measured rows, the generator's mean truth, and the standard deviation of
        that measured mean around the truth implied by the generator's noise model (N·m).
    n : int
        Number of rows averaged.
    """

    label: str
    x: dict[str, float]
    measured: float
    truth: float
    sd: float
    n: int

    @property
    def z(self) -> float:
        """(measured - truth) / sd."""
        return (self.measured - self.truth) / self.sd


@dataclass(frozen=True)
class Adapter:
    """How one generator's truth is evaluated at SI inputs and checked against its data.

    Attributes
    ----------
    dataset : str
        The data set (``data/<dataset>/``).
    series : callable
        ``series(gen, select) -> list``: the generator's series (units, setups) the study's row
        selection covers; the truth of a sizing point is the mean over them.
    truth : callable
        ``truth(gen, x, series) -> ndarray``: mean friction magnitude in N·m (SI) at SI inputs
        ``x`` (dict of arrays) for one series, without noise.
    blocks : callable
        ``blocks(gen, ds) -> list[Block]``: every tested point of the (selected) data set.
    reference : callable
        ``reference(blocks) -> Block``: the tested point printed in the cross-check.
    note : str
        What "mean over series" means for this generator.
    """

    dataset: str
    series: Callable[[ModuleType, dict], list]
    truth: Callable[[ModuleType, dict[str, np.ndarray], Any], np.ndarray]
    blocks: Callable[[ModuleType, Any], list[Block]]
    reference: Callable[[Sequence[Block]], Block]
    note: str = ""


def _chosen(select: dict, key: str, values: Sequence) -> list:
    """The ``values`` a study's ``select = {key = ...}`` keeps (all when it names none)."""
    if key not in select:
        return list(values)
    wanted = select[key] if isinstance(select[key], list | tuple) else [select[key]]
    return [v for v in values if v in wanted or str(v) in map(str, wanted)]


# robot_joint: normalised torque (by MAX_JOINT_TORQUE) of speed in rad/s, three series with drift

def _robot_truth(gen: ModuleType, x: dict[str, np.ndarray], series: Any) -> np.ndarray:
    """N·m of one series: ``friction_truth`` (speed in rad/s) times the assumed maximum joint torque."""
    speed = np.abs(from_si(x["velocity"], "rad/s", "velocity"))
    return gen.friction_truth(speed, int(series)) * to_si(gen.MAX_JOINT_TORQUE, "N*m", "torque")


def _robot_blocks(gen: ModuleType, ds: Any) -> list[Block]:
    """Per joint speed: the mean over the series of the measured torque against the mean truth."""
    speed, series, torque = (ds[k].values for k in ("velocity", "series", "torque"))
    scale = to_si(gen.MAX_JOINT_TORQUE, "N*m", "torque")
    out = []
    for v in np.unique(speed):
        rows = speed == v
        truth = np.array([_robot_truth(gen, {"velocity": np.asarray(v)}, s) for s in series[rows]])
        sd = scale * np.hypot(gen.NOISE_REL * truth / scale, gen.NOISE_ABS)
        names = ",".join(str(s) for s in series[rows])
        out.append(Block(f"{v:g} rad/s, mean of series {names}", {"velocity": float(v)},
                         float(torque[rows].mean()), float(truth.mean()),
                         float(np.sqrt(np.sum(sd**2)) / rows.sum()), int(rows.sum())))
    return out


ROBOT_JOINT = Adapter(
    dataset="robot_joint",
    series=lambda gen, select: _chosen(select, "series", range(1, gen.N_SERIES + 1)),
    truth=_robot_truth,
    blocks=_robot_blocks,
    reference=lambda blocks: max(blocks, key=lambda b: b.x["velocity"]),
    note="mean over the generator's series (drift between series: warm-up continues)",
)


# pitch_bearing: kN·m of bending moment (MN·m) and pitch speed (rpm); one bearing

def solve_load_sums(gen: ModuleType, moment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P1 = Σ|Q| (N) and Σ Q^(4/3) (N^(4/3)) solved at bending moments ``moment`` (N·m, 1-d).

    The generator's load case at any moment: radial force = moment / rope arm, no axial force,
    the :mod:`bayesfric.laws.ball_loads` contact solve with ``PITCH_BEARING``, as
    ``generate.ball_load_sums`` does at the tested moments.

    Parameters
    ----------
    gen : types.ModuleType
        The pitch_bearing generator.
    moment : numpy.ndarray
        Blade-root bending moments in N·m, one dimension.

    Returns
    -------
    tuple of numpy.ndarray
        P1 and Σ Q^(4/3), shaped like ``moment``.
    """
    from bayesfric.runtime import configure

    configure()  # x64, as the generator
    from bayesfric.laws.ball_loads import PITCH_BEARING, contact_loads

    moment = np.asarray(moment, dtype=float)
    radial = moment / gen.ROPE_ARM_M  # N·m / m: the rope's shear force at the blade root, N
    q = np.asarray(contact_loads(moment, 0.0, radial, PITCH_BEARING), dtype=np.float64)  # all >= 0
    return np.sum(q, axis=(-3, -2, -1)), np.sum(q ** (4.0 / 3.0), axis=(-3, -2, -1))


def pitch_load_sums(gen: ModuleType, moment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P1 and Σ Q^(4/3) at any bending moments (N·m): the generator's own sums at its tested
    moments, :func:`solve_load_sums` elsewhere (one solve per distinct moment).

    Parameters
    ----------
    gen : types.ModuleType
        The pitch_bearing generator.
    moment : numpy.ndarray
        Blade-root bending moments in N·m.

    Returns
    -------
    tuple of numpy.ndarray
        P1 (N) and Σ Q^(4/3) (N^(4/3)), shaped like ``moment``.
    """
    moment = np.asarray(moment, dtype=float)
    unique, index = np.unique(moment, return_inverse=True)
    tested = to_si(np.asarray(gen.MOMENTS_MNM, dtype=float), "MN*m", "bending_moment")
    p1, s43 = (np.array(v, dtype=float) for v in gen.ball_load_sums())
    match = np.isclose(unique[:, None], tested[None, :], rtol=1e-12, atol=1e-6)
    known, pos = match.any(axis=1), match.argmax(axis=1)
    out_p1, out_s43 = p1[pos], s43[pos]
    if not known.all():
        out_p1[~known], out_s43[~known] = solve_load_sums(gen, unique[~known])
    return out_p1[index].reshape(moment.shape), out_s43[index].reshape(moment.shape)


def _pitch_truth(gen: ModuleType, x: dict[str, np.ndarray], series: Any = None) -> np.ndarray:
    """N·m: seal torque (with its small speed term, speed in rpm) + P1 term + Σ Q^(4/3) term, in kN·m."""
    coef = gen.truth_coefficients()  # seal in kN·m, c_p1 in kN·m/N, c_s43 in kN·m/N^(4/3)
    moment = np.abs(np.asarray(x["bending_moment"], dtype=float))
    speed = np.abs(from_si(x["velocity"], "rpm", "velocity"))
    mean_speed = float(np.mean(gen.SPEEDS_RPM))
    p1, s43 = pitch_load_sums(gen, moment)
    seal = coef["seal"] * (1.0 + gen.SPEED_EFFECT * (speed - mean_speed) / mean_speed)
    return to_si(seal + coef["c_p1"] * p1 + coef["c_s43"] * s43, "kN*m", "torque")


def _pitch_blocks(gen: ModuleType, ds: Any) -> list[Block]:
    """Per load-speed block of repetitions: block mean against the truth (offset + scatter noise)."""
    moment, speed, torque = (ds[k].values for k in ("bending_moment", "velocity", "torque"))
    blade = ds["blade"].values
    cells = sorted(set(zip(moment.tolist(), speed.tolist(), strict=True)))
    truth = _pitch_truth(gen, {"bending_moment": np.array([c[0] for c in cells]),
                               "velocity": np.array([c[1] for c in cells])})
    out = []
    for (m, v), t in zip(cells, truth, strict=True):
        rows = (moment == m) & (speed == v)
        rpm = float(from_si(v, "rpm", "velocity"))
        a, b = gen.VIBRATION_NO_BLADE_KNM if (blade[rows] == "without").all() else gen.VIBRATION_KNM
        scatter = to_si(a + b * rpm / gen.TOP_SPEED_RPM, "kN*m", "torque")
        sd = math.hypot(t * gen.BLOCK_OFFSET_SD, scatter / math.sqrt(rows.sum()))  # drift ramp averages out
        label = f"{from_si(m, 'MN*m', 'bending_moment'):g} MN*m, {rpm:.3g} rpm"
        out.append(Block(label, {"bending_moment": m, "velocity": v}, float(torque[rows].mean()), float(t),
                         sd, int(rows.sum())))
    return out


PITCH_BEARING = Adapter(
    dataset="pitch_bearing",
    series=lambda gen, select: ["bearing"],
    truth=_pitch_truth,
    blocks=_pitch_blocks,
    reference=lambda blocks: max(blocks, key=lambda b: (b.x["bending_moment"], b.x["velocity"])),
    note=("one bearing, no series: the blade group changes only the scatter; block offsets and drift "
          "are mean-zero repeatability effects, not part of the truth"),
)


# unwinder: N·m at the motor shaft of omega (rad/s) and oil temperature (degC); setups belt_off/on

def _unwinder_truth(gen: ModuleType, x: dict[str, np.ndarray], setup: Any) -> np.ndarray:
    """N·m at the motor shaft: ``mass1_torque`` (omega in rad/s, oil in degC), + mass 2 with the belt on."""
    omega = np.abs(from_si(x["velocity"], "rad/s", "velocity"))
    temp_c = from_si(x["temperature"], "degC", "temperature")
    torque = gen.mass1_torque(omega, temp_c)
    if str(setup) == "belt_on":
        torque = torque + gen.mass2_torque(omega)
    return to_si(torque, "N*m", "torque")


def ar1_mean_factor(phi: float, n: int) -> float:
    """Variance of the mean of ``n`` unit-variance AR(1) samples with lag-1 correlation ``phi``.

    Parameters
    ----------
    phi : float
        Lag-1 autocorrelation.
    n : int
        Samples averaged.

    Returns
    -------
    float
        ``(1/n²) Σ_ij phi^|i-j|`` (1/n for white noise).
    """
    lags = np.arange(1, n)
    return float((n + 2.0 * np.sum((n - lags) * phi**lags)) / n**2)


def _unwinder_blocks(gen: ModuleType, ds: Any) -> list[Block]:
    """Per 30 s steady-state average: the measured torque against the truth at its mean oil temperature."""
    velocity, temperature, torque = (ds[k].values for k in ("velocity", "temperature", "torque"))
    setup, cycle = ds["setup"].values, ds["cycle"].values
    factor = ar1_mean_factor(math.exp(-1.0 / gen.NOISE_CORR_S), int(gen.STEP_S))  # 1 s samples
    out = []
    for j in range(velocity.size):
        x = {"velocity": velocity[j], "temperature": temperature[j]}
        t = float(_unwinder_truth(gen, x, setup[j]))
        sd = (gen.TORQUE_NOISE_ABS + gen.TORQUE_NOISE_REL * t) * math.sqrt(factor)
        label = (f"{from_si(velocity[j], 'rpm', 'velocity'):.0f} rpm, "
                 f"{from_si(temperature[j], 'degC', 'temperature'):.2f} degC, {setup[j]} cycle {cycle[j]}")
        out.append(Block(label, {k: float(v) for k, v in x.items()}, float(torque[j]), t, sd, 1))
    return out


UNWINDER = Adapter(
    dataset="unwinder",
    series=lambda gen, select: _chosen(select, "setup", list(gen.AMBIENT_C)),
    truth=_unwinder_truth,
    blocks=_unwinder_blocks,
    reference=lambda blocks: max(blocks, key=lambda b: (b.x["velocity"], -b.x["temperature"])),
    note=("one machine: mean over the setups the study selects (the cycles are repeated staircases "
          "of the same machine, no drift in the truth beyond the oil temperature input)"),
)

#: Truth adapters by data set.
ADAPTERS = {a.dataset: a for a in (ROBOT_JOINT, PITCH_BEARING, UNWINDER)}


def truth_over_series(adapter: Adapter, x: dict[str, np.ndarray], select: dict) -> np.ndarray:
    """The truth at SI inputs ``x`` for every series of the selection.

    Parameters
    ----------
    adapter : Adapter
        The data set's adapter.
    x : dict of str to numpy.ndarray
        SI inputs, one array per input name (broadcast together).
    select : dict
        The study's ``[data] select`` (may be empty).

    Returns
    -------
    numpy.ndarray
        Shape ``(n_series, n_points)``: mean friction magnitude in N·m (or N).
    """
    gen = generator(adapter.dataset)
    series = adapter.series(gen, select)
    if not series:
        raise ValueError(f"{adapter.dataset}: the selection {select} keeps no series of the generator")
    x = dict(zip(x, np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in x.values())), strict=True))
    return np.abs(np.stack([np.atleast_1d(adapter.truth(gen, x, s)) for s in series]))


def cross_check(adapter: Adapter, select: dict) -> list[Block]:
    """Every tested point of the shipped data set (with the study's selection) against the truth.

    Parameters
    ----------
    adapter : Adapter
        The data set's adapter.
    select : dict
        The study's ``[data] select``.

    Returns
    -------
    list of Block
        One per tested point, in SI.
    """
    ds = load_dataset(DATA / adapter.dataset / f"{adapter.dataset}.csv")
    return adapter.blocks(generator(adapter.dataset), select_rows(ds, select or None))


# -- studies and reports -----------------------------------------------------------------------

@dataclass
class Study:
    """What this check reads from a ``studies/<name>.toml``."""

    name: str
    dataset: str
    select: dict
    questions: list[str] = field(default_factory=list)
    inputs: list[str] = field(default_factory=list)
    horizons: list[str] = field(default_factory=list)  # time-to-exceed questions' labels


def read_study(path: Path) -> Study:
    """The study's name, data set, row selection, sizing question labels and their inputs.

    Parameters
    ----------
    path : pathlib.Path
        A study TOML file.

    Returns
    -------
    Study
    """
    with path.open("rb") as fh:
        spec = tomllib.load(fh)
    data = spec.get("data", {})
    return Study(name=str(spec.get("study", {}).get("name", path.stem)), dataset=str(data.get("dataset", "")),
                 select=dict(data.get("select") or {}),
                 questions=[str(q.get("label", "")) for q in spec.get("sizing", [])],
                 inputs=list(dict.fromkeys(k for q in spec.get("sizing", []) for k in q.get("at", {}))),
                 horizons=[str(q.get("label", "")) for q in spec.get("sizing", []) if "horizon" in q])


def _float(text: str | None) -> float:
    """A CSV cell as a float (NaN when empty or not a number)."""
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def read_sizing(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    """Header and model-average rows of a ``sizing.csv``.

    Parameters
    ----------
    path : pathlib.Path
        The report's ``sizing.csv``.

    Returns
    -------
    header : list of str
    rows : list of dict
        Rows with ``role == "average"``.
    """
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        rows = [r for r in reader if r.get("role") == AVERAGE]
        return list(reader.fieldnames or []), rows


def input_names(header: Sequence[str]) -> list[str]:
    """SI input columns of a sizing.csv: those with a ``distance[<input>]`` column."""
    return [h[len("distance["):-1] for h in header if h.startswith("distance[") and h.endswith("]")
            and h[len("distance["):-1] in header]


def _where(row: dict[str, str], header: Sequence[str], name: str) -> str:
    """``name=value unit`` in the question's unit (its ``name [unit]`` column), else in SI."""
    shown = next((h for h in header if h.startswith(f"{name} [") and h.endswith("]")), None)
    if shown is None:
        return f"{name}={_g(_float(row.get(name)))} (SI)"
    return f"{name}={_g(_float(row.get(shown)))} {shown[len(name) + 2:-1]}"


@dataclass
class PointCheck:
    """One sizing point: the truth and the bands of the model average."""

    question: str
    point: str
    where: str
    truth: float
    series_lo: float
    series_hi: float
    bands: dict[str, tuple[float, float]]

    def inside(self, band: str) -> bool | None:
        """Whether the truth lies in ``band`` (None: band absent or NaN)."""
        lo, hi = self.bands.get(band, (math.nan, math.nan))
        if not (math.isfinite(lo) and math.isfinite(hi)):
            return None
        return lo <= self.truth <= hi


def check_points(study: Study, header: Sequence[str], rows: Sequence[dict[str, str]]) -> list[PointCheck]:
    """Truth and bands at every model-average row of a study's sizing.csv.

    Parameters
    ----------
    study : Study
        The study (its data set names the adapter).
    header : sequence of str
        The sizing.csv header.
    rows : sequence of dict
        Its ``role == "average"`` rows.

    Returns
    -------
    list of PointCheck
    """
    names = [k for k in dict.fromkeys([*study.inputs, *input_names(header)]) if k in header]
    x = {k: np.array([_float(r[k]) for r in rows]) for k in names}
    truth = truth_over_series(ADAPTERS[study.dataset], x, study.select) if rows else np.zeros((1, 0))
    out = []
    for j, r in enumerate(rows):
        where = ", ".join(_where(r, header, k) for k in names)
        bands = {b: (_float(r.get(lo)), _float(r.get(hi))) for b, (lo, hi) in BANDS.items()}
        out.append(PointCheck(r.get("question", ""), r.get("point", str(j + 1)), where,
                              float(truth[:, j].mean()), float(truth[:, j].min()), float(truth[:, j].max()),
                              bands))
    return out


# -- printing ----------------------------------------------------------------------------------

def _g(x: float) -> str:
    """Four significant digits."""
    return "nan" if not math.isfinite(x) else f"{x:.4g}"


def _mark(flag: bool | None) -> str:
    """yes / NO / n/a."""
    return {True: "yes", False: "NO", None: "n/a"}[flag]


def format_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A plain fixed-width text table."""
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows, strict=True)]
    lines = ["  ".join(str(c).ljust(w) for c, w in zip(line, widths, strict=True)).rstrip()
             for line in (header, ["-" * w for w in widths], *rows)]
    return "\n".join(lines)


def print_cross_check(study: Study, blocks: Sequence[Block]) -> None:
    """The reference tested point and the spread of z over all tested points."""
    adapter = ADAPTERS[study.dataset]
    ref = adapter.reference(blocks)
    z = np.array([b.z for b in blocks])
    worst = blocks[int(np.argmax(np.abs(z)))]
    print(f"cross-check of the truth against data/{study.dataset}/{study.dataset}.csv (SI, as loaded"
          f"{', select ' + str(study.select) if study.select else ''}):")
    print(f"  at {ref.label}: measured mean {_g(ref.measured)} N*m over {ref.n} row(s), truth {_g(ref.truth)} N*m, "
          f"noise sd of that mean {_g(ref.sd)} N*m -> z = {ref.z:+.2f}")
    print(f"  all {len(blocks)} tested points: rms z = {np.sqrt(np.mean(z**2)):.2f}, mean z = {z.mean():+.2f}, "
          f"max |z| = {abs(worst.z):.2f} at {worst.label}")


def print_points(checks: Sequence[PointCheck], unit: str, columns: Sequence[str]) -> None:
    """The per-point table of one study (``columns``: the sizing.csv header)."""
    header = ["q", "point", "where (question units)", f"truth [{unit}]", "series min-max",
              "within-model 5-95 %", "inside?", "calibrated 5-95 %", "inside?"]
    present = {b: lo in columns and hi in columns for b, (lo, hi) in BANDS.items()}
    rows = []
    for c in checks:
        bands = {b: f"{_g(lo)} - {_g(hi)}" if present[b] else "(absent)" for b, (lo, hi) in c.bands.items()}
        rows.append([c.question, c.point, c.where, _g(c.truth), f"{_g(c.series_lo)} - {_g(c.series_hi)}",
                     bands["within-model"], _mark(c.inside("within-model")), bands["calibrated"],
                     _mark(c.inside("calibrated"))])
    print(format_table(header, rows))


def summarise(checks: Sequence[PointCheck], header: Sequence[str]) -> int:
    """Print the counts per band; 1 when the truth misses the calibrated band anywhere, else 0."""
    for band, (lo, hi) in BANDS.items():
        if lo not in header or hi not in header:
            print(f"  {band}: columns {lo}, {hi} ABSENT from this report (older format): NOT CHECKED")
            continue
        flags = [c.inside(band) for c in checks]
        known = [f for f in flags if f is not None]
        if not known:
            print(f"  {band}: all NaN in this report (nothing measured): NOT CHECKED")
            continue
        print(f"  {band}: truth inside at {sum(known)} of {len(known)} points"
              + (f" ({len(flags) - len(known)} NaN)" if len(known) < len(flags) else ""))
    return int(any(c.inside(GATE) is False for c in checks))


def check_study(study: Study, reports: Path) -> int:
    """Cross-check, compare and print one study; its exit status (0, 1 or 2).

    Parameters
    ----------
    study : Study
        A study with sizing questions.
    reports : pathlib.Path
        Folder holding ``<study>/sizing.csv``.

    Returns
    -------
    int
        2: report missing or no truth adapter; 1: truth outside the calibrated band; 0: otherwise.
    """
    print(f"\n=== {study.name} (data set {study.dataset}) ===")
    if study.horizons and len(study.horizons) == len(study.questions):
        return check_service(study, reports)
    if study.dataset not in ADAPTERS:
        print(f"NO TRUTH ADAPTER for data set {study.dataset!r} (known: {', '.join(ADAPTERS)}): cannot check")
        return 2
    adapter = ADAPTERS[study.dataset]
    print_cross_check(study, cross_check(adapter, study.select))
    path = reports / study.name / "sizing.csv"
    if not path.is_file():
        print(f"REPORT MISSING: {path} (run `bayesfric study studies/{study.name}.toml --out {reports}`)")
        return 2
    header, rows = read_sizing(path)
    labels = sorted({r.get("label", "") for r in rows})
    if sorted(study.questions) != labels:
        print(f"WARNING: {path} answers {labels}, the study now asks {sorted(study.questions)}: stale report?")
    checks = check_points(study, header, rows)
    series = adapter.series(generator(study.dataset), study.select)
    print(f"truth = generator's noise-free mean friction magnitude; {adapter.note}; series {series}")
    unit = rows[0].get("unit", "SI") if rows else "SI"
    if rows:
        print(f"model average: {rows[0].get('basis') or rows[0].get('law', '?')} ({len(rows)} points, {path})")
    print_points(checks, unit, header)
    return summarise(checks, header)


def check_service(study: Study, reports: Path) -> int:
    """Time-to-exceed questions: the generator's true crossing time (``data/<dataset>/truth.json``,
    ``query.crossing_hours``) against the 90 % interval of the model average in the study's
    ``results.nc`` (``/service/q<i>/average``); the exit status as :func:`check_study`'s."""
    import json

    import xarray as xr

    truth_file = ROOT / "data" / study.dataset / "truth.json"
    path = reports / study.name / "results.nc"
    if not truth_file.is_file() or not path.is_file():
        print(f"MISSING: {truth_file if not truth_file.is_file() else path}: cannot check")
        return 2
    truth = json.loads(truth_file.read_text())["query"]
    status = 0
    with xr.open_datatree(path) as tree:
        for name, q in sorted(tree["service"].children.items()):
            res = q["average"] if "average" in q.children else next(iter(q.children.values()))
            lo, mid, hi = (float(res["crossing_q"].sel(quantile=p)) for p in (0.05, 0.5, 0.95))
            inside = lo <= truth["crossing_hours"] <= hi
            print(f"{name} {q.attrs['label']!r}: true crossing {truth['crossing_hours']:g} h "
                  f"({truth['crossing_definition']}); {res.attrs['law']} median {mid:g} h, 90 % {lo:g} – {hi:g} h: "
                  f"{'inside' if inside else 'OUTSIDE'}")
            status = max(status, 0 if inside else 1)
    return status


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reports", type=Path, default=ROOT / "reports",
                        help="folder with <study>/sizing.csv (default: reports/)")
    parser.add_argument("--studies", nargs="+", metavar="NAME",
                        help="studies to check (default: every studies/*.toml with [[sizing]])")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Check the chosen studies; the exit status (2 before 1 before 0)."""
    args = parse_args(argv)
    paths = sorted(STUDIES.glob("*.toml"))
    studies = {s.name: s for s in map(read_study, paths)}
    names = args.studies or [n for n, s in studies.items() if s.questions]
    status = 0
    for name in names:
        study = studies.get(Path(name).stem)
        if study is None:
            print(f"\n=== {name}: no studies/{name}.toml (known: {', '.join(studies)})")
            status = 2
        elif not study.questions:
            print(f"\n=== {study.name}: no [[sizing]] questions: nothing to check")
        else:
            code = check_study(study, args.reports)
            status = max(status, code)
    print(f"\nexit status {status}")
    return status


if __name__ == "__main__":
    sys.exit(main())
