"""Laws as plug-ins: simple_law from a signature, composition on objects, law files named by a
study, entry points, check_law, and bad input (one line, exit 2, nothing written)."""

from __future__ import annotations

import multiprocessing
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor

import jax.numpy as jnp
import pytest

from bayesfric.errors import UserError
from bayesfric.laws import REGISTRY, get_law, simple_law
from bayesfric.laws.base import LawDeclarationError
from bayesfric.laws.plugins import _DECLARED, _ENTRY_POINTS, _LOADED, LawModuleError, load_entry_points, load_module
from bayesfric.laws.variants import VariantError
from bayesfric.priors import Prior
from bayesfric.study import load_study
from bayesfric.testing import LawContractError, check_law
from tests.hostile.harness import assert_user_error
from tests.test_study import data_csv, study_text  # noqa: F401 - the fixture is used by name

LAW_FILE = '''
import jax.numpy as jnp
from bayesfric.laws import simple_law

def {name}(velocity, T_C, c_v):
    """Coulomb + viscous, declared the short way."""
    return jnp.sign(velocity) * T_C + c_v * velocity

simple_law({name}, units={{"T_C": "N*m", "c_v": "N*m*s/rad"}})
'''


@pytest.fixture(autouse=True)
def clean_registry():
    """Every law, law file and entry-point state a test adds is removed after it."""
    laws, loaded, modules, points = dict(REGISTRY), dict(_LOADED), set(sys.modules), dict(_ENTRY_POINTS)
    declared = dict(_DECLARED)
    yield
    REGISTRY.clear()
    REGISTRY.update(laws)
    _DECLARED.clear()
    _DECLARED.update(declared)
    _LOADED.clear()
    _LOADED.update(loaded)
    for name in set(sys.modules) - modules:
        del sys.modules[name]
    _ENTRY_POINTS.update(points)


def test_simple_law_reads_the_signature_in_any_order():
    def smooth(T_C, velocity, c_v, v_eps=0.01):
        """Smooth Coulomb + viscous."""
        return T_C * jnp.tanh(velocity / v_eps) + c_v * velocity

    law = simple_law(smooth, units={"T_C": "N*m", "c_v": "N*m*s/rad", "v_eps": "rad/s"},
                     priors={"T_C": Prior("HalfNormal", scale=2.0, scaled_by={"response": 1})})
    assert get_law("smooth") is law and law.inputs == ("velocity",) and list(law.params) == ["T_C", "c_v"]
    assert law.constants["v_eps"].value == 0.01 and law.constants["v_eps"].unit == "rad/s"
    assert law.params["T_C"].prior.args == {"scale": 2.0}
    assert law.params["c_v"].prior.scaled_by == {"response": 1.0, "velocity": -1.0}  # from its unit
    assert law.summary == "Smooth Coulomb + viscous." and law.family == "user"
    assert float(law(0.5, 1.0, 2.0, 0.01)) == pytest.approx(float(smooth(1.0, 0.5, 2.0)))  # inputs first
    assert check_law(law, draws=8)[:3] == ["declaration", "rotary: mean finite and jit-able", "rotary: gradient finite"]


def test_simple_law_as_a_decorator_and_its_errors():
    @simple_law(units={"k": "1", "a": "N/K"}, register=False, response="force")
    def ratio(preload, temperature, k, a):
        return k * preload + a * (temperature - 293.15)

    assert ratio.response == "force" and str(ratio.params["k"].prior) == "LogNormal(loc=0, scale=1)"
    assert ratio.params["a"].prior.scaled_by == {"response": 1.0, "temperature": -1.0}
    with pytest.raises(LawDeclarationError, match="parameter 'c' needs a unit"):
        simple_law(lambda velocity, c: c * velocity, units={})
    with pytest.raises(LawDeclarationError, match="'nope' is not a parameter"):
        simple_law(lambda velocity, c: c * velocity, units={"c": "N*m*s/rad", "nope": "1"})
    with pytest.raises(LawDeclarationError, match="give a prior"):  # kg is no power of N*m and rad/s
        simple_law(lambda velocity, m: m * velocity, units={"m": "kg"}, name="massive")
    with pytest.raises(LawDeclarationError, match="already registered .*defined once"):
        simple_law(lambda velocity, T_C: T_C * velocity, units={"T_C": "N*m"}, name="coulomb")


