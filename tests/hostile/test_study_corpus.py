"""Bad-input corpus for study files, the study runner's paths and the CLI options (issue #9).

Every case runs ``bayesfric`` in-process through :func:`tests.hostile.harness.assert_user_error`:
exit status 2, one line ``bayesfric: error: ...`` naming the file (or option) and the key, no
traceback, and the whole case tree unchanged. The tree holds a ``reports/`` folder with another
study's report (marked), a colleague's unmarked folder, a plain file and a symbolic link, so a
run that deleted or wrote anything there would be caught. Study cases are one base study (valid:
see ``test_base_study_is_valid``) with a few keys changed; they all fail before any fitting.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import pytest

from bayesfric.datasets import load_dataset, resolve
from bayesfric.fsutil import MARKER
from bayesfric.study import load_study
from bayesfric.study.runner import validate_against_data
from tests.hostile.harness import assert_user_error

DELETE = object()
BASE = {
    "study": {"name": "tiny", "title": "tiny study"},
    "data": {"dataset": "robot_joint"},
    "sampler": {"draws": 200, "tune": 200, "chains": 2, "seed": 0},
    "laws": [{"name": "coulomb_viscous"}],
    "compare": {"loo": True, "evidence": False, "blocked": [{"axis": "velocity", "threshold": 0.5}]},
}
STUDY_ARGV = ("study", "s.toml", "--out", "reports")
FIT = ("fit", "robot_joint", "coulomb_viscous", "--quiet")


@dataclass(frozen=True)
class Case:
    """One hostile input: CLI arguments, the fragments the error must name, and the study file."""

    id: str
    argv: tuple[str, ...]
    mentions: tuple[str, ...]
    changes: dict | None = None  # dotted key -> value (DELETE removes) applied to BASE
    raw: bytes | None = None  # the study file's bytes instead of BASE
    file: str = "s.toml"
    skip: str | None = None  # reason to skip on this machine


def S(id: str, changes: dict, *mentions: str, extra: tuple[str, ...] = (), file: str = "s.toml") -> Case:
    """A study-file case: BASE with ``changes``; the message names the file and ``mentions``."""
    argv = ("study", file, "--out", "reports") + extra
    return Case(id, argv, (file, *mentions), changes=changes, file=file)


def R(id: str, raw: bytes, *mentions: str) -> Case:
    """A study file given as raw bytes."""
    return Case(id, STUDY_ARGV, ("s.toml", *mentions), raw=raw)


def C(id: str, argv: tuple[str, ...], *mentions: str, skip: str | None = None) -> Case:
    """A CLI case without a study file."""
    return Case(id, argv, mentions, skip=skip)


AS_ROOT = "file permissions do not bind root" if os.geteuid() == 0 else None
NO_PROC = None if Path("/proc/self").is_dir() and not os.access("/proc/self", os.W_OK) else "no read-only /proc/self"


def HN(scale: float, **powers: float) -> dict:
    """A HalfNormal prior spec, data-scaled by ``powers`` when given."""
    return {"dist": "HalfNormal", "scale": scale} | ({"scaled_by": powers} if powers else {})


NAME = "[study] name"
CASES = [
    # -- finding 1: the study name is a path --------------------------------------------------
    S("name-dot", {"study.name": "."}, NAME, "not a plain name"),
    S("name-empty", {"study.name": ""}, NAME, "must not be empty"),
    S("name-dotdot", {"study.name": ".."}, NAME),
    S("name-absolute", {"study.name": "{root}/victim"}, NAME),
    S("name-escapes", {"study.name": "../../x"}, NAME),
    S("name-subfolder", {"study.name": "a/b"}, NAME),
    S("name-space", {"study.name": "my study"}, NAME),
    S("name-nul", {"study.name": "a\x00b"}, NAME),
    S("name-hidden", {"study.name": ".tiny"}, NAME),
    S("name-too-long", {"study.name": "x" * 65}, NAME, "at most 64"),
    S("name-not-string", {"study.name": 5}, NAME, "got integer 5"),
    S("name-from-bad-file-name", {"study.name": DELETE}, NAME, "file name", file="my study.toml"),
    S("name-unmarked-folder", {"study.name": "colleague"}, NAME, "not written by bayesfric"),
    S("name-is-a-file", {"study.name": "README.md"}, NAME, "not written by bayesfric"),
    S("name-symlink", {"study.name": "evil"}, NAME, "outside the reports folder"),
    # -- finding 2: wrong types -----------------------------------------------------------------
    S("seed-string", {"sampler.seed": "abc"}, "[sampler] seed", "must be an integer"),
    S("kfold-string", {"compare.kfold": "ten"}, "[compare] kfold", "must be an integer"),
    S("threshold-string", {"compare.blocked.0.threshold": "high"}, "compare.blocked[0].threshold", "number"),
    S("dataset-int", {"data.dataset": 5}, "[data] dataset", "got integer 5"),
    S("draws-float", {"sampler.draws": 1.5}, "[sampler] draws", "integer"),
    S("loo-string", {"compare.loo": "yes"}, "[compare] loo", "true or false"),
    S("companions-string", {"compare.companions": "no"}, "[compare] companions", "true or false"),
    S("select-not-table", {"data.select": 5}, "[data] select", "must be a table"),
    S("select-nested", {"data.select": {"series": {"a": 1}}}, "[data] select.series"),
    S("laws-not-array", {"laws": "coulomb"}, "[laws]", "array of tables"),
    S("constants-string", {"laws.0.constants": {"x": "y"}}, "laws[0].constants.x", "number"),
    # -- finding 2: out of range ---------------------------------------------------------------
    S("smc-particles-zero", {"compare.smc_particles": 0}, "[compare] smc_particles", "≥ 20"),
    S("smc-runs-one", {"compare.smc_runs": 1}, "[compare] smc_runs", "≥ 2"),
    S("kfold-one", {"compare.kfold": 1}, "[compare] kfold", "0 (off) or ≥ 2"),
    S("kfold-more-than-rows", {"compare.kfold": 1000}, "[compare] kfold", "1000"),
    S("tune-negative", {"sampler.tune": -1}, "[sampler] tune", "≥ 0"),
    S("seed-negative", {"sampler.seed": -1}, "[sampler] seed", "≥ 0"),
    S("target-accept-one", {"sampler.target_accept": 1.0}, "[sampler] target_accept", "< 1"),
    S("retry-below-target", {"sampler.retry_target_accept": 0.8}, "[sampler] retry_target_accept",
      "above target_accept"),
    S("metric-unknown", {"sampler.metric": "full"}, "[sampler] metric", "diag"),
    S("metric-emcee", {"sampler.name": "emcee", "sampler.chains": DELETE, "sampler.metric": "dense"},
      "[sampler] metric", "only to sampler nuts"),
    S("law-metric-unknown", {"laws.0.metric": "full"}, "laws[0].metric", "diag"),
    S("law-metric-emcee", {"sampler.name": "emcee", "sampler.chains": DELETE, "laws.0.metric": "dense"},
      "laws[0].metric", "only to sampler nuts"),
    S("retry-one", {"sampler.retry_target_accept": 1.0}, "[sampler] retry_target_accept", "< 1"),
    S("init-unknown", {"sampler.init": "uniform"}, "[sampler] init", "must be one of"),
    S("quantile-above-one", {"compare.blocked.0.threshold": DELETE, "compare.blocked.0.quantile": 1.5},
      "compare.blocked[0].quantile", "< 1"),
    S("threshold-and-quantile", {"compare.blocked.0.quantile": 0.5}, "compare.blocked[0]", "exactly one"),
    S("direction-unknown", {"compare.blocked.0.direction": "sideways"}, "compare.blocked[0].direction"),
    S("evidence-few-draws", {"sampler.draws": 20, "compare.evidence": True}, "[sampler] draws", "40"),
    S("laws-empty", {"laws": []}, "[laws]", "at least 1"),
    # -- issue 27: every size-like setting bounded by the memory it implies ------------------------
    S("draws-3e9", {"sampler.draws": 3_000_000_000}, "[sampler] draws", "of memory", "at most"),
    S("draws-1e30", {"sampler.draws": 10**30}, "[sampler] draws", "of memory"),
    S("tune-3e9", {"sampler.tune": 3_000_000_000}, "[sampler] tune", "of memory"),
    S("chains-1e8", {"sampler.chains": 100_000_000}, "[sampler] chains", "of memory"),
    S("emcee-walkers-1e8", {"sampler.name": "emcee", "sampler.chains": DELETE, "sampler.walkers": 100_000_000},
      "[sampler] walkers", "of memory"),
    S("emcee-thin-above-draws", {"sampler.name": "emcee", "sampler.chains": DELETE, "sampler.thin": 1000},
      "[sampler] draws", "keep no draw"),
    S("smc-particles-1e12", {"compare.smc": True, "compare.smc_particles": 10**12}, "[compare] smc_particles",
      "of memory"),
    S("smc-runs-1e12", {"compare.smc": True, "compare.smc_runs": 10**12}, "[compare] smc_runs", "of memory"),
    S("quick-draws-3e9", {"sampler.draws": 3_000_000_000}, "[sampler] draws", "of memory", extra=("--quick",)),
    # -- finding 3: --quick never hides invalid settings ----------------------------------------
    S("quick-negative-draws", {"sampler.draws": -10}, "[sampler] draws", "≥ 1", extra=("--quick",)),
    S("quick-zero-chains", {"sampler.chains": 0}, "[sampler] chains", "≥ 1", extra=("--quick",)),
    # -- unknown keys -----------------------------------------------------------------------------
    S("unknown-sampler-key", {"sampler.draw": 10}, "[sampler]", "unknown key 'draw'"),
    S("unknown-section", {"extra": {"a": 1}}, "unknown key 'extra'"),
    S("unknown-compare-key", {"compare.kfolds": 5}, "[compare]", "unknown key 'kfolds'"),
    S("unknown-law-key", {"laws.0.prior": {}}, "laws[0]", "unknown key 'prior'"),
    # -- finding 4: per-sampler settings ----------------------------------------------------------
    S("emcee-with-chains", {"sampler.name": "emcee"}, "[sampler] chains", "only to sampler nuts"),
    S("nuts-with-walkers", {"sampler.walkers": 32}, "[sampler] walkers", "only to sampler emcee"),
    S("sampler-unknown", {"sampler.name": "hmc"}, "[sampler] name", "'nuts', 'emcee'"),
    S("emcee-walkers-one", {"sampler.name": "emcee", "sampler.chains": DELETE, "sampler.walkers": 1},
      "[sampler] walkers", "≥ 2"),
    S("emcee-walkers-too-few", {"sampler.name": "emcee", "sampler.chains": DELETE, "sampler.walkers": 5},
      "[sampler] walkers", "at least 2 × 3 = 6 walkers"),
    S("emcee-thin-zero", {"sampler.name": "emcee", "sampler.chains": DELETE, "sampler.thin": 0},
      "[sampler] thin", "≥ 1"),
    # -- laws and priors ----------------------------------------------------------------------------
    S("prior-negative-scale", {"laws.0.priors": {"T_C": {"dist": "HalfNormal", "scale": -1.0}}},
      "laws[0].priors.T_C", "scale=-1 must be > 0"),
    S("prior-not-table", {"laws.0.priors": {"T_C": [1, 2]}}, "laws[0].priors.T_C", "must be a table"),
    S("prior-scaled-by-missing-input", {"laws.0.priors": {"T_C": HN(1.0, temperature=1)}},
      "laws[0].priors.T_C.scaled_by.temperature", "no such input", "coulomb_viscous"),
    # -- issue 27: priors overflow while resolved, keys named ------------------------------------
    S("prior-power-1e308", {"laws.0.priors": {"T_C": HN(1.0, response=1e308)}},
      "laws[0].priors.T_C.scaled_by.response", "from -2 to 2"),
    S("prior-power-400", {"laws.0.priors": {"T_C": HN(1.0, response=400)}},
      "laws[0].priors.T_C.scaled_by.response", "got 400"),
    S("prior-power-nan", {"laws.0.priors": {"T_C": HN(1.0, response=float("nan"))}},
      "laws[0].priors.T_C.scaled_by.response"),
    S("prior-scaled-by-unknown-name", {"laws.0.priors": {"T_C": HN(1.0, pressure=1)}},
      "laws[0].priors.T_C.scaled_by.pressure", "neither 'response' nor an operating quantity"),
    S("prior-scaled-by-not-table", {"laws.0.priors": {"T_C": {"dist": "HalfNormal", "scale": 1.0, "scaled_by": 2}}},
      "laws[0].priors.T_C.scaled_by", "table of powers"),
    S("prior-scale-1e300", {"laws.0.priors": {"T_C": HN(1e300)}}, "laws[0].priors.T_C", "reaches 1e301"),
    S("prior-lognormal-wide", {"laws.0.priors": {"T_C": {"dist": "LogNormal", "loc": 0.0, "scale": 400.0}}},
      "laws[0].priors.T_C", "must stay within"),
    S("prior-rate-tiny", {"laws.0.priors": {"T_C": {"dist": "Exponential", "rate": 1e-300}}},
      "laws[0].priors.T_C", "must stay within"),
    S("prior-overflows-when-scaled", {"laws.0.priors": {"T_C": HN(1e99, response=2)}},
      "laws[0].priors.T_C", "scaled by the data scale R^2"),
    S("fixed-1e308", {"laws.0.fixed": {"c_v": 1e308}}, "laws[0].fixed.c_v", "1e±100"),
    S("fixed-1e-300", {"laws.0.fixed": {"c_v": 1e-300}}, "laws[0].fixed.c_v", "1e±100"),
    S("law-unknown", {"laws.0.name": "no_such_law"}, "laws[0].name", "unknown law"),
    S("law-twice", {"laws": [{"name": "coulomb"}, {"name": "coulomb"}]}, "laws[1].name", "twice"),
    S("constant-unknown", {"laws.0.constants": {"nope": 1.0}}, "laws[0].constants.nope"),
    # -- data-dependent checks ----------------------------------------------------------------------
    S("noise-group-unknown", {"noise": {"group": "nope"}}, "[noise] group", "'nope'"),
    S("noise-ar1-without-trajectories", {"noise": {"kind": "ar1"}}, "[noise] kind", "trajectory"),
    S("grouped-unknown", {"compare.grouped": "nope"}, "[compare] grouped", "'nope'"),
    S("blocked-axis-unknown", {"compare.blocked.0.axis": "temperature"}, "compare.blocked[0].axis"),
    S("blocked-nothing-held-out", {"compare.blocked.0.threshold": 100.0}, "compare.blocked[0]",
      "no held-out point"),
    S("blocked-labels-twice", {"compare.blocked": [{"axis": "velocity", "threshold": 0.5, "label": "a"},
                                                    {"axis": "velocity", "threshold": 1.0, "label": "a"}]},
      "compare.blocked[1].label"),
    S("select-absent-level", {"data.select": {"series": 99}}, "[data] select", "series = 99", "no row",
      "its series values: 1, 2, 3"),
    S("select-unknown-coordinate", {"data.select": {"nope": 1}}, "[data] select", "'nope'"),
    S("dataset-missing", {"data.dataset": "nope.csv"}, "[data] dataset"),
    # -- the file itself ----------------------------------------------------------------------------
    R("invalid-toml", b"[study\nname = 1\n", "invalid TOML"),
    R("not-utf8", b"[study]\nname = \"\xff\xfe\"\n", "UTF-8"),
    C("study-file-missing", ("study", "nothere.toml", "--out", "reports"), "nothere.toml", "not found"),
    C("study-file-is-folder", ("study", "reports", "--out", "reports"), "reports", "not a file"),
    C("study-out-is-file", ("study", "s.toml", "--out", "notes.txt"), "--out notes.txt", "not a folder"),
    # -- CLI: main options (checked before any study runs) ------------------------------------------
    C("main-jobs-zero", ("main", "--jobs", "0", "--out", "reports"), "--jobs", "≥ 1, got 0"),
    C("main-jobs-and-workers", ("main", "--jobs", "2", "--workers", "2", "--out", "reports"), "--jobs and --workers"),
    C("main-studies-is-file", ("main", "--studies", "notes.txt", "--out", "reports"), "--studies notes.txt",
      "not a folder"),
    C("main-studies-missing", ("main", "--studies", "nothere", "--out", "reports"), "--studies nothere",
      "not a folder"),
    C("main-jobs-huge", ("main", "--jobs", "100000", "--out", "reports"), "--jobs", "of memory", "at most"),
    C("study-workers-huge", ("study", "s.toml", "--out", "reports", "--workers", "100000"), "--workers", "of memory"),
    # -- CLI: fit options -----------------------------------------------------------------------------
    C("fit-draws-3e9", FIT + ("--draws", "3000000000"), "--draws", "of memory", "at most"),
    C("fit-tune-3e9", FIT + ("--tune", "3000000000"), "--tune", "of memory"),
    C("fit-chains-1e8", FIT + ("--chains", "100000000"), "--chains", "of memory"),
    C("fit-emcee-walkers-1e8", FIT + ("--sampler", "emcee", "--walkers", "100000000"), "--walkers", "of memory"),
    C("fit-emcee-draws-below-thin", FIT + ("--sampler", "emcee", "--draws", "5"), "--draws", "keep no draw"),
    C("fit-draws-zero", FIT + ("--draws", "0"), "--draws", "≥ 1"),
    C("fit-chains-zero", FIT + ("--chains", "0"), "--chains", "≥ 1"),
    C("fit-tune-negative", FIT + ("--tune", "-1"), "--tune", "≥ 0"),
    C("fit-seed-negative", FIT + ("--seed", "-1"), "--seed", "≥ 0"),
    C("fit-retry-below-target", FIT + ("--retry-target-accept", "0.5"), "--retry-target-accept",
      "above target_accept (0.9)"),
    C("fit-retry-one", FIT + ("--retry-target-accept", "1"), "--retry-target-accept", "< 1"),
    C("fit-metric-unknown", FIT + ("--metric", "full"), "--metric", "diag"),
    C("fit-emcee-with-retry", FIT + ("--sampler", "emcee", "--retry-target-accept", "0.99"),
      "--retry-target-accept", "only to sampler nuts"),
    C("fit-emcee-walkers-one", FIT + ("--sampler", "emcee", "--walkers", "1"), "--walkers", "≥ 2"),
    C("fit-emcee-walkers-too-few", ("fit", "robot_joint", "stribeck", "--sampler", "emcee", "--walkers", "5"),
      "--walkers", "2 × 5 = 10"),
    C("fit-emcee-with-chains", FIT + ("--sampler", "emcee", "--chains", "2"), "--chains", "only to sampler nuts"),
    C("fit-prior-list", FIT + ("--prior", "T_C=[1,2]"), "--prior T_C", "table/object"),
    C("fit-prior-negative-scale", FIT + ("--prior", 'T_C={"dist":"HalfNormal","scale":-1}'), "--prior T_C",
      "scale=-1 must be > 0"),
    C("fit-prior-bad-json", FIT + ("--prior", "T_C={dist"), "--prior T_C", "invalid JSON"),
    C("fit-prior-unknown-parameter", FIT + ("--prior", 'nope={"dist":"HalfNormal","scale":1}'), "--prior nope"),
    C("fit-prior-power-1e308", FIT + ("--prior", 'T_C={"dist":"HalfNormal","scale":1,"scaled_by":{"response":1e308}}'),
      "--prior T_C", "scaled_by.response", "from -2 to 2"),
    C("fit-prior-power-400", FIT + ("--prior", 'T_C={"dist":"HalfNormal","scale":1,"scaled_by":{"response":400}}'),
      "--prior T_C", "scaled_by.response"),
    C("fit-prior-scaled-by-pressure",
      FIT + ("--prior", 'T_C={"dist":"HalfNormal","scale":1,"scaled_by":{"pressure":1}}'),
      "--prior T_C", "scaled_by.pressure"),
    C("fit-prior-scaled-by-missing-input",
      FIT + ("--prior", 'T_C={"dist":"HalfNormal","scale":1,"scaled_by":{"temperature":1}}'),
      "--prior T_C", "scaled_by.temperature", "no such input"),
    C("fit-prior-scale-1e300", FIT + ("--prior", 'T_C={"dist":"HalfNormal","scale":1e300}'), "--prior T_C", "reaches"),
    C("fit-prior-overflows-when-scaled",
      FIT + ("--prior", 'T_C={"dist":"HalfNormal","scale":1e99,"scaled_by":{"response":2}}'),
      "--prior T_C", "scaled by the data scale"),
    C("fit-fix-1e308", FIT + ("--fix", "c_v=1e308"), "--fix c_v", "1e±100"),
    C("fit-out-folder", FIT + ("--out", "reports"), "--out reports", "is a folder"),
    C("fit-out-under-file", FIT + ("--out", "notes.txt/fit.nc"), "--out notes.txt/fit.nc", "not a folder"),
    C("fit-out-unwritable", FIT + ("--out", "locked/sub/fit.nc"), "--out locked/sub/fit.nc", "not writable",
      skip=AS_ROOT),
    C("fit-out-unwritable-system", FIT + ("--out", "/proc/self/fit.nc"), "--out /proc/self/fit.nc", "not writable",
      skip=NO_PROC),
    C("fit-select-unknown-coordinate", FIT + ("--select", "nope=1"), "--select nope=1", "'nope'"),
    C("fit-select-absent-level", FIT + ("--select", "series=99"), "--select series=99", "series = 99", "no row"),
    C("fit-group-unknown", FIT + ("--group", "nope"), "--group nope"),
    # -- finding 8: argparse's own errors ---------------------------------------------------------------
    C("argparse-unknown-option", FIT + ("--bogus",), "unrecognized arguments: --bogus"),
    C("argparse-missing-argument", ("fit", "robot_joint"), "fit:", "required: law"),
    C("argparse-bad-int", FIT + ("--draws", "ten"), "--draws", "invalid int value: 'ten'"),
    C("argparse-bad-choice", FIT + ("--sampler", "hmc"), "--sampler", "invalid choice"),
    C("argparse-no-command", (), "required"),
    C("argparse-study-no-file", ("study",), "study:", "required: file"),
    # -- group terms (vary_by) and thinning ([data] every) ------------------------------------------------
    S("vary-by-unknown-parameter", {"laws.0.vary_by": {"series": ["nope"]}}, "laws[0].vary_by.series",
      "no sampled parameter 'nope'"),
    S("vary-by-not-list", {"laws.0.vary_by": {"series": 3}}, "laws[0].vary_by"),
    S("vary-by-empty", {"laws.0.vary_by": {"series": []}}, "laws[0].vary_by.series"),
    S("vary-by-two-columns", {"laws.0.vary_by": {"series": ["T_C"], "run": ["T_C"]}}, "laws[0].vary_by",
      "varies by both"),
    S("vary-by-missing-column", {"laws.0.vary_by": {"unit": ["T_C"]}}, "laws[0].vary_by", "'unit' is not a column"),
    S("vary-by-bad-column-name", {"laws.0.vary_by": {"a b": ["T_C"]}}, "laws[0].vary_by", "not a plain name"),
    # -- trends over a service coordinate and time-to-exceed questions ----------------------------------
    S("trend-bad-form", {"laws.0.trend": {"series": ["T_C"]}, "laws.0.trend_form": "cubic"}, "trend_form", "cubic"),
    S("trend-missing-column", {"laws.0.trend": {"hours": ["T_C"]}}, "laws[0].trend", "'hours' is not a column"),
    S("trend-unknown-parameter", {"laws.0.trend": {"series": ["nope"]}}, "laws[0].trend.series",
      "no sampled parameter 'nope'"),
    S("trend-and-group-column", {"laws.0.trend": {"series": ["T_C"]}, "laws.0.vary_by": {"series": ["c_v"]}},
      "laws[0].trend", "both a group and a trend"),
    S("forecast-missing-column", {"compare.forecast": "hours"}, "[compare] forecast"),
    S("horizon-without-capacity", {"sizing": [{"at": {"velocity": "1 rad/s"}, "horizon": "100 h"}]},
      "sizing[0].capacity", "horizon"),
    S("horizon-not-a-time", {"sizing": [{"at": {"velocity": "1 rad/s"}, "capacity": "5 N*m", "horizon": "soon"}]},
      "sizing[0].horizon", "soon"),
    S("horizon-without-trend", {"sizing": [{"at": {"velocity": "1 rad/s"}, "capacity": "5 N*m", "horizon": "100 h"}]},
      "sizing[0].horizon", "no law follows a trend"),
    S("every-zero", {"data.every": 0}, "[data] every", "≥ 1"),
    S("every-string", {"data.every": "ten"}, "[data] every", "integer"),
]


def _set(tree: dict, dotted: str, value) -> None:
    *parents, last = dotted.split(".")
    node = tree
    for key in parents:
        node = node[int(key)] if isinstance(node, list) else node.setdefault(key, {})
    if isinstance(node, list):
        node[int(last)] = value
    elif value is DELETE:
        node.pop(last, None)
    else:
        node[last] = value


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return "{ " + ", ".join(f"{json.dumps(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"


def study_toml(changes: dict, root: Path) -> str:
    """BASE with ``changes`` applied (``{root}`` in a string becomes the case tree), as TOML."""
    tree = json.loads(json.dumps(BASE))
    for dotted, value in changes.items():
        _set(tree, dotted, value.replace("{root}", str(root)) if isinstance(value, str) else value)
    return "\n".join(f"{json.dumps(k)} = {_toml_value(v)}" for k, v in tree.items()) + "\n"


@pytest.fixture
def tree(tmp_path):
    """A case tree: reports/ with another study's marked report, a colleague's unmarked folder, a
    plain file and a symbolic link; a victim folder outside reports/; a file; a read-only folder."""
    root = tmp_path / "case"
    reports = root / "reports"
    (reports / "other" / "fits").mkdir(parents=True)
    (reports / "other" / MARKER).write_text(json.dumps({"tool": "bayesfric", "study": "other", "pid": 1}))
    (reports / "other" / "summary.md").write_text("# another study's report\n")
    (reports / "colleague").mkdir()
    (reports / "colleague" / "notes.md").write_text("not bayesfric's\n")
    (reports / "README.md").write_text("reports\n")
    (root / "victim").mkdir()
    (root / "victim" / "keep.txt").write_text("keep\n")
    (root / "victim" / MARKER).write_text(json.dumps({"tool": "bayesfric", "study": "evil"}))
    (reports / "evil").symlink_to(root / "victim")
    (root / "notes.txt").write_text("a file\n")
    (root / "locked").mkdir(mode=0o555)
    yield root
    (root / "locked").chmod(0o755)


def test_corpus_is_large_and_ids_unique():
    assert len(CASES) >= 30
    assert len({c.id for c in CASES}) == len(CASES)


def test_base_study_is_valid(tree):
    """Each study case differs from a valid study only by its changes."""
    (tree / "s.toml").write_text(study_toml({}, tree))
    study = load_study(tree / "s.toml")
    validate_against_data(study, load_dataset(resolve(study.dataset)))


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_one_line_and_changes_nothing(case: Case, tree: Path):
    if case.skip:
        pytest.skip(case.skip)
    if case.raw is not None:
        (tree / case.file).write_bytes(case.raw)
    elif case.changes is not None:
        (tree / case.file).write_text(study_toml(case.changes, tree))
    assert_user_error(case.argv, tree, case.mentions)
