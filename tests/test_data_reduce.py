"""``bayesfric data reduce``: segment means of a raw log recovered within their standard errors,
the reduced data's likelihood by hand, bad input, and a study that ranks the laws as on the raw log.

The synthetic raw log (:func:`raw_log`): a joint run at a series of constant speeds, each reached
by a linear ramp; the torque follows the steady-state Stribeck (+ viscous) truth through a
first-order lag (a transient after every change) plus AR(1) noise; the measured speed carries
white noise; a time column at 200 Hz.
"""

from __future__ import annotations

import csv as csv_module
import hashlib
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bayesfric.cli import main
from bayesfric.datasets import load_dataset
from bayesfric.datasets.reduce import ReduceOptions, find_segments, mean_se, reduce_log, write_reduction
from bayesfric.errors import DataError
from bayesfric.laws import get_law
from bayesfric.model import Noise, build_program

SPEEDS = (0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.5, 3.0)
SIDECAR = """[dataset]
name = "rawlog"
provenance = "simulated"
source = "synthetic raw log (tests/test_data_reduce.py)"
[columns.t_s]
role = "input"
quantity = "time"
unit = "s"
[columns.speed]
role = "input"
quantity = "velocity"
unit = "rpm"
[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"
"""


def truth(v, viscous=2.0):
    """Steady-state torque: Stribeck (T_C 10, T_s 16 N*m, v_s 0.1 rad/s, delta 1) + viscous."""
    v = np.asarray(v, dtype=float)
    return np.sign(v) * (10.0 + 6.0 * np.exp(-np.abs(v) / 0.1)) + viscous * v


def raw_log(folder: Path, seed=0, speeds=SPEEDS, plateau=250, ramp=20, rho=0.8, sd=0.5, lag=10.0,
            viscous=2.0, signs=(1, -1)) -> tuple[Path, np.ndarray]:
    """Write ``raw.csv`` + ``raw.toml``; return the CSV path and the true plateau torques."""
    rng = np.random.default_rng(seed)
    levels = np.asarray([s * v for s in signs for v in speeds])
    v = np.concatenate([np.concatenate([np.linspace(a, b, ramp + 1)[1:], np.full(plateau, b)])
                        for a, b in zip(np.r_[0.0, levels[:-1]], levels, strict=True)])
    steady, decay = truth(v, viscous), np.exp(-1.0 / lag)
    torque, noise = np.empty(v.size), np.empty(v.size)
    torque[0], noise[0] = steady[0], rng.normal(0.0, sd)
    shocks = rng.normal(0.0, sd * np.sqrt(1.0 - rho**2), v.size)
    for k in range(1, v.size):
        torque[k] = decay * torque[k - 1] + (1.0 - decay) * steady[k]
        noise[k] = rho * noise[k - 1] + shocks[k]
    rpm = (v + rng.normal(0.0, 0.0005, v.size)) * 60.0 / (2.0 * np.pi)
    folder.mkdir(parents=True, exist_ok=True)
    csv = folder / "raw.csv"
    rows = "\n".join(f"{t:.6g},{s:.7g},{y:.6g}" for t, s, y in zip(np.arange(v.size) / 200.0, rpm, torque + noise,
                                                                    strict=True))
    csv.write_text("t_s,speed,torque\n" + rows + "\n")
    csv.with_suffix(".toml").write_text(SIDECAR)
    return csv, truth(levels, viscous)


