"""Public API: a saved fit read back with the program that produced it, and a fit's diagnostics."""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from bayesfric.errors import UserError
from bayesfric.model import Program

__all__ = ["load_fit", "diagnostics"]


def load_fit(path: str | Path) -> tuple[xr.DataTree, Program]:
    """A saved fit and the program that produced it.

    The program is rebuilt from what the fit records (:func:`bayesfric.model.program_of_fit`):
    the law by name with its variant recipe (fixed parameters, added terms, direction asymmetry,
    motion kind), the user's law files it came from (loaded again if this process has not), the
    noise model, priors resolved on the recorded data scale, the constants, and the fit's own
    inputs and response. Its log density is the fit's.

    Parameters
    ----------
    path : str or Path
        A NetCDF file written by ``bayesfric fit --out``, :func:`bayesfric.inference.save_fit`
        or a study (``reports/<study>/fits/<law>.nc``).

    Returns
    -------
    tree : xarray.DataTree
        The fit (posterior, log_likelihood, observed_data, constant_data ..., provenance attrs),
        as :func:`bayesfric.fit` returns it: :func:`bayesfric.size`, :func:`bayesfric.compare_laws`
        and :func:`bayesfric.diagnostics` take it.
    program : bayesfric.model.Program
        Its program (frozen): ``program.law``, ``program.priors``, ``program.density()`` ...

    Raises
    ------
    UserError
        No such file, not a bayesfric fit, or a law that cannot be rebuilt here (no longer
        registered, a recorded law file gone or failing to load), naming the file.

    Examples
    --------
    >>> import bayesfric, pathlib, tempfile
    >>> from bayesfric.inference import save_fit
    >>> f = bayesfric.fit(bayesfric.law("coulomb_viscous").fix(c_v=0.5), "robot_joint",
    ...                   draws=50, tune=100, chains=1)
    >>> path = save_fit(f, pathlib.Path(tempfile.mkdtemp()) / "fit.nc")
    >>> tree, program = bayesfric.load_fit(path)
    >>> program.law.name, dict(program.law.recipe["fixed"]), list(program.law.params)
    ('coulomb_viscous_c_v_eq_0.5', {'c_v': 0.5}, ['T_C'])
    """
    from bayesfric.laws.plugins import LawModuleError
    from bayesfric.model import program_of_fit
    from bayesfric.sizing.single import read_fit

    tree = read_fit(path)
    try:
        program = program_of_fit(tree)
    except LawModuleError:
        raise
    except (KeyError, ValueError) as exc:
        raise UserError(f"{path}: the fit's program cannot be rebuilt: {exc.args[0]}") from None
    return tree, program


def diagnostics(fit: xr.DataTree | str | Path) -> dict:
    """A fit's convergence diagnostics and the gate's verdict, as a plain dict.

    Why: the fit keeps them in its attrs in a form a NetCDF file can hold (text); this is the
    form to read them in, the same for a fit in memory and for one saved and read back.

    Parameters
    ----------
    fit : xarray.DataTree, str or Path
        A fit (:func:`bayesfric.fit`) or its file (``.nc``).

    Returns
    -------
    dict
        ``passed`` (the gate: its predictions may be used), ``problems`` (why not, one line
        each), ``rhat_max``, ``ess_bulk_min``, ``ess_tail_min``, ``divergences``, ``ebfmi_min``,
        ``acceptance_mean`` (None where the sampler has none), the pointwise log-likelihood's
        ``loglik_rhat_max`` / ``loglik_ess_bulk_min`` / ``predictions_converged`` when the chains
        did not mix, and ``multimodal``, ``modes`` (the chains of each mode), ``weights``,
        ``mode_ranges``, ``mode_note`` (:class:`bayesfric.inference.diagnostics.Verdict`).

    Raises
    ------
    UserError
        Not a fit, or a fit without a recorded verdict.

    Examples
    --------
    >>> import bayesfric
    >>> f = bayesfric.fit("coulomb_viscous", "robot_joint", draws=100, tune=100, chains=2)  # doctest: +SKIP
    >>> d = bayesfric.diagnostics(f)                                                       # doctest: +SKIP
    >>> d["passed"], d["rhat_max"] < 1.01, d["problems"]                                   # doctest: +SKIP
    (True, True, [])
    """
    from dataclasses import asdict

    from bayesfric.inference.diagnostics import Verdict
    from bayesfric.sizing.single import read_fit

    tree = read_fit(fit) if isinstance(fit, str | Path) else fit
    if not isinstance(tree, xr.DataTree):
        raise UserError(f"fit: expected a fit (an xarray.DataTree from bayesfric.fit) or its file, got "
                        f"{type(fit).__name__}")
    if "diagnostics" not in tree.attrs:
        raise UserError("fit: no diagnostics recorded (not a fit made by bayesfric.fit or a study)")
    return asdict(Verdict.from_json(str(tree.attrs["diagnostics"])))
