"""Structure models from NASTRAN: BDF + OP4 matrices, or OP2 modes.

Pipeline (:func:`import_nastran`)::

    BDF (grids, coordinate systems, elements, SPCs)  --pyNastran-->  DOF map, geometry
    OP4 K, M (OUTPUT4 of KGG/MGG or KAA/MAA)         --pyNastran-->  sparse K, M
        -> declared units to SI -> piezo stacks replace members (Eq. 1)
        -> constrained and empty DOFs removed
        -> structfmu.reduce.reduce_matrices: eigenvectors + Gram-Schmidt Ritz (Eq. 3-8)
    or SOL 103 OP2 eigenvalues + eigenvectors -> modal model (no Ritz vectors: they need K)
    -> ReducedModel (the same object the built-in trusses give) -> structure FMU

Conventions
-----------
* Units: the BDF and the matrices are in one declared system (:data:`UNIT_SYSTEMS`:
  ``"SI"``, ``"in-lbf-s"``, ``"mm-t-s"``), converted to SI here; the rest of the suite
  is SI.  A model without a declared system is an error.
* DOFs: a matrix row is ``(grid, component)``, component 1-3 translations and 4-6
  rotations in the grid's displacement coordinate system (GRID field CD), 0 for a
  scalar point.  By default the matrices are the g-set (every grid x 6 and every
  SPOINT, sorted by id, as NASTRAN orders them); an a-set (KAA/MAA) needs its DOF map.
* Constraints: DOFs of SPC/SPC1 cards (all sets) and GRID PS fields are removed, and so
  are DOFs whose stiffness and mass rows are both empty (the rotations of a rod-only
  grid: what NASTRAN's AUTOSPC removes).
* Actuators: an axial member (CROD, CONROD, CBAR, CBEAM) becomes the piezo stack of Eq.
  (1): its axial stiffness ``E A / L`` is replaced by the stack's ``k_e`` and its mass by
  the stack's mass (lumped, or coupled when the BDF has PARAM,COUPMASS,1), on the
  translations of its end grids (bending and torsion of bars and beams are kept).  The
  input ``fc_<name>`` (N) pushes the end grids apart along the member; the outputs
  ``elong_<name>`` (m) and ``strain_<name>`` (1, on the gauge element if one is given,
  else on the stack) read it.
"""

from __future__ import annotations

import difflib
import re
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from fmukit.units import INCH, LBF, MM
from piezofmu import preset
from structfmu.errors import DimensionError, ModelError, ReductionError
from structfmu.fem import assemble
from structfmu.reduce import Damping, reduce_matrices, reduced_from_basis
from structfmu.reduced import ReducedModel

__all__ = ["UNIT_SYSTEMS", "UnitSystem", "Stack", "Actuator", "Point", "LineOfSight",
           "Channel", "NastranError", "NastranWarning", "import_nastran",
           "parse_actuator", "parse_point", "parse_los", "write_truss_deck", "read_deck"]

ACTUATOR_ELEMENTS = ("CROD", "CONROD", "CBAR", "CBEAM")
BIGMAT_ROWS = 65535  # larger OP4 matrices need the BIGMAT layout
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
    eid = _int(eid, f"actuator {text!r}: element id")
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
        vals = {k: _float(opts[k], f"actuator {text!r}: {k}") for k in explicit}
        stack = Stack("custom", vals["k_e"] * u.force / u.length, vals["ch"] * u.force,
                      vals["mass"] * u.mass)
    else:
        raise NastranError(f"actuator {text!r}: missing "
                           f"{', '.join(sorted({'k_e', 'ch', 'mass'} - explicit))}")
    gauge = _int(opts["gauge"], f"actuator {text!r}: gauge") if "gauge" in opts else None
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
    grid = _int(parts[0], f"{text!r}: grid id")
    comp = _int(parts[1], f"{text!r}: component")
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
    grids = tuple(_int(g, f"line of sight {text!r}: grid id") for g in rest.split(","))
    if len(grids) == 2:
        raise NastranError(f"line of sight {text!r}: two grids do not define a rotation; "
                           "give one grid (its rotations) or three or more (a bench)")
    return LineOfSight(name.strip(), grids)


def _int(text, what) -> int:
    try:
        return int(str(text).strip())
    except ValueError:
        raise NastranError(f"{what} {text!r} is not an integer") from None


def _float(text, what) -> float:
    try:
        return float(str(text).strip())
    except ValueError:
        raise NastranError(f"{what} {text!r} is not a number") from None


# -- pyNastran --------------------------------------------------------------------------

def _pynastran():
    """pyNastran's BDF, OP2 and OP4 readers.

    pyNastran 1.4.1 binds ``numpy.in1d`` at import, which numpy 2.4 removed; the
    equivalent ``numpy.isin`` is lent for the import only.
    """
    lent = not hasattr(np, "in1d")
    if lent:
        np.in1d = np.isin
    try:
        # deferred: optional dependency (the nastran extra)
        from pyNastran.bdf.bdf import BDF
        from pyNastran.op2.op2 import OP2
        from pyNastran.op4.op4 import OP4
    except ImportError as exc:  # pragma: no cover - dependency missing
        raise ImportError(f"reading NASTRAN files needs pyNastran ({exc}); run "
                          "'make setup'") from None
    finally:
        if lent:
            del np.in1d
    return BDF, OP2, OP4


