"""Example (b) of issue 31, as CI runs it: a user's law file used by a study through
``[study] modules``, checked with ``check_law`` and run on 2 Dask workers (examples/own_law/)."""

import csv
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow  # ~50 s with a warm compilation cache, ~95 s cold, on the loaded 2-core machine
def test_own_law_example_runs_on_two_workers(tmp_path):
    pytest.importorskip("distributed")  # the dask extra (installed by make test's bootstrap)
    run = subprocess.run([sys.executable, str(REPO / "examples" / "own_law" / "run.py"), "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "check_law(smooth_stribeck): 14 checks passed" in run.stdout  # 6 per motion kind + declaration and form
    report = tmp_path / "own_law"
    with (report / "ranking.csv").open(newline="") as fh:
        rows = {row["law"]: row for row in csv.DictReader(fh)}
    assert set(rows) == {"coulomb_viscous", "smooth_stribeck"}
    assert rows["smooth_stribeck"]["diagnostics_passed"] == "True"  # fitted on a worker that loaded my_laws.py
    assert (report / "fits" / "smooth_stribeck.nc").is_file()
    with (report / "timings.csv").open(newline="") as fh:
        assert {r["status"] for r in csv.DictReader(fh) if r["law"] == "smooth_stribeck"} == {"computed"}
