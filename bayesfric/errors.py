"""The one error class of everything a user gives bayesfric: :class:`UserError`, keyed.

Every mistake in what a user gives -- a data file, a sidecar, a study file, a prior, a unit, a
law declaration or variant, a sizing question, a path, a command line -- raises a subclass of
:class:`UserError`: a one-line ``problem`` and the ``key`` it concerns (a file, a key path, an
option; empty when the message already says where). The CLI reports any of them as one line,
exit status 2 (:mod:`bayesfric.cli`); a caller that knows more of the place puts its prefix
before the key with :meth:`UserError.within`. The subclasses say which input it was; they keep
the constructor their callers use.

What is not the user's mistake -- a broken invariant of bayesfric itself -- is an
:class:`InternalError`: the CLI does not turn it into a one-line input error, because it is a bug
to report.

A fit that ran but whose draws must not be read as they stand (it failed the diagnostics gate,
or it is used only with parameters the data do not identify, or as separate modes combined) is
not an error: :func:`bayesfric.fit` returns it and warns with a :class:`FitWarning`, which a
caller may turn into an error (``warnings.simplefilter("error", bayesfric.errors.FitWarning)``).
"""

from __future__ import annotations

__all__ = ["UserError", "DataError", "InternalError", "FitWarning"]


class UserError(ValueError):
    """A mistake in what the user asked for (reported in one line, exit code 2).

    Parameters
    ----------
    problem : str
        What is wrong, one line.
    key : str, optional
        What it concerns (``"fixed.i"``, ``"[sampler] draws"``, a file); the message is
        ``"key: problem"`` when it is given.

    Examples
    --------
    >>> err = UserError("must be ≥ 1, got 0", "draws")
    >>> str(err), str(err.within("[sampler]"))
    ('draws: must be ≥ 1, got 0', '[sampler].draws: must be ≥ 1, got 0')
    """

    def __init__(self, problem: str = "", key: str = ""):
        super().__init__(f"{key}: {problem}" if key else problem)
        self.key, self.problem = key, problem

    def within(self, prefix: str, sep: str = ".") -> UserError:
        """The same error (same class) with ``prefix`` placed before its key."""
        return _rebuilt(type(self), self.problem, f"{prefix}{sep}{self.key}" if self.key else prefix,
                        self.__dict__)

    def __reduce__(self):
        # the subclasses' constructors differ (key first, a key path ...): rebuild from the fields,
        # so any of them pickles (a Dask worker's error reaches the client)
        return _rebuilt, (type(self), self.problem, self.key, self.__dict__)


def _rebuilt(cls: type[UserError], problem: str, key: str, fields: dict) -> UserError:
    """An error of class ``cls`` with ``problem`` and ``key``, and the other ``fields`` it had."""
    err = cls.__new__(cls)
    err.__dict__.update(fields)
    UserError.__init__(err, problem, key)
    return err


class DataError(UserError):
    """Bad input data: the message is one line naming file, column and row where they apply.

    Declared here, in a base module, because the laws raise it too (a law that cannot run on a data
    set's motion kind, :func:`bayesfric.laws.variants.for_data`); :mod:`bayesfric.datasets` and
    :mod:`bayesfric.datasets.loader` re-export it."""


class InternalError(RuntimeError):
    """A broken invariant of bayesfric itself, not of what the user gave: a bug to report.

    Examples
    --------
    >>> isinstance(InternalError("unknown unit stage 'fold'"), UserError)
    False
    """


class FitWarning(UserWarning):
    """A fit returned by :func:`bayesfric.fit` that did not pass the diagnostics gate as it stands:
    failed (its draws are not a posterior to act on), or used under the multimodal or unidentified
    rule (:mod:`bayesfric.inference.modes`). The message is the verdict.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn("fit of stribeck FAILED the diagnostics gate", FitWarning)
    >>> caught[0].category.__name__
    'FitWarning'
    """
