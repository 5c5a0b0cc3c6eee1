"""One frozen sampler configuration, and an engine without hidden state.

The configuration (:class:`bayesfric.inference.config.SamplerConfig`) is what the command line, a
study file, ``bayesfric.fit`` and the engine read: each of them checks a setting with the same
rule and names it in the same words. The engine is a value: its variations are new engines of the
same compiled kernel, nothing in :mod:`bayesfric.inference` (nor the study's units) copies an object
to change it or keeps a cache at module level; a law's compiled engine lives in an
:class:`~bayesfric.study.units.Engines` its caller owns.
"""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import pytest

from bayesfric.errors import InternalError, UserError
from bayesfric.inference.config import RULES, SamplerConfig, default_of

PACKAGE = Path(__file__).resolve().parents[1] / "bayesfric"
#: Where no module-level cache and no copy-then-change may live.
PURE = sorted((PACKAGE / "inference").glob("*.py")) + [PACKAGE / "study" / "units.py"]
MUTATORS = {"append", "extend", "insert", "update", "setdefault", "pop", "popitem", "clear", "add", "remove",
            "discard", "__setitem__"}
CONTAINERS = {"dict", "list", "set", "defaultdict", "OrderedDict", "WeakValueDictionary", "WeakKeyDictionary"}


def _module_containers(tree: ast.Module) -> set[str]:
    """Names bound at module level to a dict, list or set (a literal or a constructor call)."""
    names = set()
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) \
            else []
        value = getattr(node, "value", None)
        mutable = isinstance(value, ast.Dict | ast.List | ast.Set | ast.DictComp | ast.ListComp | ast.SetComp) or (
            isinstance(value, ast.Call) and getattr(value.func, "id", getattr(value.func, "attr", "")) in CONTAINERS)
        names |= {t.id for t in targets if isinstance(t, ast.Name) and mutable}
    return names


def _hidden_state(path: Path) -> list[str]:
    """What in ``path`` keeps or changes state behind its callers' backs."""
    tree = ast.parse(path.read_text())
    containers, found = _module_containers(tree), []
    for node in ast.walk(tree):
        if isinstance(node, ast.Global):
            found.append(f"line {node.lineno}: global {', '.join(node.names)}")
        elif isinstance(node, ast.Attribute) and node.attr == "copy" and getattr(node.value, "id", "") == "copy":
            found.append(f"line {node.lineno}: copy.copy")
        elif isinstance(node, ast.ImportFrom) and node.module == "copy":
            found.append(f"line {node.lineno}: from copy import")
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            keyed = node.args.args or node.args.posonlyargs or node.args.kwonlyargs or node.args.vararg
            for deco in node.decorator_list:  # a constant of the process (no argument) is no cache
                name = ast.unparse(deco)
                if keyed and ("lru_cache" in name or name in ("cache", "functools.cache")):
                    found.append(f"line {node.lineno}: {name} on {node.name}")
            for inner in ast.walk(node):  # a module-level container changed inside a function
                target = inner.func.value if isinstance(inner, ast.Call) and isinstance(inner.func, ast.Attribute) \
                    and inner.func.attr in MUTATORS else None
                if isinstance(inner, ast.Subscript) and isinstance(inner.ctx, ast.Store | ast.Del):
                    target = inner.value
                if isinstance(target, ast.Name) and target.id in containers:
                    found.append(f"line {inner.lineno}: {target.id} changed in {node.name}")
    return found