@dataclass(frozen=True)
class Deck:
    """What the importer needs from a BDF, in SI.

    Parameters
    ----------
    grids : dict of int to ndarray, shape (3,)
        Grid positions in the basic system (m).
    cd : dict of int to ndarray, shape (3, 3)
        ``T`` with ``u_basic = T u_cd`` for each grid's displacement frame.
    spoints : tuple of int
        Scalar point ids.
    elements : dict of int to (str, (int, int), float, float)
        Axial members: type, end grids, axial stiffness ``E A / L`` (N/m), mass (kg).
    element_types : dict of int to str
        Type of every element (for error messages).
    constrained : set of (int, int)
        SPC'd DOFs.
    coupled_mass : bool
        PARAM,COUPMASS > 0.
    path : str
        The BDF (for messages).
    offset_or_pinned : set of int
        CBAR/CBEAM ids with end offsets or pin flags (they cannot carry a stack here).
    """

    grids: dict
    cd: dict
    spoints: tuple
    elements: dict
    element_types: dict
    constrained: frozenset
    coupled_mass: bool
    path: str = ""
    offset_or_pinned: frozenset = frozenset()

    def position(self, grid: int) -> np.ndarray:
        self.check_grid(grid)
        return self.grids[grid]

    def check_grid(self, grid: int, what: str = "") -> None:
        """Raise NastranError naming ``what`` when ``grid`` is not a GRID or SPOINT.

        Parameters
        ----------
        grid : int
            GRID or SPOINT id.
        what : str
            Prefix of the error message naming what refers to the grid.
        """
        if grid not in self.grids and grid not in self.spoints:
            close = difflib.get_close_matches(str(grid), [str(g) for g in self.grids], 3)
            hint = f"; close ids: {', '.join(close)}" if close else ""
            raise NastranError(f"{what}grid {grid} is not in {self.path}{hint}")

    def element(self, eid: int, what: str = "element"):
        """The axial member ``eid``, checked to carry a piezo stack.

        Raises NastranError (naming ``what``) when it is missing, not an axial member, or
        a CBAR/CBEAM with end offsets or pin flags.

        Parameters
        ----------
        eid : int
            Element id.
        what : str
            What the element is, for the error message.

        Returns
        -------
        (str, (int, int), float, float)
            Element type, end grids, axial stiffness ``E A / L`` (N/m) and mass (kg).
        """
        if eid not in self.element_types:
            raise NastranError(f"{what} {eid} is not in {self.path}")
        kind = self.element_types[eid]
        if kind not in ACTUATOR_ELEMENTS:
            raise NastranError(f"{what} {eid} is a {kind}, which cannot carry a piezo stack; "
                               f"expected an axial member ({', '.join(ACTUATOR_ELEMENTS)})")
        if eid in self.offset_or_pinned:
            raise NastranError(f"{what} {eid} is a {kind} with end offsets or pin flags, which "
                               "this import does not carry a stack on; use a member between "
                               "its grids (CROD, CONROD, or a CBAR/CBEAM without offsets)")
        return self.elements[eid]


def read_deck(bdf_path, units) -> Deck:
    """Read the geometry, axial members and SPCs of a BDF (SI units).

    Parameters
    ----------
    bdf_path : path-like
        The BDF (bulk data, with or without executive and case control).
    units : str or UnitSystem
        The declared unit system.
    """
    u = unit_system(units)
    BDF, _, _ = _pynastran()
    path = Path(bdf_path)
    if not path.is_file():
        raise NastranError(f"BDF file {str(path)!r} does not exist")
    model = BDF(debug=None)
    try:
        model.read_bdf(str(path), xref=True, punch=_is_punch(path))
    except Exception as exc:  # pyNastran raises many kinds; one sentence here
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise NastranError(f"cannot read BDF {str(path)!r}: {first}") from None
    grids, cd = {}, {}
    for nid, g in model.nodes.items():
        grids[nid] = np.asarray(g.get_position(), float) * u.length
        cid = g.Cd()
        if cid:
            coord = model.coords[cid]
            if coord.type not in ("CORD1R", "CORD2R"):
                raise NastranError(f"grid {nid}: displacement coordinate system {cid} is a "
                                   f"{coord.type}; only rectangular systems (CORD1R, CORD2R) "
                                   "are supported")
            cd[nid] = np.asarray(coord.beta(), float).T
    spoints = tuple(sorted(getattr(model, "spoints", {}) or {}))
    elements, types, shaped = {}, {}, set()
    for eid, e in model.elements.items():
        types[eid] = e.type
        if e.type in ACTUATOR_ELEMENTS:
            n1, n2 = e.node_ids[:2]
            length = np.linalg.norm(grids[n2] - grids[n1])
            mat = e.mid_ref if e.type == "CONROD" else e.pid_ref.mid_ref
            if getattr(mat, "e", None) is None:
                types[eid] = f"{e.type} without a Young's modulus (material {mat.mid})"
                continue
            area = e.Area() * u.length**2
            young = mat.e * u.force / u.length**2
            mass = float(e.Mass()) * u.mass
            k_axial = young * area / length if length > 0 else np.nan
            elements[eid] = (e.type, (int(n1), int(n2)), k_axial, mass)
            if e.type in ("CBAR", "CBEAM") and (np.any(np.asarray(e.wa, float) != 0)
                                                or np.any(np.asarray(e.wb, float) != 0)
                                                or str(e.pa or 0) != "0"
                                                or str(e.pb or 0) != "0"):
                shaped.add(eid)
    for eid, e in getattr(model, "masses", {}).items():
        types.setdefault(eid, e.type)
    constrained = set()
    for nid, g in model.nodes.items():
        for c in str(g.ps or ""):
            if c.isdigit() and c != "0":
                constrained.add((nid, int(c)))
    for cards in model.spcs.values():
        for card in cards:
            if card.type == "SPC1":
                for nid in card.node_ids:
                    for c in str(card.components):
                        constrained.add((int(nid), int(c) if nid in grids else 0))
            elif card.type == "SPC":
                for nid, comps in zip(card.node_ids, card.components):
                    for c in str(comps):
                        constrained.add((int(nid), int(c) if nid in grids else 0))
    coupmass = model.params.get("COUPMASS")
    coupled = bool(coupmass is not None and int(coupmass.values[0]) > 0)
    return Deck(grids, cd, spoints, elements, types, frozenset(constrained), coupled, str(path),
                frozenset(shaped))


