"""Steady-state reduction of a raw friction log (``bayesfric data reduce``).

The field reduces long logs by hand: run the joint (or load the bearing) at a series of constant
speeds (loads), drop the transient after each change, and average the rest of each plateau
(seed 004's Stribeck tables). This module does that reproducibly and writes the result as a data
file the loader reads, with the standard error and count of every mean, so the same study can fit
the raw log or its reduction; the likelihood of a reduced row adds its standard error to the noise
model (:mod:`bayesfric.model`).

Algorithm
---------
Rows are taken in file order (the time order of a log); a new *block* starts at the first row and
wherever any group label (a run, a series, the trajectory group) changes: no segment spans two
blocks. Within a block, on the chosen input ``on`` (``velocity`` by default; any input quantity
or its column name, e.g. ``axial_force``):

1. **Split.** A row joins the current segment while it lies within the tolerance
   ``tol(m) = max(rtol * |m|, atol)`` of the segment's running mean ``m``; otherwise it starts a new
   segment. A step starts a new segment at once; a ramp breaks into short pieces (its running mean
   lags behind), which step 4 drops.
2. **Trim.** Rows at either end of a segment farther than ``tol`` from the segment's median are
   dropped (the end of a ramp-in, the start of a ramp-out).
3. **Settle.** The first rows of what is left are dropped as transient: ``settle`` is a fraction
   of the segment (``"10%"``, the default), a number of rows (``"25"``), or a duration
   (``"0.5 s"``, any time unit; needs a ``time`` input, read per block).
4. **Keep.** A segment is kept if at least ``min_samples`` rows remain (default 20), and, when
   ``on`` is a velocity, if its level is not a standstill (``|m| > atol``: friction at rest is not
   a steady-state sliding value; ``keep_standstill`` keeps those).

``atol`` defaults to 5 robust noise standard deviations of ``on``, from the median absolute
first difference (``1.4826 * median|dx| / sqrt(2)``), floored at ``1e-9 * max|x|``.

Means and standard errors
-------------------------
Each kept segment gives the mean of every input (the row's operating point) and of the response,
with ``se = sd / sqrt(n_eff)``: the **effective sample size** of the response inside the segment,
from its autocorrelation by Geyer's (1992) initial monotone sequence estimator (the estimator Stan
and arviz use for MCMC draws), ``n_eff = n / tau``, ``tau = 1 + 2 * sum_k rho_k``, capped at
``n_eff <= n`` (anti-correlated noise is not credited). A logger's noise is autocorrelated (an
AR(1) with rho = 0.9 has ``tau`` = 19): the naive ``sd / sqrt(n)`` would be 4.4 times too small.
Centring on the segment's own mean biases the summed autocovariances low by about
``(2K + 1) / n`` (K the last lag summed); ``tau`` is divided by ``1 - (2K + 1) / n`` (at most 2x).
Measured (``benchmarks/bench_reduce_coverage.py``, ~225 rows per plateau, 480 plateaus each):
the truth lies within 1.96 se in 94.8 / 94.6 / 91.9 / 90.4 % of segments at AR(1) rho = 0 / 0.5
/ 0.8 / 0.9; short segments of strongly correlated noise (n_eff ~ 12) still get an se ~20 % low.

Output
------
A CSV with one row per segment -- the inputs (segment means, ``time`` left out) and group labels
under their source column names and units, the response mean, ``<response>_se`` (role ``se``),
``count`` (rows averaged), ``n_eff``, ``segment`` (a group, 1, 2, ...), ``first_row`` and
``last_row`` (the source's data rows averaged, counted from 1 as the loader counts) -- and its
sidecar, whose ``[reduction]`` table names the source file and the SHA-256 of it and its sidecar,
and every setting. Aux columns of the source are not carried. Both files are written atomically
after every check passed (:mod:`bayesfric.datasets.reduced_file`); any problem is one line naming
file, column or option.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np
import xarray as xr

from bayesfric.datasets.errors import DataError
from bayesfric.datasets.loader import OBS_DIM, load_dataset
from bayesfric.datasets.reduce_options import ReduceOptions, add_arguments
from bayesfric.datasets.reduced_file import Reduction, Segment, write_reduction
from bayesfric.errors import UserError
from bayesfric.outpaths import checked_out
from bayesfric.quantities import QUANTITIES, UnitError, conversion

__all__ = ["ReduceOptions", "Segment", "Reduction", "MAX_RAW_ROWS", "SE_METHOD", "find_segments", "mean_se",
           "reduce_log", "write_reduction", "add_arguments", "run_command", "plateau_warning", "PLATEAU_N_EFF"]

#: Largest --min-samples accepted. A raw log itself has no row limit but the memory its text needs
#: to load (:func:`bayesfric.limits.load_problem`).
MAX_RAW_ROWS = 2_000_000
#: How the standard error of a segment mean is computed (module docstring).
SE_METHOD = "sd / sqrt(n_eff), n_eff by Geyer's initial monotone sequence (autocorrelation), n_eff <= count"
_VELOCITIES = ("velocity", "linear_velocity")


def mean_se(y: np.ndarray) -> tuple[float, float, float]:
    """Mean, standard error and effective sample size of an autocorrelated series.

    Parameters
    ----------
    y : ndarray, shape (n,)
        The response inside one segment, in time order (n >= 2).

    Returns
    -------
    tuple of float
        ``(mean, se, n_eff)``, ``se = sd / sqrt(n_eff)``; ``n_eff = n / tau`` from Geyer's initial
        monotone sequence of autocorrelation pair sums, within ``[1, n]``.
    """
    y = np.asarray(y, dtype=float)
    n, mean = y.size, float(y.mean())
    c = y - mean
    var = float(c @ c) / n
    if var == 0.0:
        return mean, 0.0, float(n)
    size = 1 << (2 * n - 1).bit_length()
    spectrum = np.fft.rfft(c, size)
    acov = np.fft.irfft(spectrum * np.conj(spectrum), size)[:n] / n
    pairs = (acov[: 2 * (n // 2)] / acov[0]).reshape(-1, 2).sum(axis=1)  # Gamma_k = rho_2k + rho_2k+1
    positive = np.flatnonzero(pairs <= 0.0)
    pairs = np.minimum.accumulate(pairs[: positive[0] if positive.size else pairs.size])
    lags = 4 * pairs.size - 1  # lags -K..K summed, K = 2 * pairs - 1
    # centring on the sample mean lowers every autocovariance by about var(mean): their sum over
    # the window is low by a factor (1 - lags / n), undone here (at most a factor 2)
    tau = max((-1.0 + 2.0 * float(pairs.sum())) / max(1.0 - lags / n, 0.5), 1.0)
    n_eff = n / tau
    return mean, float(np.sqrt(var / n_eff)), float(n_eff)


def find_segments(x: np.ndarray, starts: np.ndarray, rtol: float, atol: float) -> list[tuple[int, int]]:
    """Split and trim (steps 1-2 of the algorithm): ``(first, stop)`` row ranges, 0-based.

    Parameters
    ----------
    x : ndarray, shape (n,)
        The quantity held constant, in SI, in row order.
    starts : ndarray of bool, shape (n,)
        True where a block starts (no segment spans two blocks).
    rtol, atol : float
        Tolerance ``max(rtol * |m|, atol)`` around the running mean ``m``.
    """
    pieces, first, total, count = [], 0, float(x[0]), 1
    for k in range(1, x.size):
        m = total / count
        if starts[k] or abs(x[k] - m) > max(rtol * abs(m), atol):
            pieces.append((first, k))
            first, total, count = k, float(x[k]), 1
        else:
            total, count = total + float(x[k]), count + 1
    pieces.append((first, x.size))
    out = []
    for a, b in pieces:
        level = float(np.median(x[a:b]))
        inside = np.flatnonzero(np.abs(x[a:b] - level) <= max(rtol * abs(level), atol))
        if inside.size:
            out.append((a + int(inside[0]), a + int(inside[-1]) + 1))
    return out


def reduce_log(csv_path: str | Path, meta_path: str | Path | None = None,
               options: ReduceOptions | None = None) -> Reduction:
    """Find the steady segments of a raw log and their means (module docstring).

    Parameters
    ----------
    csv_path : str or Path
        The raw log (CSV with its TOML sidecar, as :func:`bayesfric.datasets.load_dataset` reads).
    meta_path : str or Path, optional
        The sidecar; default ``csv_path`` with suffix ``.toml``.
    options : ReduceOptions, optional
        The settings; default :class:`ReduceOptions()`.

    Raises
    ------
    DataError, UserError
        Bad file (as the loader), an unknown ``on``, a bad option, or no segment kept.
    """
    options = options or ReduceOptions()
    _check_options(options)
    ds = load_dataset(csv_path, meta_path)
    on = _on_quantity(ds, options.on, csv_path)
    x = np.asarray(ds[on].values, dtype=float)
    starts = _block_starts(ds)
    atol = _atol(x, options.atol, on)
    settle = _settler(ds, options.settle)
    segments, y, resting = [], np.asarray(ds[ds.attrs["response"]].values, dtype=float), 0
    for a, b in find_segments(x, starts, options.rtol, atol):
        a = min(b, a + settle(a, b))
        standstill = on in _VELOCITIES and abs(float(x[a:b].mean() if b > a else 0.0)) <= atol
        resting += b - a >= options.min_samples and standstill and not options.keep_standstill
        if b - a >= options.min_samples and (options.keep_standstill or not standstill):
            segments.append(Segment(a, b, *mean_se(y[a:b])))
    if not segments and resting:
        raise DataError(f"{csv_path}: every steady segment of {on} ({resting}) is at standstill ({on} zero within "
                        "the tolerance), which the reduction leaves out by default; --keep-standstill keeps them")
    if not segments:
        raise DataError(f"{csv_path}: no steady segment of {on} found with at least {options.min_samples} rows "
                        f"after settling (tolerance max({options.rtol:g} * |level|, {atol:.3g} "
                        f"{QUANTITIES[on].unit}), settle {options.settle}); widen --rtol/--atol or lower "
                        f"--min-samples")
    record = {"on": on, "rtol": options.rtol, "atol": f"{atol:.6g} {QUANTITIES[on].unit}",
              "settle": options.settle, "min_samples": options.min_samples,
              "keep_standstill": options.keep_standstill, "se_method": SE_METHOD, "segments": len(segments),
              "rows_used": sum(s.stop - s.first for s in segments), "rows_total": int(ds.sizes[OBS_DIM])}
    return Reduction(ds, on, segments, record)


def _check_options(options: ReduceOptions) -> None:
    if not (np.isfinite(options.rtol) and 0.0 <= options.rtol < 1.0):
        raise UserError(f"--rtol {options.rtol!r}: a relative tolerance in [0, 1)")
    if not 2 <= options.min_samples <= MAX_RAW_ROWS:
        raise UserError(f"--min-samples {options.min_samples}: between 2 and {MAX_RAW_ROWS} rows")


def _on_quantity(ds: xr.Dataset, on: str, path: str | Path) -> str:
    """The input coordinate named by quantity or by its source column."""
    inputs = {k: v for k, v in ds.coords.items() if v.attrs.get("role") == "input"}
    for name, var in inputs.items():
        if on in (name, var.attrs.get("column")) and name != "time":
            return str(name)
    shown = ", ".join(f"{n} (column {v.attrs.get('column')!r})" for n, v in inputs.items() if n != "time")
    raise UserError(f"--on {on!r}: {path} has no such input to hold constant (inputs: {shown or 'none'})")


def _block_starts(ds: xr.Dataset) -> np.ndarray:
    """True at the first row and wherever any group label changes."""
    starts = np.zeros(ds.sizes[OBS_DIM], dtype=bool)
    starts[0] = True
    for var in ds.coords.values():
        if var.attrs.get("role") == "group":
            labels = np.asarray(var.values)
            starts[1:] |= labels[1:] != labels[:-1]
    return starts


def _atol(x: np.ndarray, text: str | None, on: str) -> float:
    """The absolute tolerance in SI: ``--atol`` read with its unit, else 5 robust noise sds."""
    if text is not None:
        value = _value(text, on, "--atol")
        if not value >= 0.0:
            raise UserError(f"--atol {text!r}: must be >= 0")
        return value
    noise = 1.4826 * float(np.median(np.abs(np.diff(x)))) / np.sqrt(2.0) if x.size > 1 else 0.0
    return max(5.0 * noise, 1e-9 * float(np.max(np.abs(x))), 1e-300)


def _value(text: str, quantity: str, option: str) -> float:
    """``"0.5 s"`` -> SI value of ``quantity``; a one-line UserError naming ``option`` otherwise."""
    number, _, unit = text.strip().partition(" ")
    try:
        scale, offset = conversion(unit.strip() or "", quantity)
        value = float(number) * scale + offset
    except (ValueError, UnitError) as exc:
        raise UserError(f"{option} {text!r}: a number and a unit of {quantity} "
                        f"(e.g. '0.5 {QUANTITIES[quantity].unit}'): {exc}") from None
    if not np.isfinite(value):
        raise UserError(f"{option} {text!r}: not a finite value")
    return value


def _settler(ds: xr.Dataset, text: str) -> Callable[[int, int], int]:
    """Rows to drop at the start of segment ``first:stop``, from ``--settle``."""
    spec = text.strip()
    if spec.endswith("%"):
        try:
            fraction = float(spec[:-1]) / 100.0
        except ValueError:
            fraction = -1.0
        if not 0.0 <= fraction < 1.0:
            raise UserError(f"--settle {text!r}: a percentage in [0, 100)")
        return lambda a, b: int(np.ceil(fraction * (b - a)))
    if spec.isdigit():
        return lambda a, b: int(spec)
    seconds = _value(spec, "time", "--settle")
    if "time" not in ds.coords:
        raise UserError(f"--settle {text!r}: a duration needs a time input in the log; give rows ('25') or a "
                        f"percentage ('10%')")
    if not seconds >= 0.0:
        raise UserError(f"--settle {text!r}: must be >= 0")
    t = np.asarray(ds["time"].values, dtype=float)
    back = np.flatnonzero((np.diff(t) <= 0.0) & ~_block_starts(ds)[1:])
    if back.size:
        raise DataError(f"{ds.attrs['csv_file']}: row {back[0] + 2}: column {ds['time'].attrs['column']!r}: time does "
                        f"not increase within a run; --settle as a duration needs increasing time")
    return lambda a, b: int(np.searchsorted(t[a:b], t[a] + seconds, side="left"))



# -- command line --------------------------------------------------------------------------------
def run_command(args: argparse.Namespace) -> None:
    """``bayesfric data reduce``: check the output path, reduce, write, print what was done."""
    src = Path(args.file)
    out = Path(args.out) if args.out else src.with_name(f"{src.stem}_reduced.csv")
    meta = Path(args.meta) if args.meta else src.with_suffix(".toml")
    if out.suffix != ".csv":
        raise UserError(f"--out {out}: the reduced table is a .csv file (its sidecar: the same name, .toml)")
    for target in (out, out.with_suffix(".toml")):  # neither the table nor its sidecar onto the raw log's
        checked_out(target, "--out", [(src, "the source log"), (meta, "the source log's sidecar")])
    options = ReduceOptions(args.on, args.rtol, args.atol, args.settle, args.min_samples, args.keep_standstill)
    red = reduce_log(src, meta, options)
    warning = plateau_warning(red)
    if warning and getattr(args, "strict", False):
        raise UserError(f"{src}: {warning} (--strict: nothing written)")
    csv_out, sidecar = write_reduction(red, out, meta)
    r = red.record
    share = r["rows_used"] / max(1, r["rows_total"])
    print(f"{src}: {r['rows_total']} rows -> {r['segments']} segments of constant {r['on']} ({r['rows_used']} rows "
          f"averaged, {share:.0%} of the log; tolerance max({r['rtol']:g} * |level|, {r['atol']}), "
          f"settle {r['settle']})")
    if red.segments:
        rows = np.median([s.stop - s.first for s in red.segments])
        n_eff = np.median([s.n_eff for s in red.segments])
        print(f"segments: median {rows:.0f} rows, median effective sample size {n_eff:.1f}")
    if warning:
        print(f"WARNING: {warning}")
    print(f"written {csv_out} and {sidecar}")


#: Median effective sample size of a reduction's segments below which they are not read as
#: plateaus: standard errors from so few effectively independent rows run ~20 % low (module docstring).
PLATEAU_N_EFF = 20.0


def plateau_warning(red: Reduction) -> str:
    """Why a reduction's segments do not look like constant-input plateaus (``""`` when they do):
    none kept, or a median effective sample size below :data:`PLATEAU_N_EFF` (a trajectory that
    only passes through each level, cut into many short pieces)."""
    if not red.segments:
        return f"no segment of constant {red.on} was found: the log has no plateaus to average"
    n_eff = float(np.median([s.n_eff for s in red.segments]))
    if n_eff >= PLATEAU_N_EFF:
        return ""
    return (f"the {len(red.segments)} segments have a median effective sample size of {n_eff:.1f} (< "
            f"{PLATEAU_N_EFF:g}): the log passes through {red.on} levels rather than holding them, so these "
            "are not plateaus and their standard errors run low; fit the raw log (a trajectory study) instead")
