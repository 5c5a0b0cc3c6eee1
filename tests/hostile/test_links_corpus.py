"""Bad-input corpus of symbolic links below the reports root (issue 27).

The run store is refused through a link planted below the reports root exactly as the report
folder is: ``reports/.store`` or ``reports/.store/<study>`` pointing elsewhere, or
``$BAYESFRIC_STORE_DIR`` named through a link inside ``reports/``. Every case runs through the
harness on the study corpus' tree (:func:`tests.hostile.test_study_corpus.tree`): exit status 2,
one line naming the study file and the path, and nothing under the tree (the link's target
included) created, changed or removed.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bayesfric import fsutil
from bayesfric.study.store import STORE_ENV, store_folder
from tests.hostile.harness import assert_user_error
from tests.hostile.test_study_corpus import study_toml, tree  # noqa: F401 - the fixture

STUDY = ("study", "s.toml", "--out", "reports")
MAIN = ("main", "--studies", "only", "--out", "reports", "--jobs", "1")


def _store_link(root: Path) -> None:
    (root / "reports" / ".store").symlink_to(root / "victim")


def _study_link(root: Path) -> None:
    (root / "reports" / ".store").mkdir()
    (root / "reports" / ".store" / "tiny").symlink_to(root / "victim")


def _named_study_link(root: Path) -> None:
    (root / "scratch").mkdir()
    (root / "scratch" / "tiny").symlink_to(root / "victim")


def _store_is_file(root: Path) -> None:
    (root / "reports" / ".store").write_text("not a folder\n")


#: (id, argv, set-up of the tree, $BAYESFRIC_STORE_DIR or None, fragments of the message)
CASES = [
    ("store-is-a-link", STUDY, _store_link, None, ("s.toml", "run store", "reports/.store", "symbolic link")),
    ("store-is-a-link-main", MAIN, _store_link, None, ("s.toml", "run store", "symbolic link")),
    ("study-store-is-a-link", STUDY, _study_link, None, ("s.toml", "run store", ".store/tiny", "symbolic link")),
    ("store-is-a-file", STUDY, _store_is_file, None, ("s.toml", "run store", ".store", "not a folder")),
    ("env-through-a-link-in-reports", STUDY, None, "reports/evil", ("s.toml", "run store", "reports/evil",
                                                                    "symbolic link")),
    ("env-below-a-link-in-reports", STUDY, None, "reports/evil/store", ("s.toml", "reports/evil", "symbolic link")),
    ("env-is-a-file", STUDY, None, "notes.txt", ("s.toml", f"${STORE_ENV}=notes.txt", "not a folder")),
    ("env-study-is-a-link", STUDY, _named_study_link, "scratch", ("s.toml", "scratch/tiny", "symbolic link")),
]


@pytest.mark.parametrize(("argv", "setup", "env", "mentions"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_store_through_a_link_is_refused(tree, monkeypatch, argv, setup, env, mentions):  # noqa: F811
    (tree / "s.toml").write_text(study_toml({}, tree))
    (tree / "only").mkdir()
    (tree / "only" / "s.toml").write_text(study_toml({}, tree))
    if setup is not None:
        setup(tree)
    if env is None:
        monkeypatch.delenv(STORE_ENV, raising=False)
    else:
        monkeypatch.setenv(STORE_ENV, env)
    assert_user_error(argv, tree, mentions)


def test_store_in_real_folders_is_accepted(tmp_path, monkeypatch):
    """Real folders pass, wherever the user names the store; a link the user names outside the
    reports root is theirs to name (followed, as any path a user gives)."""
    monkeypatch.delenv(STORE_ENV, raising=False)
    reports = tmp_path / "reports"
    (reports / ".store").mkdir(parents=True)
    assert store_folder(reports, "tiny") == reports / ".store" / "tiny"
    (tmp_path / "big").mkdir()
    (tmp_path / "scratch").symlink_to(tmp_path / "big")
    monkeypatch.setenv(STORE_ENV, str(tmp_path / "scratch"))
    assert store_folder(reports, "tiny") == tmp_path / "scratch" / "tiny"
    monkeypatch.setenv(STORE_ENV, str(reports / "cache"))  # inside reports, through real folders
    assert store_folder(reports, "tiny") == reports / "cache" / "tiny"
    with pytest.raises(fsutil.PathError, match="symbolic link"):
        (reports / "linked").symlink_to(tmp_path / "big")
        monkeypatch.setenv(STORE_ENV, str(reports / "linked"))
        store_folder(reports, "tiny")


def test_a_fit_written_over_a_link_replaces_the_link(tmp_path):
    """``fit --out`` names a path the user chose; a link at that name is replaced by the fit (the
    file is written beside it and renamed over it), never written through to its target."""
    import numpy as np

    from bayesfric.inference import save_fit
    from tests.sizing_helpers import hand_fit

    victim = tmp_path / "victim.txt"
    victim.write_text("keep\n")
    (tmp_path / "fit.nc").symlink_to(victim)
    draws = {"T_C": np.full((2, 5), 5.0), "sigma": np.full((2, 5), 0.2)}
    save_fit(hand_fit("coulomb", draws, {"velocity": np.linspace(0.1, 2.0, 5)}), tmp_path / "fit.nc")
    assert victim.read_text() == "keep\n"
    assert not (tmp_path / "fit.nc").is_symlink() and (tmp_path / "fit.nc").stat().st_size > 0
