"""Tables derived from law declarations, data sets and fits (used by the CLI, Markdown and HTML reports)."""

from __future__ import annotations

import json
from dataclasses import dataclass

import arviz_stats
import numpy as np
import xarray as xr

from bayesfric.hierarchy import spread_of
from bayesfric.inference.diagnostics import verdict_of
from bayesfric.laws.base import Law
from bayesfric.listing import datasets_listing, format_table, law_rows, laws_listing  # noqa: F401 - re-exported
from bayesfric.quantities import QUANTITIES
from bayesfric.report.typeset import fmt, unit

__all__ = ["ParameterRow", "parameter_rows", "format_table", "law_rows", "unit_of", "noise_text", "fit_report",
           "laws_listing", "datasets_listing"]

_NOISE_UNITS = {"sigma": "response", "sigma_floor": "response", "nu": "1", "sigma_rel": "1", "group_sd": "1",
                "rho": "1"}
_NOISE_MEANING = {
    "sigma": "noise standard deviation",
    "nu": "Student-t degrees of freedom",
    "sigma_rel": "relative (proportional) noise",
    "sigma_floor": "noise floor of the proportional model",
    "group_sd": "relative spread of group offsets",
    "rho": "AR(1) lag-one correlation of residuals along a trajectory (sigma: innovation sd)",
}


@dataclass
class ParameterRow:
    """One line of a parameter report."""

    name: str
    unit: str
    meaning: str
    mean: float
    sd: float
    q05: float
    q95: float
    r_hat: float
    ess_bulk: float


def unit_of(name: str, law: Law, response: str) -> str:
    """Unit of a posterior variable: law parameter, derived quantity or noise parameter."""
    if name in law.params:
        return law.params[name].unit
    if name in law.derived:
        return law.derived[name].unit
    if (spread := spread_of(law, name)) is not None:
        return spread[0]
    unit = _NOISE_UNITS.get(name, "?")
    return QUANTITIES[response].unit if unit == "response" and response in QUANTITIES else unit


def _meaning(name: str, law: Law) -> str:
    if name in law.params:
        return law.params[name].meaning
    if name in law.derived:
        return law.derived[name].meaning
    if (spread := spread_of(law, name)) is not None:
        return spread[1]
    return _NOISE_MEANING.get(name, "")


def parameter_rows(dt: xr.DataTree, law: Law) -> list[ParameterRow]:
    """Posterior summary per scalar parameter: mean, sd, 90 % equal-tailed interval, R-hat, ESS.

    Vector-valued parameters (spline knots) get one row per element, ``name[k]``.
    """
    post = dt["posterior"].to_dataset()
    response = dt.attrs.get("response_quantity", law.response)
    noise = list(json.loads(dt.attrs["priors"]).keys()) if "priors" in dt.attrs else []
    order = list(law.params) + list(law.derived) + [n for n in noise if n not in law.params]
    order = [n for n in order if n in post]
    # a quantity constant in every draw (σ1 = 0 where fixed values hold it) has no R-hat: NaN, not computed
    moving = [n for n in order if not bool((post[n] == post[n].values.flat[0]).all())]
    rhat = arviz_stats.rhat(post[moving]) if moving else {}
    ess = arviz_stats.ess(post[order], method="bulk")
    rows = []
    for name in order:
        values = np.asarray(post[name].values)
        flat = values.reshape(values.shape[0] * values.shape[1], -1)
        r = np.atleast_1d(np.asarray(rhat[name].values)).ravel() if name in moving else np.full(flat.shape[1], np.nan)
        e = np.atleast_1d(np.asarray(ess[name].values)).ravel()
        for k in range(flat.shape[1]):
            col = flat[:, k]
            label = name if flat.shape[1] == 1 else f"{name}[{k}]"
            rows.append(ParameterRow(
                label, unit_of(name, law, response), _meaning(name, law), float(col.mean()),
                float(col.std(ddof=1)), float(np.quantile(col, 0.05)), float(np.quantile(col, 0.95)),
                float(r[k]), float(e[k]),
            ))
    return rows


_NOISE_FORM = {
    "normal": "Gaussian residuals, sd sigma",
    "student_t": "Student-t residuals, scale sigma, nu degrees of freedom",
    "proportional": "Gaussian residuals, sd = sqrt((sigma_rel · mean)² + sigma_floor²)",
    "ar1": "Gaussian AR(1) residuals along each trajectory: lag-one correlation rho, innovation sd sigma",
}