def _is_punch(path: Path) -> bool:
    """True when the file has no BEGIN BULK (a bulk-data-only deck)."""
    with open(path, errors="replace") as f:
        return not any(line.upper().lstrip().startswith("BEGIN") for line in f)


def _gset(deck: Deck) -> list:
    """The g-set DOF map: grids x 6 and SPOINTs, sorted by id."""
    ids = sorted([(g, 6) for g in deck.grids] + [(s, 1) for s in deck.spoints])
    return [(i, c) for i, n in ids for c in (range(1, 7) if n == 6 else (0,))]


def read_dof_map(path) -> list:
    """A DOF map file: one ``ID COMPONENT`` pair per matrix row (``#`` comments)."""
    rows = []
    for k, line in enumerate(Path(path).read_text().splitlines(), start=1):
        line = line.split("#")[0].replace(",", " ").split()
        if not line:
            continue
        if len(line) != 2:
            raise NastranError(f"DOF map {str(path)!r} line {k}: expected 'ID COMPONENT'")
        rows.append((_int(line[0], f"DOF map line {k}: id"),
                     _int(line[1], f"DOF map line {k}: component")))
    return rows


def _dof_scale(dofs, u: UnitSystem) -> np.ndarray:
    """Length unit in m for translations (and SPOINTs), 1 for rotations (rad)."""
    return np.array([1.0 if 4 <= c <= 6 else u.length for _, c in dofs])


def read_matrices(op4_path, dofs, units, k_name=None, m_name=None):
    """Stiffness and mass from an OP4, in SI, on the given DOF map.

    Parameters
    ----------
    op4_path : path-like
        The OP4 file.
    dofs : list of (int, int), length n
        ``(grid, component)`` of each matrix row (:func:`read_dof_map`).
    units : str or UnitSystem
        Declared unit system of the NASTRAN files (``"SI"``, ``"in-lbf-s"``,
        ``"mm-t-s"``).
    k_name, m_name : str, optional
        Names of the stiffness and mass matrices in the file; default the only matrix
        whose name starts with ``K`` (``M``).

    Returns
    -------
    K, M : scipy.sparse.csc_matrix, shape (n, n)
        ``n = len(dofs)``; N/m, N m/rad, kg, kg m^2 on the matching DOFs.
    """
    u = unit_system(units)
    _, _, OP4 = _pynastran()
    path = Path(op4_path)
    if not path.is_file():
        raise NastranError(f"OP4 file {str(path)!r} does not exist")
    try:
        mats = OP4(debug=None).read_op4(str(path))
    except Exception as exc:
        raise NastranError(f"cannot read OP4 {str(path)!r}: {exc}") from None
    names = list(mats)
    k_name = k_name or _pick(names, "K", path)
    m_name = m_name or _pick(names, "M", path)
    out = []
    for label, name in (("stiffness", k_name), ("mass", m_name)):
        if name not in mats:
            raise NastranError(f"OP4 {str(path)!r} has no matrix {name!r}; it has "
                               f"{', '.join(names)}")
        data = mats[name].data
        A = sp.csc_matrix(data) if sp.issparse(data) else sp.csc_matrix(np.asarray(data))
        if np.iscomplexobj(A.data):
            raise NastranError(f"{label} matrix {name} in {str(path)!r} is complex")
        if A.shape[0] != A.shape[1]:
            raise DimensionError(f"{label} matrix {name} has shape {A.shape}; expected a "
                                 "square matrix")
        if A.shape[0] != len(dofs):
            raise DimensionError(f"{label} matrix {name} has {A.shape[0]} rows but the DOF "
                                 f"map has {len(dofs)} entries; give the DOF map of the "
                                 "matrices (a-set: dof_map / --dof-map)")
        out.append(A.astype(float))
    s = 1.0 / _dof_scale(dofs, u)
    S = sp.diags(s)
    K = (S @ out[0] @ S) * u.energy
    M = (S @ out[1] @ S) * u.energy
    return K.tocsc(), M.tocsc()


def _pick(names, letter, path):
    cand = [n for n in names if n.upper().startswith(letter)]
    if len(cand) != 1:
        what = "stiffness" if letter == "K" else "mass"
        raise NastranError(f"OP4 {str(path)!r} has matrices {', '.join(names)}; name the "
                           f"{what} matrix (k_name/m_name, CLI --k-name/--m-name)")
    return cand[0]


# -- the import ----------------------------------------------------------------------------

