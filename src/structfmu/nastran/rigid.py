"""Rigid elements and MPCs: the g-set to n-set transform ``u_g = T u_n``.

RBE2, RBAR and MPC cards become constraint equations ``C u = 0`` over the DOFs they
touch, each equation with its dependent DOF (NASTRAN's m-set).  With every equation of
the model stacked, ``C_m u_m + C_n u_n = 0`` gives ``u_m = -C_m^-1 C_n u_n`` (chains of
rigid elements included), and ``K_n = T^T K_g T``, ``M_n = T^T M_g T``, ``E_n = T^T
E_g``, ``H_n = H_g T``: what NASTRAN does between KGG and KNN.

Geometry of a rigid link from grid ``a`` to grid ``b`` (basic frame, ``r = x_b - x_a``):
``u_b = u_a + theta_a x r = u_a - [r]_x theta_a`` and ``theta_b = theta_a``; each grid's
DOFs are in its CD frame (``u_basic = T_cd u_cd``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from structfmu.nastran.spec import NastranError, UnitSystem

__all__ = ["Constraint", "constraints", "transform"]


@dataclass(frozen=True)
class Constraint:
    """Linear constraint equations ``sum_j C[i, j] u[dofs[j]] = 0`` of one card.

    Parameters
    ----------
    card : str
        ``"RBE2 12"``, ``"MPC 3"``: the card, for messages.
    dofs : tuple of (int, int)
        ``(grid, component)`` the equations involve (components in CD frames).
    C : ndarray, shape (n_eq, len(dofs))
        Coefficients (SI: a translation row is in m, a rotation in rad).
    dependent : tuple of (int, int)
        One dependent DOF per equation (NASTRAN's m-set of the card).
    """

    card: str
    dofs: tuple
    C: np.ndarray
    dependent: tuple

REFUSED = ("RBE1", "RBE3", "RROD", "RBAR1", "RSPLINE", "RSSCON")


def _skew(r):
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def _frame(cd, grid):
    T = cd.get(grid, np.eye(3))
    Z = np.zeros((3, 3))
    return np.block([[T, Z], [Z, T]])  # u_basic (6) = F u_cd (6)


def _rigid_link(grids, cd, a, b, u: UnitSystem):
    """``(C_a, C_b)`` with ``C_a u_a + C_b u_b = 0`` (6 equations, CD frames, SI)."""
    r = grids[b] - grids[a]  # m
    R = np.eye(6)
    R[:3, 3:] = -_skew(r)
    Fa, Fb = _frame(cd, a), _frame(cd, b)
    # in basic: F_b u_b - R F_a u_a = 0; express in b's CD frame
    return -(Fb.T @ R @ Fa), np.eye(6)


def _comps(text) -> list:
    return [int(c) for c in str(text or "") if c.isdigit() and c != "0"]


def constraints(model, grids, cd, u: UnitSystem):
    """Constraint equations of a pyNastran model's RBE2, RBAR and MPC cards.

    Parameters
    ----------
    model : pyNastran.bdf.bdf.BDF
        The cross-referenced model.
    grids : dict of int to ndarray, shape (3,)
        Grid positions in basic (m).
    cd : dict of int to ndarray, shape (3, 3)
        Displacement frames ``u_basic = T u_cd``.
    u : UnitSystem
        Declared units (MPC coefficients mix translations and rotations).

    Returns
    -------
    list of Constraint, dict of int to str
        The equations; rigid elements of other types (id to type), refused later by name
        when the matrices are a g-set.
    """
    out, refused = [], {}
    for eid, e in sorted(model.rigid_elements.items()):
        if e.type == "RBE2":
            gn, dep = int(e.gn), _comps(e.cm)
            for gm in e.Gmi_node_ids:
                Ca, Cb = _rigid_link(grids, cd, gn, int(gm), u)
                rows = [c - 1 for c in dep]
                dofs = [(gn, c) for c in range(1, 7)] + [(int(gm), c) for c in range(1, 7)]
                C = np.hstack([Ca[rows], Cb[rows]])
                out.append(Constraint(f"RBE2 {eid}", tuple(dofs), C,
                                      tuple((int(gm), c) for c in dep)))
        elif e.type == "RBAR":
            ga, gb = (int(n) for n in e.nodes)
            dep = [(ga, c) for c in _comps(e.cma)] + [(gb, c) for c in _comps(e.cmb)]
            ind = [(ga, c) for c in _comps(e.cna)] + [(gb, c) for c in _comps(e.cnb)]
            if len(dep) != 6 or len(ind) != 6 or set(dep) & set(ind):
                raise NastranError(f"RBAR {eid}: expected six independent (CNA, CNB) and six "
                                   f"dependent (CMA, CMB) components, got {len(ind)} and "
                                   f"{len(dep)}; fix the card")
            Ca, Cb = _rigid_link(grids, cd, ga, gb, u)
            dofs = [(ga, c) for c in range(1, 7)] + [(gb, c) for c in range(1, 7)]
            out.append(Constraint(f"RBAR {eid}", tuple(dofs), np.hstack([Ca, Cb]),
                                  tuple(dep)))
        else:
            refused[int(eid)] = e.type
    for cards in model.mpcs.values():
        for card in cards:
            if card.type != "MPC":
                continue
            dofs, coef = [], []
            for nid, comp, a in zip(card.nodes, card.components, card.coefficients):
                c = int(comp) if int(nid) in grids else 0
                dofs.append((int(nid), c))
                # a translation coefficient multiplies a length: SI rows are in m
                coef.append(float(a) / (u.length if c in (0, 1, 2, 3) else 1.0))
            out.append(Constraint(f"MPC {card.conid}", tuple(dofs), np.array([coef]),
                                  (dofs[0],)))
    return out, refused


def transform(deck, dofs):
    """The transform ``u_dofs = T u_n`` that applies the deck's rigid elements.

    Parameters
    ----------
    deck : Deck
        The model (its :attr:`Deck.rigid` equations).
    dofs : list of (int, int)
        The g-set DOFs of the matrices.

    Returns
    -------
    T : scipy.sparse.csc_matrix, shape (len(dofs), n_n)
        Columns: the independent DOFs ``n`` (identity rows) in the order of ``dofs``.
    keep : ndarray of int
        Indices in ``dofs`` of the independent DOFs.
    """
    n = len(dofs)
    if deck.refused_rigid:
        eid, kind = next(iter(sorted(deck.refused_rigid.items())))
        raise NastranError(f"rigid element {kind} {eid} cannot be applied by this import "
                           f"({len(deck.refused_rigid)} such elements); replace it by RBE2 or "
                           "RBAR, or export the matrices after MPC elimination (KAA/MAA, or "
                           "KNN/MNN with a DOF map)")
    if not deck.rigid:
        return sp.identity(n, format="csc"), np.arange(n)
    index = {d: i for i, d in enumerate(dofs)}
    owner = {}
    rows, cols, vals, dep = [], [], [], []
    for con in deck.rigid:
        for d in con.dofs:
            if d not in index:
                raise NastranError(f"{con.card}: grid {d[0]} component {d[1]} is not a row of "
                                   "the matrices; give the g-set matrices (KGG/MGG) with it")
        for k, m in enumerate(con.dependent):
            if m in owner:
                raise NastranError(f"{con.card} makes grid {m[0]} component {m[1]} dependent, "
                                   f"which {owner[m]} already does; a DOF may be dependent on "
                                   "one rigid element or MPC only")
            if m in deck.constrained:
                raise NastranError(f"{con.card} makes grid {m[0]} component {m[1]} dependent, "
                                   "but an SPC fixes it; constrain the independent grid "
                                   "instead")
            owner[m] = con.card
            i = len(dep)
            dep.append(index[m])
            for d, a in zip(con.dofs, con.C[k]):
                if a != 0.0:
                    rows.append(i)
                    cols.append(index[d])
                    vals.append(a)
    C = sp.csc_matrix((vals, (rows, cols)), shape=(len(dep), n))
    is_dep = np.zeros(n, bool)
    is_dep[dep] = True
    keep = np.flatnonzero(~is_dep)
    Cm, Cn = C[:, dep], C[:, keep]
    try:
        lu = spla.splu(Cm.tocsc())
        G = -lu.solve(Cn.toarray())
    except RuntimeError:
        raise NastranError("the rigid elements and MPCs cannot be solved for their dependent "
                           "DOFs (a loop of rigid elements, or an MPC whose dependent DOF is "
                           "another's independent one in a cycle); check the m-set of "
                           f"{', '.join(sorted(set(owner.values()))[:3])}") from None
    if not np.all(np.isfinite(G)):
        raise NastranError("the rigid elements and MPCs are singular for their dependent DOFs; "
                           "check the m-set")
    gr, gc = np.nonzero(G)
    r = np.concatenate([keep, np.asarray(dep)[gr]])
    c = np.concatenate([np.arange(keep.size), gc])
    v = np.concatenate([np.ones(keep.size), G[gr, gc]])
    return sp.csc_matrix((v, (r, c)), shape=(n, keep.size)), keep
