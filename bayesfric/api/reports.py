"""Public API: a study's report rendered again from its result tree alone (:func:`write_report`)."""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from bayesfric.api.studies import StudyResult
from bayesfric.errors import UserError

__all__ = ["write_report"]


def write_report(result: StudyResult | xr.DataTree | str | Path, folder: str | Path) -> Path:
    """Write a study's report into a new folder from its result tree alone: ``summary.md``,
    ``report.html``, the CSV tables, the figures and ``results.nc`` (what ``bayesfric report
    results.nc --out FOLDER`` does), the same bytes as the run's own report.

    Parameters
    ----------
    result : StudyResult, xarray.DataTree, str or Path
        What :func:`run` returned, its result tree (``result.tree``), or a ``results.nc`` file.
    folder : str or Path
        A new or empty folder; written atomically (a hidden folder beside it, renamed when complete).

    Returns
    -------
    Path
        ``folder``.

    Raises
    ------
    UserError
        ``result`` holds no study report (a fit, another file), or ``folder`` exists and is not
        empty, is a link, or cannot be created: one line, nothing written.

    Examples
    --------
    >>> import bayesfric, tempfile, pathlib
    >>> study = bayesfric.Study("doc2", "robot_joint", laws=["coulomb_viscous"],
    ...                         sampler={"draws": 100, "tune": 100, "chains": 2}, compare={"evidence": False})
    >>> result = bayesfric.run(study, tempfile.mkdtemp())  # doctest: +ELLIPSIS
    [doc2] ...
    >>> copy = bayesfric.write_report(result, pathlib.Path(tempfile.mkdtemp()) / "copy")
    >>> (copy / "summary.md").read_bytes() == (result.folder / "summary.md").read_bytes()
    True
    """
    from bayesfric.report.summary import rerender

    if isinstance(result, StudyResult):
        if result.tree is None:
            raise UserError("result: holds no result tree (read it with StudyResult.read, or pass its results.nc)")
        result = result.tree
    elif not isinstance(result, xr.DataTree | str | Path):
        raise UserError(f"result: a StudyResult, its result tree or a results.nc file, got {type(result).__name__}")
    return rerender(result, folder)