@dataclass
class _Rows:
    """Sparse rows over the DOF map, built from (grid, component) weights.

    Terms on ``removed`` DOFs (constrained, or empty in K and M) are dropped: those DOFs
    do not move.  A term on a DOF outside the map, or a row with every term dropped, is
    an error.
    """

    index: dict
    removed: frozenset = frozenset()
    rows: list = field(default_factory=list)

    def add(self, terms, what: str) -> None:
        cols, vals = [], []
        for (g, c), w in terms:
            if (g, c) in self.removed:
                continue
            if (g, c) not in self.index:
                raise NastranError(f"{what}: grid {g} component {c} is not in the DOF map "
                                   "of the matrices")
            cols.append(self.index[(g, c)])
            vals.append(float(w))
        if terms and not cols:
            raise NastranError(f"{what}: every DOF it uses is constrained or has neither "
                               "stiffness nor mass (a grid of rods only has no rotations: "
                               "read a line of sight from three grids instead)")
        self.rows.append((cols, vals))

    def matrix(self) -> sp.csr_matrix:
        r = [np.full(len(c), i) for i, (c, _) in enumerate(self.rows)]
        if not self.rows:
            return sp.csr_matrix((0, len(self.index)))
        return sp.csr_matrix((np.concatenate([v for _, v in self.rows]),
                              (np.concatenate(r), np.concatenate([c for c, _ in self.rows]))),
                             shape=(len(self.rows), len(self.index)))


def _translation_terms(deck: Deck, grid: int, vector) -> list:
    """Weights on a grid's CD translations of the basic vector ``vector``."""
    T = deck.cd.get(grid)
    w = np.asarray(vector, float) if T is None else T.T @ np.asarray(vector, float)
    return [((grid, c + 1), w[c]) for c in range(3) if w[c] != 0.0]


def _rotation_terms(deck: Deck, grid: int, axis: int) -> list:
    """Weights on a grid's CD rotations of the basic rotation about ``axis``."""
    T = deck.cd.get(grid)
    w = np.eye(3)[axis] if T is None else T[axis]
    return [((grid, c + 4), w[c]) for c in range(3) if w[c] != 0.0]


def _member(deck: Deck, eid: int, what: str):
    kind, (n1, n2), k_el, m_el = deck.element(eid, what)
    d = deck.position(n2) - deck.position(n1)
    length = float(np.linalg.norm(d))
    if length == 0:
        raise NastranError(f"{what} {eid} has zero length")
    e = d / length
    terms = _translation_terms(deck, n1, -e) + _translation_terms(deck, n2, e)
    return terms, length, k_el, m_el, (n1, n2), e


def _actuator_update(deck: Deck, act: Actuator, index: dict, n: int):
    """Stiffness and mass changes that make the member the stack (sparse, SI).

    DOFs constrained by SPCs may be absent from the DOF map (an a-set): they do not move,
    so their share of the change is dropped.
    """
    terms, length, k_el, m_el, (n1, n2), e = _member(deck, act.element, "actuator element")
    rows = _Rows(index, deck.constrained)
    rows.add(terms, f"actuator element {act.element}")
    w = rows.matrix()
    dK = (act.stack.k_e - k_el) * (w.T @ w)
    dm = act.stack.mass - m_el
    if deck.coupled_mass:
        blocks = [(n1, n1, dm / 3.0), (n2, n2, dm / 3.0), (n1, n2, dm / 6.0),
                  (n2, n1, dm / 6.0)]
    else:
        blocks = [(n1, n1, dm / 2.0), (n2, n2, dm / 2.0)]
    r, c, v = [], [], []
    for ga, gb, m in blocks:
        B = m * (deck.cd.get(ga, np.eye(3)).T @ deck.cd.get(gb, np.eye(3)))
        for i in range(3):
            for j in range(3):
                a, b = (ga, i + 1), (gb, j + 1)
                if B[i, j] == 0.0 or a not in index or b not in index:
                    continue  # constrained (checked by rows.add above)
                r.append(index[a])
                c.append(index[b])
                v.append(B[i, j])
    dM = sp.csc_matrix((v, (r, c)), shape=(n, n))
    return dK.tocsc(), dM


