"""The BDF side of an import: geometry, members, constraints, sets, in SI.

:func:`read_deck` reads a BDF with pyNastran (its log kept quiet) and keeps what the
importer uses; every card it does not interpret is counted, and the import says so in
one warning.  Rigid elements and MPCs become constraint equations
(:class:`Constraint`), applied by :mod:`structfmu.nastran.rigid`.
"""

from __future__ import annotations

import difflib
import re
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from structfmu.nastran.pyn import QuietLog, includes_inside, pynastran, quiet_output, reason
from structfmu.nastran.rigid import Constraint, constraints
from structfmu.nastran.spec import (ACTUATOR_ELEMENTS, NastranError, NastranWarning,
                                    UnitSystem, to_int, unit_system)

__all__ = ["Deck", "Constraint", "read_deck", "read_dof_map", "gset", "dof_scale",
           "INTERPRETED_CARDS"]

#: Cards the import reads, or whose whole effect is in the matrices or modes it reads
#: (elements, properties and materials of the members it knows, solution and output
#: control, residual-vector DOF).
INTERPRETED_CARDS = frozenset("""
    GRID SPOINT CORD1R CORD2R CORD1C CORD2C CORD1S CORD2S SPC SPC1 SPCADD PARAM ENDDATA
    CROD CONROD CBAR CBEAM PROD PBAR PBARL PBEAM PBEAML MAT1 CONM2 RBE2 RBAR MPC MPCADD
    ASET ASET1 QSET QSET1 BSET BSET1 CSET CSET1 OMIT OMIT1 EIGRL EIGR USET USET1 PLOTEL DTI
    EXTRN SEBULK SECONCT DMIG RVDOF RVDOF1
""".split())
#: Rigid elements refused by name (their equations are not built here).
REFUSED_RIGID = ("RBE1", "RBE3", "RROD", "RBAR1", "RSPLINE", "RSSCON")
SET_CARDS = {"a": "asets", "q": "qsets", "b": "bsets", "c": "csets", "o": "omits"}


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
    rigid : tuple of Constraint
        Rigid elements (RBE2, RBAR) and MPC equations, as constraint equations.
    refused_rigid : dict of int to str
        Rigid elements this import cannot apply (RBE3, RBE1, RROD...), id to type.
    sets : dict of str to frozenset of (int, int)
        DOFs of ASET/ASET1 (``"a"``), QSET/QSET1 (``"q"``), BSET/BSET1 (``"b"``),
        CSET/CSET1 (``"c"``) and OMIT/OMIT1 (``"o"``).
    wtmass : float
        PARAM,WTMASS (1 when absent); element masses here are already multiplied by it.
    unread : dict of str to int
        Cards this import does not interpret, with their count.
    eigrl : tuple
        ``(v1, v2, nd)`` of the deck's EIGRL (Hz, Hz, roots; None when blank), or ``()``.
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
    rigid: tuple = ()
    refused_rigid: dict = field(default_factory=dict)
    sets: dict = field(default_factory=dict)
    wtmass: float = 1.0
    unread: dict = field(default_factory=dict)
    eigrl: tuple = ()

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


def read_deck(bdf_path, units, include_dirs=()) -> Deck:
    """Read the geometry, members, constraints and sets of a BDF (SI units).

    Warns (NastranWarning) once for the cards it does not interpret and when the deck
    has no ENDDATA (it may be cut short; a ``.pch`` punch file has none by design); an unreadable deck is one NastranError that
    carries pyNastran's own reason.  Superelement punch files (``BEGIN SUPER``) are read
    as their bulk data.

    Parameters
    ----------
    bdf_path : path-like
        The BDF (bulk data, with or without executive and case control), or the
        ``.pch`` NASTRAN wrote for an external superelement.
    units : str or UnitSystem
        The declared unit system.
    include_dirs : sequence of path-like
        Folders besides the deck's own that its INCLUDE statements may name; an INCLUDE
        of any other file is refused.
    """
    u = unit_system(units)
    path = Path(bdf_path)
    if not path.is_file():
        raise NastranError(f"BDF file {str(path)!r} does not exist")
    text = path.read_text(errors="replace")
    model, log = _read_bdf(path, text, include_dirs)
    _warn_unread(model, path)
    punch = path.suffix.lower() == ".pch" or re.search(r"(?im)^BEGIN\s+SUPER", text)
    if not punch and not re.search(r"(?im)^\s*ENDDATA", text) and not _includes_enddata(model):
        warnings.warn(f"BDF {str(path)!r} has no ENDDATA: it may be cut short (grids, SPCs "
                      "or rigid elements missing); check that the file is complete",
                      NastranWarning, stacklevel=3)
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
    wt = model.params.get("WTMASS")
    wtmass = float(wt.values[0]) if wt is not None else 1.0
    elements, types, shaped = _members(model, grids, u, wtmass)
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
    rigid, refused = constraints(model, grids, cd, u)
    for eid, e in model.rigid_elements.items():
        types.setdefault(eid, e.type)
    sets = {key: frozenset(_set_dofs(getattr(model, attr, []) or [], grids))
            for key, attr in SET_CARDS.items()}
    unread = _unread(model)
    eigrl = ()
    for method in (getattr(model, "methods", {}) or {}).values():
        if method.type == "EIGRL":
            eigrl = (method.v1, method.v2, method.nd)
            break
    del log
    return Deck(grids, cd, spoints, elements, types, frozenset(constrained), coupled, str(path),
                frozenset(shaped), tuple(rigid), refused, sets, wtmass, unread, eigrl)


