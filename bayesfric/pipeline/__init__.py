"""A study run from its file to its installed report folder, and the main job over every study.

:mod:`bayesfric.pipeline.runner` (``run_study``, ``execute_study``: the public
:func:`bayesfric.run`) checks a study, has :mod:`bayesfric.study` compute its units and result
tree, answers its sizing questions and claims, has :mod:`bayesfric.report` write the report, and
installs the folder atomically; :mod:`bayesfric.pipeline.mainjob` runs every seed study
(``bayesfric main``). This package sits above the report, which reads the study package's scores
and result tree, so no package imports one that imports it back. Its ``__init__`` imports
neither module.
"""
