"""Studies: TOML files under studies/ that run comparisons and write reports/<study>/."""

from bayesfric.study.demo import run_flagship

__all__ = ["run_flagship", "run_study"]


def run_study(path, out_root="reports", quick=False):
    """Run one study file (see bayesfric.study.runner)."""
    from bayesfric.study.runner import run_study as _run

    return _run(path, out_root=out_root, quick=quick)