def test_segment_means_recovered_within_their_standard_errors(tmp_path):
    """Over 10 logs x 16 plateaus (AR(1) rho = 0.8: tau = 9, n_eff ~ 25 of ~225 rows), the true
    plateau torque lies within 1.96 se of the mean in >= 85 % of segments (measured 92-93 %; the
    naive sd/sqrt(n) would cover about 50 %), and z = (mean - truth) / se has sd within 0.8-1.35."""
    z = []
    for seed in range(10):
        csv, true = raw_log(tmp_path / str(seed), seed=seed)
        red = reduce_log(csv)
        assert len(red.segments) == true.size
        level = red.source["velocity"].values
        for seg, mu, target in zip(red.segments, true, np.r_[SPEEDS, -np.asarray(SPEEDS)], strict=True):
            assert abs(level[seg.first:seg.stop].mean() - target) < 0.01  # the segment is the plateau
            assert 1.0 <= seg.n_eff <= seg.stop - seg.first
            z.append((seg.mean - mu) / seg.se)
    z = np.asarray(z)
    assert np.mean(np.abs(z) < 1.96) >= 0.85, np.mean(np.abs(z) < 1.96)
    assert 0.8 < z.std() < 1.35, z.std()


def test_mean_se_white_and_constant():
    rng = np.random.default_rng(1)
    y = rng.normal(3.0, 2.0, 400)
    mean, se, n_eff = mean_se(y)
    assert mean == pytest.approx(y.mean())
    assert se == pytest.approx(y.std() / np.sqrt(400), rel=0.25)  # white noise: n_eff about n
    assert mean_se(np.full(50, 7.0)) == (7.0, 0.0, 50.0)


def test_find_segments_steps_ramps_and_blocks():
    x = np.r_[np.full(30, 1.0), np.linspace(1.0, 2.0, 42)[1:-1], np.full(30, 2.0), np.full(30, 2.0)]
    starts = np.zeros(x.size, dtype=bool)
    starts[[0, 100]] = True  # a new run at row 100: same level, another segment
    segs = [(a, b) for a, b in find_segments(x, starts, 0.02, 1e-6) if b - a >= 10]
    assert segs == [(0, 30), (69, 100), (100, 130)]  # row 69 (1.976) lies within 2 % of 2


def test_written_files_load_and_carry_the_reduction(tmp_path):
    csv, _ = raw_log(tmp_path, speeds=(0.1, 1.0), signs=(1,), plateau=120)
    red = reduce_log(csv, options=ReduceOptions(settle="0.1 s", min_samples=30))
    out, sidecar = write_reduction(red, tmp_path / "red.csv")
    ds = load_dataset(out)
    meta = tomllib.loads(sidecar.read_text())
    assert ds.sizes["obs"] == 2 and "time" not in ds.coords
    assert np.allclose(ds["velocity"].values, [0.1, 1.0], atol=1e-3)  # written in rpm, read back in SI
    assert np.array_equal(ds["count"].values, [s.stop - s.first for s in red.segments])
    assert ds["torque_se"].attrs["role"] == "se" and np.all(ds["torque_se"].values > 0)
    assert meta["reduction"]["source_file"] == "raw.csv" and meta["reduction"]["settle"] == "0.1 s"
    assert meta["reduction"]["source_sha256"] == hashlib.sha256(csv.read_bytes()).hexdigest()
    assert meta["reduction"]["sidecar_sha256"] == hashlib.sha256(csv.with_suffix(".toml").read_bytes()).hexdigest()
    assert ds.attrs["reduced_from"].startswith("raw.csv (sha256 ")
    unsettled = reduce_log(csv, options=ReduceOptions(settle="0", min_samples=30))
    assert [s.first - u.first for s, u in zip(red.segments, unsettled.segments, strict=True)] == [20, 20]  # 200 Hz
    # segment means are no trajectory: a stateful law is refused in one line, naming the data set
    with pytest.raises(DataError, match="trajectory .stateful. law, but data set .* segment means"):
        build_program(get_law("dahl"), ds)