@pytest.mark.parametrize("path", PURE, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_module_level_cache_and_no_copy_then_change(path):
    assert _hidden_state(path) == []


def test_the_check_finds_what_it_looks_for(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import copy\nfrom functools import cache\n_ENGINES = {}\nSEEN: list = []\n\n"
                   "def engine(key):\n    global LAST\n    _ENGINES[key] = 1\n    SEEN.append(key)\n"
                   "    return copy.copy(_ENGINES)\n\n@cache\ndef compiled(program):\n    return program\n\n"
                   "@cache\ndef versions():\n    return '1'\n")
    found = {f.split(": ", 1)[1] for f in _hidden_state(bad)}
    assert found == {"global LAST", "_ENGINES changed in engine", "SEEN changed in engine", "copy.copy",
                     "cache on compiled"}


def test_a_configuration_is_checked_frozen_and_varied_by_replace():
    config = SamplerConfig(draws=200, tune=300, chains=2, seed=5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.draws = 10
    quick = config.replace(tune=150)
    assert (config.tune, quick.tune, quick.draws, quick.seed) == (300, 150, 200, 5)
    with pytest.raises(UserError, match=r"^tune: must be an integer ≥ 0, got integer -1$"):
        config.replace(tune=-1)
    with pytest.raises(UserError, match=r"^retry_target_accept: must be above target_accept \(0.9\)"):
        SamplerConfig.from_table({"retry_target_accept": 0.8})  # asked for and unusable: said
    assert SamplerConfig(retry_target_accept=0).retry is None and SamplerConfig().retry == 0.99
    assert SamplerConfig(target_accept=0.99).retry is None  # the default retry has nothing to raise
    assert (SamplerConfig().draws, SamplerConfig(name="emcee").tune) == (1000, 2500)  # each backend's own
    assert default_of("nuts", "chains") == 4 and default_of("emcee", "walkers") is None


@pytest.mark.parametrize(("table", "message"), [
    ({"draws": 0}, "--draws: must be an integer ≥ 1, got integer 0"),
    ({"draws": 1.5}, "--draws: must be an integer ≥ 1, got number 1.5"),
    ({"walkers": 8}, "--walkers: applies only to sampler emcee (here 'nuts')"),
    ({"name": "emcee", "chains": 2}, "--chains: applies only to sampler nuts (here 'emcee')"),
    ({"metric": "full"}, "--metric: must be one of 'diag', 'dense', 'auto', got string 'full'"),
    ({"name": "hmc"}, "--name: must be one of 'nuts', 'emcee', got string 'hmc'"),
    ({"thinning": 2}, "--thinning: unknown key 'thinning'"),
    ({"target_accept": 1.0}, "--target_accept: must be a number > 0 and < 1, got number 1"),
])
def test_one_constructor_names_the_setting_as_its_caller_spells_it(table, message):
    with pytest.raises(UserError) as info:
        SamplerConfig.from_table(table, key=lambda k: f"--{k}")
    assert str(info.value).startswith(message)


def test_the_study_schema_is_built_from_the_same_rules(tmp_path):
    """A study's ``[sampler]`` table, the ``fit`` options and ``bayesfric.fit`` share the rules and
    the defaults; a study file's table becomes the same configuration."""
    from bayesfric.api.fitting import sampler_options
    from bayesfric.study.sections import SAMPLER

    fields = {f.key: f for f in SAMPLER.fields}
    assert list(fields) == list(RULES)
    for key, rule in RULES.items():
        f = fields[key]
        assert (f.kind, f.min, f.max, f.gt, f.lt, f.choices, f.doc) == (rule.kind, rule.min, rule.max, rule.gt,
                                                                        rule.lt, rule.choices, rule.doc)
        assert f.only == (("name", rule.only) if rule.only else None)
    from bayesfric.study.schema import parse

    section = parse(SAMPLER, {"draws": 300, "metric": "dense"})
    assert SamplerConfig.from_table(section) == sampler_options("nuts", 0, {"draws": 300, "metric": "dense"})
    assert SamplerConfig.from_table(section).settings() == {
        "draws": 300, "tune": 1000, "chains": 4, "target_accept": 0.9, "retry_target_accept": 0.99,
        "metric": "dense", "init": "median"}


def test_a_broken_invariant_is_an_internal_error_not_a_user_error():
    from bayesfric.study.schema import Field

    with pytest.raises(InternalError):
        Field("x", "colour")
    assert not issubclass(InternalError, UserError) and issubclass(UserError, ValueError)


def test_a_study_keeps_a_law_engine_in_an_object_it_owns(monkeypatch):
    """:class:`Engines` builds a law's engine once and gives the next law a new one."""
    from bayesfric.study import units

    built = []
    monkeypatch.setattr(units, "_base_engine", lambda job: built.append(job.key) or object())
    monkeypatch.setattr(units, "release_compiled_code", lambda **kw: built.append("released"))
    engines = units.Engines()
    first = type("Job", (), {"key": "a"})
    assert engines.of(first) is engines.of(first) and built == ["a"]
    engines.of(type("Job", (), {"key": "b"}))
    assert built == ["a", "released", "b"]
