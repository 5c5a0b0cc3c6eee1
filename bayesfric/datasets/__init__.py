"""Measurement data: loading (CSV + TOML sidecar -> SI xarray.Dataset) and the built-in data sets."""

from bayesfric.datasets.loader import OBS_DIM, DataError, load_dataset
from bayesfric.datasets.registry import builtin_names, describe, load_builtin, resolve
from bayesfric.datasets.views import data_scale, law_inputs, response_values, select, trajectory_starts

__all__ = [
    "OBS_DIM",
    "DataError",
    "load_dataset",
    "load_builtin",
    "builtin_names",
    "describe",
    "resolve",
    "data_scale",
    "law_inputs",
    "response_values",
    "select",
    "trajectory_starts",
]
