"""Measurement data: loading (CSV + TOML sidecar -> SI xarray.Dataset) and the built-in data sets.

The names below are imported on first use (module ``__getattr__``): importing a submodule
(``bayesfric.datasets.loader`` for ``bayesfric data check``) runs this file first, and
:mod:`bayesfric.datasets.views` reads laws and priors, which import JAX and numpyro; the light
commands must not pay for that.
"""

from importlib import import_module

#: Where each public name lives.
_WHERE = {
    "OBS_DIM": "loader", "DataError": "loader", "load_dataset": "loader",
    "builtin_names": "registry", "describe": "registry", "load_builtin": "registry", "resolve": "registry",
    "data_scale": "views", "law_inputs": "views", "response_values": "views", "select": "rows",
    "trajectory_starts": "rows",
}

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


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(import_module(f"bayesfric.datasets.{_WHERE[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
