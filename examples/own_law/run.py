"""Example (b): a law of my own, checked with check_law, then compared in a study on 2 Dask workers.

    python examples/own_law/run.py [--out REPORTS]

Uses the public API only (``bayesfric.Study``, ``bayesfric.law``, ``bayesfric.run``) and the
contract checks of :mod:`bayesfric.testing`: reading ``study.toml`` loads my_laws.py through
``[study] modules`` (each worker process loads it again before building the law), so the law is
then found by its name; the study runs as ``bayesfric study examples/own_law/study.toml
--workers 2`` would, and the ranking is printed. CI runs it (tests/test_example_own_law.py).
"""

import argparse
from pathlib import Path

import bayesfric
from bayesfric.testing import check_law

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":  # Dask starts worker processes: nothing runs at their import
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="reports", help="reports root folder (default reports)")
    out = Path(parser.parse_args().out)
    study = bayesfric.Study.from_toml(HERE / "study.toml")  # loads my_laws.py
    passed = check_law(bayesfric.law("smooth_stribeck"))
    print(f"check_law(smooth_stribeck): {len(passed)} checks passed ({', '.join(passed)})")
    result = bayesfric.run(study, out, workers=2)
    print(result.ranking.to_csv(index=False))
