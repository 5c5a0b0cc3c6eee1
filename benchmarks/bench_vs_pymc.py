"""One bayesfric fit against the same fit in PyMC + nutpie, whole processes, cold and warm.

Usage::

    /work/bench-venv/bin/python benchmarks/bench_vs_pymc.py [--laws stribeck joint_tribological]
        [--noise proportional] [--repeats 3] [--draws 1000] [--tune 1000] [--chains 4]

Needs the optional ``bench`` extra (``pip install -e ".[bench]"``: PyMC and nutpie).

Each timed run is a fresh subprocess, timed by this (parent) process from start to exit:

* **bayesfric**: the CLI ``bayesfric fit robot_joint LAW --quiet --seed S --noise NOISE --draws D
  --tune T --chains C --out fit.nc`` (the law's compiled blackjax NUTS engine, Stan warm-up,
  target acceptance 0.9, tree depth 10);
* **PyMC**: this file run as ``--child pymc``: import PyMC and nutpie, build the same model,
  ``nutpie.compile_pymc_model`` (numba backend), ``nutpie.sample`` with the same chains, tune and
  draws, target acceptance 0.9 and tree depth 10, posterior written to ``.npz``.

Same data (the built-in ``robot_joint`` set, all 111 rows, SI units), same laws, same priors and
noise model: the parent resolves them with :func:`bayesfric.model.build_program` and hands the
numbers and arrays to the PyMC child in a JSON spec, so both sides use identical values; the
child maps each bayesfric ``Prior`` to the PyMC distribution with the same density (``HalfNormal
(scale)`` → ``pm.HalfNormal(sigma)``, ``LogNormal(loc, scale)`` → ``pm.LogNormal(mu, sigma)``,
``Beta(c1, c0)`` → ``pm.Beta(alpha, beta)``) and keeps the laws' reparametrisations (``T_s = T_C +
dT_s`` as a deterministic). Both samplers work on the same unconstrained space (log for positive
parameters, logit for Beta).

Caches: **cold** = a fresh empty cache folder for the run (bayesfric: ``BAYESFRIC_CACHE_DIR``,
JAX's persistent compilation cache; PyMC: ``PYTENSOR_FLAGS=base_compiledir=...``, which holds
pytensor's numba cache, and ``NUMBA_CACHE_DIR``); **warm** = the next run with the same folder.
Order, interleaved: for each repeat, for each law: bayesfric cold, PyMC cold, bayesfric warm,
PyMC warm, with fresh folders per repeat and law. Seeds: ``2 * repeat`` cold, ``2 * repeat + 1``
warm.

Reported per law: the median wall time of the four kinds of run, the ratios bayesfric / nutpie
cold and warm (targets of the engine issue: ≤ 1.0 cold, ≤ 0.5 warm), the PyMC child's own
phases (import, model, compile, sample), and posterior agreement of the warm runs of each repeat:
per parameter ``z = (mean_bf − mean_pymc) / sqrt(mcse_bf² + mcse_pymc²)``, flagged where
``|z| > 4``. Writes ``reports/benchmarks/bench_vs_pymc.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

DATASET = "robot_joint"
LAWS = ("stribeck", "joint_tribological")
Z_FLAG = 4.0
TARGET_ACCEPT = 0.9  # bayesfric's NUTS default (bayesfric.inference.nuts)
MAX_TREE_DEPTH = 10
REPO = Path(__file__).resolve().parents[1]
OUT_JSON = REPO / "reports" / "benchmarks" / "bench_vs_pymc.json"

# --- the PyMC side (child process; imports only PyMC, nutpie and numpy) ----------------------------

#: bayesfric Prior name -> (PyMC class name, {bayesfric argument: PyMC argument}); same densities.
PYMC_PRIORS = {
    "HalfNormal": ("HalfNormal", {"scale": "sigma"}),
    "LogNormal": ("LogNormal", {"loc": "mu", "scale": "sigma"}),
    "Beta": ("Beta", {"concentration1": "alpha", "concentration0": "beta"}),
    "Normal": ("Normal", {"loc": "mu", "scale": "sigma"}),
    "Gamma": ("Gamma", {"concentration": "alpha", "rate": "beta"}),
}


def _stribeck(pt, velocity, p, c):
    """bayesfric.laws.classical.stribeck: sign(q̇)[T_C + dT_s exp(−(|q̇|/v_s)^δ)]."""
    speed = pt.abs(velocity)
    return pt.sign(velocity) * (p["T_C"] + p["dT_s"] * pt.exp(-((speed / p["v_s"]) ** p["delta"])))


def _joint_tribological(pt, velocity, p, c):
    """bayesfric.laws.classical.joint_tribological: sign(q̇)[T_a0 e^(−(|q̇|/v_s)^δa) + c_v (|q̇|/ω_ref)^(1−δv)]."""
    speed = pt.abs(velocity)
    asperity = p["T_a0"] * pt.exp(-((speed / p["v_s"]) ** p["delta_a"]))
    viscous = p["c_v"] * (speed / c["omega_ref"]) ** (1.0 - p["delta_v"])
    return pt.sign(velocity) * (asperity + viscous)


#: law -> (mean function, parameter names in declaration order, derived quantities)
PYMC_LAWS = {
    "stribeck": (_stribeck, ("T_C", "dT_s", "v_s", "delta"), {"T_s": lambda p: p["T_C"] + p["dT_s"]}),
    "joint_tribological": (_joint_tribological, ("T_a0", "v_s", "delta_a", "c_v", "delta_v"), {}),
}


def pymc_model(spec: dict):
    """The PyMC model of ``spec`` (written by :func:`write_spec`): law, priors, noise, data."""
    import pymc as pm
    import pytensor.tensor as pt

    mean, names, derived = PYMC_LAWS[spec["law"]]
    velocity = np.asarray(spec["velocity"], dtype=float)
    torque = np.asarray(spec["torque"], dtype=float)

    def prior(name):
        p = spec["priors"][name]
        cls, rename = PYMC_PRIORS[p["dist"]]
        return getattr(pm, cls)(name, **{rename[k]: v for k, v in p["args"].items()})

    with pm.Model() as model:
        params = {name: prior(name) for name in names}
        for name, fn in derived.items():
            pm.Deterministic(name, fn(params))
        mu = mean(pt, velocity, params, spec["constants"])
        if spec["noise"] == "normal":
            sd = prior("sigma")
        elif spec["noise"] == "proportional":
            rel, floor = prior("sigma_rel"), prior("sigma_floor")
            sd = pt.sqrt((rel * mu) ** 2 + floor**2)
        else:
            raise ValueError(f"noise {spec['noise']!r} is not mirrored on the PyMC side")
        pm.Normal("response", mu=mu, sigma=sd, observed=torque)
    return model


def pymc_child(args: argparse.Namespace) -> None:
    """Child process: import, build, compile with nutpie, sample; posterior to ``args.out`` (npz)."""
    t0 = time.perf_counter()
    import nutpie
    import pymc  # noqa: F401  (timed with the imports)

    t1 = time.perf_counter()
    spec = json.loads(Path(args.spec).read_text())
    model = pymc_model(spec)
    t2 = time.perf_counter()
    compiled = nutpie.compile_pymc_model(model)
    t3 = time.perf_counter()
    trace = nutpie.sample(compiled, draws=args.draws, tune=args.tune, chains=args.chains, seed=args.seed,
                          progress_bar=False, target_accept=TARGET_ACCEPT, maxdepth=MAX_TREE_DEPTH)
    t4 = time.perf_counter()
    posterior = trace["posterior"]
    np.savez(args.out, **{k: np.asarray(v.values) for k, v in posterior.data_vars.items()})
    stats = trace["sample_stats"]
    print(json.dumps({"import": t1 - t0, "model": t2 - t1, "compile": t3 - t2, "sample": t4 - t3,
                      "divergent": int(np.asarray(stats["diverging"]).sum()),
                      "n_steps_mean": float(np.asarray(stats["n_steps"]).mean())}))


# --- the parent: specs, timed subprocesses, summary ----------------------------------------------


def write_spec(law_name: str, noise: str, folder: Path) -> Path:
    """Resolve law, priors and noise with bayesfric; write them and the SI data as a JSON spec."""
    from bayesfric.datasets import load_builtin
    from bayesfric.laws import get_law
    from bayesfric.model import Noise, build_program

    ds = load_builtin(DATASET)
    law = get_law(law_name)
    program = build_program(law, ds, noise=Noise(kind=noise))
    names = PYMC_LAWS[law_name][1]
    if tuple(law.params) != names or set(law.derived) != set(PYMC_LAWS[law_name][2]):
        raise RuntimeError(f"the PyMC mirror of {law_name} is out of date: {list(law.params)}, {list(law.derived)}")
    velocity = program.inputs["velocity"]
    if not np.all(velocity != 0):
        raise RuntimeError("the PyMC mirror assumes non-zero speeds (bayesfric's _pow guards |q̇| = 0)")
    priors = {k: {"dist": p.dist, "args": dict(p.args)} for k, p in program.resolved.items()}
    spec = {"law": law_name, "noise": noise, "velocity": velocity.tolist(), "torque": program.response.tolist(),
            "priors": priors, "constants": program.constants, "parameters": program.parameter_names()}
    path = folder / f"spec_{law_name}.json"
    path.write_text(json.dumps(spec, indent=1))
    return path


def timed(cmd: list[str], env: dict[str, str], log: Path) -> tuple[float, str]:
    """Run ``cmd`` as a fresh process; wall seconds from start to exit, and its stdout."""
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=REPO, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    log.write_text(f"$ {' '.join(cmd)}\n--- stdout\n{proc.stdout}\n--- stderr\n{proc.stderr}")
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd[:4]} failed ({proc.returncode}); see {log}:\n{proc.stderr[-2000:]}")
    return seconds, proc.stdout


def run_one(side: str, law: str, seed: int, caches: Path, spec: Path, out: Path, args) -> dict:
    """One timed whole-process run of ``side`` ("bayesfric" or "pymc") with the given cache folder."""
    env = dict(os.environ)
    sampling = ["--draws", str(args.draws), "--tune", str(args.tune), "--chains", str(args.chains)]
    if side == "bayesfric":
        env["BAYESFRIC_CACHE_DIR"] = str(caches / "jax")
        exe = Path(sys.executable).with_name("bayesfric")
        cmd = [str(exe), "fit", DATASET, law, "--quiet", "--seed", str(seed), "--noise", args.noise,
               *sampling, "--out", str(out)]
    else:
        env["PYTENSOR_FLAGS"] = f"base_compiledir={caches / 'pytensor'}"
        env["NUMBA_CACHE_DIR"] = str(caches / "numba")
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "pymc", "--spec", str(spec),
               "--seed", str(seed), "--out", str(out), *sampling]
    load1 = os.getloadavg()[0]
    seconds, stdout = timed(cmd, env, out.with_suffix(".log"))
    row = {"side": side, "law": law, "seed": seed, "seconds": seconds, "load1_at_start": load1, "posterior": str(out)}
    if side == "pymc":
        row["phases"] = json.loads(stdout.strip().splitlines()[-1])
    return row


def posterior_of(row: dict) -> dict[str, np.ndarray]:
    """Posterior draws (chain, draw) by parameter from a run's output file."""
    if row["side"] == "pymc":
        with np.load(row["posterior"]) as f:
            return {k: f[k] for k in f.files}
    import xarray as xr

    with xr.open_datatree(row["posterior"], engine="h5netcdf") as dt:
        return {k: np.asarray(v.values) for k, v in dt["posterior"].to_dataset().data_vars.items()}


