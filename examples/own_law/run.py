"""Example (b): a law of my own, checked with check_law, then compared in a study on 2 Dask workers.

    python examples/own_law/run.py [--out REPORTS]

Runs ``bayesfric study examples/own_law/study.toml --workers 2`` (the study loads my_laws.py
through ``[study] modules``; each worker process loads it again before building the law) and
prints the ranking. CI runs it (tests/test_example_own_law.py).
"""

import argparse
import sys
from pathlib import Path

from bayesfric.cli import main
from bayesfric.laws import get_law
from bayesfric.laws.plugins import load_module
from bayesfric.testing import check_law

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":  # Dask starts worker processes: nothing runs at their import
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="reports", help="reports root folder (default reports)")
    out = Path(parser.parse_args().out)
    load_module(HERE / "my_laws.py")
    passed = check_law(get_law("smooth_stribeck"))
    print(f"check_law(smooth_stribeck): {len(passed)} checks passed ({', '.join(passed)})")
    code = main(["study", str(HERE / "study.toml"), "--workers", "2", "--out", str(out)])
    if code == 0:
        print((out / "own_law" / "ranking.csv").read_text())
    sys.exit(code)
