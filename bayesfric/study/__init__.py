"""Studies: TOML files under studies/ that run comparisons and write reports/<study>/.

A study is run by :func:`bayesfric.pipeline.runner.run_study` (the public :func:`bayesfric.run`),
the seed studies by :func:`bayesfric.pipeline.mainjob.run_flagship`: both are above the report,
which reads this package's scores and result tree, so this package never imports the report.
This package's ``__init__`` imports only the study file's types and loader: commands that only
read the study schema (``bayesfric fit``) should not pay for importing every comparison, report
and sizing module.
"""

from __future__ import annotations

from bayesfric.builtin import builtin_folder
from bayesfric.study.config import Study, StudyError, load_study

__all__ = ["Study", "StudyError", "load_study", "STUDIES_DIR"]

#: The seed studies: ``studies/`` of the repository, shipped as package data (bayesfric.builtin).
STUDIES_DIR = builtin_folder("bayesfric.builtin_studies", "studies")
