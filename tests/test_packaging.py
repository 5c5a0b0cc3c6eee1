"""A pip-installed bayesfric carries its built-in data sets and seed studies."""

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_every_code_package_is_listed_in_pyproject():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    code = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "bayesfric").rglob("__init__.py")}
    assert code <= listed, f"packages missing from pyproject's [tool.setuptools] packages: {sorted(code - listed)}"


@pytest.mark.slow
def test_an_installed_wheel_finds_the_builtin_data_and_studies(tmp_path):
    """Build the wheel offline, install it into a folder, run it from elsewhere (not the checkout)."""
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", str(ROOT),
                    "-w", str(tmp_path / "wheel")], check=True, capture_output=True, timeout=300)
    (wheel,) = (tmp_path / "wheel").glob("bayesfric-*.whl")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(tmp_path / "site"),
                    str(wheel)], check=True, capture_output=True, timeout=300)
    code = ("import bayesfric, json; from bayesfric.datasets.registry import DATA_ROOT, builtin_names; "
            "from bayesfric.study import STUDIES_DIR; from importlib.resources import files; "
            "print(json.dumps([bayesfric.__file__, str(DATA_ROOT), builtin_names(), "
            "sorted(p.name for p in STUDIES_DIR.glob('*.toml')), "
            "sorted(p.name for p in files('bayesfric.report').joinpath('templates').iterdir())]))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, timeout=300,
                         cwd=tmp_path, env={"PYTHONPATH": str(tmp_path / "site"), "PATH": "/usr/bin:/bin"})
    module, data_root, names, studies, templates = json.loads(out.stdout.strip().splitlines()[-1])
    assert templates == ["report.html.j2", "summary.md.j2"]  # the report templates are package data
    assert module.startswith(str(tmp_path / "site")) and data_root.startswith(str(tmp_path / "site"))
    assert names == ["asym_joint", "dahl_duplex", "drum_campaigns", "drum_rollout", "gms_loops", "pitch_bearing",
                     "robot_joint", "tribo_loops", "unwinder"]
    assert studies == ["dahl_duplex.toml", "drum_campaigns.toml", "drum_rollout.toml", "pitch_bearing.toml",
                       "robot_joint.toml", "unwinder.toml"]