def import_nastran(bdf, *, units, op4=None, op2=None, n_modes: int, actuators=(),
                   sensors=(), loads=(), los=(), inputs=(), outputs=(), ritz=None,
                   shift=None, damping: Damping | None = None, zeta_bands=(),
                   dof_map=None, k_name=None, m_name=None, name=None) -> ReducedModel:
    """Reduced model from a NASTRAN BDF + OP4 (or SOL 103 OP2).

    Parameters
    ----------
    bdf : path-like
        The BDF: grids, coordinate systems, elements, SPCs.
    units : {"SI", "in-lbf-s", "mm-t-s"} or UnitSystem
        Unit system of the BDF, the OP4 and the explicit stack values (required).
    op4 : path-like, optional
        Stiffness and mass (OUTPUT4 of KGG/MGG, or KAA/MAA with ``dof_map``).
    op2 : path-like, optional
        SOL 103 results (eigenvalues, mass-normalised eigenvectors) instead of ``op4``:
        a modal model without Ritz vectors.
    n_modes : int
        Number of eigenvectors (rigid-body modes included).
    actuators : sequence of Actuator
        Members replaced by piezo stacks; input ``fc_<name>`` (N), outputs
        ``elong_<name>`` (m) and ``strain_<name>`` (1).
    sensors : sequence of Point
        Outputs at one DOF each, kind ``"disp"`` (m or rad) or ``"accel"`` (m/s^2, rad/s^2).
    loads : sequence of Point
        Inputs at one DOF each: force (N) on components 1-3, moment (N m) on 4-6.
    los : sequence of LineOfSight
        Outputs ``<name>_roll/_pitch/_yaw`` (rad).
    inputs, outputs : sequence of Channel
        General channels (weights on DOFs), appended after the above.
    ritz : {"all", "actuators", "none"} or sequence of str, optional
        Static Ritz vectors for actuators and loads (``"all"``, the default with an OP4),
        for actuators only, none (the only choice, and the default, with an OP2), or for
        the named inputs.
    shift : float, optional
        Shift-invert shift ((rad/s)^2); negative for a free-free model (rigid-body modes).
    damping : Damping, optional
        Modal damping (``zeta`` scalar or per mode), ``zeta_ritz``, ``alpha``, ``beta``.
    zeta_bands : sequence of (f_lo, f_hi, zeta)
        Modal damping ratio for the modes with ``f_lo <= f < f_hi`` (Hz), applied after
        ``damping`` (later bands win).
    dof_map : path-like or sequence of (int, int), optional
        ``(id, component)`` of each matrix row; default the g-set of the BDF.
    k_name, m_name : str, optional
        OP4 matrix names (default: the one name starting with K, resp. M).
    name : str, optional
        Model name (default the BDF's file stem).

    Returns
    -------
    ReducedModel
    """
    u = unit_system(units)
    if op2 is not None and ritz is not None and (ritz != "none" if isinstance(ritz, str)
                                                 else list(ritz)):
        raise NastranError("static Ritz vectors need the stiffness matrix; the OP2 gives "
                           "modes only: give --op4 with K and M, or ritz='none'")
    if (op4 is None) == (op2 is None):
        raise NastranError("give the matrices (op4, --op4) or the SOL 103 modes (op2, --op2), "
                           "exactly one of them")
    if isinstance(ritz, str) and ritz not in ("all", "actuators", "none"):
        raise NastranError(f"ritz={ritz!r}; expected 'all', 'actuators', 'none' or a list "
                           "of input names")
    deck = read_deck(bdf, u)
    name = name or Path(bdf).stem
    acts = list(actuators)
    labels = [a.label for a in acts]
    if len(set(labels)) != len(labels):
        dup = sorted({x for x in labels if labels.count(x) > 1})
        raise NastranError(f"duplicate actuator names {dup}")
    for a in acts:
        deck.element(a.element, "actuator element")
        if a.gauge is not None:
            deck.element(a.gauge, f"gauge element of actuator {a.label!r}:")
    for p in (*sensors, *loads):
        deck.check_grid(p.grid, f"{p.name!r}: ")
    for line in los:
        for g in line.grids:
            deck.check_grid(g, f"line of sight {line.name!r}: ")

    if op4 is not None:
        dofs = _dof_list(dof_map, deck)
        K, M = read_matrices(op4, dofs, u, k_name, m_name)
        index = {d: i for i, d in enumerate(dofs)}
        for a in acts:
            dK, dM = _actuator_update(deck, a, index, len(dofs))
            K, M = K + dK, M + dM
        keep = _kept(K, M, dofs, deck)
        removed = (frozenset(dofs) - frozenset(dofs[i] for i in keep)) | deck.constrained
        dofs = [dofs[i] for i in keep]
        K, M = K[keep][:, keep].tocsc(), M[keep][:, keep].tocsc()
        _check_massless(K, M, dofs)
    else:
        lam, phi, dofs = read_modes(op2, u, n_modes)
        removed = frozenset((g, c) for g, c in deck.constrained)
    index = {d: i for i, d in enumerate(dofs)}

    E_rows, in_names, in_units = _Rows(index, removed), [], []
    H_rows, out_names, out_kinds = _Rows(index, removed), [], []
    for p in loads:
        if p.kind != "force":
            raise NastranError(f"load {p.name!r}: a load is a force or moment at a DOF "
                               f"(NAME=GRID:COMP), not {p.kind!r}")
        kind = "torque" if 4 <= p.component <= 6 else "force"
        E_rows.add([((p.grid, p.component), 1.0)], f"load {p.name!r}")
        in_names.append(p.name)
        in_units.append("N.m" if kind == "torque" else "N")
    for c in inputs:
        E_rows.add(c.terms, f"input {c.name!r}")
        in_names.append(c.name)
        in_units.append("N.m" if c.kind == "torque" else "N")
    for a in acts:
        terms = _member(deck, a.element, "actuator element")[0]
        E_rows.add(terms, f"actuator {a.label!r}")
        in_names.append(f"fc_{a.label}")
        in_units.append("N")
    for a in acts:
        terms, length = _member(deck, a.element, "actuator element")[:2]
        if a.gauge is not None:
            terms, length = _member(deck, a.gauge, f"gauge element of {a.label!r}")[:2]
        H_rows.add([(d, w / length) for d, w in terms], f"strain of {a.label!r}")
        out_names.append(f"strain_{a.label}")
        out_kinds.append("strain")
    for a in acts:
        H_rows.add(_member(deck, a.element, "actuator element")[0], f"elong of {a.label!r}")
        out_names.append(f"elong_{a.label}")
        out_kinds.append("elong")
    for p in sensors:
        if p.kind not in SENSOR_KINDS:
            raise NastranError(f"sensor {p.name!r}: kind {p.kind!r}; expected "
                               f"{' or '.join(SENSOR_KINDS)}")
        H_rows.add([((p.grid, p.component), 1.0)], f"sensor {p.name!r}")
        out_names.append(p.name)
        out_kinds.append(p.kind)
    for line in los:
        for axis, rows in enumerate(_los_terms(deck, line)):
            H_rows.add(rows, f"line of sight {line.name!r}")
            out_names.append(f"{line.name}_{('roll', 'pitch', 'yaw')[axis]}")
            out_kinds.append("angle")
    for c in outputs:
        H_rows.add(c.terms, f"output {c.name!r}")
        out_names.append(c.name)
        out_kinds.append(c.kind)
    for group, what in ((in_names, "input"), (out_names, "output")):
        dup = sorted({x for x in group if group.count(x) > 1})
        if dup:
            raise NastranError(f"duplicate {what} names {dup}")
    E = E_rows.matrix().T.tocsc()
    H = H_rows.matrix()

    meta = {"model": name, "source": {"bdf": Path(bdf).name,
                                      "op4": Path(op4).name if op4 else None,
                                      "op2": Path(op2).name if op2 else None},
            "units": u.name, "n_dof": len(dofs), "input_units": in_units,
            "actuators": {a.label: {"stack": a.stack.name, "ch": float(a.stack.ch),
                                    "element": int(a.element)} for a in acts}}
    damping = damping or Damping()
    if op4 is not None:
        ritz = "all" if ritz is None else ritz
        if not isinstance(ritz, str):
            sel = list(ritz)
        else:
            sel = [] if ritz == "none" else [f"fc_{a.label}" for a in acts]
            if ritz == "all":
                sel = [n for n in in_names if n not in sel] + sel
        try:
            model = reduce_matrices(K, M, E, H, n_modes, input_names=in_names,
                                    output_names=out_names, output_kinds=out_kinds,
                                    ritz_inputs=sel, shift=shift, damping=damping, name=name,
                                    meta=meta)
        except ReductionError as exc:
            if "singular" in str(exc) and not shift and "Ritz" not in str(exc):
                raise NastranError(f"the stiffness matrix of {name!r} is singular (rigid-body "
                                   "modes or a mechanism): give a negative shift for a "
                                   "free-free model (shift=-1.0, CLI --shift -1.0) or "
                                   "constrain it with SPC cards") from None
            raise
    else:
        warnings.warn(f"{name}: modes only (SOL 103 OP2): no static Ritz vectors, which need "
                      "the stiffness matrix (give an OP4 with K and M); the local response at "
                      "actuators and loads is that of the retained modes", NastranWarning,
                      stacklevel=2)
        if acts:
            warnings.warn(f"{name}: with modes only the stacks cannot replace the members' "
                          "stiffness and mass; the modes must already contain them",
                          NastranWarning, stacklevel=2)
        model = reduced_from_basis(lam, phi, np.zeros((len(dofs), 0)), None, E, H,
                                   input_names=in_names, output_names=out_names,
                                   output_kinds=out_kinds, damping=damping, name=name,
                                   meta={**meta, "n_modes": int(len(lam)), "shift": None})
    if zeta_bands:
        model = _band_damping(model, damping, zeta_bands)
    return model