def agreement(bf: dict, pm: dict, names: list[str]) -> dict[str, dict]:
    """Per parameter: means, MCSEs, bulk ESS and z = Δmean / sqrt(mcse_bf² + mcse_pymc²)."""
    import arviz_stats as azs
    import xarray as xr

    def stats(draws):
        ds = xr.Dataset({k: (("chain", "draw"), draws[k]) for k in names})
        mcse, ess = azs.mcse(ds, method="mean"), azs.ess(ds, method="bulk")
        return {k: (float(draws[k].mean()), float(mcse[k]), float(ess[k])) for k in names}

    a, b = stats(bf), stats(pm)
    out = {}
    for k in names:
        z = (a[k][0] - b[k][0]) / np.hypot(a[k][1], b[k][1])
        out[k] = {"mean_bf": a[k][0], "mean_pymc": b[k][0], "mcse_bf": a[k][1], "mcse_pymc": b[k][1],
                  "ess_bulk_bf": a[k][2], "ess_bulk_pymc": b[k][2], "z": float(z), "flag": bool(abs(z) > Z_FLAG)}
    return out


def load_average() -> dict:
    """``uptime`` output and the 1/5/15-minute load averages."""
    text = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    return {"uptime": text, "loadavg": list(os.getloadavg())}


def run_pair(repeat: int, law: str, spec: Path, work: Path, args: argparse.Namespace) -> list[dict]:
    """bayesfric cold, PyMC cold, bayesfric warm, PyMC warm for one law, with fresh cache folders."""
    caches = {side: work / f"r{repeat}_{law}_{side}_cache" for side in ("bayesfric", "pymc")}
    rows = []
    for kind, seed in (("cold", 2 * repeat), ("warm", 2 * repeat + 1)):
        for side in ("bayesfric", "pymc"):
            out = work / f"r{repeat}_{law}_{side}_{kind}.{'nc' if side == 'bayesfric' else 'npz'}"
            row = dict(run_one(side, law, seed, caches[side], spec, out, args), repeat=repeat, kind=kind)
            rows.append(row)
            print(f"repeat {repeat} {law:20s} {side:9s} {kind}: {row['seconds']:6.1f} s "
                  f"(load {row['load1_at_start']:.1f})", flush=True)
    return rows


