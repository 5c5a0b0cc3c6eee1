"""Generate *simulated* tribometer force-displacement loops (µm, mN) -- not measured, known truth.

Usage, from the repository root: ``PYTHONPATH=. python data/tribo_loops/generate.py [OUTDIR]``
writes ``tribo_loops.csv`` and ``tribo_loops.toml`` (default OUTDIR: this folder). Bit-identical
on every run: numpy float64, one fixed seed, fixed text formats.

What is simulated: a reciprocating tribometer's sinusoidal strokes of 10, 20 and 30 µm amplitude
at 1 Hz, two cycles each, 60 samples per cycle (360 rows), one normal load (no preload column).
The friction force follows Dahl's model (seed 001 Eq. 3, the exact step update of
:mod:`bayesfric.laws.hysteresis`) on translational quantities, starting each stroke on the
saturated branch: running friction 0.5 mN, knee 2 µm, exponent 1.5, with Gaussian noise of 5 µN.
Sliding velocity and time are recorded too, so LuGre can be fitted to the same loops. The law is
the one the study fits (built by :mod:`bayesfric.laws.variants`), so the data test the inference
at µm scale, not an independent tribological model.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

NAME = "tribo_loops"
SEED = 20261123
#: Ground truth (SI: N, m): running friction, knee, exponent.
TRUTH = {"F_c0": 5e-4, "x_c0": 2e-6, "i": 1.5}
SIGMA = 5e-6  # N
AMPLITUDES = (10e-6, 20e-6, 30e-6)  # m
PER_CYCLE, CYCLES, FREQ = 60, 2, 1.0


def table() -> dict[str, np.ndarray]:
    """Columns in SI units: displacement, linear_velocity, time, run, force."""
    from bayesfric.laws import get_law
    from bayesfric.laws.base import TRAJECTORY_START
    from bayesfric.laws.variants import vary
    from bayesfric.runtime import configure

    configure()
    t = np.arange(PER_CYCLE * CYCLES) / (PER_CYCLE * FREQ)
    phase = 2 * np.pi * FREQ * t
    x = np.concatenate([a * np.sin(phase) for a in AMPLITUDES])
    v = np.concatenate([a * 2 * np.pi * FREQ * np.cos(phase) for a in AMPLITUDES])
    run = np.repeat(np.arange(1, len(AMPLITUDES) + 1), t.size)
    start = np.r_[True, run[1:] != run[:-1]]
    law = vary(get_law("dahl"), without=["preload"], motion="translational")
    mean = np.asarray(law.mean({"displacement": x, TRAJECTORY_START: start}, TRUTH), dtype=float)
    force = mean + np.random.default_rng(SEED).normal(0.0, SIGMA, mean.size)
    return {"displacement": x, "linear_velocity": v, "time": np.tile(t, len(AMPLITUDES)), "run": run,
            "force": force}


def toml_text() -> str:
    truth = ", ".join(f"{k} = {v:g}" for k, v in TRUTH.items())
    source = (
        f"data/tribo_loops/generate.py: Dahl model on translational quantities, strokes of 10/20/30 "
        f"um at 1 Hz; truth {truth} (SI); noise sd {SIGMA:g} N; seed {SEED}"
    )
    description = (
        "Friction force against displacement of a reciprocating tribometer, three stroke "
        "amplitudes. SIMULATED, not measured: see data/tribo_loops/README.md."
    )
    return f'''[dataset]
name = "{NAME}"
title = "SIMULATED tribometer loops at µm scale (known truth)"
provenance = "simulated"
source = "{source}"
description = "{description}"
trajectory = "run"

[columns.x_um]
role = "input"
quantity = "displacement"
unit = "um"

[columns.v_um_s]
role = "input"
quantity = "linear_velocity"
unit = "um/s"

[columns.t_ms]
role = "input"
quantity = "time"
unit = "ms"

[columns.run]
role = "group"

[columns.F_mN]
role = "response"
quantity = "force"
unit = "mN"
'''


def main(outdir: Path) -> None:
    """Write ``tribo_loops.csv`` and ``tribo_loops.toml`` into ``outdir``."""
    c = table()
    lines = ["# SIMULATED from a known truth (data/tribo_loops/generate.py) -- not measured data",
             "x_um,v_um_s,t_ms,run,F_mN"]
    lines += [f"{x * 1e6:.6f},{v * 1e6:.6f},{t * 1e3:.4f},{r:d},{f * 1e3:.7f}"
              for x, v, t, r, f in zip(c["displacement"], c["linear_velocity"], c["time"], c["run"], c["force"],
                                       strict=True)]
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent)
