"""Start-up time of the light commands: ``--version``, ``--help``, ``laws``, ``data list|check|reduce``.

Each command runs as a user runs it, a fresh ``python -m bayesfric`` process, ``--repeats`` times
in turn with the others (so a change of the machine's load hits every command alike); the
table gives the median and the fastest wall seconds of each, and the machine's load average
before and after. For reference it also times a bare interpreter and ``import jax, numpyro``,
the cost the light commands no longer pay (issue 48 item 5: ≤ 1 s on the 2-core machine).

    .venv/bin/python benchmarks/bench_cli_start.py [--repeats 5] [--src FOLDER]

``--src FOLDER`` times the ``bayesfric`` package found in FOLDER instead (on ``PYTHONPATH``),
e.g. an earlier commit's: ``git archive <commit> bayesfric | tar -x -C FOLDER`` (link
``FOLDER/bayesfric/builtin_data`` to ``data/`` for ``data list``). Writes
``reports/benchmarks/cli_start.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SIDECAR = """[dataset]
name = "rawlog"
provenance = "simulated"
source = "synthetic raw log (benchmarks/bench_cli_start.py)"
[columns.t_s]
role = "input"
quantity = "time"
unit = "s"
[columns.speed]
role = "input"
quantity = "velocity"
unit = "rad/s"
[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"
"""


def raw_log(folder: Path) -> Path:
    """A raw log of 16 constant-speed plateaus of 250 rows (4 000 rows) with its sidecar."""
    rows, t = [], 0.0
    for i, speed in enumerate(s * v for s in (1, -1) for v in (0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.5, 3.0)):
        for k in range(250):
            noise = ((i * 250 + k) * 7919 % 1000 - 500) / 5000  # deterministic, no numpy needed
            rows.append(f"{t:.4f},{speed:.5g},{(10 if speed > 0 else -10) + 2 * speed + noise:.5g}")
            t += 0.005
    csv = folder / "raw.csv"
    csv.write_text("t_s,speed,torque\n" + "\n".join(rows) + "\n")
    csv.with_suffix(".toml").write_text(SIDECAR)
    return csv


def commands(folder: Path) -> dict[str, list[str]]:
    """Label -> arguments of ``python`` (the light commands and the two references)."""
    robot = str(REPO / "data" / "robot_joint" / "robot_joint.csv")
    cli = ["-m", "bayesfric"]
    return {
        "python -c pass (reference)": ["-c", "pass"],
        "import jax, numpyro (reference)": ["-c", "import jax, numpyro"],
        "--version": [*cli, "--version"],
        "--help": [*cli, "--help"],
        "laws --names": [*cli, "laws", "--names"],
        "laws": [*cli, "laws"],
        "data list": [*cli, "data", "list"],
        "data check robot_joint.csv": [*cli, "data", "check", robot],
        "data reduce (4 000 rows)": [*cli, "data", "reduce", str(raw_log(folder)), "--out",
                                     str(folder / "out.csv")],
    }


def timed(args: list[str], env: dict[str, str], cwd: Path) -> tuple[float, int]:
    """(wall seconds, exit status) of one process: a command an earlier version lacks (``--version``)
    still costs the user the time it takes to say so."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, *args], env=env, cwd=cwd, capture_output=True, text=True)
    return time.perf_counter() - start, done.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--src", type=Path, help="time the bayesfric package in this folder instead")
    args = parser.parse_args()
    env = dict(os.environ)
    if args.src is not None:
        env["PYTHONPATH"] = str(args.src.resolve())
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        todo = commands(folder)
        load_before = os.getloadavg()
        seconds: dict[str, list[float]] = {label: [] for label in todo}
        status: dict[str, int] = {}
        for _ in range(args.repeats):
            for label, argv in todo.items():
                wall, status[label] = timed(argv, env, folder)
                seconds[label].append(wall)
        load_after = os.getloadavg()
    print(f"load average before {load_before[0]:.2f}, after {load_after[0]:.2f} ({os.cpu_count()} cores); "
          f"{args.repeats} runs each; package: {args.src or REPO}")
    print(f"{'command':34s} {'median s':>9s} {'fastest s':>9s} {'exit':>5s}")
    for label, values in seconds.items():
        print(f"{label:34s} {statistics.median(values):9.2f} {min(values):9.2f} {status[label]:5d}")
    out = REPO / "reports" / "benchmarks" / "cli_start.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"load": [load_before, load_after], "src": str(args.src or REPO),
                               "seconds": seconds, "exit": status}, indent=1) + "\n")


if __name__ == "__main__":
    main()
