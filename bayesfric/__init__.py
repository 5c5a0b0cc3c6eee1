"""bayesfric: Bayesian model comparison of friction laws.

Laws are declared once (:mod:`bayesfric.laws`), data are SI xarray Datasets
(:mod:`bayesfric.datasets`), fits are arviz DataTrees (:mod:`bayesfric.inference`).
"""

import jax
import numpyro  # noqa: F401  (see below)

# arviz-base lazy-loads numpyro; a later `import numpyro.distributions` through that lazy module
# leaves `numpyro.distributions.distribution` unset and numpyro.factor fails inside NUTS.
# Importing numpyro eagerly here, before any arviz import of ours, avoids that.

# Friction coefficients span many decades (N·m and N·m·s/rad on MN·m loads); use 64-bit floats.
jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"
