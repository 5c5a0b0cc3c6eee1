"""bayesfric: Bayesian model comparison of friction laws.

Laws are declared once (:mod:`bayesfric.laws`), data are SI xarray Datasets
(:mod:`bayesfric.datasets`), fits are arviz DataTrees (:mod:`bayesfric.inference`).

Importing the package changes no process-wide setting: 64-bit floats and the persistent
compilation cache are switched on by :func:`bayesfric.runtime.configure` when a program is built
or the CLI starts.
"""

import numpyro  # noqa: F401  (see below)

# arviz-base lazy-loads numpyro; a later `import numpyro.distributions` through that lazy module
# leaves `numpyro.distributions.distribution` unset and numpyro.factor fails inside NUTS.
# Importing numpyro eagerly here, before any arviz import of ours, avoids that.
from bayesfric._version import __version__

#: The public API (:mod:`bayesfric.api`), imported on first use so ``import bayesfric`` stays cheap.
_API = ("load_data", "law", "Param", "Prior", "fit", "load_fit", "compare_laws", "size", "predict", "score", "Study",
        "StudyResult", "run", "write_report")
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        from bayesfric import api

        return getattr(api, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