def test_composition_on_objects():
    stribeck = get_law("stribeck")
    fixed = stribeck.fix(delta=1.0)
    assert "delta" not in fixed.params and fixed.constants["delta"].value == 1.0
    assert fixed.name == "stribeck_delta_eq_1"  # a variant's name shows every modification
    asym = get_law("armstrong_helouvry").asymmetric("dT_s", "c_v") + "offset"
    assert asym.name == "armstrong_helouvry_asym_dT_s_c_v+offset"
    both = get_law("coulomb") + get_law("coulomb_viscous")
    assert both.name == "coulomb+coulomb_viscous" and set(both.params) == {"T_C", "T_C_coulomb_viscous", "c_v"}
    assert list((get_law("coulomb") + "offset").params) == ["T_C", "offset"]
    assert set(stribeck.asymmetric("T_C").params) >= {"T_C_pos", "T_C_neg"}
    # a law declared without registering composes too: it is found by its name in this process
    loose = simple_law(lambda velocity, c: c * velocity, units={"c": "N*m*s/rad"}, name="loose", register=False)
    assert "loose" not in REGISTRY and get_law("loose") is loose
    assert set((get_law("coulomb") + loose).params) == {"T_C", "c"}
    assert (loose + "offset").recipe == {"base": "loose", "add": ["offset"]}
    assert set(loose.asymmetric("c").params) == {"c_pos", "c_neg"}
    assert not loose.fix(c=1.0).params and loose.fix(c=1.0).constants["c"].value == 1.0
    # ... unless another law of that name was declared since: the variant would be built from that one
    later = simple_law(lambda velocity, k: k * velocity, units={"k": "N*m*s/rad"}, name="loose", register=False)
    assert get_law("loose") is later
    with pytest.raises(VariantError, match="'loose' is not the law its name finds"):
        loose.fix(c=1.0)
    with pytest.raises(VariantError, match="'loose' is not the law its name finds"):
        get_law("coulomb") + loose
    assert set((later + "offset").params) == {"k", "offset"}


def test_check_law_names_a_broken_law():
    def backwards(velocity, T_C):
        """Friction that drives the motion."""
        return -jnp.sign(velocity) * T_C

    law = simple_law(backwards, units={"T_C": "N*m"}, register=False)
    with pytest.raises(LawContractError, match="backwards: 100.0% of prior-predictive means have the wrong sign"):
        check_law(law, draws=8)


def test_law_file_loads_once_with_its_helper_and_rolls_back_on_error(tmp_path):
    (tmp_path / "helper.py").write_text("def level(x):\n    return 2 * x\n")
    (tmp_path / "mine.py").write_text(LAW_FILE.format(name="mine_cv") + "import helper\nLEVEL = helper.level(1)\n")
    module = load_module(tmp_path / "mine.py")
    assert module.LEVEL == 2 and load_module(tmp_path / "mine.py") is module and get_law("mine_cv").family == "user"
    assert not (tmp_path / "__pycache__").exists()  # nothing written beside the user's files
    (tmp_path / "half.py").write_text(LAW_FILE.format(name="half_cv") + "raise RuntimeError('stop here')\n")
    with pytest.raises(LawModuleError, match=r"half.py: law module does not load: RuntimeError: stop here \(line 10\)"):
        load_module(tmp_path / "half.py")
    assert "half_cv" not in REGISTRY  # the registry is as it was before the failed file
    (tmp_path / "again.py").write_text(LAW_FILE.format(name="mine_cv"))
    with pytest.raises(LawModuleError, match=r"again.py: .*'mine_cv' is already registered \(in .*mine.py\)"):
        load_module(tmp_path / "again.py")


