"""The light commands answer without JAX (issue 48 item 5): ``--version``, ``--help``, ``laws``,
``data list|check|reduce`` import neither JAX nor numpyro nor dask (the import list of each,
measured in a fresh process), and ``bayesfric laws`` reads a stored catalogue that is current and
prints what the registry prints. The computing commands' argument errors come before JAX loads
too (:mod:`bayesfric.precheck`). Their time is measured by ``benchmarks/bench_cli_start.py``, not here.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from bayesfric import lawcatalogue

REPO = Path(__file__).resolve().parents[1]
#: Imported by no light command (top-level package names).
HEAVY = ("jax", "jaxlib", "numpyro", "blackjax", "arviz", "arviz_base", "arviz_stats", "matplotlib", "diffrax")
#: Runs one command through ``bayesfric.cli.main`` and prints the top-level modules it imported.
WRAPPER = """
import json, sys
from bayesfric.cli import main
try:
    code = main(sys.argv[1:])
except SystemExit as exc:  # --version, --help
    code = exc.code
print("\\nMODULES " + json.dumps(sorted({m.split(".")[0] for m, mod in sys.modules.items() if mod is not None})))
sys.exit(code or 0)
"""
SIDECAR = """[dataset]
name = "rawlog"
provenance = "simulated"
source = "synthetic raw log (tests/test_cli_start.py)"
[columns.t_s]
role = "input"
quantity = "time"
unit = "s"
[columns.speed]
role = "input"
quantity = "velocity"
unit = "rad/s"
[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"
"""


def _raw_log(folder: Path) -> Path:
    """Eight constant-speed plateaus of 100 rows with a little deterministic noise."""
    rows, t = [], 0.0
    for i, v in enumerate(s * x for s in (1, -1) for x in (0.1, 0.4, 1.5, 3.0)):
        for k in range(100):
            rows.append(f"{t:.3f},{v:g},{(10 if v > 0 else -10) + 2 * v + ((i * 100 + k) * 37 % 11 - 5) / 50:.4f}")
            t += 0.01
    csv = folder / "raw.csv"
    csv.write_text("t_s,speed,torque\n" + "\n".join(rows) + "\n")
    csv.with_suffix(".toml").write_text(SIDECAR)
    return csv


def _imports(args: list[str], cwd: Path) -> tuple[subprocess.CompletedProcess, set[str]]:
    done = subprocess.run([sys.executable, "-c", WRAPPER, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)
    line = next(x for x in done.stdout.splitlines()[::-1] if x.startswith("MODULES "))
    return done, set(json.loads(line.removeprefix("MODULES ")))


@pytest.mark.parametrize("args", [
    ["--version"], ["--help"], ["laws"], ["laws", "--names"], ["laws", "--family", "classical", "--markdown"],
    ["data", "list"], ["data", "check", "{robot}"], ["data", "reduce", "{raw}", "--out", "{out}"],
    ["data", "reduce", "--help"],
], ids=lambda a: " ".join(a))
def test_light_commands_import_no_jax_or_numpyro(tmp_path, args):
    if lawcatalogue._current() is None and args[0] == "laws":
        pytest.skip("the stored law catalogue is stale: test_the_law_catalogue_is_current says what to run")
    names = {"robot": str(REPO / "data" / "robot_joint" / "robot_joint.csv"), "raw": str(_raw_log(tmp_path)),
             "out": str(tmp_path / "out.csv")}
    done, modules = _imports([a.format(**names) for a in args], tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert not modules & set(HEAVY), sorted(modules & set(HEAVY))
    assert "dask" not in modules  # xarray and pint import it when installed: runtime.without_dask
    if args[0] in ("--version", "--help", "laws") or args[-1] == "--help":  # nor numpy, xarray, pint
        assert not modules & {"numpy", "xarray", "pandas", "pint", "scipy"}, sorted(modules)


ROBOT = "{robot}"
#: One-line argument errors of the computing commands: each answered before JAX loads
#: (bayesfric.precheck), exit status 2.
ARGUMENT_ERRORS = [
    ["fit", "robot_joint", "stribeck", "--draws", "0"],
    ["fit", "robot_joint", "stribeck", "--walkers", "8"],
    ["fit", ROBOT, "stribeck", "--out", ROBOT],
    ["fit", "robot_joint", "stribeck", "--select", "series=99"],
    ["fit", "robot_joint", "stribeck", "--group", "velocity"],
    ["fit", "robot_joint", "stribeck", "--prior", "T_C=[bad"],
    ["fit", "robot_joint", "stribeck", "--fix", "i=one"],
    ["fit", "nowhere.csv", "stribeck"],
    ["size", "fit.nc", "--at", "velocity=6"],
    ["size", "fit.nc", "--at", "velocity=6 rad/s", "--confidence", "1.5"],
    ["size", "fit.nc", "--at", "velocity=1 rad/s", "--capacity", "5 N*m", "--horizon", "20000 rpm"],
    ["size", "gone.nc", "--at", "velocity=6 rad/s"],
    ["size", "gone.toml"],
    ["study", "gone.toml"],
    ["study", "gone.toml", "--workers", "-1"],
    ["study", "gone.toml", "--out", ROBOT],
    ["predict", "fit.nc", "robot_joint", "--out", "p.csv", "--quantiles", "0.5", "0.5"],
    ["predict", "fit.nc", "robot_joint", "--out", "p.csv", "--seed", "-1"],
    ["predict", "fit.nc", ROBOT, "--out", ROBOT],
    ["score", "fit.nc", "robot_joint", "--out", "fit.nc"],
    ["score", "nowhere", "robot_joint"],
    ["main", "--jobs", "0"],
]


@pytest.mark.parametrize("args", ARGUMENT_ERRORS, ids=lambda a: " ".join(a))
def test_argument_errors_come_before_jax_loads(tmp_path, args):
    """``fit``, ``size``, ``study``, ``predict``, ``score`` and ``main`` check their arguments
    (options, files, ``--out`` against their inputs, points and units) before JAX loads: one
    line, exit status 2, and neither JAX nor numpyro imported (``bayesfric.precheck``)."""
    (tmp_path / "fit.nc").write_bytes(b"")  # a target that exists (its content is read after JAX loads)
    robot = str(REPO / "data" / "robot_joint" / "robot_joint.csv")
    done, modules = _imports([a.format(robot=robot) for a in args], tmp_path)
    assert done.returncode == 2, (done.returncode, done.stderr[-2000:])
    assert len(done.stderr.strip().splitlines()) == 1 and done.stderr.startswith("bayesfric: error: "), done.stderr
    assert not modules & set(HEAVY), (sorted(modules & set(HEAVY)), done.stderr)


def test_version_prints_the_package_version():
    from bayesfric import __version__

    done = subprocess.run([sys.executable, "-m", "bayesfric", "--version"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == f"bayesfric {__version__}"


def test_the_law_catalogue_is_current():
    """The stored catalogue describes the package as it is (else ``bayesfric laws`` falls back to
    importing JAX: correct, but slow)."""
    stored = json.loads(lawcatalogue.CATALOGUE.read_text(encoding="utf-8"))
    # built in a fresh process: in this one, other test files may have declared laws of their own
    built = subprocess.run([sys.executable, "-c", "import json; from bayesfric import lawcatalogue; "
                            "print(json.dumps(lawcatalogue.build()))"],
                           capture_output=True, text=True, cwd=REPO, check=True).stdout
    assert stored == json.loads(built), ("bayesfric/lawcatalogue.json is stale: run "
                                         "`.venv/bin/python -m bayesfric.lawcatalogue` and commit it")


def test_the_catalogue_prints_what_the_registry_prints(tmp_path, monkeypatch, capsys):
    """The same text from the catalogue as from the registry, for every option; a stale catalogue
    is not used."""
    from bayesfric.laws import all_laws
    from bayesfric.listing import laws_listing

    path = tmp_path / "catalogue.json"
    lawcatalogue.write(path)
    monkeypatch.setattr(lawcatalogue, "CATALOGUE", path)
    laws = all_laws()
    for family in (None, "classical", "hysteresis"):
        chosen = [w for w in laws if family in (None, w.family)]
        for markdown in (False, True):
            assert lawcatalogue.listing(family, markdown=markdown) == laws_listing(chosen, markdown=markdown)
        assert lawcatalogue.listing(family, names=True) == "\n".join(w.name for w in chosen)
    with pytest.raises(KeyError):
        lawcatalogue.listing("no_such_family")
    data = json.loads(path.read_text())
    data["sources_sha256"] = "0" * 64  # a law edited since: the registry answers instead
    path.write_text(json.dumps(data))
    assert lawcatalogue.listing(None) is None


def test_the_catalogue_hashes_every_module_the_laws_import():
    """What the listing reads: the module-level import closure of bayesfric.laws and the renderer
    (bayesfric.listing), not the report package."""
    sources = set(lawcatalogue._listing_sources())
    package = lawcatalogue._PACKAGE
    assert {"laws/base.py", "priors.py", "quantities.py", "listing.py"} <= sources
    assert not any(rel.startswith("report/") for rel in sources)  # edits to the report keep the catalogue
    assert all((package / rel).is_file() for rel in sources)
