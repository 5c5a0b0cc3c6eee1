"""Public API: predictions of a study's laws (or of one fit) at the rows of a new log, and scores there.

``bayesfric predict`` and ``bayesfric score`` call the same functions. What they read is what
sizing reads (:mod:`bayesfric.sizing.store`): a study's fits, stacking weights and gate verdicts
from its result tree (``results.nc``, or a :class:`~bayesfric.api.studies.StudyResult`), the
weights chosen for the new log's rows as sizing chooses them for a question's points
(:func:`bayesfric.sizing.choose_basis`: LOO stacking inside the tested envelope, the blocked folds'
stacking beyond it), laws that failed the gate left out of the average and named; or one fit
(``bayesfric fit --out``). The computing is :mod:`bayesfric.predictive`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from bayesfric.argcheck import quantile_levels, seed_value
from bayesfric.errors import UserError

__all__ = ["predict", "score", "predictions_table", "score_text", "QUANTILES"]

#: Quantile levels reported by default.
QUANTILES = (0.05, 0.5, 0.95)
_BANDS = ("within-model bands: parameter (and group) uncertainty and the fit's noise model; not widened by the "
          "model-form error blocked folds measured (sizing's calibrated answers)")


@dataclass(frozen=True)
class _Sources:
    laws: list  # of bayesfric.sizing.LawSource
    schemes: list  # of bayesfric.sizing.Scheme
    label: str
    study: bool


def _fit_node(node: xr.DataTree) -> xr.DataTree:
    """A ``/fits/<law>`` node of a result tree as a fit of its own (loaded)."""
    groups = {name: node[name].to_dataset().load() for name in node.children}
    return xr.DataTree.from_dict({"/": xr.Dataset(attrs=dict(node.attrs))} | groups)


def _tree_sources(tree: xr.DataTree, folder: Path, label: str, fits: dict | None = None) -> _Sources:
    from bayesfric import sizing

    if not set(sizing.store.NODES) <= set(tree.children):
        raise UserError(f"{label}: not a study's result tree (no {', '.join(sizing.store.NODES)} nodes); "
                        "rerun the study with this version")
    if fits is None and "fits" in tree.children:
        fits = {name: _fit_node(tree["fits"][name]) for name in tree["fits"].children}
    basis = xr.DataTree.from_dict({n: tree[n].to_dataset().load()
                                   for n in sizing.store.NODES + sizing.store.OPTIONAL if n in tree.children})
    return _Sources(sizing.sources(basis, folder, fits=fits), sizing.basis_schemes(basis), label, True)


def _fit_source(fit: xr.DataTree, label: str) -> _Sources:
    from bayesfric.sizing import LawSource

    if not {"law", "noise", "priors", "constants"} <= set(fit.attrs) or "posterior" not in fit.children:
        raise UserError(f"{label}: not a bayesfric fit or study result (no law, noise model or posterior recorded)")
    return _Sources([LawSource(str(fit.attrs["law"]), fit)], [], label, False)


def _path_sources(path: Path) -> _Sources:
    import h5netcdf

    from bayesfric.sizing.single import read_fit

    results = path / "results.nc" if path.is_dir() else path
    if not results.is_file():
        raise UserError(f"{path}: no such file or report folder (a study's report folder, its results.nc, or a fit)")
    try:
        with h5netcdf.File(results, "r") as fh:
            is_study = "sizing_basis" in fh.groups
    except (OSError, ValueError):
        raise UserError(f"{results}: not a readable NetCDF file (a study's results.nc or a fit)") from None
    if not is_study:
        return _fit_source(read_fit(results), str(results))
    with xr.open_datatree(results, engine="h5netcdf") as tree:
        return _tree_sources(tree, results.parent, str(results))


def _sources(source: Any, key: str) -> _Sources:
    from bayesfric.api.studies import StudyResult

    if isinstance(source, StudyResult):
        return _tree_sources(source.tree, source.folder, f"study {source.study.name}", dict(source.fits))
    if isinstance(source, xr.DataTree):
        if "sizing_basis" in source.children:
            return _tree_sources(source, Path("."), f"study {source.attrs.get('study', '?')}")
        return _fit_source(source, f"fit of {source.attrs.get('law', '?')}")
    if isinstance(source, str | Path):
        return _path_sources(Path(source))
    raise UserError(f"expected a StudyResult, a fit (DataTree), a report folder, a results.nc or a fit file, "
                    f"got {type(source).__name__}", key)


def _log(data: Any, key: str) -> tuple[xr.Dataset, str]:
    from bayesfric.api.fitting import load_data

    if not isinstance(data, str | Path | xr.Dataset):
        raise UserError(f"expected a CSV file (with its TOML sidecar), a built-in name or an xarray.Dataset, "
                        f"got {type(data).__name__}", key)
    if isinstance(data, str | Path) and str(data).endswith(".csv"):  # a log may lack the response
        from bayesfric.datasets import load_dataset

        ds = load_dataset(data, response=False)
    else:
        ds = load_data(data)
    return ds, str(ds.attrs.get("csv_file") or (data if isinstance(data, str | Path) else ds.attrs.get("name", key)))


def _new_run(src: _Sources, group: Any, seed: int, preds: list) -> tuple[Any, list]:
    """The new-run rule over a study's laws (:mod:`bayesfric.sizing.newrun`; none for one fit or
    a named group) and the laws' predictions, a law blind to a flagged group widened by its spread."""
    from dataclasses import replace

    from bayesfric.sizing.answer import new_run_rule
    from bayesfric.sizing.newrun import NewRun

    rule = new_run_rule(src.laws) if src.study and group is None else NewRun()
    out = [replace(p, mixture=replace(p.mixture, mu=rule.widen(p.name, p.mixture.mu, seed))) if rule.widened(p.name)
           else p for p in preds]
    return rule, out