def _band_damping(model: ReducedModel, damping: Damping, bands) -> ReducedModel:
    f = model.frequencies_hz
    zeta = np.array(np.broadcast_to(np.asarray(damping.zeta, float), f.shape))
    for lo, hi, z in bands:
        if not (0 <= z < 1) or hi <= lo:
            raise NastranError(f"damping band {lo}-{hi} Hz = {z}: expected f_lo < f_hi and "
                               "0 <= zeta < 1")
        zeta[(f >= lo) & (f < hi)] = z
    lam = model.omega**2
    c_e = 2 * zeta * model.omega + damping.alpha + damping.beta * lam
    meta = {**model.meta, "damping": {**model.meta["damping"], "zeta": zeta.tolist(),
                                      "bands": [list(map(float, b)) for b in bands]}}
    return replace(model, modal_damping=c_e, meta=meta)


def _dof_list(dof_map, deck: Deck) -> list:
    if dof_map is None:
        return _gset(deck)
    dofs = read_dof_map(dof_map) if isinstance(dof_map, (str, Path)) else \
        [(int(i), int(c)) for i, c in dof_map]
    for g, c in dofs:
        deck.check_grid(g, "DOF map: ")
        if not 0 <= c <= 6:
            raise NastranError(f"DOF map: grid {g} component {c}; expected 1-6 (0: SPOINT)")
    if len(set(dofs)) != len(dofs):
        raise NastranError("DOF map: a (grid, component) pair appears twice")
    return dofs


def _kept(K, M, dofs, deck: Deck) -> np.ndarray:
    """Indices of DOFs neither constrained nor empty in both K and M."""
    has = (np.asarray(abs(K).sum(axis=0)).ravel() + np.asarray(abs(M).sum(axis=0)).ravel()) > 0
    free = np.array([d not in deck.constrained for d in dofs], bool)
    return np.flatnonzero(has & free)


def _check_massless(K, M, dofs) -> None:
    d = M.diagonal()
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        g, c = dofs[bad[0]]
        raise NastranError(f"grid {g} component {c} has stiffness but no mass ({bad.size} such "
                           "DOFs); add mass there (e.g. CONM2 inertia, PARAM,COUPMASS) or "
                           "condense the massless DOFs in NASTRAN (OMIT/ASET) before OUTPUT4")


