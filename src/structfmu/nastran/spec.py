"""What an import is asked for: unit systems, piezo stacks, channels, their parsers.

Pure data and text parsing (no pyNastran): the CLI builds these from its options and
:func:`structfmu.nastran.import_nastran` takes them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from fmukit.units import INCH, LBF, MM
from piezofmu import preset
from structfmu.errors import ModelError

__all__ = ["UNIT_SYSTEMS", "UnitSystem", "unit_system", "Stack", "Actuator", "Point",
           "LineOfSight", "Channel", "NastranError", "NastranWarning", "parse_actuator",
           "parse_point", "parse_los"]

ACTUATOR_ELEMENTS = ("CROD", "CONROD", "CBAR", "CBEAM")
SENSOR_KINDS = ("disp", "accel")


class NastranError(ModelError):
    """A NASTRAN model cannot be imported (ids, units, sizes...)."""


class NastranWarning(UserWarning):
    """Something the user must know about an import (e.g. modes only, no Ritz vectors)."""


@dataclass(frozen=True)
class UnitSystem:
    """A consistent NASTRAN unit system (time in seconds).

    Parameters
    ----------
    name : str
        ``"SI"``, ``"in-lbf-s"`` or ``"mm-t-s"``.
    length : float
        One length unit in metres.
    force : float
        One force unit in newtons.
    """

    name: str
    length: float
    force: float

    @property
    def mass(self) -> float:
        """One mass unit (force unit s^2 / length unit) in kg."""
        return self.force / self.length

    @property
    def energy(self) -> float:
        """One energy unit (force unit x length unit) in J."""
        return self.force * self.length


UNIT_SYSTEMS = {u.name: u for u in (UnitSystem("SI", 1.0, 1.0),
                                    UnitSystem("in-lbf-s", INCH, LBF),
                                    UnitSystem("mm-t-s", MM, 1.0))}


def unit_system(units) -> UnitSystem:
    """The declared unit system (a name or a UnitSystem)."""
    if isinstance(units, UnitSystem):
        return units
    if units is None:
        raise NastranError("the unit system of the NASTRAN model is not declared; pass "
                           f"units= one of {', '.join(UNIT_SYSTEMS)} (CLI: --units)")
    if units not in UNIT_SYSTEMS:
        raise NastranError(f"unknown unit system {units!r}; expected one of "
                           f"{', '.join(UNIT_SYSTEMS)}")
    return UNIT_SYSTEMS[units]


# -- specifications --------------------------------------------------------------------

@dataclass(frozen=True)
class Stack:
    """The Eq. (1) properties of a piezo stack, SI.

    Parameters
    ----------
    name : str
        Datasheet name (``"P-845.37"``) or ``"custom"``.
    k_e : float
        Stiffness under voltage drive (N/m).
    ch : float
        Force per volt ``c h`` (N/V).
    mass : float
        Stack mass (kg).
    """

    name: str
    k_e: float
    ch: float
    mass: float

    def __post_init__(self):
        for attr in ("k_e", "ch", "mass"):
            v = getattr(self, attr)
            if not (np.isfinite(v) and v >= 0) or (attr != "mass" and v == 0):
                raise NastranError(f"piezo stack {self.name!r}: {attr} must be a positive "
                                   f"number, got {v!r}")

    @classmethod
    def preset(cls, name: str) -> "Stack":
        """A piezofmu datasheet preset (``"P-243.30"``, ``"P-243.40"``, ``"P-845.37"``)."""
        try:
            s = preset(name)
        except KeyError as exc:
            raise NastranError(exc.args[0]) from None
        return cls(s.name, s.k_e, s.ch, s.mass)


@dataclass(frozen=True)
class Actuator:
    """A member replaced by a piezo stack.

    Parameters
    ----------
    element : int
        Element id (CROD, CONROD, CBAR or CBEAM).
    stack : Stack
        Stack properties (SI).
    name : str, optional
        Channel name; default ``e<element>``.
    gauge : int, optional
        Element id of a strut in series carrying the strain gauge.
    """

    element: int
    stack: Stack
    name: str = ""
    gauge: int | None = None

    @property
    def label(self) -> str:
        return self.name or f"e{self.element}"


@dataclass(frozen=True)
class Point:
    """A sensor or load at one DOF: ``grid`` and ``component`` (1-6, 0 for a SPOINT).

    ``kind`` is ``"disp"`` or ``"accel"`` for sensors, ``"force"`` for loads (a moment
    on components 4-6).
    """

    name: str
    grid: int
    component: int
    kind: str = "disp"


@dataclass(frozen=True)
class LineOfSight:
    """Roll, pitch and yaw (rad, about basic x, y, z) of one grid or a rigid bench.

    One grid: its rotational DOFs.  Three or more grids: the least-squares rigid
    rotation of their translations (an optical bench), as
    :meth:`structfmu.fem.Truss.angle_channels`.  Outputs ``<name>_roll/_pitch/_yaw``.
    """

    name: str
    grids: tuple


@dataclass(frozen=True)
class Channel:
    """A general channel: weights on ``(grid, component)`` DOFs.

    Parameters
    ----------
    name : str
        Channel name.
    kind : str
        ``"force"``/``"torque"`` for an input, an output kind otherwise.
    terms : tuple of ((int, int), float)
        ``((grid, component), weight)`` pairs; components in the grid's CD frame, SI.
    """

    name: str
    kind: str
    terms: tuple


# -- CLI-style parsers -------------------------------------------------------------------

def parse_actuator(text: str, units) -> Actuator:
    """Parse an actuator: ``EID=PRESET[,name=N][,gauge=EID]``.

    Or ``EID=k_e=..,ch=..,mass=..[,name=N][,gauge=EID]``.

    Explicit ``k_e`` (force/length), ``ch`` (force/V) and ``mass`` are in the declared
    unit system and converted to SI.

    Parameters
    ----------
    text : str
        The specification, as given on the command line.
    units : str or UnitSystem
        Declared unit system of the NASTRAN files (``"SI"``, ``"in-lbf-s"``,
        ``"mm-t-s"``).

    Returns
    -------
    Actuator
        With the stack properties in SI (N/m, N/V, kg).
    """
    u = unit_system(units)
    eid, sep, rest = text.partition("=")
    if not sep or not rest:
        raise NastranError(f"actuator {text!r}: expected EID=PRESET or "
                           "EID=k_e=..,ch=..,mass=..")
    eid = to_int(eid, f"actuator {text!r}: element id")
    preset, opts = None, {}
    for item in rest.split(","):
        key, sep, value = item.partition("=")
        if not sep:
            if preset is not None:
                raise NastranError(f"actuator {text!r}: two stack names {preset!r} and "
                                   f"{item!r}")
            preset = item.strip()
            continue
        key = key.strip().lower()
        if key not in ("name", "gauge", "k_e", "ch", "mass"):
            raise NastranError(f"actuator {text!r}: unknown key {key!r}; expected name, "
                               "gauge, k_e, ch, mass")
        opts[key] = value.strip()
    explicit = {k for k in ("k_e", "ch", "mass") if k in opts}
    if preset is not None and explicit:
        raise NastranError(f"actuator {text!r}: give a stack preset or k_e, ch and mass, "
                           "not both")
    if preset is not None:
        stack = Stack.preset(preset)
    elif explicit == {"k_e", "ch", "mass"}:
        vals = {k: to_float(opts[k], f"actuator {text!r}: {k}") for k in explicit}
        stack = Stack("custom", vals["k_e"] * u.force / u.length, vals["ch"] * u.force,
                      vals["mass"] * u.mass)
    else:
        raise NastranError(f"actuator {text!r}: missing "
                           f"{', '.join(sorted({'k_e', 'ch', 'mass'} - explicit))}")
    gauge = to_int(opts["gauge"], f"actuator {text!r}: gauge") if "gauge" in opts else None
    name = opts.get("name", "")
    if name and not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        raise NastranError(f"actuator {text!r}: name {name!r} must be letters, digits, _")
    return Actuator(eid, stack, name, gauge)


def parse_point(text: str, kind: str = "disp") -> Point:
    """Parse a sensor or load ``NAME=GRID:COMP[:KIND]``.

    KIND is ``disp`` or ``accel`` (sensors only).

    Parameters
    ----------
    text : str
        The specification, as given on the command line.
    kind : str
        Kind used when ``text`` gives none (e.g. ``"force"`` for loads).

    Returns
    -------
    Point
    """
    name, sep, rest = text.partition("=")
    parts = rest.split(":")
    if not sep or len(parts) not in (2, 3) or not name:
        raise NastranError(f"{text!r}: expected NAME=GRID:COMP (e.g. acc_tip=1201:3)")
    grid = to_int(parts[0], f"{text!r}: grid id")
    comp = to_int(parts[1], f"{text!r}: component")
    if not 0 <= comp <= 6:
        raise NastranError(f"{text!r}: component {comp}; expected 1-6 (0 for a SPOINT)")
    if len(parts) == 3:
        kind = parts[2].strip()
        if kind not in SENSOR_KINDS:
            raise NastranError(f"{text!r}: kind {kind!r}; expected {' or '.join(SENSOR_KINDS)}")
    return Point(name.strip(), grid, comp, kind)


def parse_los(text: str) -> LineOfSight:
    """Parse a line of sight ``NAME=GRID`` or ``NAME=G1,G2,G3,...``."""
    name, sep, rest = text.partition("=")
    if not sep or not name or not rest:
        raise NastranError(f"line of sight {text!r}: expected NAME=GRID or NAME=G1,G2,G3")
    grids = tuple(to_int(g, f"line of sight {text!r}: grid id") for g in rest.split(","))
    if len(grids) == 2:
        raise NastranError(f"line of sight {text!r}: two grids do not define a rotation; "
                           "give one grid (its rotations) or three or more (a bench)")
    return LineOfSight(name.strip(), grids)


def to_int(text, what) -> int:
    """``text`` as an integer, or NastranError naming ``what``.

    Parameters
    ----------
    text : str or int
        The value.
    what : str
        What it is, for the message.
    """
    try:
        return int(str(text).strip())
    except ValueError:
        raise NastranError(f"{what} {text!r} is not an integer") from None


def to_float(text, what) -> float:
    """``text`` as a number, or NastranError naming ``what``.

    Parameters
    ----------
    text : str or float
        The value.
    what : str
        What it is, for the message.
    """
    try:
        return float(str(text).strip())
    except ValueError:
        raise NastranError(f"{what} {text!r} is not a number") from None

