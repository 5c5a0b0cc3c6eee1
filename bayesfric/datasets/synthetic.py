"""Build in-memory datasets (simulated from a law, or from arrays) with the loader's layout."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import xarray as xr

from bayesfric.datasets.loader import OBS_DIM
from bayesfric.laws.base import TRAJECTORY_START, Law
from bayesfric.quantities import QUANTITIES
from bayesfric.runtime import configure

__all__ = ["make_dataset", "simulate"]


def make_dataset(
    inputs: Mapping[str, np.ndarray],
    response: np.ndarray,
    *,
    response_quantity: str = "torque",
    groups: Mapping[str, np.ndarray] | None = None,
    trajectory: str | None = None,
    name: str = "simulated",
    provenance: str = "simulated",
    source: str = "simulated in memory",
) -> xr.Dataset:
    """An SI dataset laid out exactly as :func:`bayesfric.datasets.load_dataset` returns it.

    Parameters
    ----------
    inputs : mapping
        Quantity name -> values in canonical SI units.
    response : array
        Response values in SI units.
    groups : mapping, optional
        Group coordinate name -> labels.
    trajectory : str, optional
        Name of the group delimiting ordered trajectories.
    """
    coords: dict[str, Any] = {}
    for q, v in inputs.items():
        coords[q] = (OBS_DIM, np.asarray(v, dtype=float),
                     {"role": "input", "quantity": q, "units": QUANTITIES[q].unit, "column": q})
    for g, v in (groups or {}).items():
        coords[g] = (OBS_DIM, np.asarray(v), {"role": "group", "column": g})
    data = {response_quantity: (OBS_DIM, np.asarray(response, dtype=float),
                                {"role": "response", "quantity": response_quantity,
                                 "units": QUANTITIES[response_quantity].unit
                                 if response_quantity in QUANTITIES else "rad/s"})}
    attrs = {"name": name, "provenance": provenance, "source": source, "response": response_quantity,
             "title": f"{name} ({provenance})", "data_hash": "in-memory"}
    if trajectory:
        attrs["trajectory"] = trajectory
    return xr.Dataset(data, coords=coords, attrs=attrs)


def simulate(
    law: Law,
    inputs: Mapping[str, np.ndarray],
    params: Mapping[str, Any],
    *,
    sigma: float,
    seed: int = 0,
    relative: bool = False,
    groups: Mapping[str, np.ndarray] | None = None,
    trajectory: str | None = None,
    constants: Mapping[str, float] | None = None,
    name: str | None = None,
) -> xr.Dataset:
    """Simulate a *simulated*-provenance dataset from ``law`` with Gaussian noise.

    ``sigma`` is absolute (SI) or, with ``relative=True``, a fraction of |mean|. Trajectory
    laws get ``trajectory_start`` computed from ``groups[trajectory]``.
    """
    configure()  # the law runs in JAX: x64 first
    arrays = {k: np.asarray(v, dtype=float) for k, v in inputs.items()}
    call_inputs = dict(arrays)
    if TRAJECTORY_START in law.inputs:
        starts = np.zeros(len(next(iter(arrays.values()))), dtype=bool)
        starts[0] = True
        if trajectory:
            labels = np.asarray(groups[trajectory])
            starts[1:] |= labels[1:] != labels[:-1]
        call_inputs[TRAJECTORY_START] = starts
    mean = np.asarray(law.mean(call_inputs, params, constants), dtype=float)
    rng = np.random.default_rng(seed)
    scale = sigma * np.abs(mean) if relative else sigma
    y = mean + rng.normal(0.0, 1.0, mean.shape) * scale
    label = ", ".join(f"{k}={v}" for k, v in params.items())
    return make_dataset(arrays, y, response_quantity=law.response, groups=groups, trajectory=trajectory,
                        name=name or f"simulated_{law.name}",
                        source=f"simulated from law {law.name} with {label}, sigma={sigma}, seed={seed}")


def simulate_runs(
    law: Law,
    inputs: Mapping[str, np.ndarray],
    params: Mapping[str, float],
    spread: Mapping[str, float],
    *,
    runs: int,
    sigma: float,
    seed: int = 0,
    column: str = "run",
) -> tuple[xr.Dataset, dict[str, np.ndarray]]:
    """Simulate ``runs`` runs of a steady law at the same ``inputs``, its parameters varying between runs.

    Each parameter ``p`` named in ``spread`` takes, per run, ``params[p] · exp(spread[p] · z)``
    with ``z ~ Normal(0, 1)`` (a run-to-run factor: the Coulomb level of one run of a joint a few
    per cent above another's); the others are ``params[p]`` in every run. Rows are grouped by
    ``column`` (labels ``r0``, ``r1``, ...). Returns the data set and each parameter's values per run.

    Examples
    --------
    >>> from bayesfric.laws import get_law
    >>> ds, truth = simulate_runs(get_law("coulomb_viscous"), {"velocity": np.linspace(0.1, 2, 20)},
    ...                           {"T_C": 2.0, "c_v": 1.0}, {"T_C": 0.15}, runs=6, sigma=0.05, seed=1)
    >>> ds.sizes["obs"], truth["T_C"].shape
    (120, (6,))
    """
    rng = np.random.default_rng([seed, runs])
    truth = {p: float(v) * np.exp(spread.get(p, 0.0) * rng.normal(size=runs)) if p in spread
             else np.full(runs, float(v)) for p, v in params.items()}
    n = len(next(iter(inputs.values())))
    run = np.repeat(np.arange(runs), n)
    tiled = {k: np.tile(np.asarray(v, dtype=float), runs) for k, v in inputs.items()}
    labels = np.array([f"r{i}" for i in run])
    ds = simulate(law, tiled, {p: v[run] for p, v in truth.items()}, sigma=sigma, seed=seed,
                  groups={column: labels}, name=f"simulated_runs_{law.name}")
    return ds, truth


def simulate_campaigns(
    law: Law,
    inputs: Mapping[str, np.ndarray],
    params: Mapping[str, Any],
    service: Sequence[float],
    spread: Mapping[str, float],
    *,
    sigma: float,
    seed: int = 0,
    column: str = "hours",
    unit: str = "h",
) -> tuple[xr.Dataset, dict[str, np.ndarray]]:
    """Simulate test campaigns of a steady law at the same ``inputs``, one per service coordinate
    (``column``, in ``unit``: the column's declared unit, as a sidecar's ``unit`` gives it).

    ``params[p]`` is a number or a function of the service coordinate (the true trend); a
    parameter named in ``spread`` takes, per campaign, that value times ``exp(spread[p] · z)``,
    ``z ~ Normal(0, 1)`` (campaign-to-campaign scatter). Rows are grouped by ``column``, whose
    labels are the campaigns' coordinates. Returns the data set and each parameter's values per
    campaign.

    Examples
    --------
    >>> from bayesfric.laws import get_law
    >>> ds, truth = simulate_campaigns(get_law("coulomb_viscous"), {"velocity": np.linspace(0.1, 2, 10)},
    ...                                {"T_C": lambda t: 2.0 + 1e-3 * t, "c_v": 1.0}, [0, 500, 1000],
    ...                                {"T_C": 0.05}, sigma=0.05, seed=1)
    >>> ds.sizes["obs"], truth["T_C"].shape
    (30, (3,))
    """
    hours = np.asarray(service, dtype=float)
    rng = np.random.default_rng([seed, hours.size])
    truth = {}
    for p, v in params.items():
        trend = np.asarray([float(v(t)) for t in hours]) if callable(v) else np.full(hours.size, float(v))
        truth[p] = trend * np.exp(spread[p] * rng.normal(size=hours.size)) if p in spread else trend
    n = len(next(iter(inputs.values())))
    level = np.repeat(np.arange(hours.size), n)
    tiled = {k: np.tile(np.asarray(v, dtype=float), hours.size) for k, v in inputs.items()}
    labels = np.array([f"{t:g}" for t in hours])[level]
    ds = simulate(law, tiled, {p: v[level] for p, v in truth.items()}, sigma=sigma, seed=seed,
                  groups={column: labels}, name=f"simulated_campaigns_{law.name}")
    ds[column].attrs["units"] = unit
    return ds, truth
