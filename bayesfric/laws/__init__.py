"""The law library. Importing this package registers every law family.

One module per family; each law is declared once with :func:`bayesfric.laws.base.law`.
"""

from bayesfric.laws import bearing, classical, contact, drum, hysteresis, slip, thermal  # noqa: F401  (registers laws)
from bayesfric.laws.base import REGISTRY, Constant, Derived, Law, Param, get_law, law, register_resolver
from bayesfric.laws.plugins import entry_point_law, load_entry_points
from bayesfric.laws.simple import simple_law
from bayesfric.laws.steady import steady_state
from bayesfric.laws.variants import alias

for _name, _recipe in hysteresis.DAHL_ALIASES.items():  # names users type; one declaration each
    alias(_name, _recipe)
for _name, _recipe in drum.ORING_ALIASES.items():  # seed 003's O-ring law is Coulomb + viscous
    alias(_name, _recipe, notes=drum.ORING_NOTES)
register_resolver(entry_point_law)  # installed packages' laws: after every family's resolver

__all__ = ["REGISTRY", "Law", "Param", "Constant", "Derived", "get_law", "law", "simple_law", "all_laws",
           "steady_state"]


def all_laws() -> list[Law]:
    """Every registered law (installed packages' entry points loaded first), sorted by family then name."""
    load_entry_points()
    return sorted(REGISTRY.values(), key=lambda w: (w.family, w.name))
