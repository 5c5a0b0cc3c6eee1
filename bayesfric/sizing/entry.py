"""A study's sizing questions answered from its laws' sources (:func:`size_study`), and one
fit's question (:func:`size_fit`): the entry points :mod:`bayesfric.sizing` exports."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr

from bayesfric.datasets.provenance import provenance_label
from bayesfric.quantities import QUANTITIES, conversion
from bayesfric.sizing.answer import answer
from bayesfric.sizing.calibration import Scheme
from bayesfric.sizing.compute import LawSource
from bayesfric.sizing.points import SizingQuestion
from bayesfric.sizing.result import SizingAnswer
from bayesfric.sizing.steady import sizing_law, tested_values

__all__ = ["size_study", "sized_response", "provenance_of_fit", "size_fit"]


def _response_display(response: str, unit: str | None) -> tuple[str, float]:
    unit = unit or QUANTITIES[response].unit
    scale, _ = conversion(unit, response)
    return unit, scale


def size_study(questions: Sequence[SizingQuestion], ds: xr.Dataset, law_sources: Sequence[LawSource],
               schemes: Sequence[Scheme], *, study_name: str, seed: int = 0, fan: bool = True) -> SizingAnswer:
    """Answer a study's questions from its laws' fits, weights and misses (``law_sources``, from
    :func:`sources`) and its blocked ``schemes`` (:func:`basis_schemes`). Stateful laws answer from
    their steady state (:mod:`bayesfric.sizing.steady`); coast-down laws' is a torque, where the
    data's response is speed: the answer is then of torque, and the measured speed its tested range."""
    measured = ds.attrs["response"]
    response = sized_response([s.fit for s in law_sources], measured)
    unit, scale = _response_display(response, ds[response].attrs.get("original_unit") if response in ds else None)
    inputs = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
    data = tested_values({k: np.asarray(ds[k].values, dtype=float) for k in inputs}, measured,
                         ds[measured].values, [k for q in questions for k in q.at])
    return answer(questions, law_sources, data, response=response, response_unit=unit, response_scale=scale,
                  provenance=provenance_label(ds), source=f"study {study_name}", schemes=list(schemes),
                  measured=np.asarray(ds[measured].values, dtype=float) if response == measured else None,
                  seed=seed, fan=fan)


def sized_response(fits: Sequence[xr.DataTree], default: str) -> str:
    """The quantity sizing answers for these fits: their laws' (a coast-down's steady state answers
    in torque), ``default`` (the data's response) where they disagree or there are none."""
    from bayesfric.laws.variants import law_of_fit

    found = {sizing_law(law_of_fit(fit.attrs)).response for fit in fits}
    return found.pop() if len(found) == 1 else default


def provenance_of_fit(fit: xr.DataTree) -> str:
    """The provenance label of the data a fit was made from (its attrs)."""
    attrs = {"provenance": fit.attrs.get("data_provenance", "?"), "source": fit.attrs.get("data_source", "")}
    return provenance_label(xr.Dataset(attrs=attrs))


def size_fit(fit: xr.DataTree, question: SizingQuestion, *, name: str, seed: int = 0) -> SizingAnswer:
    """Answer one question for one fit (weight 1; the tested range is the fit's own data)."""
    from bayesfric.density import OBS_SITE
    from bayesfric.laws.variants import law_of_fit

    fitted = law_of_fit(fit.attrs)
    law = sizing_law(fitted)  # a trajectory law: its steady state (sizing.steady)
    data = fit["constant_data"].to_dataset()
    unit = question.capacity.unit if question.capacity is not None else None
    unit, scale = _response_display(law.response, unit)
    observed = fit["observed_data"][OBS_SITE].values if "observed_data" in fit.children else None
    tested = tested_values({k: np.asarray(data[k].values, dtype=float) for k in law.operating_inputs if k in data},
                           fitted.response, observed, list(law.operating_inputs))
    return answer([question], [LawSource(fitted.name, fit)], tested,
                  response=law.response, response_unit=unit, response_scale=scale,
                  provenance=provenance_of_fit(fit), source=f"fit {name}", seed=seed, fan=False)
