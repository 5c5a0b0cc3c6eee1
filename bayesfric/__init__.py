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

__version__ = "0.1.0"
