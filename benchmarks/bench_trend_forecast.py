"""Forecasts over service time: do the 90 % bands of the next campaign and of the time to exceed
cover the truth?

Usage::

    .venv/bin/python benchmarks/bench_trend_forecast.py [--replicates 120] [--cases linear accelerating walk]
        [--scatter 0.03]
    .venv/bin/python benchmarks/bench_trend_forecast.py --drum-cost   # a trend fit's cost

SIMULATED data. Each replicate simulates 8 test campaigns of ``coulomb_viscous`` at 0, 500, …,
3500 service hours (10 speeds 0.1–2 rad/s each, noise sd 0.05 N·m), the Coulomb level following
a true trend and scattering between campaigns by a factor ``exp(s z)`` (``--scatter s``, 0.03)
(:func:`bayesfric.datasets.synthetic.simulate_campaigns`); ``c_v = 1 N·m·s/rad`` throughout.
The law ``coulomb_viscous.trend("hours", "T_C", form=...)`` is fitted (NUTS, 4 × 500 after 500
warm-up, the study's retry) on the first 7 campaigns; the 8th (3500 h) is masked out of the likelihood, so its level
is the model's forecast of a new campaign there (leave-future-out, as a study's
``[compare] forecast`` folds score it). Reported per case:

* coverage of the 3500 h campaign's true mean curve (at 0.1, 1 and 2 rad/s, and the whole curve
  at once) by the central 90 % band of its forecast, and the mean interval score (Gneiting &
  Raftery 2007, alpha = 0.1) at 1 rad/s;
* coverage of the true time to exceed -- when the true trend's friction at 1 rad/s reaches the
  capacity 5 N·m (6000 h for the linear truth) -- by the central 90 % interval of the crossing
  times of the fitted typical-campaign curves (:func:`bayesfric.sizing.exceed.crossing_times`,
  the function ``time_to_exceed`` uses), searched to 20 000 h.

Each is reported twice: ``within`` (the trend's own posterior) and ``allowed`` (with the
model-form allowance, :mod:`bayesfric.sizing.forecast`): leave-future-out folds fitted in the
same call forecast the campaigns from ``--forecast-from`` (2500 h: two folds, 2500 h from
0–2000 h and 3000 h from 0–2500 h, as ``drum_campaigns`` has two) to 3000 h, their misses give
the rate, and the curves are widened by it as ``time_to_exceed`` does. Where a fold fails the
gate no allowance is measured (as in a study); ``rate>0`` is the share of replicates with a
positive rate, ``folds failed`` the replicates with a fold that failed the gate.

Below each case, the time to exceed as the answer gives it: the share of replicates whose answer
leads with the statement that the campaign levels bend upward (the shape check of
:mod:`bayesfric.sizing.bend` on the fit's 7 campaigns at 1 rad/s: a one-sided 5 % t-test of
curvature, :func:`bayesfric.compare.trendfit.curvature_test`), or bend downward; the crossing
coverage and its mean and median interval score (an end beyond the 20 000 h search counts as
20 000 h); and the **silent miss**: the share of replicates whose 90 % interval misses the true
crossing AND whose answer does not carry the statement (within-model and with the allowance).
The same at a one-sided 10 % level is printed for comparison (not shipped).

Cases: ``linear`` (truth T_C = 2 (1 + t/6000), candidate linear: the trend form is a candidate);
``accelerating`` (truth T_C = 2 (1 + (t/6000)²), true crossing 6000 h as well, candidate linear:
the form is NOT a candidate); ``accelerating-loglinear`` (the same truth, the log-linear form
offered: a constant factor per hour, also accelerating); ``walk`` (linear truth, random-walk
candidate: no trend shape). One
compiled sampler per case serves every replicate (``NutsEngine.with_response``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bayesfric.compare.heldout import heldout_predictive
from bayesfric.datasets.synthetic import simulate_campaigns
from bayesfric.inference.engine import NutsEngine
from bayesfric.laws import get_law
from bayesfric.model import build_program
from bayesfric.sizing.bend import point_bend
from bayesfric.sizing.calibration import GROWTH, LAMBDA, Miss
from bayesfric.sizing.exceed import crossing_times
from bayesfric.sizing.forecast import allowance, forecast_pieces, widen_curves
from bayesfric.trend import FLOOR, coordinates, span

SPEEDS = np.linspace(0.1, 2.0, 10)
HOURS = np.arange(8) * 500.0
AT = np.array([0.1, 1.0, 2.0])
CAPACITY, C_V, SIGMA, SCATTER, ALPHA = 5.0, 1.0, 0.05, 0.03, 0.1
TRUTHS = {"linear": lambda t: 2.0 * (1 + t / 6000.0), "accelerating": lambda t: 2.0 * (1 + (t / 6000.0) ** 2)}
CASES = {"linear": ("linear", "linear"), "accelerating": ("accelerating", "linear"), "walk": ("linear", "walk"),
         "accelerating-loglinear": ("accelerating", "loglinear")}
SEARCH = np.linspace(3000.0, 20000.0, 681)


def interval_score(lo, hi, x, alpha=ALPHA):
    """Gneiting & Raftery (2007) interval score of the central (1 - alpha) interval [lo, hi] at x."""
    return (hi - lo) + (2 / alpha) * np.maximum(lo - x, 0) + (2 / alpha) * np.maximum(x - hi, 0)


def true_crossing(truth) -> float:
    t = np.linspace(0, 20000, 200001)
    return float(t[np.argmax(truth(t) + C_V >= CAPACITY)])


def typical_curves(post: dict, form: str, labels, rng, times: np.ndarray = SEARCH) -> np.ndarray:
    """Friction at 1 rad/s over ``times`` (a walk: ``SEARCH`` only) per draw: the fitted trend (or a walk's path)."""
    tau = times / span(coordinates(labels))
    t_c, c_v = post["T_C"].reshape(-1)[:, None], post["c_v"].reshape(-1)[:, None]
    if form == "linear":
        return t_c * np.maximum(1 + post["T_C_trend"].reshape(-1)[:, None] * tau, FLOOR) + c_v
    if form == "loglinear":
        return t_c * np.exp(post["T_C_trend"].reshape(-1)[:, None] * tau) + c_v
    last = np.log(post["T_C_hours"].reshape(-1, len(labels))[:, 6])[:, None]  # 3000 h, the last trained
    dtau = np.diff(np.concatenate([[3000.0], times])) / span(coordinates(labels))
    steps = np.sqrt(dtau)[None, :] * rng.normal(size=(t_c.shape[0], times.size))
    return np.exp(last + post["T_C_sd"].reshape(-1)[:, None] * np.cumsum(steps, axis=1)) + c_v


def campaign_bend(post: dict, form: str, labels):
    """The time to exceed's shape check (:func:`bayesfric.sizing.bend.point_bend`) at 1 rad/s on the
    7 trained campaigns: each campaign's log friction against the fitted trend's there (None: a walk)."""
    if form == "walk":
        return None
    fitted = HOURS[:7]
    level = post["T_C_hours"].reshape(-1, len(labels))[:, :7] + post["c_v"].reshape(-1)[:, None]
    trend = typical_curves(post, form, labels, None, fitted)
    return point_bend(fitted, np.log(level).mean(axis=0), np.log(trend).mean(axis=0))


def run_case(name: str, replicates: int, scatter: float = SCATTER, forecast_from: float = 2500.0) -> dict:
    truth_name, form = CASES[name]
    truth = TRUTHS[truth_name]
    law = get_law("coulomb_viscous")

    def data(r):
        return simulate_campaigns(law, {"velocity": SPEEDS}, {"T_C": truth, "c_v": C_V}, HOURS, {"T_C": scatter},
                                  sigma=SIGMA, seed=r)

    first, _ = data(0)
    engine = NutsEngine.build(build_program(law.trend("hours", "T_C", form=form), first), draws=500, tune=500,
                              chains=4, seed=0)
    hours = np.asarray(first["hours"].values).astype(float)
    # leave-future-out folds (forecast 2500 h from 0-2000 h, 3000 h from 0-2500 h) and the fit on 0-3000 h
    scored = HOURS[(HOURS >= forecast_from) & (HOURS < 3500)]
    train = np.stack([hours < h for h in scored] + [hours < 3500])
    heldout = np.stack([hours == h for h in scored]) if scored.size else np.zeros((0, hours.size), dtype=bool)
    k = scored.size
    labels = [f"{h:g}" for h in HOURS]
    crossing = true_crossing(truth)
    row = {k: [] for k in ("cover", "cover_cal", "score", "score_cal", "cross", "cross_cal", "width", "width_cal",
                           "rate", "cscore", "cscore_cal", "bend", "p_up")} | {"failed": 0, "folds_failed": 0, "s": 0.0}
    for r in range(replicates):
        ds, values = data(r)
        start = time.perf_counter()
        fits = engine.with_response(np.asarray(ds["torque"].values)).run(train, seed=r)
        row["s"] += time.perf_counter() - start
        samples = {k: np.asarray(v) for k, v in fits.samples.items()}
        miss = None
        row["folds_failed"] += int(not all(v.passed for v in fits.verdicts[:k]))
        if k and all(v.passed for v in fits.verdicts[:k]):
            kept = heldout_predictive(engine.program, {n: v[:k] for n, v in samples.items()}, heldout)
            p = forecast_pieces(kept, hours, np.asarray(ds["torque"].values, dtype=float))
            beta, se, _ = p.gls(GROWTH)
            miss = Miss("lfo", np.sqrt(max(0.0, beta**2 - LAMBDA * se**2)), beta, se, p.e.size, float(p.d.max()))
        row["rate"].append(0.0 if miss is None else miss.rate)
        rng = np.random.default_rng(r)
        post = {n: v[k] for n, v in samples.items()}
        level = post["T_C_hours"].reshape(-1, len(labels))[:, 7]
        curve = level[:, None] + post["c_v"].reshape(-1)[:, None] * AT[None, :]
        true_curve = values["T_C"][7] + C_V * AT
        rel = allowance(miss, np.array([3500.0]), first=0.0, last=3000.0)
        times = typical_curves(post, form, labels, rng)
        bend = campaign_bend(post, form, labels)
        row["bend"].append("not tested" if bend is None else bend.direction)
        row["p_up"].append(np.nan if bend is None else bend.p_up)
        for tag, band, paths in (("", curve, times),
                                 ("_cal", widen_curves(curve, np.repeat(rel, AT.size), rng),
                                  widen_curves(times, allowance(miss, SEARCH, first=0.0, last=3000.0), rng))):
            lo, hi = np.quantile(band, ALPHA / 2, axis=0), np.quantile(band, 1 - ALPHA / 2, axis=0)
            row["cover" + tag].append((lo <= true_curve) & (true_curve <= hi))
            row["score" + tag].append(interval_score(lo[1], hi[1], true_curve[1]))
            c_lo, c_hi = np.quantile(crossing_times(paths, SEARCH, CAPACITY), [ALPHA / 2, 1 - ALPHA / 2],
                                     method="inverted_cdf")
            row["cross" + tag].append(c_lo <= crossing <= c_hi)
            row["width" + tag].append(c_hi - c_lo)
            row["cscore" + tag].append(interval_score(min(c_lo, SEARCH[-1]), min(c_hi, SEARCH[-1]), crossing))
        row["failed"] += int(not fits.verdicts[k].passed)
    row["truth"] = crossing
    return row


def drum_cost() -> None:
    """A trend law's fit against the pooled law's on drum_campaigns (1008 rows, 4 × 500), each
    fitted twice in this process; the second call is compiled (its seconds are the ones to read)."""
    from bayesfric.datasets import load_dataset, resolve
    from bayesfric.inference import fit

    ds = load_dataset(resolve("drum_campaigns"))
    oring = get_law("coastdown_oring_closed_form")
    for law in (oring.trend("hours", "T_C", "c_v"), oring):
        for rep in range(2):
            start = time.perf_counter()
            dt = fit(law, ds, seed=rep, draws=500, tune=500, chains=4)
            print(f"{law.name}: {time.perf_counter() - start:.1f} s, "
                  f"{float(dt['sample_stats']['n_steps'].mean()):.1f} leapfrog steps per draw", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=120)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--scatter", type=float, default=SCATTER, help="sd of the campaigns' log scatter")
    ap.add_argument("--forecast-from", type=float, default=2500.0,
                    help="first campaign (h) a leave-future-out fold forecasts (2500: two folds, as drum_campaigns)")
    ap.add_argument("--drum-cost", action="store_true", help="only time a trend fit against the pooled one")
    args = ap.parse_args()
    if args.drum_cost:
        return drum_cost()
    n = args.replicates
    print(f"SIMULATED: 8 campaigns at 0-3500 h x {SPEEDS.size} speeds, trained on the first 7, forecast the 8th; "
          f"scatter {args.scatter} (log), noise sd {SIGMA} N*m, capacity {CAPACITY} N*m at 1 rad/s, {n} replicates")
    print("case (truth / candidate)        band   cover@0.1/1/2 rad/s   whole curve  IS@1   crossing cover  "
          "median 90% width h  true crossing h  gate failed  s/fit  rate>0  folds failed")
    for name in args.cases:
        row = run_case(name, n, args.scatter, args.forecast_from)
        for tag, what in (("", "within"), ("_cal", "allowed")):
            cover = np.mean(row["cover" + tag], axis=0)
            print(f"{name:10s} ({CASES[name][0]} / {CASES[name][1]})".ljust(32) + f"{what:7s} "
                  + " / ".join(f"{c:.3f}" for c in cover) + f"   {np.mean(np.all(row['cover' + tag], axis=1)):.3f}"
                  + f"      {np.mean(row['score' + tag]):.3f}  {np.mean(row['cross' + tag]):.3f}"
                  + f"           {np.median(row['width' + tag]):8.0f}          {row['truth']:7.0f}"
                  + f"       {row['failed']:5d}  {row['s'] / n:5.2f}  {np.mean(np.asarray(row['rate']) > 0):.2f}"
                  + f"  {row['folds_failed']:5d}",
                  flush=True)
        print_exceed(name, row)
    print(f"binomial sd of a 90 % coverage over {n} replicates: {np.sqrt(0.09 / n):.3f}")


def print_exceed(name: str, row: dict) -> None:
    """The time to exceed's figures for one case: coverage, interval score, the statement, the silent miss."""
    bend, p_up = np.asarray(row["bend"]), np.asarray(row["p_up"], dtype=float)
    said, loose = bend == "upward", p_up < 0.10  # the shipped one-sided 5 % test; at 10 % for comparison
    print(f"  {name}: time to exceed (truth {row['truth']:.0f} h): statement (levels bend upward) in "
          f"{said.mean():.3f}, downward in {np.mean(bend == 'downward'):.3f}, not tested in "
          f"{np.mean(bend == 'not tested'):.3f}; at a one-sided 10 % level the statement would come in "
          f"{loose.mean():.3f}", flush=True)
    for tag, what in (("", "within"), ("_cal", "allowed")):
        miss = ~np.asarray(row["cross" + tag], dtype=bool)
        print(f"    {what:7s} crossing cover {1 - miss.mean():.3f}  interval score (inf -> {SEARCH[-1]:.0f} h) mean "
              f"{np.mean(row['cscore' + tag]):8.0f} median {np.median(row['cscore' + tag]):8.0f}  silent miss "
              f"{np.mean(miss & ~said):.3f} (at 10 %: {np.mean(miss & ~loose):.3f})", flush=True)


if __name__ == "__main__":
    main()