def test_reduced_likelihood_by_hand(dataset_factory):
    """y_i ~ Normal(mu_i, sqrt(sigma^2 + se_i^2)): the pointwise log-likelihood of a three-row
    reduced data set at a fixed parameter point, against scipy-free arithmetic."""
    v, y, se = np.array([0.5, 1.0, 2.0]), np.array([10.3, 11.1, 12.2]), np.array([0.1, 0.3, 0.05])
    ds = dataset_factory({"velocity": v}, y)
    ds["torque_se"] = ("obs", se, {"role": "se", "quantity": "torque", "units": "N*m"})
    law = get_law("coulomb_viscous")
    for noise in (Noise(), Noise(sigma=0.2)):
        program = build_program(law, ds, noise=noise)
        assert np.array_equal(program.response_se, se)
        density = program.density()
        x = density.x0
        draw = density.constrain(x)
        sigma = 0.2 if noise.sigma else float(draw["sigma"])
        mu = float(draw["T_C"]) + float(draw["c_v"]) * v
        var = sigma**2 + se**2
        expected = -0.5 * (np.log(2 * np.pi * var) + (y - mu) ** 2 / var)
        assert np.allclose(np.asarray(density.log_likelihood(x)), expected, rtol=1e-10)
    plain = build_program(law, ds.drop_vars("torque_se"))
    assert plain.response_se is None
    with pytest.raises(ValueError, match="does not apply"):
        build_program(law, ds.assign_coords(run=("obs", [1, 1, 1])).assign_attrs(trajectory="run"),
                      noise=Noise(kind="ar1"))


