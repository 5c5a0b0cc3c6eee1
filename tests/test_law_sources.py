"""Keys that see everything (issue 31, item 5): a law's key covers every module its code imports,
within the package and the user's law files, and an edit to an imported helper recomputes its fit."""

import csv
import inspect
import sys
from pathlib import Path

import pytest

from bayesfric import codegraph, fingerprint
from bayesfric.laws import REGISTRY, get_law
from bayesfric.laws.plugins import _LOADED
from bayesfric.pipeline.runner import run_study
from tests.test_study import data_csv  # noqa: F401 - the fixture is used by name

PACKAGE = Path(fingerprint.__file__).resolve().parent


def _files(name: str) -> list[str]:
    files = codegraph.source_files(inspect.getmodule(get_law(name).fn))
    return [f.relative_to(PACKAGE).as_posix() if PACKAGE in f.parents else str(f) for f in files]


def test_a_law_reads_its_module_and_the_package_modules_it_imports():
    assert _files("palmgren")[:2] == ["laws/bearing.py", "laws/ball_loads.py"]
    assert "laws/ball_loads.py" not in _files("stribeck") and "laws/bearing.py" not in _files("stribeck")
    assert "laws/classical.py" in _files("coastdown_oring_closed_form")  # drum.py imports classical
    for name in ("palmgren", "stribeck", "dahl"):  # no site-packages, no registry-wide __init__
        assert all(not f.startswith("/") for f in _files(name)), _files(name)
        assert "laws/__init__.py" not in _files(name) and "laws/drum.py" not in _files(name)


def test_editing_an_imported_helper_changes_the_key_of_the_laws_that_import_it(monkeypatch):
    """ball_loads.py under bearing.py, edited in memory only: the real file is never touched."""
    before = {n: fingerprint.law_fingerprint(get_law(n)) for n in ("palmgren", "skf_2014", "stribeck")}
    read = fingerprint._source
    monkeypatch.setattr(fingerprint, "_source",
                        lambda p: read(p) + b"\n# edited\n" if p.name == "ball_loads.py" else read(p))
    after = {n: fingerprint.law_fingerprint(get_law(n)) for n in before}
    assert after["palmgren"] != before["palmgren"] and after["skf_2014"] != before["skf_2014"]
    assert after["stribeck"] == before["stribeck"]


LAW = '''
import jax.numpy as jnp
from helper import level

from bayesfric.laws import simple_law


@simple_law(units={"T_C": "N*m", "c_v": "N*m*s/rad"})
def helped_cv(velocity, T_C, c_v):
    """Coulomb + viscous through a helper module."""
    return level(jnp.sign(velocity) * T_C + c_v * velocity)
'''

STUDY = '''[study]
name = "helped"
modules = ["laws/mine.py"]
[data]
dataset = "bench.csv"
[sampler]
draws = 300
tune = 300
chains = 2
[[laws]]
name = "helped_cv"
[compare]
loo = true
evidence = false
'''


@pytest.fixture
def user_files(tmp_path, data_csv):  # noqa: F811
    """A study whose law lives in laws/mine.py and calls laws/helper.py (registry restored after)."""
    laws, loaded, modules = dict(REGISTRY), dict(_LOADED), set(sys.modules)
    (tmp_path / "laws").mkdir()
    (tmp_path / "laws" / "mine.py").write_text(LAW)
    (tmp_path / "laws" / "helper.py").write_text("def level(x):\n    return x\n")
    (tmp_path / "s.toml").write_text(STUDY)
    yield tmp_path
    REGISTRY.clear()
    REGISTRY.update(laws)
    _LOADED.clear()
    _LOADED.update(loaded)
    for name in set(sys.modules) - modules:
        del sys.modules[name]


def _fit_status(root: Path) -> str:
    rows: list = []
    run_study(root / "s.toml", out_root=root / "reports", timings=rows, live_progress=False)
    return next((r.status for r in rows if r.stage == "fit"), "report unchanged")


def test_an_edit_to_a_helper_of_a_users_law_recomputes_the_stored_fit(user_files):
    assert _fit_status(user_files) == "computed"
    assert _fit_status(user_files) == "report unchanged"  # nothing changed: nothing recomputed
    helper = user_files / "laws" / "helper.py"
    helper.write_text("def level(x):\n    return 1.0 * x  # same numbers, new code\n")
    assert _fit_status(user_files) == "computed"  # the helper is not the module declaring the law
    with (user_files / "reports" / "helped" / "timings.csv").open(newline="") as fh:
        assert [r["status"] for r in csv.DictReader(fh) if r["stage"] == "fit"] == ["computed"]