def noise_text(dt: xr.DataTree, law: Law) -> str:
    """The noise model a fit used, in one line: its kind, its form and each of its parameters
    (posterior mean ± sd with its unit, or the known value it was held at).

    Parameters
    ----------
    dt : xarray.DataTree
        A fit (its ``noise`` attribute and posterior).
    law : Law
        The fitted law (for the response's unit).

    Returns
    -------
    str
        E.g. ``"noise model: normal (Gaussian residuals, sd sigma): sigma = 0.198 ± 0.011 N·m"``.
    """
    try:
        noise = json.loads(dt.attrs.get("noise", "{}"))
    except (TypeError, ValueError):
        noise = {}
    kind = noise.get("kind", "?")
    response = dt.attrs.get("response_quantity", law.response)
    post = dt["posterior"] if "posterior" in dt.children else None
    values = []
    for name in (*_NOISE_MEANING, "group_sd"):
        if post is None or name not in post or name in law.params or name in values:
            continue
        draws = np.asarray(post[name].values, dtype=float).ravel()
        shown = unit(unit_of(name, law, response))
        values.append(f"{name} = {fmt(float(draws.mean()), float(draws.std(ddof=1)))}"
                      + (f" {shown}" if shown not in ("", "–") else ""))
    if noise.get("sigma") is not None:
        shown = unit(unit_of("sigma", law, response))
        values.append(f"sigma = {fmt(float(noise['sigma']))} {shown} (known, not sampled)")
    form = _NOISE_FORM.get(kind, "")
    group = f", partial-pooled offsets per {noise['group']}" if noise.get("group") else ""
    return (f"noise model: {kind}{group}" + (f" ({form})" if form else "") + ": "
            + ("; ".join(values) if values else "no noise parameter in the posterior"))


def fit_report(dt: xr.DataTree, law: Law, markdown: bool = False) -> str:
    """The parameter report of one fit: table with units, mean, sd, 90 % interval (each rounded to
    the parameter's posterior sd), the noise model it used and the diagnostics."""
    header = ["parameter", "unit", "mean", "sd", "5 %", "95 %", "R-hat", "ESS bulk", "meaning"]
    rows = [[r.name, unit(r.unit), fmt(r.mean, r.sd, pm=False), fmt(r.sd, r.sd, pm=False), fmt(r.q05, r.sd, pm=False),
             fmt(r.q95, r.sd, pm=False), f"{r.r_hat:.3f}", f"{r.ess_bulk:.0f}", r.meaning]
            for r in parameter_rows(dt, law)]
    verdict = verdict_of(dt)
    lines = [
        f"law {law.name}: {law.summary}",
        f"source: {law.source}",
        f"data: {dt.attrs.get('dataset')} ({dt.attrs.get('data_provenance')}), "
        f"{dt['observed_data'].sizes.get('obs', 0)} observations, sampler {dt.attrs.get('sampler')}",
        noise_text(dt, law),
        "",
        format_table(header, rows, markdown=markdown),
        "",
        f"diagnostics: {verdict}{retry_note(dt)}",
    ]
    if note := storage_note(dt):
        lines.append(note)
    return "\n".join(lines)


def storage_note(dt: xr.DataTree) -> str:
    """One line saying which draws a thinned fit keeps per data row (:mod:`bayesfric.inference.pointwise`);
    ``""`` for a fit that keeps every draw."""
    try:
        info = json.loads(dt.attrs.get("pointwise_storage") or "{}")
    except (TypeError, ValueError):
        return ""
    if not info.get("thinned"):
        return ""
    kinds = sorted(set(info["dtypes"].values()))
    return (f"kept per data row: 1 in {info['every']} draws of each chain ({info['kept_draws']} of "
            f"{info['chains'] * info['draws']}) in log_likelihood and posterior_predictive, "
            f"{info['prior_predictive_draws']} prior-predictive draws, {' / '.join(kinds)} "
            f"({info['rows']} rows; bayesfric.inference.pointwise)")


def retry_note(dt: xr.DataTree) -> str:
    """``" (sampled again: ...)"`` when the fit's first run diverged and it was sampled again at a
    higher target acceptance (:class:`bayesfric.inference.engine.NutsEngine`), else ``""``."""
    try:
        retried = json.loads(dt.attrs.get("sampler_settings", "{}")).get("retried")
    except (TypeError, ValueError):
        return ""
    return f" (sampled again: {retried})" if retried else ""
