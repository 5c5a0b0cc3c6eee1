"""The public Python API: what ``import bayesfric`` offers, and what the command line wraps.

=======================  ===================================================================
:func:`load_data`        a built-in data set or a CSV file (+ sidecar) -> SI ``xarray.Dataset``
:func:`law`              a registered law, or a plain function declared as one
:class:`Param`, `Prior`  the pieces of a full law declaration (:func:`bayesfric.laws.law`)
:func:`fit`              one law on one data set -> arviz ``DataTree``
:func:`load_fit`         a saved fit -> ``(DataTree, Program)``: the program that produced it
:func:`diagnostics`      a fit's convergence diagnostics and gate verdict -> ``dict``
:func:`compare_laws`     fits ranked by PSIS-LOO with stacking weights -> ``pandas.DataFrame``
:func:`size`             friction a drive must deliver at untested points (+ P(|T| > capacity)),
                         one Dataset law × point × quantile (:class:`SizingAnswer`)
:func:`predict`          every row of a new log predicted by a study's laws and average, or a fit
:func:`score`            the laws scored on a new log: elpd, RMS error, band coverage
:class:`Study`, `run`    a full comparison study (blocked extrapolation, evidence, sizing,
                         report) -> :class:`StudyResult`
:func:`write_report`     a study's report rendered again from its result tree (``results.nc``)
=======================  ===================================================================

Every argument is checked where it is given; a bad one raises a one-line
:class:`~bayesfric.errors.UserError` naming it (the CLI prints the same line and exits 2).
"""

from bayesfric.api.fitfile import diagnostics, load_fit
from bayesfric.api.fitting import compare_laws, fit, law, load_data
from bayesfric.api.predicting import predict, score
from bayesfric.api.reports import write_report
from bayesfric.api.sizing import size, time_to_exceed
from bayesfric.api.studies import Study, StudyResult, run
from bayesfric.laws.base import Param
from bayesfric.priors import Prior
from bayesfric.sizing.result import SizingAnswer

__all__ = ["load_data", "law", "Param", "Prior", "fit", "load_fit", "diagnostics", "compare_laws", "size",
           "SizingAnswer", "time_to_exceed", "predict", "score", "Study", "StudyResult", "run", "write_report"]