def benchmark(args: argparse.Namespace, work: Path) -> tuple[list[dict], dict]:
    """All timed runs, interleaved (module docstring), and the agreement of each repeat's warm runs."""
    specs = {law: write_spec(law, args.noise, work) for law in args.laws}
    rows, agree = [], {law: [] for law in args.laws}
    for repeat in range(args.repeats):
        for law in args.laws:
            pair = run_pair(repeat, law, specs[law], work, args)
            rows += pair
            warm = {r["side"]: r for r in pair if r["kind"] == "warm"}
            names = json.loads(specs[law].read_text())["parameters"]
            agree[law].append(agreement(posterior_of(warm["bayesfric"]), posterior_of(warm["pymc"]), names))
    return rows, agree


def summarise(rows: list[dict], agree: dict, laws: list[str]) -> dict:
    """Medians by law, side and kind; ratios; PyMC phase medians; worst |z| over repeats."""
    summary = {}
    for law in laws:
        med = {f"{side}_{kind}": statistics.median(r["seconds"] for r in rows
                                                  if r["law"] == law and r["side"] == side and r["kind"] == kind)
               for side in ("bayesfric", "pymc") for kind in ("cold", "warm")}
        phases = {kind: {ph: statistics.median(r["phases"][ph] for r in rows
                                               if r["law"] == law and r["side"] == "pymc" and r["kind"] == kind)
                         for ph in ("import", "model", "compile", "sample")} for kind in ("cold", "warm")}
        z_max = {k: max(abs(a[k]["z"]) for a in agree[law]) for k in agree[law][0]}
        summary[law] = {"median_seconds": med, "ratio_cold": med["bayesfric_cold"] / med["pymc_cold"],
                        "ratio_warm": med["bayesfric_warm"] / med["pymc_warm"], "pymc_phases_median": phases,
                        "abs_z_max_over_repeats": z_max, "flagged": sorted(k for k, z in z_max.items() if z > Z_FLAG)}
    return summary


