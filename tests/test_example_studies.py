"""The simulated example studies of issue 13 (studies/examples/, not run by the main job) pass
every check before writing, and their law entries are the variants they say they are."""

from __future__ import annotations

from bayesfric.study import STUDIES_DIR, load_study
from bayesfric.study.plan import _prepare

EXAMPLES = STUDIES_DIR / "examples"


def test_example_studies_pass_every_check_before_writing(tmp_path):
    files = sorted(EXAMPLES.glob("*.toml"))
    assert {f.name for f in files} >= {"asym_joint.toml", "tribo_loops.toml"}
    for f in files:
        _prepare(f, tmp_path / "reports", quick=False)
    assert not (tmp_path / "reports").exists()


def test_asym_joint_lists_one_law_three_ways():
    study = load_study(EXAMPLES / "asym_joint.toml")
    assert [s.name for s in study.laws] == ["armstrong_helouvry", "ah_offset", "ah_asym_offset"]
    assert {s.law for s in study.laws} == {"armstrong_helouvry"}
    laws = [s.build() for s in study.laws]
    assert "offset" in laws[1].params and {"dT_s_pos", "dT_s_neg", "c_v_pos", "c_v_neg"} <= set(laws[2].params)


def test_tribo_loops_runs_translationally_without_preload(tmp_path):
    study, _, ds, *_ = _prepare(EXAMPLES / "tribo_loops.toml", tmp_path / "reports", quick=True)
    from bayesfric.model import build_program

    program = build_program(study.laws[0].build(), ds)
    assert program.law.response == "force" and "preload" not in program.law.inputs
    assert program.law.params["x_c0"].unit == "m" and "gamma" not in program.law.params
