"""User-facing error types shared by the CLI and the study runner."""


class UserError(ValueError):
    """A mistake in what the user asked for (reported in one line, exit code 2)."""