def _los_terms(deck: Deck, line: LineOfSight) -> list:
    if len(line.grids) == 1:
        g = line.grids[0]
        return [_rotation_terms(deck, g, axis) for axis in range(3)]
    xyz = np.array([deck.position(g) for g in line.grids])
    r = xyz - xyz.mean(axis=0)
    G = np.vstack([np.hstack([np.eye(3), -np.array([[0, -ri[2], ri[1]], [ri[2], 0, -ri[0]],
                                                    [-ri[1], ri[0], 0]])]) for ri in r])
    if np.linalg.matrix_rank(G) < 6:
        raise NastranError(f"line of sight {line.name!r}: the grids are collinear; a bench "
                           "needs three non-collinear grids")
    P = np.linalg.pinv(G)[3:]
    out = []
    for axis in range(3):
        terms = []
        for k, g in enumerate(line.grids):
            terms += _translation_terms(deck, g, P[axis, 3 * k:3 * k + 3])
        out.append(terms)
    return out


def read_modes(op2_path, units, n_modes: int):
    """Eigenvalues and eigenvectors (SI) from a SOL 103 OP2.

    Parameters
    ----------
    op2_path : path-like
        The OP2 file.
    units : str or UnitSystem
        Declared unit system of the NASTRAN files (``"SI"``, ``"in-lbf-s"``,
        ``"mm-t-s"``).
    n_modes : int
        Number of modes to read (the lowest in the file).

    Returns
    -------
    lam : ndarray, shape (n_modes,)
        ``omega^2`` ((rad/s)^2), rigid-body ones (below 1e-6 (rad/s)^2) set to 0.
    phi : ndarray, shape (n_dof, n_modes)
        Eigenvectors on ``dofs``, mass-normalised in SI.
    dofs : list of (int, int)
        ``(grid, component)`` of each row.
    """
    u = unit_system(units)
    _, OP2, _ = _pynastran()
    path = Path(op2_path)
    if not path.is_file():
        raise NastranError(f"OP2 file {str(path)!r} does not exist")
    op2 = OP2(debug=None)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # np.chararray in pyNastran
            op2.read_op2(str(path))
    except Exception as exc:
        raise NastranError(f"cannot read OP2 {str(path)!r}: {exc}") from None
    if not op2.eigenvectors:
        raise NastranError(f"OP2 {str(path)!r} has no eigenvectors; expected SOL 103 results")
    vec = op2.eigenvectors[sorted(op2.eigenvectors)[0]]
    data = np.asarray(vec.data, float)  # (n_modes, n_nodes, 6)
    if data.shape[0] < n_modes:
        raise NastranError(f"{n_modes} modes requested but OP2 {str(path)!r} has "
                           f"{data.shape[0]}")
    nodes = vec.node_gridtype[:, 0]
    gtype = vec.node_gridtype[:, 1]
    dofs = [(int(n), c if t == 1 else 0) for n, t in zip(nodes, gtype)
            for c in (range(1, 7) if t == 1 else (1,))]
    cols = [(k, c) for k, t in enumerate(gtype) for c in (range(6) if t == 1 else (0,))]
    phi = np.array([data[:n_modes, k, c] for k, c in cols])  # (n_dof, n_modes)
    if op2.eigenvalues:
        eig = op2.eigenvalues[sorted(op2.eigenvalues)[0]]
        lam = np.asarray(eig.eigenvalues[:n_modes], float)
        gm = np.asarray(eig.generalized_mass[:n_modes], float)
    else:  # no LAMA table: the eigenvalues the eigenvector table carries
        lam = np.asarray(vec.eigns[:n_modes], float)
        gm = np.ones(n_modes)
    phi = phi / np.sqrt(np.where(gm > 0, gm, 1.0))
    phi = phi * _dof_scale(dofs, u)[:, None] / np.sqrt(u.energy)
    lam = np.where(np.abs(lam) < 1e-6, 0.0, lam)
    if np.any(lam < 0):
        raise NastranError(f"OP2 {str(path)!r}: negative eigenvalue {lam.min():.3g}")
    return lam, phi, dofs


# -- writing a deck (test data, benchmarks, exporting built-in models) -------------------

def write_modes_op2(op2_path, lam, phi, grids, units="SI"):
    """Write eigenvalues and eigenvectors as a SOL 103-style OP2.

    pyNastran 1.4.1 writes the eigenvector table (single precision) but skips the LAMA
    eigenvalue table; the eigenvalues travel in the eigenvector table's header (single
    precision too), which :func:`read_modes` reads when LAMA is absent.

    Parameters
    ----------
    op2_path : path-like
        File to write.
    lam : ndarray, shape (n_modes,)
        Eigenvalues ((rad/s)^2).
    phi : ndarray, shape (6 * n_grids, n_modes)
        SI eigenvectors on the grids' 6 DOFs (m, rad), mass-normalised in SI.
    grids : sequence of int
        Grid ids, in the order of ``phi``'s row blocks.
    units : str or UnitSystem
        Unit system of the file.
    """
    u = unit_system(units)
    _, OP2, _ = _pynastran()
    # deferred: optional dependency (the nastran extra)
    from pyNastran.op2.tables.oug.oug_eigenvectors import RealEigenvectorArray

    grids = np.asarray(grids, int)
    dofs = [(int(g), c) for g in grids for c in range(1, 7)]
    native = phi / _dof_scale(dofs, u)[:, None] * np.sqrt(u.energy)
    data = native.T.reshape(len(lam), len(grids), 6).astype(np.float32)
    node_gridtype = np.column_stack([grids, np.ones(len(grids), int)]).astype(np.int32)
    modes = np.arange(1, len(lam) + 1)
    vec = RealEigenvectorArray.add_modal_case("OUGV1", node_gridtype, data, 1, modes,
                                              np.asarray(lam, float),
                                              np.sqrt(np.abs(lam)) / (2 * np.pi))
    vec.table_code = 7  # eigenvector (add_modal_case leaves the displacement code 1)
    vec.data_code["table_code"] = 7
    op2 = OP2(debug=None)
    op2.set_mode("msc")
    op2.eigenvectors[1] = vec
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pyNastran's "downcasting" notice
        op2.write_op2(str(op2_path), nastran_format="msc")
    return Path(op2_path)