@pytest.mark.parametrize(("modules", "files", "mentions"), [
    ('["missing.py"]', {}, ["s.toml: [study] modules[0]: missing.py: law module: no such file"]),
    ('"mine.py"', {}, ["s.toml: [study] modules: must be a list of law file paths"]),
    ('["data.txt"]', {"data.txt": "x"}, ["modules[0]: data.txt: law module: not a Python file"]),
    ('["broken.py"]', {"broken.py": "def f(:\n"}, ["modules[0]: broken.py: law module does not load: SyntaxError"]),
    ('["bad.py"]', {"bad.py": "import no_such_package_here\n"},
     ["modules[0]: bad.py: law module does not load: ModuleNotFoundError", "no_such_package_here", "(line 1)"]),
    ('["a.py", "b.py"]', {"a.py": LAW_FILE.format(name="twice"), "b.py": LAW_FILE.format(name="twice")},
     ["modules[1]: b.py: law module does not load:", "'twice' is already registered (in ", "a.py)"]),
    ('["a.py"]', {"a.py": LAW_FILE.format(name="coulomb")}, ["modules[0]: a.py:", "'coulomb' is already registered"]),
])
def test_bad_law_modules_are_one_line_and_write_nothing(tmp_path, data_csv, modules, files, mentions):  # noqa: F811
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "s.toml").write_text(study_text().replace('name = "tiny"', f'name = "tiny"\nmodules = {modules}'))
    assert_user_error(["study", "s.toml", "--out", "reports"], tmp_path, mentions)


def test_a_study_names_a_law_of_its_law_file(tmp_path, data_csv):  # noqa: F811
    (tmp_path / "laws").mkdir()
    (tmp_path / "laws" / "mine.py").write_text(LAW_FILE.format(name="mine_cv"))
    (tmp_path / "s.toml").write_text(study_text('[[laws]]\nname = "mine_cv"\nadd = ["offset"]\n')
                                     .replace('name = "tiny"', 'name = "tiny"\nmodules = ["laws/mine.py"]'))
    study = load_study(tmp_path / "s.toml")
    spec = study.laws[0]
    assert spec.modules == (str((tmp_path / "laws" / "mine.py").absolute()),)
    _LOADED.clear()  # a fresh process: the spec loads the file itself before resolving the name
    del REGISTRY["mine_cv"]
    assert list(spec.build().params) == ["T_C", "c_v", "offset"]


def test_entry_points_load_when_a_name_is_not_found(tmp_path, monkeypatch):
    package = tmp_path / "plugpkg"
    package.mkdir()
    (package / "__init__.py").write_text(LAW_FILE.format(name="plugged_cv"))
    dist = tmp_path / "plugpkg-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: plugpkg\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[bayesfric.laws]\nplugged = plugpkg\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(_ENTRY_POINTS, "loaded", False)
    assert "plugged_cv" not in REGISTRY  # nothing loaded at import
    assert get_law("plugged_cv").params["c_v"].unit == "N*m*s/rad"
    assert load_entry_points() is False  # once per process
    (dist / "entry_points.txt").write_text("[bayesfric.laws]\nbroken = plugpkg.nothing_here\n")
    monkeypatch.setitem(_ENTRY_POINTS, "loaded", False)
    with pytest.raises(LawModuleError, match=r"entry point broken = 'plugpkg.nothing_here' \(group bayesfric.laws, "
                                             r"distribution plugpkg 1.0\): does not load: ModuleNotFoundError"):
        get_law("no_such_law_anywhere")


def test_importing_the_laws_loads_no_plug_in():
    code = "import bayesfric.laws; from bayesfric.laws.plugins import _ENTRY_POINTS; assert not _ENTRY_POINTS['loaded']"
    subprocess.run([sys.executable, "-c", code], check=True)


