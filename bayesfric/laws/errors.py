"""The errors of law declarations and variants, below every module of :mod:`bayesfric.laws`
(:mod:`bayesfric.laws.base` raises both and re-exports them, as does :mod:`bayesfric.laws.variants`)."""

from bayesfric.errors import UserError

__all__ = ["LawDeclarationError", "VariantError"]


class LawDeclarationError(UserError, TypeError):
    """A law declaration that is inconsistent with its function or the vocabulary (a
    :class:`~bayesfric.errors.UserError`; also a ``TypeError``, as declaration errors were)."""


class VariantError(LawDeclarationError):
    """A variant the law cannot take (unknown parameter, asymmetry of a trajectory law ...).

    ``key`` is the option it concerns (``"fixed.i"``, ``"asymmetric"``, ``"add"``), ``problem``
    the message without it, so callers name the option in their own terms (study key, CLI flag).
    """

    def __init__(self, problem: str, key: str = ""):
        UserError.__init__(self, problem, key)
