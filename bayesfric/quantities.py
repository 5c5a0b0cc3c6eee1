"""The fixed vocabulary of operating quantities and their canonical SI units.

Every law names its inputs and its response from this vocabulary, every dataset column declares
one of these quantities, and every unit string anywhere in bayesfric is parsed by the one pint
registry defined here. Canonical units are SI (angles in radians, temperature in kelvin).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pint

from bayesfric.errors import UserError

__all__ = [
    "QUANTITIES",
    "Quantity",
    "UnitError",
    "ureg",
    "to_canonical",
    "check_unit",
    "conversion",
    "SCALE_RANGE",
    "ROUNDING",
    "rounding_slack",
    "DERIVED_POSITIONS",
]

#: Allowed range (SI) of the largest |value| of an operating quantity: the data loader checks the
#: response and every input that is not all zero against it (:mod:`bayesfric.datasets.loader`), and
#: every value a user states (sizing points, claims) must not exceed its upper end
#: (:mod:`bayesfric.sizing.points`). Data-scaled priors use R^a X^b with |a|, |b| <= 2
#: (:data:`bayesfric.priors.MAX_POWER`) and the likelihood divides by a noise scale of order R;
#: within 1e-12..1e12 every such factor stays within 1e+-24, far inside float64 (1e-308..1e308),
#: while 1e-300 would square to 0 and 1e300 to inf. No friction measurement or operating point
#: leaves this range (an AFM's lateral force is about 1e-12 N, a micro-tribometer's 1e-6 N; the
#: largest bearing moments are about 1e8 N*m): outside it, the unit is wrong.
SCALE_RANGE = (1e-12, 1e12)

#: Relative rounding of a unit conversion ``si = scale * value + offset`` in float64: a result
#: within ``ROUNDING * (|scale * value| + |offset|)`` of a physical bound is *on* the bound
#: (:func:`rounding_slack`), so -459.67 degF is 0 K (not the 6e-14 K that float64 computes) and
#: fails "> 0 K", while 1e-300 K written in kelvin (no offset) is still above it.
ROUNDING = 1e-9


def rounding_slack(values, scale: float = 1.0, offset: float = 0.0) -> np.ndarray:
    """How far from a bound a converted value may lie and still count as on it (see :data:`ROUNDING`).

    Parameters
    ----------
    values : array_like
        The values as written, in the unit whose conversion is ``scale``, ``offset``.
    scale, offset : float
        The conversion to SI (:func:`conversion`).
    """
    return ROUNDING * (np.abs(scale * np.asarray(values, dtype=float)) + abs(offset))

def _unit_registry() -> pint.UnitRegistry:
    """pint's registry, its parsed definitions read from ``<cache>/pint`` when the cache is on.

    Parsing pint's definitions file took 125 of the 140 ms the registry cost at every start of
    bayesfric (a warm ``bayesfric fit`` is ~3 s); read back from pint's own disk cache
    (``cache_folder``) it takes ~13 ms. pint writes that cache non-atomically, so a file caught
    half-written by a process starting beside this one (the main job starts studies side by
    side) or left truncated by a killed one makes this parse afresh and drop the folder, ours.
    """
    from bayesfric.runtime import cache_dir

    folder = cache_dir()
    if folder is not None:
        try:
            return pint.UnitRegistry(autoconvert_offset_to_baseunit=True, cache_folder=folder / "pint")
        except Exception:  # noqa: BLE001 -- any unreadable cache entry: parse the definitions instead
            shutil.rmtree(folder / "pint", ignore_errors=True)
    return pint.UnitRegistry(autoconvert_offset_to_baseunit=True)


ureg = _unit_registry()
# Spellings engineers use in data sheets that pint does not know out of the box.
ureg.define("revolutions_per_minute_alias = revolution / minute = RPM")
ureg.define("inch_ounce = inch * force_ounce = in_oz = inoz")
ureg.define("newton_metre = newton * meter = Nm")


class UnitError(UserError):
    """A unit string that pint cannot parse, or a unit of the wrong dimension."""


@dataclass(frozen=True)
class Quantity:
    """One entry of the operating-quantity vocabulary.

    ``lower`` is the physical lower bound of a value in the canonical unit (``None``: a signed
    quantity, any finite value); ``lower_inclusive`` says whether the bound itself is allowed. The
    loader rejects data outside the bound, so each bound is declared here, once.
    """

    name: str
    unit: str  # canonical SI unit, pint syntax
    meaning: str
    lower: float | None = None
    lower_inclusive: bool = True

    def bound_text(self) -> str:
        """The bound as text, e.g. ``"> 0 K"``; empty for an unbounded quantity."""
        if self.lower is None:
            return ""
        return f"{'>=' if self.lower_inclusive else '>'} {self.lower:g} {self.unit}"

    def violations(self, values: np.ndarray, slack=0.0) -> np.ndarray:
        """Boolean mask of ``values`` (canonical unit) outside the physical bound.

        A value within ``slack`` (:func:`rounding_slack` of its conversion) of the bound counts as
        on it: allowed by an inclusive bound (``>= 0 N``), refused by an exclusive one (``> 0 K``).
        """
        values = np.asarray(values, dtype=float)
        if self.lower is None:
            return np.zeros(values.shape, dtype=bool)
        slack = np.asarray(slack, dtype=float)
        return values < self.lower - slack if self.lower_inclusive else values <= self.lower + slack


# Bounds: loads that the laws use as magnitudes (radial force of the drum's ball-load law,
# preload, axial force, a tribometer's normal force) are >= 0; absolute temperature > 0 K; time
# since the start of a trajectory >= 0. Signed by nature, so unbounded: velocities,
# accelerations, angles, displacements, the friction response (torque, force: its sign follows
# the direction of motion), initial_velocity (its sign is the coast-down direction) and
# bending_moment (a tilting moment has a direction; the bearing laws
# read |M| or solve the ball loads for either sign).
_VOCABULARY = [
    Quantity("velocity", "rad/s", "angular velocity of the moving part (joint, shaft, bearing ring)"),
    Quantity("linear_velocity", "m/s", "sliding velocity of a translational contact"),
    Quantity("bending_moment", "N*m", "tilting / blade-root bending moment on a bearing"),
    Quantity("axial_force", "N", "axial force on a bearing (magnitude)", lower=0.0),
    Quantity("radial_force", "N", "radial force on a bearing (magnitude)", lower=0.0),
    Quantity("preload", "N", "axial preload of a bearing pair (magnitude)", lower=0.0),
    Quantity("temperature", "K", "lubricant or housing temperature (absolute)", lower=0.0, lower_inclusive=False),
    Quantity("angle", "rad", "angular displacement (drive angle, ball position)"),
    Quantity("displacement", "m", "translational displacement"),
    Quantity("time", "s", "time since the start of a trajectory", lower=0.0),
    Quantity("initial_velocity", "rad/s", "angular velocity at t = 0 of a coast-down trajectory"),
    # drive dynamics: inertia terms read these (bayesfric.laws.terms); a sidecar may
    # derive them from velocity and time (bayesfric.datasets.derive)
    Quantity("acceleration", "rad/s**2", "angular acceleration of the moving part (joint, shaft)"),
    Quantity("linear_acceleration", "m/s**2", "acceleration of a translational axis (carriage, slider)"),
    Quantity("normal_force", "N", "normal load pressing a sliding contact together (tribometer)", lower=0.0),
    Quantity("torque", "N*m", "friction torque"),
    Quantity("force", "N", "friction force"),
]

QUANTITIES: dict[str, Quantity] = {q.name: q for q in _VOCABULARY}

#: Quantities a law may return as its response.
RESPONSES = ("torque", "force", "velocity")

#: Positions whose data scale is derived from a speed and ``time`` where a data set records those
#: and not the position (``position: speed``; :func:`bayesfric.datasets.views.data_scale`): a law
#: that reads the speed and time may scale a prior on a deflection by the position.
DERIVED_POSITIONS = {"angle": "velocity", "displacement": "linear_velocity"}


@lru_cache(maxsize=256)
def _parse(unit: str) -> pint.Unit:
    try:
        return ureg.parse_units(unit.replace("·", "*").replace("°", "deg"))
    except Exception as exc:  # pint raises several exception types
        raise UnitError(f"unknown unit {unit!r}") from exc


def check_unit(unit: str, quantity: str) -> pint.Unit:
    """Parse ``unit`` and check it has the dimension of ``quantity``'s canonical unit.

    Parameters
    ----------
    unit : str
        Unit string in pint syntax (``"rpm"``, ``"in*ozf"``, ``"degC"`` ...).
    quantity : str
        A name from :data:`QUANTITIES`.

    Returns
    -------
    pint.Unit
        The parsed unit.

    Raises
    ------
    UnitError
        If the unit is unknown or its dimension differs from the quantity's.
    """
    if quantity not in QUANTITIES:
        raise UnitError(f"unknown quantity {quantity!r}; known: {', '.join(QUANTITIES)}")
    parsed = _parse(unit)
    canonical = _parse(QUANTITIES[quantity].unit)
    if parsed.dimensionality != canonical.dimensionality:
        raise UnitError(
            f"unit {unit!r} has dimension {parsed.dimensionality}, but {quantity} needs "
            f"{canonical.dimensionality} (canonical unit {QUANTITIES[quantity].unit})"
        )
    return parsed


def parse_unit(unit: str) -> pint.Unit:
    """Parse any unit string (used to validate parameter units of law declarations)."""
    return _parse(unit)


def conversion(unit: str, quantity: str) -> tuple[float, float]:
    """Affine map ``si = scale * value + offset`` from ``unit`` to ``quantity``'s canonical unit.

    Offset units (°C, °F) are the only ones with a non-zero offset.
    """
    parsed = check_unit(unit, quantity)
    target = QUANTITIES[quantity].unit
    zero = ureg.Quantity(0.0, parsed).to(target).magnitude
    one = ureg.Quantity(1.0, parsed).to(target).magnitude
    return float(one - zero), float(zero)


def to_canonical(values, unit: str, quantity: str):
    """Convert an array of ``values`` in ``unit`` to the canonical SI unit of ``quantity``."""
    scale, offset = conversion(unit, quantity)
    return values * scale + offset