def _params_in_a_fresh_process(spec) -> list[str]:
    return list(spec.build().params)


def test_a_law_spec_builds_in_a_fresh_process(tmp_path, data_csv):  # noqa: F811
    """What a ``main --jobs`` study process or a Dask worker does: a spawned interpreter that has
    imported nothing gets the pickled spec and loads the law file itself."""
    (tmp_path / "mine.py").write_text(LAW_FILE.format(name="mine_cv"))
    (tmp_path / "s.toml").write_text(study_text('[[laws]]\nname = "mine_cv"\n')
                                     .replace('name = "tiny"', 'name = "tiny"\nmodules = ["mine.py"]'))
    spec = load_study(tmp_path / "s.toml").laws[0]
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        assert pool.submit(_params_in_a_fresh_process, spec).result(timeout=300) == ["T_C", "c_v"]


UNREGISTERED = '''
import jax.numpy as jnp
import bayesfric

def {name}(velocity, T_C, c_v):
    """Coulomb + viscous, declared and not registered."""
    return jnp.sign(velocity) * T_C + c_v * velocity

mine = bayesfric.law({name}, units={{"T_C": "N*m", "c_v": "N*m*s/rad"}})
'''


def test_a_study_takes_law_objects_that_are_not_registered(tmp_path, data_csv):  # noqa: F811
    """A law declared without registering enters a Study as an object; its file joins the study's
    law files, so a spawned process (a ``--workers`` or Dask worker) builds it from its spec."""
    import bayesfric
    from bayesfric.study import StudyError

    (tmp_path / "unreg.py").write_text(UNREGISTERED.format(name="unreg_cv"))
    mine = load_module(tmp_path / "unreg.py").mine
    assert "unreg_cv" not in REGISTRY and get_law("unreg_cv") is mine  # found by its name, not registered
    variant = get_law("coulomb_viscous").fix(c_v=0.5) + "offset"
    study = bayesfric.Study("objects", str(tmp_path / "bench.csv"), laws=[mine, variant, "coulomb"])
    own, var = study.laws[0], study.laws[1]
    assert own.modules == (str((tmp_path / "unreg.py").resolve()),) and own.build() is mine
    assert var.name == "coulomb_viscous_c_v_eq_0.5_offset" and var.law == "coulomb_viscous"  # a plain label
    assert list(var.build().params) == ["T_C", "offset"] and var.build().recipe == dict(variant.recipe)
    # a variant of the unregistered law, as an object: its recipe names the law, its file travels
    fixed = bayesfric.Study("fixed", str(tmp_path / "bench.csv"), laws=[mine.fix(c_v=0.5) + "offset"]).laws[0]
    assert fixed.modules == own.modules and list(fixed.build().params) == ["T_C", "offset"]
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        assert pool.submit(_params_in_a_fresh_process, own).result(timeout=300) == ["T_C", "c_v"]
        assert pool.submit(_params_in_a_fresh_process, fixed).result(timeout=300) == ["T_C", "offset"]

    def inline(velocity, T_C):
        """Declared in a notebook: no file."""
        return jnp.sign(velocity) * T_C

    here = bayesfric.law(inline, units={"T_C": "N*m"})
    assert bayesfric.Study("inline", str(tmp_path / "bench.csv"), laws=[here]).laws[0].build() is here
    with pytest.raises(UserError, match="name: 'coulomb' is a registered law's name"):
        bayesfric.law(inline, units={"T_C": "N*m"}, name="coulomb")
    other = simple_law(inline, units={"T_C": "N*m"}, name="coulomb", register=False)
    with pytest.raises(StudyError, match="law 'coulomb' is not the registered law of that name"):
        bayesfric.Study("clash", str(tmp_path / "bench.csv"), laws=[other])
