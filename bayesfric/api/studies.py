"""Public API: a study built from Python objects or a TOML file, run into a report folder.

:class:`Study` *is* the validated study of :mod:`bayesfric.study.config` (a subclass that only
adds constructors): ``Study(...)`` assembles the TOML file's tables from its arguments and
validates them with the same schema and checks (:func:`~bayesfric.study.config.study_from_raw`),
so every error names the key as a study file would, prefixed ``Study('<name>')``.
:func:`run` is :func:`bayesfric.pipeline.runner.execute_study`; it returns a :class:`StudyResult`
that holds the report folder, the result tree the run saved as ``results.nc`` and every law's fit,
as the run held them in memory (an unchanged rerun reads them from the earlier run's folder). The
report itself (``summary.md``, ``report.html``, CSV tables, figures) is written by :func:`run`
and rendered from the result tree alone; :func:`bayesfric.api.reports.write_report` renders it
again from a result, its tree or its ``results.nc`` into another folder.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.laws.base import Law
from bayesfric.priors import Prior
from bayesfric.study import config

__all__ = ["Study", "StudyResult", "run", "as_study"]


def _plain(value: Any) -> Any:
    """Python objects as the TOML reader gives them: dicts, lists, strings, numbers."""
    if isinstance(value, Prior):
        return value.to_dict()
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return str(value) if isinstance(value, Path) else value


def _law_entry(where: str, i: int, entry: Any, files: list[str]) -> dict[str, Any]:
    """The ``[[laws]]`` table of one entry; a law object's file, if it is not registered, is
    appended to ``files`` (the study's law files, so every process can load it)."""
    if isinstance(entry, str):
        return {"name": entry}
    if isinstance(entry, Law):
        return _law_object(f"{where}: laws[{i}]", entry, files)
    if isinstance(entry, Mapping):
        return _plain(entry)
    raise config.StudyError(f"{where}: laws[{i}]: expected a law name, a Law or a dict of a [[laws]] "
                            f"entry, got {type(entry).__name__}")


def _law_object(where: str, law: Law, files: list[str]) -> dict[str, Any]:
    """A Law given as an object: registered (its name), a variant (its recipe as the entry's keys,
    labelled by its name, with the files of its base and added laws), or declared without
    registering (its name, and the file that declares it, which the study's processes load:
    :func:`bayesfric.laws.plugins.law_file`)."""
    from bayesfric.laws.base import REGISTRY
    from bayesfric.laws.plugins import law_file, law_files, unregistered_law

    if REGISTRY.get(law.name) is law:
        return {"name": law.name}
    if law.recipe:
        if unknown := set(law.recipe) - {"base", "add", "fixed", "asymmetric", "vary_by", "trend", "trend_form"}:
            raise config.StudyError(f"{where}: variant {law.name!r} ({', '.join(sorted(unknown))}) is made for "
                                    "one data set; give the law it was made from")
        files.extend(f for f in law_files(law) if f not in files)  # of its base and added laws
        label = re.sub(r"[^A-Za-z0-9_.-]", "_", law.name)  # a plain name: "a+offset" -> "a_offset"
        return {"name": law.recipe["base"], "label": label} | {k: _plain(v) for k, v in law.recipe.items()
                                                               if k != "base"}
    if law.name in REGISTRY:
        raise config.StudyError(f"{where}: law {law.name!r} is not the registered law of that name: "
                                "declare yours under another name")
    if (path := law_file(law)) is not None:
        files.extend([str(path)] if str(path) not in files else [])
    elif unregistered_law(law.name) is not law:
        raise config.StudyError(f"{where}: law {law.name!r} cannot be found by its name: declare it with "
                                "bayesfric.law(fn, ...) or in a law file")
    return {"name": law.name}


def _sizing_entry(where: str, i: int, entry: Any) -> dict[str, Any]:
    from bayesfric.sizing.points import SizingError, value_text

    if not isinstance(entry, Mapping):
        raise config.StudyError(f"{where}: sizing[{i}]: expected a dict of a [[sizing]] entry (at, capacity, ...)")
    out = _plain(entry)
    try:
        if isinstance(entry.get("at"), Mapping):
            out["at"] = {str(k): value_text(v, f"at.{k}", str(k)) for k, v in entry["at"].items()}
        for key, quantity in (("capacity", "torque"), ("energy_rotation", "angle"), ("horizon", "time")):
            if entry.get(key) is not None and (key != "horizon" or isinstance(entry[key], tuple | list)):
                out[key] = value_text(entry[key], key, quantity)  # a horizon may be a number in the column's unit
    except SizingError as exc:
        raise config.StudyError(f"{where}: sizing[{i}].{exc}") from None
    return out


def _noise_table(where: str, noise: Any) -> dict[str, Any]:
    from bayesfric.model import Noise

    if isinstance(noise, str):
        return {"kind": noise}
    if isinstance(noise, Noise):
        if noise.sigma is not None:
            raise config.StudyError(f"{where}: [noise] sigma: a study samples the noise; a known sigma is for fit()")
        return {"kind": noise.kind} | ({"group": noise.group} if noise.group else {})
    return _plain(noise)


class Study(config.Study):
    """A study: data, candidate laws, comparisons, sizing questions; :func:`run` runs it.

    Built from Python objects with the keys of a study file's tables (documented in
    :mod:`bayesfric.study.config`), or read from one with :meth:`from_toml`.

    Parameters
    ----------
    name : str
        Plain name (letters, digits, ``-``, ``_``, ``.``): the report folder ``<out>/<name>/``.
    data : str or Path
        Built-in data set name or CSV path (relative to the working folder).
    laws : sequence
        Each a registered name, a :class:`~bayesfric.laws.Law`, or a dict of a ``[[laws]]`` entry
        (``{"name": "stribeck", "priors": {...}, "fixed": {...}}``). A law object may be a
        variant (``law("stribeck").fix(delta=1)``: its recipe becomes the entry, labelled by its
        name with any character other than letters, digits, ``-``, ``_``, ``.`` as ``_``) or a law
        declared without registering it (``bayesfric.law(fn, units=...)``): if a file declares
        it, that file joins ``modules``, so ``--workers`` and Dask processes load it too; a law
        declared in a notebook or script is found by its name in this process only (run the
        study without workers, or move the law into a file).
    title, question : str, optional
        Report title and the question the study answers.
    select : mapping, optional
        ``[data] select``: rows to keep.
    every : int
        ``[data] every``: keep one row in ``every`` (of each trajectory, its first row kept).
    max_levels : int, optional
        ``[data] max_levels``: confirm a group column with more levels than
        :data:`bayesfric.datasets.rows.MAX_LEVELS` (each a leave-one-group-out refit).
    noise : str, mapping or Noise, optional
        ``[noise]``: ``"proportional"``, ``{"kind": "normal", "group": "series"}``.
    sampler, compare : mapping, optional
        ``[sampler]`` (draws, tune, chains, seed, ...) and ``[compare]`` (loo, kfold, grouped,
        evidence, ``blocked=[{"axis": "velocity", "threshold": 0.5}]``, ...).
    sizing, claims : sequence of mappings, optional
        ``[[sizing]]`` entries (values as in :func:`bayesfric.size`: ``(0.5, 6, "rad/s")``) and ``[[claims]]``.
    modules : sequence of str, optional
        ``[study] modules``: law files (relative to the working folder).

    Raises
    ------
    StudyError
        One line naming the key, e.g. ``Study('bench'): [sampler] draws: ...``.

    Examples
    --------
    >>> import bayesfric
    >>> study = bayesfric.Study("bench", "robot_joint", laws=["coulomb_viscous", "stribeck"],
    ...                         sampler={"draws": 200, "tune": 200, "chains": 2},
    ...                         compare={"evidence": False, "blocked": [{"axis": "velocity", "threshold": 0.5}]},
    ...                         sizing=[{"at": {"velocity": (0.5, 6, "rad/s")}, "capacity": (40, "N*m")}])
    >>> [spec.name for spec in study.laws], study.sizing[0].capacity_text
    (['coulomb_viscous', 'stribeck'], '40 N*m')
    >>> bayesfric.Study("bench", "robot_joint", laws=["stribeck"], sampler={"draws": 0})
    Traceback (most recent call last):
    ...
    bayesfric.study.spec.StudyError: Study('bench'): [sampler] draws: must be an integer ≥ 1, got integer 0
    """

    def __init__(self, name: str, data: str | Path, *, laws: Sequence[str | Law | Mapping[str, Any]],
                 title: str | None = None, question: str | None = None, select: Mapping[str, Any] | None = None,
                 every: int = 1, max_levels: int | None = None,
                 noise: Any = None, sampler: Mapping[str, Any] | None = None,
                 compare: Mapping[str, Any] | None = None, sizing: Sequence[Mapping[str, Any]] = (),
                 claims: Sequence[Mapping[str, Any]] = (), modules: Sequence[str | Path] = ()) -> None:
        from bayesfric.fsutil import name_problem

        if not isinstance(name, str) or (problem := name_problem(name)):
            raise config.StudyError(f"Study: name: {problem if isinstance(name, str) else 'must be a string'}")
        where = f"Study({name!r})"
        if isinstance(data, xr.Dataset) or not isinstance(data, str | Path):
            raise config.StudyError(f"{where}: [data] dataset: a study reads its data itself: give a built-in "
                                    "name or a CSV path")
        files: list[str] = []  # the files of laws given as objects, declared but not registered
        entries = [_law_entry(where, i, x, files) for i, x in enumerate(laws)]
        meta = {"name": name, "title": title, "question": question,
                "modules": _plain(list(modules)) + [f for f in files if f not in _plain(list(modules))] or None}
        raw = {"study": {k: v for k, v in meta.items() if v is not None},
               "data": {"dataset": str(data)} | ({"select": _plain(select)} if select else {})
                       | ({"every": every} if every != 1 else {})
                       | ({"max_levels": max_levels} if max_levels is not None else {}),
               "laws": entries,
               "sizing": [_sizing_entry(where, i, x) for i, x in enumerate(sizing)],
               "claims": _plain(list(claims))}
        for key, value in (("noise", None if noise is None else _noise_table(where, noise)),
                           ("sampler", sampler), ("compare", compare)):
            if value is not None:
                raw[key] = _plain(value)
        self.__dict__.update(vars(config.study_from_raw(Path(where), raw)))

    @classmethod
    def from_toml(cls, path: str | Path) -> Study:
        """Read and validate a study file (:func:`bayesfric.study.config.load_study`).

        Examples
        --------
        >>> import bayesfric
        >>> from bayesfric.study import STUDIES_DIR
        >>> bayesfric.Study.from_toml(STUDIES_DIR / "robot_joint.toml").name
        'robot_joint'
        """
        study = cls.__new__(cls)
        study.__dict__.update(vars(config.load_study(path)))
        return study


def process_local_laws(study: config.Study) -> list[str]:
    """The laws of ``study`` that only this process can build: declared (not registered) in a
    notebook, a script or a function, in no law file a worker process would load
    (:func:`bayesfric.laws.plugins.law_file`)."""
    from bayesfric.laws.base import REGISTRY
    from bayesfric.laws.plugins import law_file, load_modules, unregistered_law

    out = []
    for spec in study.laws:
        load_modules(spec.modules)
        for name in (spec.law or spec.name, *spec.add):
            law = unregistered_law(name) if name not in REGISTRY else None
            if law is not None and law_file(law) is None and name not in out:
                out.append(name)
    return out


def as_study(study: Any, argument: str = "study") -> config.Study:
    """A study given as a :class:`Study` (or a loaded one) or as a study file's path."""
    if isinstance(study, config.Study):
        return study
    if isinstance(study, str | Path):
        return Study.from_toml(study)
    raise UserError(f"{argument}: expected a Study or a study file (.toml), got {type(study).__name__}")


@dataclass(frozen=True)
class StudyResult:
    """What :func:`run` wrote, read back: the report folder, its tables and the fits.

    Attributes
    ----------
    study : Study
    folder : Path
        ``<out>/<name>/``: ``summary.md``, ``report.html``, the CSV tables, ``figures/``, ``fits/``.
    scores : pandas.DataFrame
        ``scores.csv``: one row per law, metric (``elpd_loo``, ``elpd_cv``, ``penalty``,
        ``log_evidence``, ``weight``) and scheme, with ``estimate``, ``se``, ``reliable``, ``reason``.
    ranking : pandas.DataFrame
        ``ranking.csv``: the laws in the report's order, one row each.
    fits : dict of str to xarray.DataTree
        Each law's full fit (``fits/<law>.nc``).
    sizing : pandas.DataFrame or None
        ``sizing.csv`` (every law and point of every ``[[sizing]]`` question), if the study asks any:
        the table rendering of :attr:`sizing_answer`.
    tree : xarray.DataTree or None
        ``results.nc``: the same results as one DataTree (``/scores`` over law × criterion,
        ``/pointwise``, ``/weights``, ``/diagnostics``, ``/checks``, the tables, ``/fits/<law>``
        posteriors, ``/sizing_basis``; :mod:`bayesfric.study.tree`, :mod:`bayesfric.report.results`),
        which names the fit files. The tables above are its table nodes.
    """

    study: config.Study
    folder: Path
    scores: pd.DataFrame
    ranking: pd.DataFrame
    fits: dict[str, xr.DataTree] = field(repr=False)
    sizing: pd.DataFrame | None = None
    tree: xr.DataTree | None = field(default=None, repr=False)
    answer: Any = field(default=None, repr=False, compare=False)  # the run's SizingAnswer, when it made one

    @property
    def sizing_answer(self):
        """The study's sizing as one :class:`~bayesfric.sizing.SizingAnswer` (law × point ×
        quantile, ``q(p)``, ``to_dataframe()``), of which :attr:`sizing` is the table; None when
        the study asks no sizing question at a point. The run's own object when this process ran
        the study; else answered once from the report (as :func:`bayesfric.size` answers it, the
        same seed: the same numbers) and kept."""
        if self.answer is None and self.sizing is not None:
            from bayesfric.study.resize import size_from_report

            reports = self.folder.parent
            object.__setattr__(self, "answer", size_from_report(
                self.study, None, reports, keys={}, run_hint=f"bayesfric.run(study, out={str(reports)!r})"))
        return self.answer

    @classmethod
    def read(cls, study: config.Study, folder: str | Path) -> StudyResult:
        """Read the report folder of ``study`` (written by :func:`run` or ``bayesfric study``):
        its ``results.nc`` and the fit files it names."""
        from bayesfric.sizing import SizingError
        from bayesfric.sizing.single import read_fit

        folder = Path(folder)
        if not (folder / "results.nc").is_file():
            raise SizingError("", f"{folder / 'results.nc'}: missing; run the study again")
        with xr.open_datatree(folder / "results.nc") as opened:
            tree = opened.load()
        files = tree["sizing_basis"]["fit"]
        fits = {spec.name: read_fit(folder / str(files.sel(law=spec.name).values)) for spec in study.laws}
        return cls.from_tree(study, folder, tree, fits)

    @classmethod
    def from_tree(cls, study: config.Study, folder: Path, tree: xr.DataTree,
                  fits: Mapping[str, xr.DataTree], answer: Any = None) -> StudyResult:
        """The result of ``study`` from its result tree and fits, in memory (:func:`run` after it
        wrote the report) or read back (:meth:`read`): the tables are the tree's table nodes, typed
        as pandas reads the CSV files (:func:`bayesfric.report.stored.table_frame`)."""
        from bayesfric.report.stored import table_frame

        sizing = table_frame(tree["sizing"].to_dataset()) if "sizing" in tree.children else None
        return cls(study, folder, table_frame(tree["score_rows"].to_dataset()),
                   table_frame(tree["ranking"].to_dataset()), dict(fits), sizing, tree, answer)


def run(study: Study | str | Path, out: str | Path = "reports", *, quick: bool = False, fresh: bool = False,
        workers: int = 0) -> StudyResult:
    """Run a study: fit every law, compare them every way it asks, answer its sizing questions,
    and write the report to ``<out>/<name>/`` (what ``bayesfric study`` does).

    Units of work are reused from the run store (``<out>/.store/``) when nothing they depend on
    changed, and an unchanged study returns its report as it is.

    Parameters
    ----------
    study : Study, str or Path
        A :class:`Study` or a study file.
    out : str or Path
        Reports root folder.
    quick : bool
        Smoke test: fewer draws and folds (the report says so).
    fresh : bool
        Recompute every unit instead of reusing the run store.
    workers : int
        Run units on a local Dask cluster of this many processes (0: serially, in this process).

    Returns
    -------
    StudyResult

    Raises
    ------
    UserError
        A bad study, data, fold, claim, sizing question or output folder: one line, before
        anything is written.

    Examples
    --------
    >>> import bayesfric, tempfile
    >>> study = bayesfric.Study("doc", "robot_joint", laws=["coulomb_viscous", "stribeck"],
    ...                         sampler={"draws": 100, "tune": 100, "chains": 2},
    ...                         compare={"evidence": False, "blocked": [{"axis": "velocity", "threshold": 0.5}]})
    >>> result = bayesfric.run(study, tempfile.mkdtemp())  # doctest: +ELLIPSIS
    [doc] ...
    >>> sorted(result.fits), result.folder.name, "elpd_loo" in set(result.scores["metric"])
    (['coulomb_viscous', 'stribeck'], 'doc', True)
    """
    from bayesfric.fsutil import PathError, check_output_folder
    from bayesfric.limits import process_problem
    from bayesfric.pipeline.runner import execute_study

    chosen = as_study(study)
    try:
        check_output_folder(out)
    except PathError as exc:
        raise UserError(f"out: {exc}") from None
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise UserError(f"workers: must be 0 (serial) or a number of processes ≥ 1, got {workers!r}")
    if problem := process_problem(workers, "worker processes"):
        raise UserError(f"workers: {problem}")
    if workers and (local := process_local_laws(chosen)):
        raise UserError(f"workers: law {', '.join(map(repr, local))} is declared in this process only (a notebook "
                        "or script), which worker processes cannot load: run with workers=0, or move it into a "
                        "law file (Study(..., modules=[...]))")
    done = execute_study(chosen, out_root=out, quick=quick, fresh=fresh, workers=workers)
    if done.tree is None:  # an unchanged rerun: the report of an earlier run, read from its folder
        return StudyResult.read(chosen, done.folder)
    return StudyResult.from_tree(chosen, done.folder, done.tree, done.fits, done.sized)