def print_summary(summary: dict, agree: dict) -> None:
    """The table of the README and the agreement of repeat 0."""
    print("\n| law | bayesfric cold | nutpie cold | ratio | bayesfric warm | nutpie warm | ratio |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for law, s in summary.items():
        m = s["median_seconds"]
        print(f"| {law} | {m['bayesfric_cold']:.1f} s | {m['pymc_cold']:.1f} s | {s['ratio_cold']:.2f} | "
              f"{m['bayesfric_warm']:.1f} s | {m['pymc_warm']:.1f} s | {s['ratio_warm']:.2f} |")
    for law, per_repeat in agree.items():
        print(f"\n{law}: posterior agreement, repeat 0 (max |z| over repeats in brackets)")
        for k, a in per_repeat[0].items():
            print(f"  {k:12s} bayesfric {a['mean_bf']:10.4g} ± {a['mcse_bf']:.2g}   PyMC {a['mean_pymc']:10.4g} ± "
                  f"{a['mcse_pymc']:.2g}   z {a['z']:+5.2f} ({summary[law]['abs_z_max_over_repeats'][k]:.2f})"
                  f"{'  FLAG' if a['flag'] else ''}")


def versions() -> dict[str, str]:
    """Installed versions of both stacks."""
    from importlib.metadata import version

    return {p: version(p) for p in ("bayesfric", "jax", "numpyro", "pymc", "pytensor", "nutpie", "numba")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--laws", nargs="+", default=list(LAWS), choices=list(PYMC_LAWS))
    parser.add_argument("--noise", default="proportional", choices=["normal", "proportional"],
                        help="noise model on both sides (default: the robot_joint study's)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--tune", type=int, default=1000)
    parser.add_argument("--chains", type=int, default=4)
    parser.add_argument("--keep", action="store_true", help="keep the work folder (fits, logs, caches)")
    parser.add_argument("--child", choices=["pymc"], help=argparse.SUPPRESS)
    parser.add_argument("--spec", help=argparse.SUPPRESS)
    parser.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        return pymc_child(args)
    work = Path(tempfile.mkdtemp(prefix="bench_vs_pymc_"))
    before = load_average()
    print(f"work folder {work}; before: {before['uptime']}", flush=True)
    try:
        rows, agree = benchmark(args, work)
    finally:
        after = load_average()
        print(f"after: {after['uptime']}")
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    summary = summarise(rows, agree, args.laws)
    print_summary(summary, agree)
    setting = {"dataset": DATASET, "rows": "all", "noise": args.noise, "draws": args.draws, "tune": args.tune,
               "chains": args.chains, "target_accept": TARGET_ACCEPT, "max_tree_depth": MAX_TREE_DEPTH,
               "repeats": args.repeats, "cpu_count": os.cpu_count()}
    OUT_JSON.parent.mkdir(parents=True, exist_ok=True)
    OUT_JSON.write_text(json.dumps({"setting": setting, "versions": versions(), "load_before": before,
                                    "load_after": after, "summary": summary, "agreement": agree, "runs": rows},
                                   indent=2))
    print(f"written {OUT_JSON.relative_to(REPO)}")


if __name__ == "__main__":
    main()
