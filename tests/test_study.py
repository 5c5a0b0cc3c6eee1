"""Study files: one-line errors naming the key, nothing written on error; an end-to-end run."""

import csv

import numpy as np
import pytest

from bayesfric.cli import main
from bayesfric.pipeline.runner import run_study
from bayesfric.study import STUDIES_DIR, StudyError, load_study
from tests.bench_data import write_bench


@pytest.fixture
def data_csv(tmp_path):
    """A small simulated Stribeck data set written as CSV + sidecar."""
    return write_bench_data(tmp_path)


def write_bench_data(tmp_path):
    """``data_csv``'s data set written into ``tmp_path`` (for fixtures of a wider scope)."""
    speeds = np.geomspace(0.005, 4.0, 20)
    return write_bench(tmp_path, np.concatenate([-speeds[::-1], speeds]), series=True)


def study_text(laws='[[laws]]\nname = "coulomb"\n[[laws]]\nname = "coulomb_viscous"\n', extra=""):
    return ('[study]\nname = "tiny"\n[data]\ndataset = "bench.csv"\n'
            '[sampler]\ndraws = 1000\ntune = 500\nchains = 2\n' + laws +
            '[compare]\nloo = true\nevidence = false\n'
            '[[compare.blocked]]\naxis = "velocity"\nthreshold = 1.0\n' + extra)


@pytest.mark.parametrize(("laws", "fragment"), [
    ('[[laws]]\nname = "no_such_law"\n', "laws[0].name: unknown law 'no_such_law'"),
    ('[[laws]]\nname = "coulomb"\npriors = { nope = { dist = "HalfNormal", scale = 1.0 } }\n',
     "laws[0].priors.nope: law 'coulomb' has no parameter 'nope'"),
    ('[[laws]]\nname = "coulomb"\nprior = {}\n', "laws[0]: unknown key 'prior'"),
    ('[[laws]]\nname = "coulomb"\npriors = { T_C = { dist = "Nope" } }\n', "laws[0].priors.T_C: unknown distribution"),
])
def test_config_errors_name_the_key(tmp_path, data_csv, laws, fragment):
    path = tmp_path / "s.toml"
    path.write_text(study_text(laws))
    with pytest.raises(StudyError) as info:
        load_study(path)
    assert fragment in str(info.value) and "\n" not in str(info.value)


