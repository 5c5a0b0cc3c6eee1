"""Fits built by hand (no MCMC): known posterior draws with the attrs and groups of a real fit."""

from __future__ import annotations

import json

import arviz as az
import numpy as np

from bayesfric.datasets.synthetic import make_dataset
from bayesfric.inference.datatree import provenance
from bayesfric.inference.diagnostics import Verdict
from bayesfric.laws import get_law
from bayesfric.model import Noise, build_program

PASSED = Verdict(True, 1.0, 1000.0, 1000.0, 0, 1.0, None)


def hand_fit(law_name: str, draws: dict[str, np.ndarray], inputs: dict[str, np.ndarray], *,
             noise: Noise | None = None, verdict: Verdict = PASSED, provenance_kind: str = "simulated"):
    """A DataTree shaped like a saved fit whose posterior is ``draws`` (each (chain, draw)).

    ``inputs`` are the 'tested' inputs (SI); the response is the law's mean at the first draw.
    """
    law = get_law(law_name)
    noise = noise or Noise()
    n = len(next(iter(inputs.values())))
    ds = make_dataset(inputs, np.ones(n), response_quantity=law.response, provenance=provenance_kind,
                      source="hand-made fit for tests",
                      groups={noise.group: np.arange(n) % 2} if noise.group else None)
    program = build_program(law, ds, noise=noise)
    dt = az.from_dict({
        "posterior": {k: np.asarray(v, dtype=float) for k, v in draws.items()},
        "observed_data": {"response": np.ones(n)},
        "constant_data": {k: np.asarray(v, dtype=float) for k, v in inputs.items()},
    }, dims={"response": ["obs"], **{k: ["obs"] for k in inputs}})
    dt.attrs.update(provenance(program, ds, "nuts", {}, 0))
    dt.attrs["versions"] = json.dumps({})
    dt.attrs["diagnostics"] = verdict.to_json()
    return dt


def write_basis(folder, laws: list[str], *, passed: bool = True) -> None:
    """A ``results.nc`` holding only the nodes sizing reads (:data:`bayesfric.sizing.store.NODES`):
    each law's fit ``fits/<law>.nc``, stacking-LOO weight 1 / n, no blocked scheme."""
    import xarray as xr

    n = len(laws)
    law = {"law": laws}
    empty = np.zeros((n, 0))
    basis = xr.DataTree.from_dict({
        "weights": xr.Dataset({"weight": (("law", "weighting"), np.full((n, 1), 1.0 / n)),
                               "excluded": (("law", "weighting"), np.full((n, 1), ""))},
                              coords=law | {"weighting": ["stacking LOO"]}),
        "diagnostics": xr.Dataset({"passed": ("law", [passed] * n), "problems": ("law", [""] * n)}, coords=law),
        "sizing_basis": xr.Dataset(
            {"fit": ("law", [f"fits/{x}.nc" for x in laws]), "evidence_disagreement": ("law", np.zeros(n)),
             "penalty": (("law", "penalty_scheme"), empty)}
            | {f"miss_{k}": (("law", "scheme"), empty) for k in ("rate", "beta", "se", "reach")}
            | {"miss_n": (("law", "scheme"), empty.astype(int))},
            coords=law | {"scheme": np.array([], dtype=str), "penalty_scheme": np.array([], dtype=str),
                          "axis": ("scheme", np.array([], dtype=str)),
                          "direction": ("scheme", np.array([], dtype=str)),
                          "use_abs": ("scheme", np.array([], dtype=bool))}),
    })
    basis.to_netcdf(folder / "results.nc", engine="h5netcdf")
