"""A fit records what rebuilds its program exactly (issue 31 item 2): bayesfric.load_fit returns
the DataTree and the Program that produced it, for a variant and for a user's own law declared in
a law file (rebuilt in a fresh process, sized by the CLI). Small data, short sampling."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import bayesfric
from bayesfric.datasets.synthetic import make_dataset
from bayesfric.errors import UserError
from bayesfric.inference import save_fit
from bayesfric.laws import REGISTRY
from bayesfric.laws.plugins import _DECLARED, _LOADED, load_module
from bayesfric.model import Program, build_program

V = np.linspace(-3.0, 3.0, 24)
SHORT = {"draws": 20, "tune": 120, "chains": 1}

LAW_FILE = '''
import jax.numpy as jnp
import bayesfric

def tanh_friction(velocity, T_C, c_v, v_eps=0.05):
    """Smooth Coulomb + viscous, declared the short way and not registered."""
    return T_C * jnp.tanh(velocity / v_eps) + c_v * velocity

mine = bayesfric.law(tanh_friction, units={"T_C": "N*m", "c_v": "N*m*s/rad", "v_eps": "rad/s"})
'''


@pytest.fixture
def clean_laws():
    laws, loaded, declared, modules = dict(REGISTRY), dict(_LOADED), dict(_DECLARED), set(sys.modules)
    yield
    REGISTRY.clear()
    REGISTRY.update(laws)
    _LOADED.clear()
    _LOADED.update(loaded)
    _DECLARED.clear()
    _DECLARED.update(declared)
    for name in set(sys.modules) - modules:
        del sys.modules[name]


def _data(group: bool = False):
    y = 2.0 * np.sign(V) + 0.5 * V + 0.05 * np.random.default_rng(0).normal(size=V.size)
    return make_dataset({"velocity": V}, y, groups={"series": np.arange(V.size) % 2} if group else None)


def assert_same_program(rebuilt: Program, original: Program, density: bool = True) -> None:
    assert rebuilt.law.name == original.law.name and dict(rebuilt.law.recipe) == dict(original.law.recipe)
    assert list(rebuilt.law.params) == list(original.law.params)
    assert rebuilt.noise == original.noise and rebuilt.constants == original.constants
    assert rebuilt.priors == original.priors and rebuilt.resolved == original.resolved
    assert rebuilt.scale == original.scale
    assert rebuilt.inputs.keys() == original.inputs.keys()
    for k, v in original.inputs.items():
        assert np.array_equal(rebuilt.inputs[k], v) and rebuilt.inputs[k].dtype == v.dtype
    assert np.array_equal(rebuilt.response, original.response)
    if original.group_index is not None:
        assert np.array_equal(rebuilt.group_index, original.group_index)
        assert len(rebuilt.group_labels) == len(original.group_labels)
    if not density:
        return
    a, b = original.density(), rebuilt.density()
    assert np.array_equal(np.asarray(a.x0), np.asarray(b.x0))
    assert float(a.log_joint(a.x0)) == float(b.log_joint(b.x0))  # the same density, bit for bit


def test_a_variant_fit_loads_with_its_exact_program(tmp_path):
    ds = _data(group=True)
    law = bayesfric.law("coulomb_viscous").fix(c_v=0.5) + "offset"
    noise = {"kind": "normal", "group": "series"}
    fit = bayesfric.fit(law, ds, noise=noise, priors={"T_C": {"dist": "HalfNormal", "scale": 4.0}}, **SHORT)
    path = save_fit(fit, tmp_path / "variant.nc")
    tree, program = bayesfric.load_fit(path)
    assert json.loads(tree.attrs["law_recipe"])["fixed"] == {"c_v": 0.5}
    original = build_program(law, ds, noise=bayesfric.api.fitting._noise(noise, ds),
                             priors={"T_C": {"dist": "HalfNormal", "scale": 4.0}})
    assert_same_program(program, original)
    assert list(program.law.params) == ["T_C", "offset"]
    answer = bayesfric.size(path, at={"velocity": (2, "rad/s")}).to_dataframe()
    assert len(answer) == 1 and np.isfinite(answer["required"]).all()


def test_a_fit_of_a_law_in_a_law_file_rebuilds_in_a_fresh_process(tmp_path, clean_laws):
    law_file = tmp_path / "my_laws.py"
    law_file.write_text(LAW_FILE)
    mine = load_module(law_file).mine
    assert "tanh_friction" not in REGISTRY  # declared, not registered
    ds = _data()
    fit = bayesfric.fit(mine, ds, **SHORT)
    assert json.loads(fit.attrs["law_files"]) == [str(law_file.resolve())]
    path = save_fit(fit, tmp_path / "mine.nc")
    assert_same_program(bayesfric.load_fit(path)[1], build_program(mine, ds))
    code = ("import bayesfric, sys; tree, program = bayesfric.load_fit(sys.argv[1]); "
            "print(program.law.name, list(program.law.params), program.constants['v_eps'])")
    run = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split("\n")[-2] == "tanh_friction ['T_C', 'c_v'] 0.05"
    size = subprocess.run([sys.executable, "-m", "bayesfric", "size", str(path), "--at", "velocity=2 rad/s"],
                          capture_output=True, text=True, timeout=300)
    assert size.returncode == 0, size.stderr[-2000:]
    assert "tanh_friction" in size.stdout
    # a variant of the unregistered law, built as an object, rebuilds there too (its recipe names the law)
    variant = bayesfric.fit(mine.fix(c_v=0.5), ds, **SHORT)
    assert json.loads(variant.attrs["law_files"]) == [str(law_file.resolve())]
    path = save_fit(variant, tmp_path / "variant.nc")
    run = subprocess.run([sys.executable, "-c", code.replace("'v_eps'", "'c_v'"), str(path)], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split("\n")[-2] == "tanh_friction_c_v_eq_0.5 ['T_C'] 0.5"
    law_file.unlink()  # the recorded file gone: one line naming it, exit 2
    gone = subprocess.run([sys.executable, "-m", "bayesfric", "size", str(path), "--at", "velocity=2 rad/s"],
                          capture_output=True, text=True, timeout=300)
    assert gone.returncode == 2 and "my_laws.py" in gone.stderr and "no such file" in gone.stderr


def test_load_fit_names_the_file_it_cannot_read(tmp_path):
    with pytest.raises(UserError, match="fit file not found"):
        bayesfric.load_fit(tmp_path / "none.nc")
    (tmp_path / "bad.nc").write_text("not a fit")
    with pytest.raises(UserError, match="bad.nc: not a readable fit"):
        bayesfric.load_fit(tmp_path / "bad.nc")


def test_a_package_law_records_no_law_file():
    from bayesfric.model import program_record

    record = program_record(build_program(bayesfric.law("coulomb"), _data()))
    assert json.loads(record["law_files"]) == [] and json.loads(record["data_scale"])["response"] > 0


def test_a_program_is_frozen_and_an_engine_on_another_response_scores_that_response():
    """Program is frozen; NutsEngine.with_response's fit has the log-likelihood of the new
    response (its compiled tables were shared with the original engine's, on the old one)."""
    from scipy import stats

    from bayesfric.inference.engine import NutsEngine

    ds = _data()
    program = build_program(bayesfric.law("coulomb_viscous"), ds)
    with pytest.raises(AttributeError):
        program.response = np.zeros(3)  # type: ignore[misc]
    engine = NutsEngine.build(program, seed=1, **SHORT)
    engine.fit(ds)
    shifted = engine.with_response(program.response + 2.0)
    fit = shifted.fit(ds)
    post = fit["posterior"].to_dataset()
    mu = post["T_C"].values[..., None] * np.sign(V) + post["c_v"].values[..., None] * V
    expected = stats.norm.logpdf(program.response + 2.0, mu, post["sigma"].values[..., None])
    np.testing.assert_allclose(fit["log_likelihood"]["response"].values, expected, rtol=1e-8)
    np.testing.assert_array_equal(fit["observed_data"]["response"].values, program.response + 2.0)


@pytest.mark.parametrize("kind", ["ar1", "se"])
def test_trajectory_starts_and_standard_errors_travel_with_the_fit(kind):
    """What a program reads besides inputs and response -- ar1's trajectory starts, a reduced data
    set's standard errors -- is kept in constant_data and comes back (no sampling: the fit's
    groups are built as assemble builds them)."""
    import arviz as az

    from bayesfric.model import Noise, program_data, program_of_fit, program_record

    y = 2.0 * np.sign(V) + 0.5 * V
    ds = make_dataset({"velocity": V}, y, groups={"run": np.arange(V.size) // 8}, trajectory="run")
    noise = Noise(kind="ar1") if kind == "ar1" else Noise()
    if kind == "se":
        ds["se"] = ("obs", np.linspace(0.01, 0.02, V.size), {"role": "se", "units": "N*m"})
    program = build_program(bayesfric.law("coulomb_viscous"), ds, noise=noise)
    assert (program.chain_start is not None) == (kind == "ar1") and (program.response_se is not None) == (kind == "se")
    constant = {k: np.asarray(v, dtype=float) for k, v in program.inputs.items()} | program_data(program)
    tree = az.from_dict({"posterior": {"T_C": np.ones((1, 2))}, "observed_data": {"response": program.response},
                         "constant_data": constant}, dims={"response": ["obs"], **{k: ["obs"] for k in constant}})
    tree.attrs.update(program_record(program))
    rebuilt = program_of_fit(tree)
    assert_same_program(rebuilt, program, density=kind == "se")  # (ar1's density compiles for ~2 min)
    if kind == "ar1":
        assert rebuilt.chain_start.dtype == bool and np.array_equal(rebuilt.chain_start, program.chain_start)
    else:
        assert np.array_equal(rebuilt.response_se, program.response_se)
