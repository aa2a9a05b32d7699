"""Modes from a SOL 103 OP2: eigenvalues, eigenvectors, generalized mass, in SI.

The eigenvalue table (LAMA) gives each mode's generalized mass and stiffness; the
eigenvectors are divided by the square root of the generalized mass, so MAX- or
POINT-normalised shapes come out mass-normalised.  Without LAMA the generalized mass is
unknown: it is taken as 1 (MASS normalisation) with a warning.  Residual vectors
(RESVEC) are what NASTRAN appends to the eigenvectors it was asked for: the vectors
past the BDF's EIGRL range (beyond ND roots, or above V2) are flagged as residual
vectors, with the generalized stiffness and mass LAMA lists for them.  An OP2 of
buckling (SOL 105) or of complex eigenvalues or responses (SOL 107/110 complex modes,
SOL 145/146) is refused with what to rerun.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from structfmu.nastran.deck import dof_scale
from structfmu.nastran.pyn import QuietLog, pynastran, quiet_output, reason
from structfmu.nastran.spec import NastranError, NastranWarning, unit_system

__all__ = ["read_modes", "load_op2", "Modes"]

RERUN = ("rerun the bulk data as SOL 103 (METHOD = an EIGRL id, DISP(PLOT)=ALL, "
         "PARAM,POST,-1; RESVEC=YES for residual vectors at the loads) and import that OP2")


MATRICES = ("DMAP: ASSIGN OUTPUT2='model.op2',UNIT=12,UNFORMATTED and OUTPUT2 KAA,MAA,,,//0/12 "
            "for a superelement's a-set, or KGG,MGG for the g-set")


class Modes(tuple):
    """``(lam, phi, dofs)`` as read, plus ``gen_mass``, ``gen_stiffness``, ``residual``."""

    gen_mass: np.ndarray
    gen_stiffness: np.ndarray
    residual: np.ndarray


def _real_eigenvectors(op2, path):
    real = {k: v for k, v in op2.eigenvectors.items()
            if type(v).__name__ == "RealEigenvectorArray"}
    aero = any(type(v).__name__.startswith("Complex") for v in op2.eigenvectors.values()) \
        or any(type(v).__name__ == "ComplexEigenvalues" for v in op2.eigenvalues.values()) \
        or bool(getattr(op2.op2_results, "vg_vf_response", None))
    if aero:
        raise NastranError(f"OP2 {str(path)!r} holds complex eigenvalues or responses "
                           "(SOL 107/110 complex modes, SOL 145 flutter or SOL 146), not the "
                           f"structure's normal modes; {RERUN}")
    # analysis code 2: real eigenvalues; 7 and 8: pre- and post-buckling (SOL 105)
    buckling = [k for k, v in real.items() if getattr(v, "analysis_code", 2) in (7, 8)]
    if buckling:
        raise NastranError(f"OP2 {str(path)!r} holds buckling modes (SOL 105), whose "
                           "eigenvalues are load factors, not the structure's normal modes; "
                           f"{RERUN}")
    if not real:
        raise NastranError(f"OP2 {str(path)!r} has neither eigenvectors nor stiffness and mass "
                           f"matrices; {RERUN}, or write the matrices into it ({MATRICES})")
    return real[sorted(real, key=str)[0]]


def load_op2(op2_path):
    """An OP2 file read by pyNastran (results, eigenvalues and matrix data blocks).

    Parameters
    ----------
    op2_path : path-like
        The OP2 file.

    Returns
    -------
    pyNastran.op2.op2.OP2
        The file's contents (``eigenvectors``, ``eigenvalues``, ``matrices``...).
    """
    OP2 = pynastran()[1]
    path = Path(op2_path)
    if not path.is_file():
        raise NastranError(f"OP2 file {str(path)!r} does not exist")
    log = QuietLog()
    op2 = OP2(log=log.log)
    try:
        with warnings.catch_warnings(), quiet_output():
            warnings.simplefilter("ignore")  # np.chararray in pyNastran
            # tables pyNastran does not know are read as matrices (OUTPUT2 of any data
            # block: GPXX, KAAX...), as its module-level read_op2 does
            op2.read_op2(str(path), skip_undefined_matrices=True)
    except Exception as exc:
        raise NastranError(f"cannot read OP2 {str(path)!r}: {reason(exc, log)}; check that it "
                           "is a NASTRAN OP2 (PARAM,POST,-1, or OUTPUT2 of matrices)") from None
    return op2


def read_modes(op2_path, units, n_modes: int, deck=None, loaded=None):
    """Eigenvalues and eigenvectors (SI) from a SOL 103 OP2.

    Parameters
    ----------
    op2_path : path-like
        The OP2 file.
    units : str or UnitSystem
        Declared unit system of the NASTRAN files (``"SI"``, ``"in-lbf-s"``,
        ``"mm-t-s"``).
    n_modes : int
        Number of vectors to read (the first in the file: eigenvectors, then residual
        vectors when the run had RESVEC).
    deck : Deck, optional
        The BDF; its grids and scalar points must be those of the OP2.
    loaded : pyNastran.op2.op2.OP2, optional
        The file as :func:`load_op2` read it (not read again).

    Returns
    -------
    Modes
        ``lam`` ((rad/s)^2, rigid-body ones below 1e-6 set to 0), ``phi`` (shape
        (n_dof, n_modes), mass-normalised in SI) and ``dofs`` ``(grid, component)`` per
        row; attributes ``gen_mass``, ``gen_stiffness`` (file units, as LAMA lists them)
        and ``residual`` (bool per vector).
    """
    u = unit_system(units)
    path = Path(op2_path)
    op2 = load_op2(path) if loaded is None else loaded
    vec = _real_eigenvectors(op2, path)
    data = np.asarray(vec.data, float)  # (n_modes, n_nodes, 6)
    if data.shape[0] < n_modes:
        raise NastranError(f"{n_modes} modes requested but OP2 {str(path)!r} has "
                           f"{data.shape[0]}; ask for at most {data.shape[0]} or rerun with "
                           "more roots (EIGRL ND)")
    nodes = vec.node_gridtype[:, 0]
    gtype = vec.node_gridtype[:, 1]
    if deck is not None:
        _check_same_model(deck, nodes, gtype, path)
        _check_same_geometry(deck, op2, path, u)
    dofs = [(int(n), c if t == 1 else 0) for n, t in zip(nodes, gtype)
            for c in (range(1, 7) if t == 1 else (1,))]
    cols = [(k, c) for k, t in enumerate(gtype) for c in (range(6) if t == 1 else (0,))]
    phi = np.array([data[:n_modes, k, c] for k, c in cols])  # (n_dof, n_modes)
    real_eig = [e for e in op2.eigenvalues.values() if type(e).__name__ == "RealEigenvalues"]
    if real_eig:
        eig = real_eig[0]
        lam = np.asarray(eig.eigenvalues[:n_modes], float)
        gm = np.asarray(eig.generalized_mass[:n_modes], float)
        gk = np.asarray(eig.generalized_stiffness[:n_modes], float)
    else:  # no LAMA table: the eigenvalues the eigenvector table carries
        lam = np.asarray(vec.eigns[:n_modes], float)
        gm = np.ones(n_modes)
        gk = lam.copy()
        warnings.warn(f"OP2 {str(path)!r} has no eigenvalue table (LAMA): the generalized "
                      "masses are unknown and taken as 1, right only for MASS-normalised "
                      "eigenvectors (EIGRL NORM=MASS); write LAMA with PARAM,POST,-1 if the "
                      "shapes are MAX-normalised", NastranWarning, stacklevel=3)
    if np.any(gm <= 0):
        k = int(np.flatnonzero(gm <= 0)[0])
        raise NastranError(f"OP2 {str(path)!r}: mode {k + 1} has generalized mass {gm[k]:.3g}; "
                           "expected a positive mass")
    residual = _residual_flags(lam, deck.eigrl if deck is not None else (), n_modes)
    phi = phi / np.sqrt(gm)
    phi = phi * dof_scale(dofs, u)[:, None] / np.sqrt(u.energy)
    lam = np.where(np.abs(lam) < 1e-6, 0.0, lam)
    if np.any(lam < 0):
        raise NastranError(f"OP2 {str(path)!r}: negative eigenvalue {lam.min():.3g}; check the "
                           "model's constraints (or use the OP4 with a shift)")
    out = Modes((lam, phi, dofs))
    out.gen_mass, out.gen_stiffness, out.residual = gm, gk, residual
    return out


def _residual_flags(lam, eigrl, n):
    """Vectors past the EIGRL range ``(v1, v2, nd)`` (Hz, Hz, roots): residual vectors."""
    flags = np.zeros(n, bool)
    if not eigrl:
        return flags
    _, v2, nd = eigrl
    if nd:
        flags[int(nd):] = True
    if v2:
        flags |= np.sqrt(np.maximum(lam, 0)) / (2 * np.pi) > float(v2) * (1 + 1e-6)
    return flags


def _check_same_geometry(deck, op2, path, u):
    """Grid positions of the OP2's BGPDT (basic, file units) against the BDF's."""
    bgpdt = getattr(op2.op2_results, "bgpdt", None)
    eqexin = getattr(op2.op2_results, "eqexin", None)
    xyz = getattr(bgpdt, "xyz", None)
    if xyz is None or eqexin is None or len(eqexin.nid) != len(xyz):
        return
    # BGPDT is in NASTRAN's internal order; EQEXIN gives each grid's first internal DOF
    ids = np.asarray(eqexin.nid)[np.argsort(np.asarray(eqexin.dof), kind="stable")]
    pts = {int(n): x for n, x in zip(ids, np.asarray(xyz, float)) if int(n) in deck.grids}
    if not pts:
        return
    bdf = np.array([deck.grids[n] / u.length for n in pts])
    op2_xyz = np.array(list(pts.values()))
    size = max(float(np.ptp(bdf, axis=0).max()), 1e-30)
    err = np.linalg.norm(op2_xyz - bdf, axis=1)
    k = int(np.argmax(err))
    if err[k] > 1e-4 * size:  # float32 positions and 8- or 16-character fields
        n = list(pts)[k]
        raise NastranError(f"grid {n} is at {np.round(op2_xyz[k], 6).tolist()} in OP2 "
                           f"{str(path)!r} but at {np.round(bdf[k], 6).tolist()} in "
                           f"{deck.path}: the OP2 is of another model (or another version of "
                           "it); give the BDF it was run from")


def _check_same_model(deck, nodes, gtype, path):
    ids = {int(n) for n in nodes}
    bdf_ids = set(deck.grids) | set(deck.spoints)
    missing = sorted(ids - bdf_ids)
    if missing:
        raise NastranError(f"OP2 {str(path)!r} has eigenvectors on {len(ids)} grids and scalar "
                           f"points, {len(missing)} of them not in {deck.path} (first "
                           f"{missing[0]}): the OP2 is of another model; give the BDF it was "
                           "run from")
    absent = sorted(set(deck.grids) - ids)
    if absent:
        raise NastranError(f"{deck.path} has {len(absent)} grids the OP2 {str(path)!r} has no "
                           f"eigenvector for (first {absent[0]}): the OP2 is of another model, "
                           "or the grid was added to the BDF after the run (one no element "
                           "uses: remove it, or rerun with it), or its DISP output set is "
                           "partial (rerun with DISP(PLOT)=ALL)")
