"""bayesfric: Bayesian model comparison of friction laws.

Laws are declared once (:mod:`bayesfric.laws`), data are SI xarray Datasets
(:mod:`bayesfric.datasets`), fits are arviz DataTrees (:mod:`bayesfric.inference`).

Importing the package changes no process-wide setting and imports neither JAX nor numpyro, so
the light commands (``bayesfric --version``, ``--help``, ``laws``, ``data``) answer at once:
64-bit floats and the persistent compilation cache are switched on by
:func:`bayesfric.runtime.configure` when a program is built or a computing command starts, and
the public API (``bayesfric.fit`` ...) loads on first use.
"""

import importlib.abc
import sys

from bayesfric._version import __version__


class _NumpyroBeforeArviz(importlib.abc.MetaPathFinder):
    """Imports numpyro just before the first import of ``arviz_base``, then steps aside.

    arviz-base lazy-loads numpyro: importing it while numpyro is not imported puts a lazy module
    in ``sys.modules``, and a later ``import numpyro.distributions`` through that lazy module
    leaves ``numpyro.distributions.distribution`` unset (``numpyro.factor`` then fails inside
    NUTS). Importing numpyro eagerly here would cost every command JAX's import time (seconds),
    so the order is kept by this finder instead: it finds nothing itself.
    """

    def find_spec(self, name, path=None, target=None):
        if name == "arviz_base":
            if self in sys.meta_path:
                sys.meta_path.remove(self)
            import numpyro  # noqa: F401
        return None


if "numpyro" not in sys.modules and not any(isinstance(f, _NumpyroBeforeArviz) for f in sys.meta_path):
    sys.meta_path.insert(0, _NumpyroBeforeArviz())

#: The public API (:mod:`bayesfric.api`), imported on first use so ``import bayesfric`` stays cheap.
_API = ("load_data", "law", "Param", "Prior", "fit", "load_fit", "diagnostics", "compare_laws", "size",
        "SizingAnswer", "time_to_exceed", "predict", "score", "Study", "StudyResult", "run", "write_report")
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        from bayesfric import api

        return getattr(api, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
