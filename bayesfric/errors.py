"""User-facing error types shared by the CLI and the study runner."""


class UserError(ValueError):
    """A mistake in what the user asked for (reported in one line, exit code 2)."""


class DataError(ValueError):
    """Bad input data: the message is one line naming file, column and row where they apply.

    Declared here, in a base module, because the laws raise it too (a law that cannot run on a data
    set's motion kind, :func:`bayesfric.laws.variants.for_data`); :mod:`bayesfric.datasets` and
    :mod:`bayesfric.datasets.loader` re-export it."""