def _read_bdf(path: Path, text: str, include_dirs=()):
    BDF = pynastran()[0]
    log = QuietLog()
    model = BDF(log=log.log)
    source = path
    tmp = None
    if re.search(r"(?im)^BEGIN\s+SUPER", text):  # a superelement punch: its bulk data
        tmp = tempfile.NamedTemporaryFile("w", suffix=".pch", dir=path.parent, delete=False)
        tmp.write(re.sub(r"(?im)^BEGIN\s+SUPER.*$", "$", text))
        tmp.close()
        source = Path(tmp.name)
    try:
        with warnings.catch_warnings(), includes_inside(path, include_dirs) as outside, \
                quiet_output():
            warnings.simplefilter("ignore")
            model.read_bdf(str(source), xref=True, punch=_is_punch(text))
        model.jf_read_outside = bool(outside)
    except NastranError:
        raise
    except Exception as exc:  # pyNastran raises many kinds; one sentence here
        raise NastranError(f"cannot read BDF {str(path)!r}: {reason(exc, log)}; fix the deck "
                           "(or the INCLUDE it names) and import again") from None
    finally:
        if tmp is not None:
            Path(tmp.name).unlink(missing_ok=True)
    return model, log


def _includes_enddata(model) -> bool:
    return bool(model.card_count.get("ENDDATA"))


def _members(model, grids, u: UnitSystem, wtmass: float):
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
            mass = float(e.Mass()) * wtmass * u.mass
            k_axial = young * area / length if length > 0 else np.nan
            elements[eid] = (e.type, (int(n1), int(n2)), k_axial, mass)
            if e.type in ("CBAR", "CBEAM") and (np.any(np.asarray(e.wa, float) != 0)
                                                or np.any(np.asarray(e.wb, float) != 0)
                                                or str(e.pa or 0) != "0"
                                                or str(e.pb or 0) != "0"):
                shaped.add(eid)
    for eid, e in getattr(model, "masses", {}).items():
        types.setdefault(eid, e.type)
    return elements, types, shaped


def _set_dofs(cards, grids) -> set:
    out = set()
    for card in cards:
        comps = card.components
        comps = [comps] * len(card.node_ids) if isinstance(comps, str) else list(comps)
        for nid, cs in zip(card.node_ids, comps):
            for c in str(cs):
                if c.isdigit():
                    out.add((int(nid), int(c) if int(nid) in grids else 0))
    return out


#: A NASTRAN card name (up to eight characters, large-field ``*`` allowed); anything else
#: in the deck's card counts is a line of text, counted but never echoed.
_CARD_NAME = re.compile(r"[A-Z][A-Z0-9]{0,7}\*?")
_NOT_CARDS = "lines that are not NASTRAN cards"


def _unread(model) -> dict:
    counts = {k: int(v) for k, v in model.card_count.items()
              if k not in INTERPRETED_CARDS and k not in REFUSED_RIGID}
    for k, v in (model.reject_count or {}).items():
        if k not in INTERPRETED_CARDS:  # EXTRN: a superelement's DOF list, read as ASET
            counts[k] = int(v)
    out = {k: v for k, v in counts.items() if _CARD_NAME.fullmatch(str(k))}
    other = sum(v for k, v in counts.items() if k not in out)
    return {**out, _NOT_CARDS: other} if other else out


def _warn_unread(model, path: Path) -> None:
    unread = _unread(model)
    if not unread:
        return
    rejected = set(model.reject_count or {}) - INTERPRETED_CARDS
    if getattr(model, "jf_read_outside", False):
        # a file of the user's outside folder: its unknown first fields are not echoed
        unknown = sum(unread.pop(k) for k in list(unread) if k in rejected)
        if unknown:
            unread[_NOT_CARDS] = unread.get(_NOT_CARDS, 0) + unknown
    items = ", ".join(f"{k} ({n}{', unknown to pyNastran' if k in rejected else ''})"
                      if k != _NOT_CARDS else f"{n} {k}" for k, n in sorted(unread.items()))
    warnings.warn(f"BDF {str(path)!r}: {sum(unread.values())} cards this import does not "
                  f"interpret: {items}; their stiffness and mass count only through the "
                  "OP4/OP2 matrices, and they carry no stack, load or constraint here",
                  NastranWarning, stacklevel=4)


def _is_punch(text: str) -> bool:
    """True when the text has no BEGIN BULK (a bulk-data-only deck)."""
    return not re.search(r"(?im)^\s*BEGIN\s+BULK", text)


def gset(deck: Deck) -> list:
    """The g-set DOF map: grids x 6 and SPOINTs, sorted by id.

    Parameters
    ----------
    deck : Deck
        The model.
    """
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
        rows.append((to_int(line[0], f"DOF map line {k}: id"),
                     to_int(line[1], f"DOF map line {k}: component")))
    return rows


def dof_scale(dofs, u: UnitSystem) -> np.ndarray:
    """Length unit in m for translations (and SPOINTs), 1 for rotations (rad).

    Parameters
    ----------
    dofs : sequence of (int, int)
        ``(grid, component)`` per row.
    u : UnitSystem
        The declared system.
    """
    return np.array([1.0 if 4 <= c <= 6 else u.length for _, c in dofs])

