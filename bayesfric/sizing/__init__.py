"""Actuator sizing: what torque (or force) must a drive deliver at an operating point nobody
tested, and how sure are we? Computed once from a study's stored fits and weights (or one fit)
into a :class:`~bayesfric.sizing.result.SizingAnswer` (one Dataset law × point × quantile,
:mod:`bayesfric.sizing.tidy`); ``summary.md``, ``report.html``, ``sizing.csv``, the fan figure
and ``bayesfric size`` render it (:mod:`bayesfric.report.sizing`).

* :mod:`bayesfric.sizing.points` — questions: values with units, ranges, checks against the data;
* :mod:`bayesfric.sizing.compute` — predictive draws, quantiles, required capacity, exceedance
  probability, model average, variance split, extrapolation distance, energy of a rotation;
* :mod:`bayesfric.sizing.calibration` — model-form error: the miss blocked folds measured, scaled
  to a point's distance beyond the envelope (the calibrated answers);
* :mod:`bayesfric.sizing.basis` — which weights and misses answer a question, from its direction;
* :mod:`bayesfric.sizing.store` — the ``/sizing_basis`` node of ``results.nc``: what a study run
  keeps so sizing never refits.

The names are imported on first use (module ``__getattr__``), as :mod:`bayesfric.datasets`'s
are: :mod:`bayesfric.sizing.points` (questions, units) imports no JAX, so the command line
checks ``size --at ...`` before JAX loads, which importing this package must not undo.
"""

from importlib import import_module

#: Where each public name lives.
_WHERE = {
    "answer_question": "answer",  # sizing.answer is the module (a submodule's name wins once it is imported)
    **dict.fromkeys(("LOO", "NEW_GROUP", "NO_EXTRAPOLATION", "Basis", "choose_basis"), "basis"),
    **dict.fromkeys(("Miss", "Scheme", "measure_miss"), "calibration"),
    **dict.fromkeys(("EXTRAPOLATION_WARN", "FAN_POINTS", "LEVELS", "Answer", "LawSource", "Mixture", "SizingResult",
                     "extrapolation_distance", "predict", "tested_ranges", "variance_split", "weighted_quantiles"),
                    "compute"),
    **dict.fromkeys(("CLI_KEYS", "RANGE_POINTS", "SizingError", "SizingQuestion", "Value", "check_question",
                     "make_question", "parse_at", "parse_capacity", "parse_value"), "points"),
    "SizingAnswer": "result",
    **dict.fromkeys(("STEADY_NOTE", "sizing_law", "tested_values"), "steady"),
    **dict.fromkeys(("basis_node", "basis_schemes", "exclusion", "read_basis", "sources"), "store"),
    **dict.fromkeys(("size_study", "sized_response", "provenance_of_fit", "size_fit"), "entry"),
}

__all__ = [
    "LOO", "NEW_GROUP", "NO_EXTRAPOLATION", "Basis", "choose_basis", "Miss", "Scheme", "measure_miss", "basis_schemes",
    "CLI_KEYS", "EXTRAPOLATION_WARN", "FAN_POINTS", "LEVELS", "RANGE_POINTS", "Answer", "LawSource",
    "Mixture", "SizingAnswer",
    "SizingError", "SizingQuestion", "SizingResult", "Value", "answer_question", "check_question",
    "exclusion", "extrapolation_distance", "make_question", "parse_at", "parse_capacity", "parse_value", "predict",
    "read_basis", "basis_node", "sources", "tested_ranges", "variance_split", "weighted_quantiles", "size_study",
    "size_fit", "provenance_of_fit", "STEADY_NOTE", "sizing_law", "sized_response",
]


def __getattr__(name: str):
    """A public name (:data:`_WHERE`) or a submodule (``sizing.store``), imported on first use."""
    if name in _WHERE:
        value = getattr(import_module(f"bayesfric.sizing.{_WHERE[name]}"), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):
        try:
            return import_module(f"bayesfric.sizing.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"bayesfric.sizing.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
