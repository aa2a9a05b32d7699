"""The import: a BDF with matrices (OP4, DMIG) or modes (OP2) to a ReducedModel.

Matrix path: the DOF map (g-set, the BDF's a-set from ASET/QSET/BSET, a DMIG's own, or a
given map) -> piezo stacks replace members -> rigid elements and MPCs (g-set only: ``u_g
= T u_n``) -> SPC'd, boundary (``boundary="fixed"``) and empty DOFs removed -> massless
DOFs of an a-set condensed exactly -> :func:`structfmu.reduce.reduce_matrices`.  Loads
and sensors are built on the matrices' own DOFs and carried through the same transform
(``E = T^T E_g``, ``H = H_g T``).  Modes path: a SOL 103 OP2, residual vectors (RESVEC)
kept as the Ritz block.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from structfmu.errors import ReductionError
from structfmu.nastran.deck import Deck, gset, read_deck, read_dof_map
from structfmu.nastran.matrices import (STANDARD_SETS, op2_matrices, pick,
                                        read_dmig_matrices, read_op4, to_si)
from structfmu.nastran.modes import MATRICES, load_op2, read_modes
from structfmu.nastran.rigid import transform
from structfmu.nastran.spec import (SENSOR_KINDS, Actuator, LineOfSight, NastranError,
                                    NastranWarning, unit_system)
from structfmu.reduce import Damping, reduce_matrices, reduced_from_basis
from structfmu.reduced import ReducedModel

__all__ = ["import_nastran"]

BOUNDARY = ("free", "fixed")


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
                               "stiffness nor mass (an SPC or a fixed boundary holds it, or "
                               "it is a rotation of a grid of rods only: read a line of sight "
                               "from three grids instead)")
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


def import_nastran(bdf, *, units, op4=None, op2=None, dmig=None, n_modes: int, actuators=(),
                   sensors=(), loads=(), los=(), inputs=(), outputs=(), ritz=None,
                   shift=None, damping: Damping | None = None, zeta_bands=(),
                   dof_map=None, k_name=None, m_name=None, boundary=None,
                   name=None, include_dirs=()) -> ReducedModel:
    """Reduced model from a NASTRAN BDF + OP4 or DMIG matrices, or a SOL 103 OP2.

    Parameters
    ----------
    bdf : path-like
        The BDF: grids, coordinate systems, elements, SPCs, rigid elements, ASET/QSET
        (or a superelement's ``.pch``).
    units : {"SI", "in-lbf-s", "mm-t-s"} or UnitSystem
        Unit system of the BDF, the matrices and the explicit stack values (required).
    op4 : path-like, optional
        Stiffness and mass: OUTPUT4 of KGG/MGG (g-set), or KAA/MAA (the BDF's a-set, or
        ``dof_map``), ASCII (read in double precision) or binary.
    op2 : path-like, optional
        SOL 103 results (eigenvalues, eigenvectors, residual vectors) instead of ``op4``.
    dmig : path-like, optional
        A DMIG punch file (``PARAM,EXTOUT,DMIGPCH``) with the stiffness and mass, on the
        DOFs its cards name.
    n_modes : int
        Number of eigenvectors (rigid-body modes included); with ``op2``, the number of
        vectors read, residual vectors included.
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
        Static Ritz vectors for actuators and loads (``"all"``, the default with
        matrices), for actuators only, none (the only choice with an OP2), or for the
        named inputs.
    shift : float, optional
        Shift-invert shift ((rad/s)^2); negative for a free-free model (rigid-body modes).
    damping : Damping, optional
        Modal damping (``zeta`` scalar or per mode), ``zeta_ritz``, ``alpha``, ``beta``.
    zeta_bands : sequence of (f_lo, f_hi, zeta)
        Modal damping ratio for the modes with ``f_lo <= f < f_hi`` (Hz), applied after
        ``damping`` (later bands win).
    dof_map : path-like or sequence of (int, int), optional
        ``(id, component)`` of each matrix row; default the g-set of the BDF, or its
        a-set (ASET/QSET/BSET/CSET DOFs sorted by id) when the matrices have that size.
    k_name, m_name : str, optional
        Matrix names (default: KGG/KNN/KFF/KAA, or the one square K*, resp. M*).
    boundary : {"free", "fixed"}, optional
        For a Craig-Bampton model (a q-set in the BDF): the boundary DOFs (the a-set
        less the q-set) free (default; loads, actuators and sensors act on them) or
        fixed (the fixed-interface modes).
    name : str, optional
        Model name (default the BDF's file stem).
    include_dirs : sequence of path-like
        Folders besides the BDF's (and the DMIG file's) own that their INCLUDE
        statements may name; any other INCLUDE is refused.

    Returns
    -------
    ReducedModel
    """
    u = unit_system(units)
    sources = [s for s in (op4, op2, dmig) if s is not None]
    if len(sources) != 1:
        raise NastranError("give the matrices (op4, --op4, dmig, --dmig, or an OP2 holding "
                           "them) or the SOL 103 modes (op2, --op2), exactly one of them")
    if isinstance(ritz, str) and ritz not in ("all", "actuators", "none"):
        raise NastranError(f"ritz={ritz!r}; expected 'all', 'actuators', 'none' or a list "
                           "of input names")
    if boundary is not None and boundary not in BOUNDARY:
        raise NastranError(f"boundary={boundary!r}; expected 'free' or 'fixed'")
    if damping is not None:
        for label, z in (("zeta", damping.zeta), ("zeta_ritz", damping.zeta_ritz)):
            bad = [float(x) for x in np.atleast_1d(np.asarray(z, float)) if not 0 <= x < 1]
            if bad:
                raise NastranError(f"damping ratio {label} = {bad[0]!r}; expected 0 <= zeta < 1 "
                                   "(CLI --zeta, --zeta-ritz)")
    deck = read_deck(bdf, u, include_dirs)
    name = name or Path(bdf).stem
    loaded, op2_mats = None, None
    if op2 is not None:
        loaded = load_op2(op2)
        op2_mats = _op2_stiffness_mass(loaded, op2, k_name, m_name)
    if op2 is not None and op2_mats is None and boundary == "fixed" and \
            getattr(loaded, "eigenvectors", None):
        raise NastranError("boundary='fixed' builds the fixed-interface modes from the "
                           "stiffness and mass, but the OP2 gives the modes NASTRAN "
                           "computed: give the matrices (--op4, --dmig), or leave "
                           "--boundary out")
    if op2 is not None and op2_mats is None and ritz is not None and (
            ritz != "none" if isinstance(ritz, str) else list(ritz)):
        raise NastranError("static Ritz vectors need the stiffness matrix; the OP2 gives "
                           "modes only: give --op4 with K and M (or an OP2 with them), or "
                           "ritz='none' (residual vectors of a RESVEC run are read from the "
                           "OP2 as they are)")
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

    info = {}
    if op2 is None or op2_mats is not None:
        K, M, dofs, is_aset = _matrices(deck, u, op4, dmig, dof_map, k_name, m_name,
                                        op2, op2_mats, include_dirs)
        index = {d: i for i, d in enumerate(dofs)}
        for a in acts:
            dK, dM = _actuator_update(deck, a, index, len(dofs))
            K, M = K + dK, M + dM
        removed = set(deck.constrained)
        qset = deck.sets.get("q", frozenset())
        if boundary is not None and not qset:
            raise NastranError(f"boundary={boundary!r} is for a Craig-Bampton model, but "
                               f"{deck.path} has no q-set (QSET/QSET1 with SPOINTs); give the "
                               "superelement's punch file, or leave boundary out")
        if boundary == "fixed":
            removed |= {d for d in dofs if d not in qset}
        if is_aset:
            _check_rigid_aset(deck, index)
            T, keep = sp.identity(len(dofs), format="csc"), np.arange(len(dofs))
        else:
            T, keep = transform(deck, dofs)
        cols = [dofs[i] for i in keep]  # the DOF of each column of T
        Kn, Mn = (T.T @ K @ T).tocsc(), (T.T @ M @ T).tocsc()
        free_n = np.array([d not in removed for d in cols], bool)
        has = (abs(Kn).sum(axis=0).A1 + abs(Mn).sum(axis=0).A1) > 0
        sel = np.flatnonzero(free_n & has)
        T, cols = T[:, sel], [cols[i] for i in sel]
        Kn, Mn = Kn[sel][:, sel].tocsc(), Mn[sel][:, sel].tocsc()
        if is_aset:
            T, Kn, Mn, cols, info = _condense_massless(T, Kn, Mn, cols)
        _check_massless(Mn, cols)
        basis = None
    else:
        basis = read_modes(op2, u, n_modes, deck, loaded=loaded)
        dofs = list(basis[2])
        removed = set(deck.constrained)
        T = sp.identity(len(dofs), format="csc")
    index = {d: i for i, d in enumerate(dofs)}

    E_rows, in_names, in_units = _Rows(index, frozenset(removed)), [], []
    H_rows, out_names, out_kinds = _Rows(index, frozenset(removed)), [], []
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
    Eg, Hg = E_rows.matrix().T.tocsc(), H_rows.matrix()
    E, H = (T.T @ Eg).tocsc(), (Hg @ T).tocsr()
    _check_reached(Eg, E, in_names, "input", axis=0)
    _check_reached(Hg, H, out_names, "output", axis=1)
    if info.get("condensed"):
        _check_feedthrough(Eg, Hg, info["condensed"], dofs)

    meta = {"model": name, "source": {"bdf": Path(bdf).name,
                                      "op4": Path(op4).name if op4 else None,
                                      "op2": Path(op2).name if op2 else None,
                                      "dmig": Path(dmig).name if dmig else None,
                                      "op2_matrices": list(op2_mats[:2]) if op2_mats else None},
            "units": u.name, "n_dof": len(dofs), "input_units": in_units,
            "wtmass": deck.wtmass, "boundary": boundary, "n_rigid": len(deck.rigid),
            "actuators": {a.label: {"stack": a.stack.name, "ch": float(a.stack.ch),
                                    "element": int(a.element)} for a in acts}}
    if info.get("condensed"):
        meta["n_condensed_massless"] = len(info["condensed"])
    damping = damping or Damping()
    if basis is None:
        ritz = "all" if ritz is None else ritz
        if not isinstance(ritz, str):
            sel = list(ritz)
        else:
            sel = [] if ritz == "none" else [f"fc_{a.label}" for a in acts]
            if ritz == "all":
                sel = [n for n in in_names if n not in sel] + sel
        try:
            model = reduce_matrices(Kn, Mn, E, H, n_modes, input_names=in_names,
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
        model = _modal_model(basis, E, H, acts, deck, name, meta, damping, in_names,
                             out_names, out_kinds)
    if zeta_bands:
        model = _band_damping(model, damping, zeta_bands)
    return model


def _modal_model(basis, E, H, acts, deck, name, meta, damping, in_names, out_names,
                 out_kinds):
    lam, phi, dofs = basis
    res = np.asarray(basis.residual, bool)
    if res.any():
        warnings.warn(f"{name}: {int(res.sum())} of the {res.size} OP2 vectors are residual "
                      f"vectors (past EIGRL {deck.eigrl}); they form the Ritz block",
                      NastranWarning, stacklevel=3)
    else:
        warnings.warn(f"{name}: modes only (SOL 103 OP2 without residual vectors): no static "
                      "Ritz vectors; the local response at actuators and loads is that of the "
                      "retained modes (add RESVEC=YES to the SOL 103 run, or give an OP4 with "
                      "K and M)", NastranWarning, stacklevel=3)
    if acts:
        warnings.warn(f"{name}: with modes only the stacks cannot replace the members' "
                      "stiffness and mass; the modes must already contain them",
                      NastranWarning, stacklevel=3)
    meta = {**meta, "n_modes": int((~res).sum()), "shift": None,
            "residual_vectors": int(res.sum())}
    model = reduced_from_basis(lam[~res], phi[:, ~res], np.zeros((len(dofs), 0)), None, E, H,
                               input_names=in_names, output_names=out_names,
                               output_kinds=out_kinds, damping=damping, name=name, meta=meta)
    if res.any():
        To, lr = phi[:, res], lam[res]
        Ed = E.toarray()
        Koo = np.diag(lr)
        Doo = damping.alpha * np.eye(lr.size) + damping.beta * Koo \
            + np.diag(2 * damping.zeta_ritz * np.sqrt(lr))
        model = replace(model, K_oo=Koo, D_oo=Doo, B_o=To.T @ Ed, C_o=np.asarray(H @ To),
                        meta={**model.meta, "n_ritz": int(lr.size)})
    return model


def _op2_stiffness_mass(loaded, op2, k_name, m_name):
    """``(K name, M name, matrices)`` of an OP2's matrix data blocks, or None for modes.

    The matrices are taken when ``k_name``/``m_name`` is given or the OP2 holds a
    standard stiffness and mass pair (KGG/MGG, KNN/MNN, KFF/MFF, KAA/MAA); one of a pair
    without the other, or a named matrix that is not there, is an error.
    """
    mats = op2_matrices(loaded, op2)
    std = {n.upper(): n for n in mats if n.upper()[:1] in "KM" and n.upper()[1:] in STANDARD_SETS
           and mats[n].shape[0] == mats[n].shape[1] and mats[n].shape[0] > 1}
    ks = sorted(n for n in std if n[0] == "K")
    ms = sorted(n for n in std if n[0] == "M")
    if k_name is None and m_name is None and not ks and not ms:
        return None
    kn = k_name or (std[ks[0]] if len(ks) == 1 else None)
    mn = m_name or (std[ms[0]] if len(ms) == 1 else None)
    have = ", ".join(mats) or "no matrices"
    for nm, label, own, other in ((kn, "stiffness", ks, ms), (mn, "mass", ms, ks)):
        if nm is None and len(own) > 1:
            raise NastranError(f"OP2 {str(op2)!r} has the {label} matrices {', '.join(own)}; "
                               "name the one to use (k_name/m_name, CLI --k-name/--m-name)")
        if nm is None or nm not in mats:
            want = nm or label[0].upper().replace("S", "K") + (other[0][1:] if other else "AA")
            raise NastranError(f"OP2 {str(op2)!r} has no {label} matrix {want} (it has "
                               f"{have}); write the stiffness and the mass into it and rerun "
                               f"({MATRICES}), or give them as OP4 (--op4) or DMIG (--dmig)")
    if getattr(loaded, "eigenvectors", None):
        warnings.warn(f"OP2 {str(op2)!r} holds both the matrices {kn}, {mn} and eigenvectors: "
                      "the matrices are used (eigenvectors and Ritz vectors computed here), "
                      "the eigenvectors are not read", NastranWarning, stacklevel=4)
    for nm in (kn, mn):
        if nm in mats.single:
            warnings.warn(f"matrix {nm} in OP2 {str(op2)!r} is single precision (7 digits): a "
                          "free-free model's rigid-body eigenvalues may come out far from zero; "
                          "write it from a double-precision run", NastranWarning, stacklevel=4)
    return kn, mn, mats


def _matrices(deck: Deck, u, op4, dmig, dof_map, k_name, m_name, op2=None, op2_mats=None,
              include_dirs=()):
    """K, M (SI) on their DOF map, and whether that map is an a-set."""
    if dmig is not None:
        K, M, dofs = read_dmig_matrices(dmig, u, k_name, m_name, include_dirs)
        for g, _ in dofs:
            deck.check_grid(g, f"DMIG {str(dmig)!r}: ")
        return K, M, dofs, True
    if op2_mats is not None:
        kn, mn, mats = op2_mats
        src, kind = op2, "OP2"
    else:
        mats, src, kind = read_op4(op4), op4, "OP4"
        kn = k_name or pick(mats, "K", op4)
        mn = m_name or pick(mats, "M", op4)
    for nm in (kn, mn):
        if nm not in mats:
            raise NastranError(f"{kind} {str(src)!r} has no matrix {nm!r}; it has "
                               f"{', '.join(mats)}")
    n = mats[kn].shape[0]
    g = gset(deck)
    aset = sorted(set().union(*(deck.sets.get(k, frozenset()) for k in "aqbc")))
    if dof_map is not None:
        dofs, is_aset = _dof_list(dof_map, deck), True
    elif n == len(g):
        dofs, is_aset = g, False
    elif aset and n == len(aset):
        dofs, is_aset = aset, True
    else:
        extra = f" and an a-set (ASET/QSET/BSET) of {len(aset)}" if aset else ""
        raise NastranError(f"the matrices of {kind} {str(src)!r} have {n} rows, but {deck.path} "
                           f"has a g-set of {len(g)} DOFs ({len(deck.grids)} grids x 6 + "
                           f"{len(deck.spoints)} scalar points){extra}: the files are of "
                           "different models, or give the DOF map of the matrices (dof_map, "
                           "--dof-map)")
    if mats[mn].shape != mats[kn].shape:
        raise NastranError(f"stiffness matrix {kn} is {mats[kn].shape[0]} x {mats[kn].shape[1]} "
                           f"but mass matrix {mn} is {mats[mn].shape[0]} x {mats[mn].shape[1]} "
                           f"in {kind} {str(src)!r}: write both matrices of one model")
    K = to_si(mats[kn], dofs, u, f"stiffness matrix {kn}", src)
    M = to_si(mats[mn], dofs, u, f"mass matrix {mn}", src)
    return K, M, dofs, is_aset


def _dof_list(dof_map, deck: Deck) -> list:
    dofs = read_dof_map(dof_map) if isinstance(dof_map, (str, Path)) else \
        [(int(i), int(c)) for i, c in dof_map]
    for g, c in dofs:
        deck.check_grid(g, "DOF map: ")
        if not 0 <= c <= 6:
            raise NastranError(f"DOF map: grid {g} component {c}; expected 1-6 (0: SPOINT)")
    if len(set(dofs)) != len(dofs):
        raise NastranError("DOF map: a (grid, component) pair appears twice")
    return dofs


def _check_rigid_aset(deck: Deck, index: dict) -> None:
    for con in deck.rigid:
        for m in con.dependent:
            if m in index:
                raise NastranError(f"{con.card} makes grid {m[0]} component {m[1]} dependent, "
                                   "but it is a row of the a-set matrices (NASTRAN removes "
                                   "dependent DOFs before the a-set); give the g-set matrices "
                                   "or the DOF map they were written with")


def _condense_massless(T, K, M, cols):
    """Exact static condensation of DOFs without mass (rows of M all zero)."""
    mass = np.asarray(abs(M).sum(axis=0)).ravel()
    o = np.flatnonzero(mass == 0)
    if o.size == 0:
        return T, K, M, cols, {}
    a = np.flatnonzero(mass > 0)
    Kd = K.toarray()
    Koo, Koa = Kd[np.ix_(o, o)], Kd[np.ix_(o, a)]
    try:
        X = -la.solve(Koo, Koa, assume_a="sym")
    except la.LinAlgError:
        raise NastranError(f"the {o.size} massless DOFs of the matrices are a mechanism on "
                           "their own (singular stiffness); add mass or constrain them") from None
    G = np.zeros((K.shape[0], a.size))
    G[a, np.arange(a.size)] = 1.0
    G[o] = X
    Kc = G.T @ Kd @ G
    Kc = 0.5 * (Kc + Kc.T)
    return (sp.csc_matrix(T @ G), sp.csc_matrix(Kc), M[a][:, a].tocsc(), [cols[j] for j in a],
            {"condensed": [cols[j] for j in o]})


def _check_feedthrough(Eg, Hg, condensed, dofs) -> None:
    idx = [dofs.index(d) for d in condensed]
    if abs(Eg[idx]).sum() > 0 and abs(Hg[:, idx]).sum() > 0:
        raise NastranError("an input and an output both act on DOFs without mass (condensed "
                           "statically); put the sensor or the load on a DOF with mass")


def _check_reached(G, Gt, names, what, axis) -> None:
    before = np.asarray(abs(G).sum(axis=axis)).ravel() > 0
    after = np.asarray(abs(Gt).sum(axis=axis)).ravel() > 0
    lost = np.flatnonzero(before & ~after)
    if lost.size:
        raise NastranError(f"{what} {names[lost[0]]!r}: every DOF it uses is constrained or has "
                           "neither stiffness nor mass; put it on a DOF that moves")


def _check_massless(M, cols) -> None:
    d = M.diagonal()
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        g, c = cols[bad[0]]
        raise NastranError(f"grid {g} component {c} has stiffness but no mass ({bad.size} such "
                           "DOFs); add mass there (e.g. CONM2 inertia, PARAM,COUPMASS) or "
                           "condense the massless DOFs in NASTRAN (OMIT/ASET) before OUTPUT4")


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