@pytest.mark.parametrize(("args", "message"), [
    (["--on", "preload"], "--on 'preload': .*raw.csv has no such input"),
    (["--settle", "abc s"], "--settle 'abc s'"),
    (["--settle", "150%"], "--settle '150%': a percentage"),
    (["--atol", "3 N*m"], "--atol '3 N\\*m'"),
    (["--rtol", "nan"], "--rtol nan"),
    (["--min-samples", "100000"], "no steady segment of velocity"),
    (["--out", "{src}"], "would overwrite .*raw.csv, the source log"),
    (["--out", "{dir}/x.txt"], "is a .csv file"),
])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, args, message):
    csv, _ = raw_log(tmp_path, speeds=(0.1, 1.0), signs=(1,), plateau=60)
    before = sorted(p.name for p in tmp_path.iterdir())
    args = [a.format(src=csv, dir=tmp_path) for a in args]
    assert main(["data", "reduce", str(csv), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("bayesfric: error: ") and "Traceback" not in err
    assert re.search(message, err), err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_bad_row_names_file_row_and_column(tmp_path, capsys):
    csv, _ = raw_log(tmp_path, speeds=(0.1,), signs=(1,), plateau=60)
    lines = csv.read_text().splitlines()
    lines[5] = lines[5].rsplit(",", 1)[0] + ",oops"
    csv.write_text("\n".join(lines) + "\n")
    assert main(["data", "reduce", str(csv)]) == 2
    err = capsys.readouterr().err
    assert f"{csv}: row 5: column 'torque': 'oops' is not a number" in err
    assert not (tmp_path / "raw_reduced.csv").exists()


def test_command_writes_default_output(tmp_path, capsys):
    csv, _ = raw_log(tmp_path, speeds=(0.1, 1.0), signs=(1, -1), plateau=80)
    assert main(["data", "reduce", str(csv), "--settle", "10"]) == 0
    out = capsys.readouterr().out
    assert "4 segments of constant velocity" in out
    assert load_dataset(tmp_path / "raw_reduced.csv").sizes["obs"] == 4
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary file left


STUDY = """[study]
name = "{name}"
question = "Which law: the raw log or its steady-state reduction?"
[data]
dataset = "{data}"
[sampler]
draws = 300
tune = 400
chains = 2
seed = 0
[[laws]]
name = "coulomb"
[[laws]]
name = "coulomb_viscous"
[[laws]]
name = "armstrong_helouvry"
[compare]
loo = true
evidence = false
"""


@pytest.mark.slow
def test_study_on_reduction_ranks_laws_as_on_raw_log(tmp_path, monkeypatch):
    """Truth Stribeck + viscous (armstrong_helouvry); the raw log (8 speeds, 960 rows, AR(1)
    noise, transients) and its 8-row reduction give the same PSIS-LOO order of the three laws
    (``place``, by score: a short run may leave a fit below the ESS gate, which ranks nothing)
    wherever the data decide it.

    On the raw log every gap is decisive (hundreds of nats). On the 8 rows of the reduction the
    truth is still first by far (≈ 20 nat), but Coulomb and Coulomb + viscous are within a tenth of
    a nat of each other (a few nats of standard error: 8 speeds cannot show the viscous slope), so
    their order there is a coin toss that changed with the installed package versions (2026-11-26);
    the test asks only that the reduction does not reverse them by more than one standard error.
    """
    from bayesfric.pipeline.runner import run_study

    monkeypatch.setenv("BAYESFRIC_STORE_DIR", str(tmp_path / "store"))
    csv, _ = raw_log(tmp_path, signs=(1,), plateau=100)
    assert main(["data", "reduce", str(csv)]) == 0
    rows = {}
    for data in ("raw", "raw_reduced"):
        study = tmp_path / f"{data}.study.toml"
        study.write_text(STUDY.format(name=f"s_{data}", data=f"{data}.csv"))
        folder = run_study(study, tmp_path / "reports", live_progress=False)
        with open(folder / "ranking.csv", newline="") as fh:
            rows[data] = sorted(csv_module.DictReader(fh), key=lambda r: int(r["place"]))
    expected = ["armstrong_helouvry", "coulomb_viscous", "coulomb"]
    assert [r["law"] for r in rows["raw"]] == expected, rows["raw"]
    elpd = {r["law"]: (float(r["elpd_loo"]), float(r["elpd_loo_se"])) for r in rows["raw_reduced"]}
    assert rows["raw_reduced"][0]["law"] == "armstrong_helouvry", rows["raw_reduced"]
    assert elpd["armstrong_helouvry"][0] - max(elpd["coulomb"][0], elpd["coulomb_viscous"][0]) > 5, elpd
    (viscous, se_v), (coulomb, se_c) = elpd["coulomb_viscous"], elpd["coulomb"]
    assert viscous > coulomb - max(se_v, se_c), elpd  # not reversed beyond one standard error


def _sweep_log(folder: Path, seconds: float = 120.0) -> Path:
    """A raw log whose speed sweeps without holding (a trajectory, no plateaus): AR(1) noise as raw_log."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, seconds, 1 / 200.0)
    v = 1.0 + 0.8 * np.sin(2 * np.pi * t / 30.0)
    noise = np.zeros(t.size)
    for k in range(1, t.size):
        noise[k] = 0.8 * noise[k - 1] + rng.normal(0.0, 0.3)
    rpm = v * 60.0 / (2.0 * np.pi)
    folder.mkdir(parents=True, exist_ok=True)
    csv = folder / "raw.csv"
    csv.write_text("t_s,speed,torque\n" + "\n".join(f"{a:.6g},{b:.7g},{c:.6g}" for a, b, c in
                                                     zip(t, rpm, truth(v, 2.0) + noise, strict=True)) + "\n")
    csv.with_suffix(".toml").write_text(SIDECAR)
    return csv


def test_the_command_states_the_plateau_share_and_warns_on_a_log_without_plateaus(tmp_path, capsys):
    """Plateaus: the share of the log averaged and the segments' sizes, no warning. A sweep: a
    warning naming the low effective sample size; with --strict exit 2 and nothing written."""
    csv, _ = raw_log(tmp_path / "steps", speeds=(0.1, 1.0), signs=(1,), plateau=250)
    assert main(["data", "reduce", str(csv)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"\d+ rows averaged, \d+% of the log", out) and "median effective sample size" in out
    assert "WARNING" not in out
    sweep = _sweep_log(tmp_path / "sweep")
    assert main(["data", "reduce", str(sweep)]) == 0
    out = capsys.readouterr().out
    assert "WARNING: the" in out and "not plateaus" in out
    (sweep.parent / "raw_reduced.csv").unlink()
    (sweep.parent / "raw_reduced.toml").unlink()
    before = sorted(p.name for p in sweep.parent.iterdir())
    assert main(["data", "reduce", str(sweep), "--strict"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--strict: nothing written" in err
    assert sorted(p.name for p in sweep.parent.iterdir()) == before