def write_truss_deck(truss, bdf_path, op4_path, *, units="SI", rotated=(), e_ref=70e9):
    """Write a truss as a BDF plus its K and M as an OP4.

    Grid ``i + 1`` is node ``i``; element ``j + 1`` is rod ``j`` (a CONROD with ``A =
    k L / E_ref`` and the rod's mass as non-structural mass); node masses are CONM2
    (ids after the rods'); fixed DOFs are SPC1; PARAM,COUPMASS,1 for consistent mass.  The
    OP4 holds KGG and MGG (ASCII sparse, 16 digits; BIGMAT above 65535 rows) on the g-set,
    rotations empty.  Scalar
    springs of the truss have no BDF card here: they are in the OP4 only.

    Parameters
    ----------
    truss : Truss
        The model (SI).
    bdf_path, op4_path : path-like
        Files to write.
    units : str or UnitSystem
        Unit system of the files.
    rotated : sequence of int
        Nodes whose displacement frame (CD) is coordinate system 9, a rectangular system
        rotated 30 degrees about (1, 1, 1); their rows of K and M are rotated with it.
    e_ref : float
        Young's modulus of the CONROD material (Pa).
    """
    u = unit_system(units)
    BDF, _, OP4 = _pynastran()
    model = BDF(debug=None)
    axis = np.ones(3) / np.sqrt(3.0)
    ang = np.pi / 6
    cx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(ang) * cx + (1 - np.cos(ang)) * cx @ cx  # columns: local axes
    rotated = set(int(i) for i in rotated)
    if rotated:
        model.add_cord2r(9, [0.0, 0.0, 0.0], list(map(float, R[:, 2])),
                         list(map(float, R[:, 0])))
    for i, xyz in enumerate(truss.nodes):
        model.add_grid(i + 1, list(map(float, xyz / u.length)), cd=9 if i in rotated else 0)
    model.add_mat1(1, e_ref / (u.force / u.length**2), None, 0.3, rho=0.0)
    _, lengths = truss.element_geometry()
    for j, (n1, n2) in enumerate(truss.elements):
        area = truss.axial_stiffness[j] * lengths[j] / e_ref
        model.add_conrod(j + 1, 1, [int(n1) + 1, int(n2) + 1], A=area / u.length**2,
                         nsm=truss.element_mass[j] / lengths[j] / (u.mass / u.length))
    first_mass = len(truss.elements) + 1
    for i, m in enumerate(truss.node_mass):
        if m > 0:
            model.add_conm2(first_mass + i, i + 1, float(m / u.mass))
    fixed = {}
    for d in truss.fixed_dofs:
        fixed.setdefault(int(d) // 3, []).append(str(int(d) % 3 + 1))
    for node, comps in sorted(fixed.items()):
        model.add_spc1(1, "".join(comps), [node + 1])
    if truss.mass_type == "consistent":
        model.add_param("COUPMASS", [1])
    model.write_bdf(str(bdf_path), size=16, is_double=False, close=True)

    K, M = assemble(truss, free_only=False)
    n = len(truss.nodes)
    T = sp.lil_matrix((6 * n, 3 * n))  # u_g (CD frames, 6 per grid) -> u_basic translations
    for i in range(n):
        B = R.T if i in rotated else np.eye(3)  # u_cd = R^T u_basic
        for a in range(3):
            for b in range(3):
                if B[a, b] != 0:
                    T[6 * i + a, 3 * i + b] = B[a, b]
    T = T.tocsr()
    s = np.tile([u.length] * 3 + [1.0] * 3, n)
    S = sp.diags(s)
    Kg = (S @ T @ K @ T.T @ S) / u.energy
    Mg = (S @ T @ M @ T.T @ S) / u.energy
    mats = {"KGG": sp.coo_matrix(Kg), "MGG": sp.coo_matrix(Mg)}
    if Kg.shape[0] <= BIGMAT_ROWS:
        OP4(debug=None).write_op4(str(op4_path), {k: (6, v) for k, v in mats.items()},
                                  name_order=list(mats), is_binary=False)
    else:  # pyNastran's writer packs row indices into 16 bits unless BIGMAT is asked for
        from pyNastran.op4.op4 import _write_sparse_matrix_ascii

        with open(op4_path, "w") as f:
            for k, v in mats.items():
                _write_sparse_matrix_ascii(f, k, v, form=6, is_big_mat=True)
    return Path(bdf_path), Path(op4_path)
