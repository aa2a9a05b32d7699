"""Stiffness and mass matrices: OP4 (ASCII or binary) and DMIG punch files, in SI.

An ASCII OP4 is read in double precision whatever its header's type says: the digits
decide (NASTRAN writes ``1P,3E22.15``, 16 significant digits, under a single-precision
type code, and reading those as float32 turns a superelement's rigid-body eigenvalues
of ~1e-4 into -0.455 (rad/s)^2).  A binary OP4 is read as its words are stored.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from structfmu.errors import DimensionError
from structfmu.nastran.deck import dof_scale
from structfmu.nastran.pyn import QuietLog, includes_inside, pynastran, quiet_output, reason
from structfmu.nastran.spec import NastranError, unit_system

__all__ = ["read_matrices", "read_op4", "read_dmig", "read_dmig_matrices", "op4_precision",
           "pick", "to_si", "op2_matrices", "STANDARD_SETS"]

#: Set suffixes of the standard stiffness and mass names (KGG/MGG ... KAA/MAA).
STANDARD_SETS = ("GG", "NN", "FF", "AA")


def op4_precision(op4_path) -> str:
    """``"double"`` for an ASCII OP4 (its digits decide), ``"default"`` for binary.

    Parameters
    ----------
    op4_path : path-like
        The OP4 file.
    """
    with open(op4_path, "rb") as f:
        head = f.read(256)
    text = head.decode("ascii", errors="replace")
    return "double" if re.match(r"\s*\d+\s+\d+\s+\d+\s+\d+\s*\S", text) else "default"


def read_op4(op4_path) -> dict:
    """Every matrix of an OP4, as float64 (complex matrices as complex128).

    Parameters
    ----------
    op4_path : path-like
        The OP4 file.

    Returns
    -------
    dict of str to scipy.sparse.csc_matrix
        Name to matrix, in the file's own units.
    """
    OP4 = pynastran()[2]
    path = Path(op4_path)
    if not path.is_file():
        raise NastranError(f"OP4 file {str(path)!r} does not exist")
    log = QuietLog()
    try:
        with quiet_output():
            mats = OP4(log=log.log).read_op4(str(path), precision=op4_precision(path))
    except Exception as exc:
        raise NastranError(f"cannot read OP4 {str(path)!r}: {reason(exc, log)}; check that "
                           "it is an OUTPUT4 file") from None
    if not mats:
        raise NastranError(f"OP4 {str(path)!r} holds no matrix ({path.stat().st_size} bytes); "
                           "check that it is the OUTPUT4 file of the stiffness and mass")
    out = {}
    for name, m in mats.items():
        data = m.data
        if not sp.issparse(data) and np.ndim(data) != 2:
            # a QHH-like stack of matrices (one per Mach number and frequency): not a
            # stiffness or mass, and not a matrix a sparse array holds
            raise NastranError(f"OP4 {str(path)!r} holds {name.strip()}, an array of "
                               f"{np.ndim(data)} dimensions {np.shape(data)} (aerodynamic "
                               "matrices?), not a stiffness or mass matrix; write KGG and "
                               "MGG (or KAA and MAA) into an OP4 of their own")
        A = sp.csc_matrix(data) if sp.issparse(data) else sp.csc_matrix(np.asarray(data))
        out[name.strip()] = A.astype(complex if np.iscomplexobj(A.data) else float)
    return out


def op2_matrices(op2, op2_path) -> dict:
    """The matrix data blocks of an OP2 (``OUTPUT2 KAA,MAA//0/12``), as read by pyNastran.

    Double-precision matrices (type 2) stay float64; single-precision ones (type 1) are
    widened exactly and their names listed in the result's ``single`` attribute.

    Parameters
    ----------
    op2 : pyNastran.op2.op2.OP2
        The file as read (:func:`structfmu.nastran.modes.load_op2`).
    op2_path : path-like
        The file, for messages.

    Returns
    -------
    dict of str to scipy.sparse.csc_matrix
        Name to matrix, in the file's own units (complex matrices as complex128).
    """
    out = _Mats()
    for name, m in getattr(op2, "matrices", {}).items():
        name = name.decode() if isinstance(name, bytes) else str(name)
        if getattr(m, "is_matpool", False):
            if name.upper()[:1] in "KM":
                raise NastranError(f"matrix {name} in OP2 {str(op2_path)!r} is in DMIG (MATPOOL) "
                                   "form, which this import does not read from an OP2; punch it "
                                   "with PARAM,EXTOUT,DMIGPCH (--dmig) or write it with OUTPUT2 "
                                   "in matrix form")
            continue
        data = m.data
        if data is None:
            continue
        A = sp.csc_matrix(data) if sp.issparse(data) else sp.csc_matrix(np.asarray(data))
        if A.dtype in (np.float32, np.complex64):
            out.single.append(name.strip())
        out[name.strip()] = A.astype(complex if np.iscomplexobj(A.data) else float)
    return out


class _Mats(dict):
    """Name to matrix, with the names of the single-precision ones in ``single``."""

    def __init__(self):
        super().__init__()
        self.single: list = []


def read_dmig(pch_path, include_dirs=()) -> dict:
    """DMIG matrices of a punch file (``PARAM,EXTOUT,DMIGPCH``) with their DOF maps.

    Parameters
    ----------
    pch_path : path-like
        Bulk data holding DMIG cards.
    include_dirs : sequence of path-like
        Folders besides the file's own that its INCLUDE statements may name.

    Returns
    -------
    dict of str to (scipy.sparse.csc_matrix, list of (int, int))
        Name to (matrix, ``(id, component)`` of each row, columns alike), in the
        file's own units; symmetric matrices (IFO 6) completed; values in double
        precision whatever TIN says (the card's digits decide).
    """
    BDF = pynastran()[0]
    path = Path(pch_path)
    if not path.is_file():
        raise NastranError(f"DMIG file {str(path)!r} does not exist")
    text = path.read_text(errors="replace")
    log = QuietLog()
    model = BDF(log=log.log)
    try:
        with includes_inside(path, include_dirs), quiet_output():
            model.read_bdf(str(path), xref=False,
                           punch=not re.search(r"(?im)^\s*BEGIN\s+BULK", text))
    except NastranError:
        raise
    except Exception as exc:
        raise NastranError(f"cannot read DMIG file {str(path)!r}: {reason(exc, log)}") from None
    out = {}
    for name, d in model.dmig.items():
        if d.tin in (1, 3):  # the digits decide, as for an ASCII OP4: never cast to float32
            d.tin += 1
        A, rows, cols = d.get_matrix(is_sparse=False, apply_symmetry=True)
        order = [tuple(int(x) for x in rows[i]) for i in range(len(rows))]
        corder = [tuple(int(x) for x in cols[i]) for i in range(len(cols))]
        A = np.asarray(A, float)
        if order != corder:  # a square DMIG: columns in the rows' order
            pos = {d: j for j, d in enumerate(corder)}
            if set(pos) != set(order):
                raise NastranError(f"DMIG {name} in {str(path)!r} is not square over one DOF "
                                   "set; expected a stiffness or mass matrix")
            A = A[:, [pos[d] for d in order]]
        out[name.strip()] = (sp.csc_matrix(A), [(g, c) for g, c in order])
    if not out:
        raise NastranError(f"{str(path)!r} has no DMIG cards; punch them with "
                           "PARAM,EXTOUT,DMIGPCH or give the OP4")
    return out


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
    path = Path(op4_path)
    mats = read_op4(path)
    names = list(mats)
    k_name = k_name or pick(mats, "K", path)
    m_name = m_name or pick(mats, "M", path)
    out = []
    for label, name in (("stiffness", k_name), ("mass", m_name)):
        if name not in mats:
            raise NastranError(f"OP4 {str(path)!r} has no matrix {name!r}; it has "
                               f"{', '.join(names)}")
        A = mats[name]
        if np.iscomplexobj(A.data):
            raise NastranError(f"{label} matrix {name} in {str(path)!r} is complex")
        if A.shape[0] != A.shape[1]:
            raise DimensionError(f"{label} matrix {name} has shape {A.shape}; expected a "
                                 "square matrix")
        if A.shape[0] != len(dofs):
            raise DimensionError(f"{label} matrix {name} has {A.shape[0]} rows but the DOF "
                                 f"map has {len(dofs)} entries: the OP4 and the BDF are of "
                                 "different models, or the matrices are an a-set; give the "
                                 "DOF map of the matrices (dof_map / --dof-map)")
        out.append(A.astype(float))
    return tuple(to_si(A, dofs, u, f"{label} matrix {name}", path)
                 for label, name, A in zip(("stiffness", "mass"), (k_name, m_name), out))


def to_si(A, dofs, units, what, path):
    """A stiffness or mass matrix in the declared units, checked and in SI.

    Parameters
    ----------
    A : scipy.sparse matrix, shape (n, n)
        The matrix as read.
    dofs : list of (int, int), length n
        ``(grid, component)`` of each row.
    units : str or UnitSystem
        Declared unit system.
    what : str
        ``"stiffness matrix KGG"``, for messages.
    path : path-like
        The file, for messages.
    """
    u = unit_system(units)
    if np.iscomplexobj(A.data):
        raise NastranError(f"{what} in {str(path)!r} is complex; expected a real matrix")
    if A.shape[0] != A.shape[1]:
        raise DimensionError(f"{what} has shape {A.shape}; expected a square matrix")
    if A.shape[0] != len(dofs):
        raise DimensionError(f"{what} has {A.shape[0]} rows but the DOF map has {len(dofs)} "
                             "entries: the matrix file and the BDF are of different models, or the "
                             "matrices are an a-set; give the DOF map of the matrices "
                             "(dof_map / --dof-map)")
    A = A.astype(float).tocsc()
    bad = ~np.isfinite(A.data)
    if bad.any():
        C = A.tocoo()
        k = int(np.flatnonzero(~np.isfinite(C.data))[0])
        raise NastranError(f"{what} in {str(path)!r} holds {float(C.data[k])!r} at row "
                           f"{C.row[k] + 1}, column {C.col[k] + 1} (non-finite entries: "
                           f"{int(bad.sum())}); "
                           "write the matrix again from the model")
    big = abs(A).max() if A.nnz else 0.0
    D = (A - A.T).tocoo()
    if D.nnz and abs(D.data).max() > SYMMETRY * big:
        k = int(np.argmax(abs(D.data)))
        i, j = sorted((int(D.row[k]) + 1, int(D.col[k]) + 1))
        raise NastranError(f"{what} in {str(path)!r} is not symmetric: A - A^T reaches "
                           f"{abs(D.data[k]) / big:.2g} of its largest entry (rows {i} "
                           f"and {j}); give the structure's stiffness and mass (not a "
                           "damping or load matrix), or name them (k_name/m_name, CLI "
                           "--k-name/--m-name)")
    S = sp.diags(1.0 / dof_scale(dofs, u))
    return ((S @ A @ S) * u.energy).tocsc()


#: ``max|A - A^T| / max|A|`` accepted as symmetric: above one float32 rounding of the
#: largest entry (1.2e-7; a single-precision file), far below any real asymmetry.
SYMMETRY = 1e-6


def pick(mats, letter, path, kind="OP4"):
    """The stiffness (``letter`` K) or mass (M) matrix's name among ``mats``.

    A standard name (``KGG``, ``KNN``, ``KFF``, ``KAA``) when exactly one is there, else
    the one square matrix (larger than 1 x 1, NASTRAN's null placeholder) whose name
    starts with ``letter``.

    Parameters
    ----------
    mats : dict of str to matrix
        The file's matrices.
    letter : str
        ``"K"`` or ``"M"``.
    path : path-like
        The file, for the message.
    kind : str
        ``"OP4"``, ``"OP2"`` or ``"DMIG file"``, for the message.
    """
    names = list(mats)
    cand = [n for n in names if n.upper().startswith(letter) and mats[n].shape[0] > 1
            and mats[n].shape[0] == mats[n].shape[1]]
    standard = [n for n in cand if n.upper()[1:] in STANDARD_SETS]
    if len(standard) == 1:
        return standard[0]
    what = "stiffness" if letter == "K" else "mass"
    if not cand:
        raise NastranError(f"{kind} {str(path)!r} has matrices {', '.join(names)}, none a "
                           f"square {what} matrix named {letter}...; write the {what} matrix "
                           "into it, or name it (k_name/m_name, CLI --k-name/--m-name)")
    if len(cand) != 1:
        raise NastranError(f"{kind} {str(path)!r} has matrices {', '.join(names)}; name the "
                           f"{what} matrix (k_name/m_name, CLI --k-name/--m-name)")
    return cand[0]


def read_dmig_matrices(pch_path, units, k_name=None, m_name=None, include_dirs=()):
    """Stiffness, mass and their DOF map from a DMIG punch file, in SI.

    Parameters
    ----------
    pch_path : path-like
        The punch file (``PARAM,EXTOUT,DMIGPCH``: ``KAAX``, ``MAAX``...).
    units : str or UnitSystem
        Declared unit system.
    k_name, m_name : str, optional
        DMIG names; default as :func:`pick`.
    include_dirs : sequence of path-like
        Folders besides the file's own that its INCLUDE statements may name.

    Returns
    -------
    K, M : scipy.sparse.csc_matrix, shape (n, n)
        SI, on ``dofs``.
    dofs : list of (int, int)
        ``(id, component)`` of each row (the stiffness matrix's order).
    """
    u = unit_system(units)
    mats = read_dmig(pch_path, include_dirs)
    shaped = {k: v[0] for k, v in mats.items()}
    k_name = k_name or pick(shaped, "K", pch_path, "DMIG file")
    m_name = m_name or pick(shaped, "M", pch_path, "DMIG file")
    for name in (k_name, m_name):
        if name not in mats:
            raise NastranError(f"{str(pch_path)!r} has no DMIG {name!r}; it has "
                               f"{', '.join(mats)}")
    K, dofs = mats[k_name]
    M, mdofs = mats[m_name]
    if set(mdofs) - set(dofs):
        g, c = sorted(set(mdofs) - set(dofs))[0]
        raise NastranError(f"DMIG {m_name} has grid {g} component {c}, which {k_name} has not; "
                           "punch both matrices of one model")
    pos = {d: i for i, d in enumerate(mdofs)}
    row = {d: i for i, d in enumerate(dofs)}
    P = sp.csc_matrix((np.ones(len(mdofs)), ([row[d] for d in mdofs],
                                              list(range(len(mdofs))))),
                      shape=(len(dofs), len(mdofs)))
    M = (P @ M @ P.T).tocsc()
    del pos
    # a square DMIG (IFO 1) is taken as written: checked for symmetry as an OP4 is
    return (to_si(K, dofs, u, f"DMIG {k_name}", pch_path),
            to_si(M, dofs, u, f"DMIG {m_name}", pch_path), list(dofs))
