"""Studies: TOML files under studies/ that run comparisons and write reports/<study>/."""

from __future__ import annotations

from typing import Any

from bayesfric.builtin import builtin_folder
from bayesfric.study.config import Study, StudyError, load_study

__all__ = ["Study", "StudyError", "load_study", "run_study", "run_flagship", "STUDIES_DIR"]

#: The seed studies: ``studies/`` of the repository, shipped as package data (bayesfric.builtin).
STUDIES_DIR = builtin_folder("bayesfric.builtin_studies", "studies")


def __getattr__(name: str) -> Any:
    # The runner pulls in every comparison, report and sizing module; commands that only read
    # the study schema (``bayesfric fit``) should not pay for importing them.
    if name == "run_study":
        from bayesfric.study.runner import run_study

        return run_study
    if name == "run_flagship":
        from bayesfric.study.mainjob import run_flagship

        return run_flagship
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