def _bend(src: _Sources, ds: xr.Dataset, weights: dict[str, float] | None, seed: int) -> str:
    """What the answer says first where the log lies beyond the fitted data along an input and the
    data bend upward against every weighted law there (:mod:`bayesfric.sizing.shape`)."""
    from bayesfric.sizing.shape import fits_bend

    fits = {s.name: s.fit for s in src.laws}
    used = weights if weights is not None else {src.laws[0].name: 1.0}
    inputs = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
    found = fits_bend(fits, used, {k: np.asarray(ds[k].values, dtype=float) for k in inputs}, seed)
    return found.statement if found.upward else ""


def _weights(src: _Sources, ds: xr.Dataset, new_run=None) -> tuple[dict[str, float] | None, str, str]:
    """(law -> weight > 0 of the average, or None for one fit; the weighting; its note)."""
    from bayesfric.sizing import choose_basis

    if not src.study:
        return None, "single fit", "one law: no model average"
    inputs = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
    data = {}
    for s in src.laws:
        held = s.fit["constant_data"]
        data |= {k: np.asarray(held[k].values, dtype=float) for k in inputs if k in held and k not in data}
    grid = {k: np.asarray(ds[k].values, dtype=float) for k in data}
    used = [s.name for s in src.laws if s.excluded is None]
    basis = choose_basis(grid, data, src.schemes, used, {s.name: dict(s.weights) for s in src.laws},
                         {s.name: dict(s.misses) for s in src.laws}, {s.name: dict(s.penalties) for s in src.laws},
                         new_run)
    weights = {k: float(v) for k, v in basis.weights.items() if k in used and math.isfinite(v) and v > 0}
    return weights, basis.key, basis.note


def _prepare(source, data, group, seed, keys: dict[str, str]):
    """Every check, then each law's predictive mixture on the new log."""
    from bayesfric.laws.plugins import LawModuleError
    from bayesfric.limits import predict_problem
    from bayesfric.predictive import MAX_DRAWS, check_group, envelope_note, law_prediction

    seed = seed_value(seed, keys["seed"])
    src = _sources(source, keys["source"])
    ds, where = _log(data, keys["data"])
    if group is not None and not isinstance(group, str | int):
        raise UserError(f"expected a group label, got {type(group).__name__}", keys["group"])
    check_group({s.name: s.fit for s in src.laws}, None if group is None else str(group), keys["group"], src.label)
    draws = [min(MAX_DRAWS, s.fit["posterior"].sizes["chain"] * s.fit["posterior"].sizes["draw"]) for s in src.laws]
    if problem := predict_problem(len(draws), max(draws, default=0), ds.sizes["obs"]):
        raise UserError(f"{where}: {problem}", keys["data"])
    try:
        preds = [law_prediction(s.name, s.fit, ds, group=None if group is None else str(group), seed=seed,
                                where=where) for s in src.laws]
    except LawModuleError:
        raise
    except (KeyError, ValueError) as exc:
        if isinstance(exc, UserError):
            raise
        raise UserError(f"{src.label}: a fit's program cannot be rebuilt: {exc.args[0]}") from None
    new_run, preds = _new_run(src, group, seed, preds)
    weights, weighting, note = _weights(src, ds, new_run)
    attrs = {"source": src.label, "data": where, "new_run": new_run.statement,
             "bend": _bend(src, ds, weights, seed),
             "weighting": weighting, "weighting_note": note,
             "weights": json.dumps(weights or {}), "bands": _BANDS,
             "answer_for": "; ".join(sorted({p.answer_for for p in preds if p.answer_for}))
             or "the fitted laws as they are (no group structure)",
             "excluded": "; ".join(f"{s.name}: {s.excluded}" for s in src.laws if s.excluded),
             "no_average": "" if weights or weights is None else
             f"no law it may use has a positive weight ({weighting})",
             "noise_note": "; ".join(sorted({p.noise_note for p in preds if p.noise_note})),
             "draws": "; ".join(f"{p.name}: {p.draws}" for p in preds),
             "envelope": envelope_note({s.name: s.fit for s in src.laws}, ds),
             "response": str(ds.attrs.get("response", ""))}
    return src, ds, where, preds, weights, attrs