def test_bad_fold_axis_is_one_line_and_writes_nothing(tmp_path, data_csv, capsys):
    path = tmp_path / "s.toml"
    path.write_text(study_text().replace('axis = "velocity"', 'axis = "temperature"'))
    out = tmp_path / "reports"
    assert main(["study", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "compare.blocked[0].axis: 'temperature' is not an input" in err and err.count("\n") == 1
    assert not out.exists() or not any(out.iterdir())


def test_shipped_studies_validate():
    files = sorted(STUDIES_DIR.glob("*.toml"))
    assert len(files) == 6
    for f in files:
        study = load_study(f)
        assert study.blocked or study.forecast, f"{f.name} asks no extrapolation question"


def test_shipped_studies_pass_every_check_before_writing(tmp_path):
    """The stricter checks (data, programs, folds, report folder) accept every shipped study."""
    from bayesfric.study.plan import _prepare

    for f in sorted(STUDIES_DIR.glob("*.toml")):
        _prepare(f, tmp_path / "reports", quick=False)
    assert not (tmp_path / "reports").exists()  # checks write nothing


@pytest.mark.slow
def test_end_to_end_tiny_study(tmp_path, data_csv):
    path = tmp_path / "s.toml"
    path.write_text(study_text())
    folder = run_study(path, out_root=tmp_path / "reports")
    names = {p.name for p in folder.iterdir()}
    assert {"summary.md", "report.html", "ranking.csv", "parameters.csv", "fits", "figures"} <= names
    assert {p.name for p in (folder / "fits").iterdir()} == {"coulomb.nc", "coulomb_viscous.nc"}
    with (folder / "ranking.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["law"] for r in rows][0] == "coulomb_viscous"  # the truth extrapolates best
    for r in rows:
        penalties = [float(v) for k, v in r.items() if k.startswith("penalty_per_point")]
        assert np.isfinite(float(r["elpd_loo"])) and len(penalties) == 1 and np.isfinite(penalties[0])
    text = (folder / "summary.md").read_text()
    assert "SIMULATED data" in text and "## Ranking" in text and "weight[stacking LOO]" in rows[0]
    hidden = [p.name for p in folder.parent.iterdir() if p.name.startswith(".")]
    assert hidden == [".store"]  # the run store (README); no temporary folder left
    _results_tree_holds_the_csv_numbers(folder, rows)


def _results_tree_holds_the_csv_numbers(folder, ranking):
    """results.nc opens with xarray and holds the numbers the CSV files show (issue 31 item 1)."""
    import xarray as xr

    with xr.open_datatree(folder / "results.nc") as tree:
        scores = tree["scores"].to_dataset()
        with (folder / "scores.csv").open() as fh:
            table = list(csv.DictReader(fh))
        criteria = {(r["metric"], r["scheme"]) for r in table}
        assert scores.sizes["law"] == 2 and scores.sizes["criterion"] == len(criteria)
        for r in table:
            crit = r["metric"] if not r["scheme"] else f"{r['metric']}[{r['scheme']}]"
            cell = scores.sel(law=r["law"], criterion=crit)
            assert float(cell.estimate) == pytest.approx(float(r["estimate"]), rel=1e-9, abs=1e-12)
            assert bool(cell.reliable) == (r["reliable"] == "True") and str(cell.reason.values) == r["reason"]
        pointwise = tree["pointwise"].to_dataset()
        for law in ("coulomb", "coulomb_viscous"):  # pointwise LOO sums to the law's elpd_loo
            total = float(pointwise.elpd.sel(criterion="elpd_loo", law=law).sum())
            assert total == pytest.approx(float(scores.estimate.sel(law=law, criterion="elpd_loo")), rel=1e-9)
        weights = tree["weights"].to_dataset()
        assert float(weights.weight.sel(weighting="stacking LOO").sum()) == pytest.approx(1.0, abs=1e-6)
        ranked = tree["ranking"].to_dataset()
        assert list(ranked.law.values) == [r["law"] for r in ranking]
        fit = tree["fits/coulomb_viscous"]
        assert fit.attrs["fit_file"] == "fits/coulomb_viscous.nc" and "c_v" in fit["posterior"].data_vars
        assert "log_likelihood" not in fit.children  # per-row groups stay in the fit file


def test_evidence_pair_end_to_end(tmp_path, data_csv):
    """A study with evidence on writes both estimators; on this easy posterior they agree."""
    path = tmp_path / "s.toml"
    text = study_text(laws='[[laws]]\nname = "coulomb_viscous"\n')
    path.write_text(text.replace("evidence = false", "evidence = true"))
    folder = run_study(path, out_root=tmp_path / "reports")
    with (folder / "ranking.csv").open() as fh:
        (row,) = list(csv.DictReader(fh))
    bridge, importance = float(row["log_z_bridge"]), float(row["log_z_importance"])
    combined = np.hypot(float(row["log_z_bridge_error"]), float(row["log_z_importance_error"]))
    assert np.isfinite(bridge) and abs(bridge - importance) <= max(3 * combined, 0.2)
    assert "log_z_SMC" not in row  # tempered SMC is opt-in
    assert "Highest log evidence (importance): **coulomb\\_viscous**" in (folder / "summary.md").read_text()


# Winners, passed-over laws and evidence disagreement: tests/report/test_scores.py (the score table).


@pytest.mark.parametrize(("sampler", "full", "quick"), [
    ("draws = 1000\ntune = 500\nchains = 2\n",
     {"draws": 1000, "tune": 500, "chains": 2, "target_accept": 0.9, "retry_target_accept": 0.99,
      "metric": "auto", "init": "median"},
     {"draws": 300, "tune": 300, "chains": 2}),
    ('name = "emcee"\ndraws = 5000\ntune = 2000\nwalkers = 16\nthin = 20\n',
     {"draws": 5000, "tune": 2000, "walkers": 16, "thin": 20}, {"draws": 1000, "tune": 1000, "thin": 10}),
    ('name = "emcee"\ndraws = 100\nthin = 2\n', {"draws": 100, "tune": 2500, "thin": 2}, {"tune": 1000}),
])
def test_settings_per_sampler_and_quick_lowers_them_after_validation(tmp_path, data_csv, sampler, full, quick):
    """Each sampler gets its own settings (backend defaults filled); --quick only lowers them, and
    uses at most QUICK_KFOLD random folds."""
    from bayesfric.study.plan import QUICK_KFOLD, _run_settings

    text = study_text().replace("draws = 1000\ntune = 500\nchains = 2\n", sampler)
    (tmp_path / "s.toml").write_text(text.replace("evidence = false\n", "evidence = false\nkfold = 10\n"))
    study = load_study(tmp_path / "s.toml")
    config, kfold = _run_settings(study, quick=False)
    assert (config.settings(), kfold) == (full, 10)
    config, kfold = _run_settings(study, quick=True)
    assert (config.settings(), kfold) == (full | quick, QUICK_KFOLD)


@pytest.mark.parametrize(("line", "engine_retry"), [("", 0.99), ("retry_target_accept = 0.95\n", 0.95),
                                                    ("retry_target_accept = 0\n", None)])
def test_the_divergence_retry_is_a_sampler_key_that_reaches_the_engine(tmp_path, data_csv, line, engine_retry):
    """``[sampler] retry_target_accept`` sets the compiled engine's retry target; 0 switches it off."""
    from bayesfric.datasets import load_dataset, resolve
    from bayesfric.study.plan import _run_settings
    from bayesfric.study.units import _base_engine, make_job

    text = study_text().replace("chains = 2\n", "chains = 2\n" + line)
    (tmp_path / "s.toml").write_text(text)
    study = load_study(tmp_path / "s.toml")
    config, _ = _run_settings(study, quick=False)
    job = make_job(study.laws[0], study.noise, load_dataset(resolve(study.dataset)), config)
    assert _base_engine(job).retry_target_accept == engine_retry


@pytest.mark.parametrize(("line", "metric"), [("", "auto"), ('metric = "dense"\n', "dense")])
def test_the_mass_matrix_is_a_sampler_key_that_reaches_the_engine(tmp_path, data_csv, line, metric):
    """``[sampler] metric`` sets the compiled engine's metric (and so its unit keys)."""
    from bayesfric.datasets import load_dataset, resolve
    from bayesfric.study.plan import _run_settings
    from bayesfric.study.units import _base_engine, make_job

    (tmp_path / "s.toml").write_text(study_text().replace("chains = 2\n", "chains = 2\n" + line))
    study = load_study(tmp_path / "s.toml")
    config, _ = _run_settings(study, quick=False)
    job = make_job(study.laws[0], study.noise, load_dataset(resolve(study.dataset)), config)
    engine = _base_engine(job)
    assert engine.metric == metric and engine.settings["metric"] == metric


def test_a_law_entry_sets_its_own_mass_matrix(tmp_path, data_csv):
    """``[[laws]] metric`` overrides ``[sampler] metric`` for that law only, and keys its units."""
    from bayesfric.study.plan import _fold_schemes, _plan_laws, _run_settings, load_study_data

    text = study_text()
    (tmp_path / "s.toml").write_text(text)
    plain = load_study(tmp_path / "s.toml")
    first = text.index("[[laws]]")
    end = text.index("\n", text.index("name =", first)) + 1
    (tmp_path / "s.toml").write_text(text[:end] + 'metric = "dense"\n' + text[end:])
    study = load_study(tmp_path / "s.toml")
    assert study.laws[0].metric == "dense" and all(w.metric is None for w in study.laws[1:])
    ds = load_study_data(study)
    settings, kfold = _run_settings(study, quick=False)
    schemes = _fold_schemes(study, ds, 0, kfold)
    jobs = [p[0] for p in _plan_laws(study, ds, schemes, settings, 0)]
    before = [p[0] for p in _plan_laws(plain, ds, schemes, settings, 0)]
    assert jobs[0].settings["metric"] == "dense" and jobs[1].settings["metric"] == "auto"
    assert jobs[0].key != before[0].key and [j.key for j in jobs[1:]] == [j.key for j in before[1:]]


def test_a_study_without_ranking_criterion_reports_that_instead_of_crashing(tmp_path, data_csv):
    """loo = false, evidence = false, no folds: nothing ranks the laws; the report says so (it
    used to raise IndexError drawing the figures)."""
    path = tmp_path / "s.toml"
    text = study_text().replace("loo = true", "loo = false")
    path.write_text(text[:text.index("[[compare.blocked]]")])
    folder = run_study(path, out_root=tmp_path / "reports", quick=True)
    summary = (folder / "summary.md").read_text()
    assert "no ranking criterion" in summary
    assert "no ranking criterion" in (folder / "report.html").read_text()
    with (folder / "ranking.csv").open() as fh:
        assert {r["law"] for r in csv.DictReader(fh)} == {"coulomb", "coulomb_viscous"}


def test_a_law_entry_is_built_once_and_travels_as_its_recipe(tmp_path, data_csv):
    """Every part of a run (checks, claims, unit keys, units) gets the same Law object of an entry;
    a pickled entry (a ``main --jobs`` process, a Dask worker) carries the recipe and builds its own,
    equal to the original. Constants enter the law once, as its constants."""
    import pickle

    from bayesfric.model import build_program
    from bayesfric.study.plan import load_study_data

    laws = '[[laws]]\nname = "helical_gear"\nconstants = { omega_ref = 2.0 }\nfixed = { delta = 0.5 }\n'
    (tmp_path / "s.toml").write_text(study_text(laws))
    spec = load_study(tmp_path / "s.toml").laws[0]
    law = spec.build()
    assert spec.build() is law
    copy = pickle.loads(pickle.dumps(spec))
    assert "_built" not in copy.__dict__ and copy == spec
    again = copy.build()
    assert again is not law and again.name == law.name and set(again.params) == set(law.params)
    assert law.constants["omega_ref"].value == 2.0 and law.constants["delta"].value == 0.5
    assert "delta" not in law.params
    program = build_program(law, load_study_data(load_study(tmp_path / "s.toml")), priors=spec.priors)
    assert program.constants["omega_ref"] == 2.0 and program.constants["delta"] == 0.5
