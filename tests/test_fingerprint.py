"""The code key of units and traced programs covers what a unit runs, and only that (issue 31 item 5).

:func:`bayesfric.fingerprint.computing_files` walks the imports from the modules a unit runs
(``study/units.py``, ``study/spec.py``); an edit there re-keys every unit and exported program, an
edit to the runner, a law's result Dataset, the result tree, the report or the API does not.
"""

import shutil

from bayesfric.fingerprint import _PACKAGE, code_fingerprint, computing_files

RUN_BY_UNITS = ("study/units.py", "study/spec.py", "study/config.py", "inference/engine.py", "inference/chunked.py",
                "inference/diagnostics.py", "compare/loo.py", "compare/refit.py", "compare/heldout.py",
                "compare/checks.py", "model.py", "density.py", "exported.py", "fingerprint.py", "laws/base.py",
                "laws/variants.py", "sizing/points.py")
RUN_AFTER_UNITS = ("study/runner.py", "pipeline/runner.py", "study/lawresult.py", "study/tree.py", "study/scores.py",
                   "study/claims.py", "study/executor.py", "study/store.py", "pipeline/mainjob.py", "report/summary.py",
                   "report/view.py",
                   "api/studies.py", "cli.py", "commands.py")


def test_the_code_key_covers_the_modules_units_run_and_not_the_rest():
    files = computing_files()
    assert set(RUN_BY_UNITS) <= set(files), sorted(set(RUN_BY_UNITS) - set(files))
    assert not set(RUN_AFTER_UNITS) & set(files)
    assert "laws/hysteresis.py" not in files  # a law family: keyed per law (law_fingerprint)


def test_an_edit_rekeys_only_when_a_unit_can_run_the_edited_code(tmp_path):
    copy = tmp_path / "bayesfric"
    shutil.copytree(_PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    fingerprint = code_fingerprint.__wrapped__  # uncached: the copy changes under the same path

    def edit(rel: str, text: str = "\n# edited\n") -> str:
        with open(copy / rel, "a") as fh:
            fh.write(text)
        return fingerprint(copy)

    base = fingerprint(copy)
    assert base == code_fingerprint()  # the copy is the package: same key
    assert edit("study/lawresult.py") == base  # flattens results after the units: not computing
    assert edit("report/summary.py") == base
    changed = edit("compare/heldout.py")  # a scorer's code
    assert changed != base
    # an import inside a function of a computing module makes the imported module computing
    rekeyed = edit("study/units.py", "\n\ndef _later():\n    from bayesfric.study import lawresult\n")
    assert "study/lawresult.py" in computing_files(copy) and rekeyed != changed
    assert edit("study/lawresult.py") != rekeyed
