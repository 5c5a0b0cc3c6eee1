"""Residual-structure checks: at the same operating point, does the response
differ between groups, or trend with a column the law does not read, by more than the noise
model allows?

Statistic, per fit and per tested column:

1. **Residuals.** ``r_i = y_i − E[mu_i | data]``: the posterior mean (at most :data:`MAX_DRAWS`
   evenly thinned draws) of the observation's mean as the fit's own program computes it (its
   group offsets or hierarchical terms included: what the law already models is not residual).
   Each row's noise sd ``s_i`` is the root of the posterior mean of the noise model's variance
   there (:meth:`bayesfric.model.Program.observation`: a reduced data set's ``response_se`` in
   quadrature, proportional noise's ``sigma_rel mu_i``, AR(1)'s stationary marginal; a Student-t
   draw with ν ≤ 2 counts its squared scale).
2. **Conditioning on the operating point.** Weighted least squares (weights ``1/s_i²``) of ``r``
   on a smooth basis of the law's own inputs (:func:`operating_basis`: a cubic B-spline per
   input with knots at quantiles, separately per direction of motion for a velocity; factors for
   inputs with at most :data:`CATEGORICAL` values; every other input also per direction of
   motion; pairwise products while the basis stays under n/4 columns; a stateful law that reads
   a position but no velocity gets the direction of motion as an input, from the recorded
   velocity or the position's steps) — the null model — and on the basis plus the column's terms
   (group indicators; ``x`` and ``x²`` for a numeric column; each also times the direction of
   motion when the velocity changes sign, since a Coulomb level that differs between runs is odd
   in it). The column's terms are F-tested (nested models). A misfit of the law along its inputs
   is absorbed by the basis, so it is not read as a group effect when the groups cover other
   operating points; a column the basis already spans (a group nested in an input's levels)
   tests only what is left (``df`` counts it; 0: not testable, never flagged).
3. **Autocorrelation.** On a data set of ordered trajectories (``attrs["trajectory"]``: raw
   logs, hysteresis loops) neighbouring residuals are correlated and an i.i.d. F-test would
   false-alarm (measured: every time at ρ = 0.8). There the regression is AR(1)-prewhitened
   within each trajectory (feasible GLS, Prais–Winsten, first row of a trajectory scaled by
   ``√(1 − ρ²)``) before the F-test, ``ρ`` by REML of the full model: the residuals' plain
   lag-one correlation is biased low once the basis absorbs slow variation, and the
   under-corrected test false-alarmed 15 % instead of 5 %. Structure that AR(1) does not
   describe is not modelled (approximation). Data sets without a trajectory: independent rows.
4. **Multiplicity.** A column is flagged when ``p < alpha / m``, ``m`` the columns tested for
   the fit (Bonferroni), so a fit of a correct model false-alarms at most ``alpha`` (5 %).
5. **Effect size.** On the null model's residuals: the largest range, within one direction of
   motion, of their weighted fit on the column's terms (a group: of the groups' weighted mean
   residuals; a numeric column: of its x, x² trend), in response units, and that over the noise
   sd the weights average to (``1/√mean(1/s²)``).

The columns (:func:`columns_to_test`): every group coordinate, every input the law does not read
and every auxiliary column with a quantity other than the response's. The F-test is exact for a
law linear in its parameters with Gaussian noise; for others it is approximate, as the posterior
mean absorbs a little of the noise. Cost: one compiled, vectorised evaluation of the program
over the thinned draws plus a few least-squares fits per column: 0.1–0.5 s for a law of the
robot_joint study (1–11 % of its fit), up to ~8 s for a stateful law whose program compiles slowly.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import fields

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
from numpyro.handlers import seed, substitute, trace

from bayesfric.compare.structure_stats import (
    ALPHA,
    DIRECTION,
    Column,
    StructureCheck,
    operating_basis,
    structure_tests,
)
from bayesfric.datasets.views import trajectory_starts
from bayesfric.errors import UserError
from bayesfric.exported import program_options
from bayesfric.laws.base import Law
from bayesfric.limits import CHUNK_NUMBERS
from bayesfric.model import OBS_SITE, Program, program_of_fit
from bayesfric.quantities import QUANTITIES, parse_unit

__all__ = ["ALPHA", "Column", "StructureCheck", "residual_structure", "curvature_checks", "fit_residuals",
           "operating_basis", "structure_tests", "columns_to_test", "structure_dataset", "checks_of", "stack_structure",
           "DIM"]

#: Posterior draws the residuals' mean and noise sd are averaged over (evenly thinned).
MAX_DRAWS = 200
#: Dimension of the columns in a Dataset of checks.
DIM = "structure_column"


# -- residuals ---------------------------------------------------------------------------------
def _sample_sites(program: Program) -> list[str]:
    tr = trace(seed(program.model, 0)).get_trace(**program.model_kwargs)
    return [k for k, s in tr.items() if s["type"] == "sample" and not s.get("is_observed", False)]


def _moments(program: Program):
    """``(loc, var)`` of the observation per row for one draw of the sample sites."""
    noise = [k for k in program.noise.sites() if k != "group_sd"]

    def one(sample):
        tr = trace(substitute(seed(program.model, 0), sample)).get_trace(**program.model_kwargs)
        fn = tr[OBS_SITE]["fn"]
        while not hasattr(fn, "loc") and hasattr(fn, "base_dist"):
            fn = fn.base_dist
        obs = program.observation(fn.loc, {k: tr[k]["value"] for k in noise}, program.response_se)
        var = jnp.broadcast_to(obs.variance, jnp.shape(fn.loc))
        return fn.loc, jnp.where(jnp.isfinite(var), var, jnp.broadcast_to(obs.scale, var.shape) ** 2)

    return jax.jit(jax.vmap(one), compiler_options=program_options(program.n_obs, optimised=False))


def fit_residuals(fit: xr.DataTree, program: Program | None = None,
                  draws: int = MAX_DRAWS) -> tuple[np.ndarray, np.ndarray]:
    """The fit's residuals at its data and each row's noise sd (module docstring, step 1).

    Parameters
    ----------
    fit : xarray.DataTree
        A fit (:func:`bayesfric.inference.fit`), with its posterior and data.
    program : Program, optional
        Its program; rebuilt from the fit (:func:`bayesfric.model.program_of_fit`) when omitted.
    draws : int
        At most this many posterior draws, evenly thinned.

    Returns
    -------
    tuple of ndarray
        ``(r, s)``: ``y − E[mu]`` and the noise model's sd per row, in response units.

    Examples
    --------
    >>> r, s = fit_residuals(fit)  # doctest: +SKIP
    >>> float((r / s).std())       # about 1 for a law that fits  # doctest: +SKIP
    0.98
    """
    program = program_of_fit(fit) if program is None else program
    post = fit["posterior"]
    names = [k for k in _sample_sites(program) if k in post]
    flat = {k: np.asarray(post[k].values, dtype=float).reshape((-1,) + post[k].shape[2:]) for k in names}
    total = len(next(iter(flat.values())))
    pick = np.unique(np.linspace(0, total - 1, min(total, draws)).round().astype(int))
    moments, n = _moments(program), program.n_obs
    size = max(1, CHUNK_NUMBERS // max(1, n))
    loc, var = np.zeros(n), np.zeros(n)
    for a in range(0, pick.size, size):
        rows = pick[a:a + size]
        m, v = moments({k: jnp.asarray(x[rows]) for k, x in flat.items()})
        loc += np.asarray(m, dtype=float).reshape(len(rows), n).sum(axis=0)
        var += np.asarray(v, dtype=float).reshape(len(rows), n).sum(axis=0)
    return program.response - loc / pick.size, np.sqrt(var / pick.size)


# -- the columns of a data set and what would model them ---------------------------------------
def _level_params(law: Law) -> list[str]:
    """The law's parameters in the response's unit (its levels: Coulomb, offset ...)."""
    unit = QUANTITIES[law.response].unit if law.response in QUANTITIES else ""
    out = []
    for name, p in law.params.items():
        try:
            if unit and not p.shape and parse_unit(p.unit) == parse_unit(unit):
                out.append(name)
        except Exception:  # noqa: BLE001 - a unit pint cannot read is simply not a level
            continue
    return out[:3] or list(law.params)[:2]


def _suggestion(column: Column, law: Law) -> str:
    if column.kind == "group":
        params = ", ".join(f'"{p}"' for p in _level_params(law))
        return f"hierarchical parameters per group: vary_by = {{ {column.name} = [{params}] }}"
    q = column.quantity
    if q == "angle":
        return 'a position-dependent load: the gravity term (add = ["gravity"], G_c cos q + G_s sin q)'
    if q.endswith("acceleration"):
        return 'the drive\'s inertia (add = ["inertia"])'
    if q == "temperature":
        return "an input the law lacks: temperature (a thermal law, e.g. thermal_viscous_quadratic)"
    if q == "time":
        return "a drift the law lacks (warm-up, wear): temperature or time as an input, or vary_by per run"
    return f"an input the law lacks: {q}"


def columns_to_test(data: xr.Dataset, law: Law) -> list[Column]:
    """The columns of ``data`` whose effect ``law`` does not model.

    Every group coordinate (a group made from an input, ``group = true``, is tested as that
    input), every input the law does not read (a trend), and every auxiliary column with a
    quantity other than the response's (a column without one, e.g. the response rescaled, is
    not tested). Columns with one value are skipped. Why: these are the recorded things besides
    the operating point that could move the response.

    Examples
    --------
    >>> from bayesfric.datasets import load_dataset, resolve
    >>> from bayesfric.laws import get_law
    >>> [c.name for c in columns_to_test(load_dataset(resolve("unwinder")), get_law("coulomb_viscous"))]
    ['temperature', 'setup', 'cycle', 'time']
    """
    inputs = {str(v.attrs.get("column", k)) for k, v in data.coords.items() if v.attrs.get("role") == "input"}
    out = []
    for name, var in list(data.coords.items()) + list(data.data_vars.items()):
        role, quantity = var.attrs.get("role"), str(var.attrs.get("quantity", ""))
        label = str(var.attrs.get("column", name))
        if role == "group" and not (label in inputs and label != name):
            out.append(Column(str(name), "group", np.asarray(var.values), "", label))
        elif (role == "input" and name not in law.inputs) or (
                role == "aux" and quantity and quantity != law.response and quantity not in law.inputs):
            out.append(Column(str(name), "trend", np.asarray(var.values, dtype=float), quantity or str(name), label))
    return [c for c in out if np.unique(c.values).size > 1]


def residual_structure(fit: xr.DataTree, data: xr.Dataset, *, alpha: float = ALPHA,
                       program: Program | None = None) -> tuple[StructureCheck, ...]:
    """Test a fit's residuals against every group column and unread input of its data set.

    Does the response at the same operating point differ between groups (runs, series, units),
    or trend with a recorded column the law does not read (angle, time, temperature), by more
    than the noise model allows? The statistic, its autocorrelation handling and its
    false-alarm rate are in the module docstring.

    Parameters
    ----------
    fit : xarray.DataTree
        A fit of a law (:func:`bayesfric.fit`, a study's ``fits/<law>.nc``).
    data : xarray.Dataset
        The data set it was fitted on (same rows, same order), with its group columns.
    alpha : float
        Per-fit false-alarm rate (Bonferroni over the columns tested).
    program : Program, optional
        The fit's program (rebuilt from the fit when omitted).

    Returns
    -------
    tuple of StructureCheck
        One per column tested; ``flagged`` where the column's effect exceeds the noise.

    Examples
    --------
    >>> import bayesfric
    >>> data = bayesfric.load_data("robot_joint")                    # doctest: +SKIP
    >>> fit = bayesfric.fit("coulomb_viscous", data)                  # doctest: +SKIP
    >>> [c.sentence() for c in residual_structure(fit, data) if c.flagged]  # doctest: +SKIP
    """
    program = program_of_fit(fit) if program is None else program
    n = int(data.sizes["obs"])
    if program.n_obs != n:
        raise UserError(f"the fit has {program.n_obs} rows, the data set {n}: pass the data it was fitted on")
    resid, sd = fit_residuals(fit, program)
    law = program.law
    columns = columns_to_test(data, law)
    starts = trajectory_starts(data) if data.attrs.get("trajectory") else None
    point = _operating_point(program.inputs, law, data, starts)
    unit = QUANTITIES[law.response].unit if law.response in QUANTITIES else ""
    return structure_tests(resid, sd, point, columns, starts=starts, alpha=alpha, unit=unit,
                           suggestions={c.name: _suggestion(c, law) for c in columns}) + curvature_checks(
        program, resid, sd, starts, unit)


def curvature_checks(program: Program, resid: np.ndarray, sd: np.ndarray, starts: np.ndarray | None,
                     unit: str = "") -> tuple[StructureCheck, ...]:
    """Lack of fit along each of a steady law's own inputs (:mod:`bayesfric.compare.lackoffit`) as
    checks of kind ``"curvature"``: ``effect`` the relative bend times the mean ``|m|`` (response
    units, positive: convex, the data above the law at both ends), ``effect_sd`` its t statistic,
    ``p_value`` the F-test of ``u²`` and ``u³``. A stateful law's residuals along a trajectory are
    not tested (its sizing is at steady state, judged by :mod:`bayesfric.sizing.shape` where it has
    steady data)."""
    from bayesfric.compare.lackoffit import lack_of_fit

    law = program.law
    if law.trajectory:
        return ()
    mu = np.asarray(program.response, dtype=float) - resid
    inputs = {k: np.asarray(v, dtype=float) for k, v in program.inputs.items() if k in law.operating_inputs}
    if not inputs:
        return ()
    size = float(np.mean(np.abs(mu)))
    out = []
    for t in lack_of_fit(resid * np.sign(mu), sd, inputs, starts=starts, scale=size):
        way = "upward (convex" if t.curvature > 0 else "downward (concave"
        out.append(StructureCheck(
            t.axis, "curvature", int(np.unique(inputs[t.axis]).size), t.curvature * size, t.t, t.p_value, t.threshold,
            t.flagged, f"a law whose curve bends {way} against this one) along {t.axis}", unit,
            ", ".join(k for k in inputs if k != t.axis), t.rho, t.df))
    return tuple(out)


def _operating_point(inputs: Mapping[str, np.ndarray], law: Law, data: xr.Dataset,
                     starts: np.ndarray | None) -> dict:
    """The law's inputs, plus the direction of motion for a stateful law that reads no velocity
    (its state depends on it: a hysteresis loop has two branches per angle): the sign of the
    data set's velocity where it records one, else of the position's step along each trajectory."""
    out = dict(inputs)
    position = next((k for k in ("angle", "displacement") if k in inputs), None)
    if not law.trajectory or position is None or any(k.endswith("velocity") for k in inputs):
        return out
    recorded = next((k for k in ("velocity", "linear_velocity") if k in data.coords), None)
    if recorded is not None:
        out[DIRECTION] = np.sign(np.asarray(data[recorded].values, dtype=float))
        return out
    x = np.asarray(inputs[position], dtype=float)
    step = np.sign(np.diff(x, append=x[-1:]))
    ends = np.r_[starts[1:], True] if starts is not None else np.zeros(x.size, dtype=bool)
    step[ends] = np.sign(x - np.r_[x[:1], x[:-1]])[ends]  # a trajectory's last row: its own last step
    out[DIRECTION] = step
    return out


# -- as a Dataset (a study's checks unit, its result tree) -------------------------------------
_FIELDS = [f.name for f in fields(StructureCheck) if f.name != "column"]
_DTYPES = {"str": str, "int": np.int64, "float": float, "bool": bool}


def structure_dataset(checks: Sequence[StructureCheck]) -> xr.Dataset:
    """The checks as a Dataset over :data:`DIM` (variables ``structure_<field>``).

    Examples
    --------
    >>> structure_dataset(()).sizes[DIM]
    0
    """
    data = {f"structure_{f.name}": (DIM, np.array([getattr(c, f.name) for c in checks], dtype=_DTYPES[str(f.type)]))
            for f in fields(StructureCheck) if f.name != "column"}
    return xr.Dataset(data, coords={DIM: np.array([c.column for c in checks], dtype=str)})


def checks_of(ds: xr.Dataset) -> tuple[StructureCheck, ...]:
    """The checks a Dataset holds (:func:`structure_dataset`, one law of :func:`stack_structure`);
    padding (an empty ``kind``) is skipped.

    Examples
    --------
    >>> checks_of(structure_dataset(()))
    ()
    """
    if DIM not in ds.dims:
        return ()
    out = []
    for i, column in enumerate(ds[DIM].values):
        row = {k: ds[f"structure_{k}"].values[i] for k in _FIELDS if f"structure_{k}" in ds}  # older trees lack some
        if not str(row["kind"]):
            continue
        out.append(StructureCheck(str(column), **{f.name: _typed(f.type, row[f.name])
                                                 for f in fields(StructureCheck) if f.name in row}))
    return tuple(out)


def _typed(kind: str, value):
    return {"str": str, "int": int, "float": float, "bool": bool}[str(kind)](value)


def stack_structure(laws: Sequence[tuple[str, xr.Dataset]]) -> xr.Dataset:
    """Each law's ``structure_*`` variables over ``(law, structure_column)``: the union of the
    columns, padded (NaN, ``""``, False, −1) where a law did not test one (it reads the input).

    Examples
    --------
    >>> stack_structure([("a", structure_dataset(()))]).sizes[DIM]
    0
    """
    columns = list(dict.fromkeys(str(c) for _, ds in laws if DIM in ds.dims for c in ds[DIM].values))
    pad = {"str": "", "int": -1, "float": np.nan, "bool": False}
    out = {}
    for f in fields(StructureCheck):
        if f.name == "column":
            continue
        key, fill = f"structure_{f.name}", pad[str(f.type)]
        rows = [[ds[key].sel({DIM: c}).values.item() if DIM in ds.dims and c in ds[DIM].values else fill
                 for c in columns] for _, ds in laws]
        out[key] = (("law", DIM), np.array(rows, dtype=_DTYPES[str(f.type)]).reshape(len(laws), len(columns)))
    return xr.Dataset(out, coords={"law": [n for n, _ in laws], DIM: np.array(columns, dtype=str)})
