"""Writing NASTRAN files: test data, benchmarks, and the built-in models as decks."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from structfmu.fem import assemble
from structfmu.nastran.deck import dof_scale
from structfmu.nastran.pyn import QuietLog, pynastran
from structfmu.nastran.spec import unit_system

__all__ = ["write_modes_op2", "write_truss_deck"]

BIGMAT_ROWS = 65535  # larger OP4 matrices need the BIGMAT layout


def write_modes_op2(op2_path, lam, phi, grids, units="SI", gen_mass=None):
    """Write eigenvalues and eigenvectors as a SOL 103-style OP2.

    The eigenvector table (OUGV1, single precision) always; the eigenvalues also travel
    in its header (single precision), which :func:`read_modes` reads when LAMA is
    absent.  With ``gen_mass`` the LAMA table too (eigenvalue, generalized mass and
    stiffness, float32 as NASTRAN writes them), and the vectors scaled to that mass
    (``phi / sqrt(gen_mass)`` is what NASTRAN's MAX or POINT normalisation gives).

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
    gen_mass : ndarray, shape (n_modes,), optional
        Generalized masses to write in LAMA (file units); None: no LAMA table.
    """
    u = unit_system(units)
    OP2 = pynastran()[1]
    # deferred: optional dependency (the nastran extra)
    from pyNastran.op2.tables.oug.oug_eigenvectors import RealEigenvectorArray

    grids = np.asarray(grids, int)
    dofs = [(int(g), c) for g in grids for c in range(1, 7)]
    native = phi / dof_scale(dofs, u)[:, None] * np.sqrt(u.energy)
    if gen_mass is not None:
        native = native * np.sqrt(np.asarray(gen_mass, float))[None, :]
    data = native.T.reshape(len(lam), len(grids), 6).astype(np.float32)
    node_gridtype = np.column_stack([grids, np.ones(len(grids), int)]).astype(np.int32)
    modes = np.arange(1, len(lam) + 1)
    vec = RealEigenvectorArray.add_modal_case("OUGV1", node_gridtype, data, 1, modes,
                                              np.asarray(lam, float),
                                              np.sqrt(np.abs(lam)) / (2 * np.pi))
    vec.table_code = 7  # eigenvector (add_modal_case leaves the displacement code 1)
    vec.data_code["table_code"] = 7
    op2 = OP2(log=QuietLog().log)
    op2.set_mode("msc")
    op2.eigenvectors[1] = vec
    if gen_mass is not None:
        from pyNastran.op2.tables.lama_eigenvalues.lama_objects import RealEigenvalues

        eig = RealEigenvalues("MODES", "LAMA", len(lam))
        lam_f = np.asarray(lam, float)
        for k in range(len(lam)):
            eig.add_f06_line((k + 1, k + 1, lam_f[k], np.sqrt(abs(lam_f[k])),
                              np.sqrt(abs(lam_f[k])) / (2 * np.pi), float(gen_mass[k]),
                              float(gen_mass[k] * lam_f[k])), k)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pyNastran's "downcasting" notice
        op2.write_op2(str(op2_path), nastran_format="msc")
    if gen_mass is not None:
        _append_lama(op2_path, eig)
    return Path(op2_path)


def _append_lama(op2_path, eig) -> None:
    """Append a LAMA table before the OP2's closing ``[4, 0, 4]``.

    pyNastran 1.4.1's writer skips LAMA on purpose (its table list), but the table
    object writes itself; this closes it as the writer closes every other table.
    """
    import io
    import struct

    path = Path(op2_path)
    data = path.read_bytes()
    close = struct.pack("<3i", 4, 0, 4)
    if not data.endswith(close):  # pragma: no cover - another writer
        raise RuntimeError(f"{path}: unexpected OP2 ending; cannot append LAMA")
    with open(path, "wb") as f:
        f.write(data[:-len(close)])
        itable = eig.write_op2(f, io.StringIO(), -1, True, (1, 1, 2026), endian=b"<")
        f.write(struct.pack("<9i", 4, itable, 4, 4, 1, 4, 4, 0, 4))
        f.write(close)
        f.write(close)


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
    BDF, _, OP4 = pynastran()
    model = BDF(log=QuietLog().log)
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
    model.write_bdf(str(bdf_path), size=16, is_double=False, close=True, enddata=True)

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
        OP4(log=QuietLog().log).write_op4(str(op4_path), {k: (6, v) for k, v in mats.items()},
                                  name_order=list(mats), is_binary=False)
    else:  # pyNastran's writer packs row indices into 16 bits unless BIGMAT is asked for
        from pyNastran.op4.op4 import _write_sparse_matrix_ascii

        with open(op4_path, "w") as f:
            for k, v in mats.items():
                _write_sparse_matrix_ascii(f, k, v, form=6, is_big_mat=True)
    return Path(bdf_path), Path(op4_path)


def write_matrices_op2(op2_path, matrices, *, precision="double"):
    """Write real matrices as OUTPUT2 matrix data blocks (``OUTPUT2 KAA,MAA//0/12``).

    pyNastran 1.4.1 reads OP2 matrices but cannot write them; this writes the layout
    its reader (``read_matrix_mat``) and NASTRAN's OUTPUT2 documentation describe, 32-bit
    little-endian, after the header pyNastran's own writer gives.  Per data block: the
    name record, record -1 (the 7-word trailer: ``101 + k``, columns, rows, form, type,
    the largest column in words, density x 10000), records -2 (name), then one record
    per column (markers ``[-3 - j, 1, 1]`` followed by its strings, each ``[first row,
    values...]`` over consecutive non-zero rows, its key the number of value words as
pyNastran reads it; a null column has none), closed by
    ``[-3 - ncols, 1, 0]`` and the end-of-block ``0``.  Test data: no NASTRAN run wrote
    these files.

    Parameters
    ----------
    op2_path : path-like
        File to write.
    matrices : dict of str to array_like or scipy.sparse matrix
        Name (up to 8 characters) to real matrix, in the order to write.
    precision : {"double", "single"}
        Type 2 (float64) or 1 (float32) words.
    """
    import struct

    if precision not in ("double", "single"):
        raise ValueError(f"precision={precision!r}; expected 'double' or 'single'")
    OP2 = pynastran()[1]
    op2 = OP2(log=QuietLog().log)
    op2.set_mode("msc")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        op2.write_op2(str(op2_path), nastran_format="msc")
    path = Path(op2_path)
    head = path.read_bytes()
    close = struct.pack("<3i", 4, 0, 4)
    if not head.endswith(close):  # pragma: no cover - another writer
        raise RuntimeError(f"{path}: unexpected OP2 ending; cannot append matrices")
    tout, ftype, fsize = (2, "d", 8) if precision == "double" else (1, "f", 4)

    def marker(*values):
        return b"".join(struct.pack("<3i", 4, v, 4) for v in values)

    def record(payload, words=None):
        words = len(payload) // 4 if words is None else words
        return marker(words) + struct.pack("<i", len(payload)) + payload \
            + struct.pack("<i", len(payload))

    out = [head[:-len(close)]]
    for k, (name, A) in enumerate(matrices.items()):
        A = sp.csc_matrix(A)
        A.eliminate_zeros()
        A.sort_indices()
        nrows, ncols = A.shape
        form = 6 if nrows == ncols and abs(A - A.T).max() == 0 else (1 if nrows == ncols else 2)
        words = np.diff(A.indptr) * (fsize // 4)
        density = int(10000 * A.nnz / max(nrows * ncols, 1))
        label = name.encode("ascii").ljust(8)[:8]
        out.append(record(label))
        out.append(marker(-1))
        out.append(record(struct.pack("<7i", 101 + k, ncols, nrows, form, tout,
                                      int(words.max(initial=0)), density)))
        out.append(marker(-2, 1, 0))
        out.append(record(label + struct.pack("<2i", 170, 170)))
        for j in range(ncols):
            out.append(marker(-3 - j, 1, 1))
            rows = A.indices[A.indptr[j]:A.indptr[j + 1]]
            vals = A.data[A.indptr[j]:A.indptr[j + 1]]
            breaks = np.flatnonzero(np.diff(rows) != 1) + 1
            for r, v in zip(np.split(rows, breaks), np.split(vals, breaks)):
                if r.size:
                    out.append(record(struct.pack(f"<i{r.size}{ftype}", int(r[0]) + 1,
                                                  *v.tolist()), r.size * fsize // 4))
        out.append(marker(-3 - ncols, 1, 0))
        out.append(close)
    out.append(close)
    path.write_bytes(b"".join(out))
    return path