#: How errors name the arguments: Python's (API_KEYS) and the command line's (CLI_KEYS).
API_KEYS = {"source": "source", "data": "data", "group": "group", "quantiles": "quantiles", "seed": "seed"}
CLI_KEYS = {"source": "TARGET", "data": "LOG", "group": "--group", "quantiles": "--quantiles", "seed": "--seed"}


def predicted(source: Any, data: Any, quantiles: Any, group: Any, seed: int, keys: dict[str, str]) -> xr.Dataset:
    """:func:`predict` with errors naming ``keys`` (:data:`API_KEYS` or :data:`CLI_KEYS`)."""
    from bayesfric.predictive import AVERAGE, prediction_dataset

    levels = quantile_levels(quantiles, keys["quantiles"])
    src, ds, _, preds, weights, attrs = _prepare(source, data, group, seed, keys)
    out = prediction_dataset(preds, ds, levels, weights=weights, attrs=attrs)
    excluded = {s.name: s.excluded or "" for s in src.laws}
    laws = [str(k) for k in out["law"].values]
    weight = [1.0 if k == AVERAGE or weights is None else weights.get(k, 0.0) for k in laws]
    return out.assign_coords(weight=("law", weight), excluded=("law", [excluded.get(k, "") for k in laws]))


def scored(source: Any, data: Any, group: Any, seed: int, keys: dict[str, str]) -> pd.DataFrame:
    """:func:`score` with errors naming ``keys`` (:data:`API_KEYS` or :data:`CLI_KEYS`)."""
    from bayesfric.predictive import score_frame

    src, ds, where, preds, weights, attrs = _prepare(source, data, group, seed, keys)
    response = ds.attrs.get("response")
    if response not in ds.data_vars:
        raise UserError(f"{where}: has no response column; scoring compares the predictions with it", keys["data"])
    frame = score_frame(preds, np.asarray(ds[response].values, dtype=float), weights=weights)
    frame.attrs.update(attrs)
    return frame


def predict(source: Any, data: Any, *, quantiles: Sequence[float] = QUANTILES, group: str | None = None,
            seed: int = 0) -> xr.Dataset:
    """Predictions of a study's laws and their model average (or of one fit) at every row of a new log.

    What for: the mean curve and the band a new measurement should fall in, row by row along a
    log nobody fitted (another run, another unit, a faster trajectory), from the study's own
    fits and weights, without refitting. Stateful laws run along the new log's trajectories.

    Parameters
    ----------
    source : StudyResult, xarray.DataTree, str or Path
        A study's result (:func:`bayesfric.run`), its report folder or ``results.nc``, or a fit
        (:func:`bayesfric.fit`, or a file of ``bayesfric fit --out``).
    data : str, Path or xarray.Dataset
        The new log: a CSV file with its TOML sidecar, a built-in name, or a loaded data set. It
        must give every input the laws read; its response is not used here.
    quantiles : sequence of float
        Levels in (0, 1) of the mean curve's and the noisy predictive's quantiles.
    group : str, optional
        Answer for this group of the fits (partial-pooled groups); default: a new group.
    seed : int
        Seed of the new group's offsets.

    Returns
    -------
    xarray.Dataset
        ``mean`` (law, obs), ``curve`` and ``predictive`` (law, quantile, obs), all SI, the law
        ``"model average"`` included for a study; coordinates ``weight`` and ``excluded`` per law;
        ``attrs``: ``answer_for``, ``weighting`` and its note, ``excluded``, ``bands``,
        ``noise_note``, ``draws``, ``envelope`` (how far rows lie outside the data the fits saw,
        per input, in tested ranges as sizing measures it; ``""`` inside).

    Raises
    ------
    UserError
        One line naming the argument: an unreadable source, a log lacking an input a law reads
        (naming the file and the input), a stateful law on a log that restarts without a
        trajectory column, a log too large for the memory available, no quantile level, one
        outside (0, 1) or given twice, a seed outside 0 … 2**32 − 1, a group no fit has.

    Examples
    --------
    >>> import bayesfric
    >>> f = bayesfric.fit("coulomb_viscous", "robot_joint", draws=100, tune=100, chains=2)
    >>> pred = bayesfric.predict(f, "robot_joint", quantiles=[0.05, 0.95])
    >>> pred["predictive"].dims, bool((pred["predictive"][0, 0] <= pred["predictive"][0, 1]).all())
    (('law', 'quantile', 'obs'), True)
    """
    return predicted(source, data, quantiles, group, seed, API_KEYS)


