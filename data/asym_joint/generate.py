"""Generate the *simulated* asymmetric robot joint with a torque offset -- not measured, known truth.

Usage: ``python data/asym_joint/generate.py [OUTDIR]`` writes ``asym_joint.csv`` and
``asym_joint.toml`` (default OUTDIR: this folder). Bit-identical on every run: numpy float64, one
fixed seed, fixed text formats.

What is simulated: steady friction torque of a joint driven in both directions at 40 speeds per
direction (0.01-2 rad/s, log-spaced), two series. The truth is the Armstrong-Hélouvry law
(Stribeck + viscous, seed 004 Eq. 5) whose static excess ``dT_s`` and viscous coefficient ``c_v``
differ by direction, plus a constant torque offset (e.g. an unbalanced gravity load or a sensor
zero), with Gaussian noise of 0.2 N*m -- the situation met on a measured joint.
The truth is :data:`TRUTH`; the law is built by :mod:`bayesfric.laws.variants`, the same code the
study fits, so the data test the workbench's inference, not an independent physical model.

Identifiability (why the Coulomb level is symmetric here): with an offset, a direction-dependent
Coulomb level is confounded with it -- only ``T_C_pos + offset`` and ``T_C_neg − offset`` are
identified by a steady curve. Direction-dependent Stribeck hump and viscous slope are not.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

NAME = "asym_joint"
SEED = 20261122
#: Ground truth in SI units (N*m, rad/s, N*m*s/rad).
TRUTH = {"T_C": 5.0, "dT_s_pos": 3.0, "dT_s_neg": 1.5, "v_s": 0.1, "delta": 1.0, "c_v_pos": 4.0,
         "c_v_neg": 2.5, "offset": 1.2}
SIGMA = 0.2
VARIANT = {"asymmetric": ["dT_s", "c_v"], "offset": True}


def truth_law():
    """The law the data are simulated from (the study's ``asym_offset`` entry)."""
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import vary

    return vary(get_law("armstrong_helouvry"), name="asym_offset", **VARIANT)


def table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(velocity, series, torque) of every row."""
    from bayesfric.runtime import configure

    configure()
    speeds = np.geomspace(0.01, 2.0, 40)
    one = np.concatenate([-speeds[::-1], speeds])
    velocity = np.tile(one, 2)
    series = np.repeat([1, 2], one.size)
    mean = np.asarray(truth_law().mean({"velocity": velocity}, TRUTH), dtype=float)
    torque = mean + np.random.default_rng(SEED).normal(0.0, SIGMA, mean.size)
    return velocity, series, torque


def toml_text() -> str:
    truth = ", ".join(f"{k} = {v:g}" for k, v in TRUTH.items())
    source = (
        f"data/asym_joint/generate.py: Armstrong-Helouvry law with direction-dependent dT_s and c_v "
        f"plus a constant offset; truth {truth} (SI); noise sd {SIGMA:g} N*m; seed {SEED}"
    )
    description = (
        "Steady friction torque against joint speed in both directions, two series. SIMULATED, not "
        "measured: see data/asym_joint/README.md."
    )
    return f'''[dataset]
name = "{NAME}"
title = "SIMULATED asymmetric joint with a torque offset (known truth)"
provenance = "simulated"
source = "{source}"
description = "{description}"

[columns.speed]
role = "input"
quantity = "velocity"
unit = "rad/s"

[columns.series]
role = "group"

[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"
'''


def main(outdir: Path) -> None:
    """Write ``asym_joint.csv`` and ``asym_joint.toml`` into ``outdir``."""
    velocity, series, torque = table()
    lines = ["# SIMULATED from a known truth (data/asym_joint/generate.py) -- not measured data",
             "speed,series,torque"]
    lines += [f"{v:.6g},{s:d},{t:.6f}" for v, s, t in zip(velocity, series, torque, strict=True)]
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent)