def score(source: Any, data: Any, *, group: str | None = None, seed: int = 0) -> pd.DataFrame:
    """How well a study's laws and their model average (or one fit) predict a new log, row by row.

    What for: a ranking on the next run rather than on the data the laws were fitted to: the
    log predictive density, the error of the posterior-mean prediction and whether the bands
    hold their stated coverage there.

    Parameters
    ----------
    source, data, group, seed
        As :func:`predict`; the log must have its response column.

    Returns
    -------
    pandas.DataFrame
        Tidy: ``law``, ``metric``, ``value``. Metrics: ``elpd`` (sum over rows of the log of the
        mean over draws of each row's predictive density), ``elpd_per_point``, ``elpd_se``,
        ``rms`` (of the posterior-mean prediction), ``coverage_50`` and ``coverage_90`` (share of
        rows inside the central bands with noise), ``n`` (rows). ``frame.attrs`` as
        :func:`predict`'s ``attrs``.

    Examples
    --------
    >>> import bayesfric
    >>> f = bayesfric.fit("coulomb_viscous", "robot_joint", draws=100, tune=100, chains=2)
    >>> table = bayesfric.score(f, "robot_joint")
    >>> sorted(set(table["metric"]))[:3], int(table.query("metric == 'n'")["value"].iloc[0])
    (['coverage_50', 'coverage_90', 'elpd'], 111)
    """
    return scored(source, data, group, seed, API_KEYS)


def predictions_table(pred: xr.Dataset) -> pd.DataFrame:
    """:func:`predict`'s Dataset as one row per law and log row (``row`` from 1): the log's inputs
    and response, ``mean``, ``curve_q<level>`` and ``predictive_q<level>``, SI units."""
    from bayesfric.datasets.loader import OBS_DIM

    frames = []
    n = pred.sizes[OBS_DIM]
    for law in pred["law"].values:
        one = pred.sel(law=law)
        cols: dict[str, Any] = {"law": [str(law)] * n, "row": np.arange(1, n + 1)}
        cols |= {k: one[k].values for k, v in pred.coords.items() if v.dims == (OBS_DIM,)}
        if "response" in pred:
            cols["response"] = pred["response"].values
        cols["mean"] = one["mean"].values
        for var in ("curve", "predictive"):
            cols |= {f"{var}_q{q:g}": one[var].sel(quantile=q).values for q in pred["quantile"].values}
        frames.append(pd.DataFrame(cols))
    return pd.concat(frames, ignore_index=True)


def score_text(frame: pd.DataFrame) -> str:
    """:func:`score`'s table as printed by ``bayesfric score``: one line per law."""
    wide = frame.pivot(index="law", columns="metric", values="value").reindex(list(dict.fromkeys(frame["law"])))
    head = f"{'law':<28} {'elpd':>11} {'± se':>8} {'per row':>9} {'RMS':>10} {'in 50 %':>8} {'in 90 %':>8} {'rows':>6}"
    lines = [head]
    for law, r in wide.iterrows():
        lines.append(f"{str(law)[:28]:<28} {r['elpd']:>11.4g} {r['elpd_se']:>8.3g} {r['elpd_per_point']:>9.4g} "
                     f"{r['rms']:>10.4g} {r['coverage_50']:>8.1%} {r['coverage_90']:>8.1%} {int(r['n']):>6d}")
    return "\n".join(lines)
