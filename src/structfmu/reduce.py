"""Model reduction by eigenvectors plus Gram-Schmidt static Ritz vectors (Eq. 3-8).

1. The lowest ``n_modes`` eigenpairs of ``K phi = lambda M phi`` by shift-invert Lanczos
   (:func:`scipy.sparse.linalg.eigsh`) around ``shift`` (0 for constrained models, a
   small negative value for free-free ones), mass-normalised; rigid-body eigenvalues are
   set to exactly zero.
2. One static Ritz vector per active member: ``T_r = (K - shift M)^-1 F`` with ``F`` the
   unit equal-and-opposite loads at the member's ends.
3. Gram-Schmidt against the mass-weighted eigenvectors, Eq. (5):
   ``T_o = T_r - T_e T_e^T M T_r`` (applied twice for round-off), then mass-orthonormalised
   among themselves so that ``T_o^T M T_o = I``.
4. Reduced matrices, Eq. (7): ``M = diag(I, I)``, ``K = diag(Lambda, T_o^T K T_o)``,
   ``E = [T_e^T E; T_o^T E]``; damping per mode and/or ``alpha M + beta K`` (Eq. 8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from structfmu.errors import ReductionError
from structfmu.fem import Truss, assemble, channel_matrix, input_matrix, output_matrix
from structfmu.reduced import ReducedModel


@dataclass(frozen=True)
class Damping:
    """Damping specification for the reduced model.

    Parameters
    ----------
    zeta : float or array_like, shape (n_modes,)
        Modal damping ratios of the eigenvectors.
    alpha, beta : float
        Proportional damping ``D = alpha M + beta K`` (Eq. 8), added to both blocks.
    zeta_ritz : float
        Damping ratio given to each eigen-direction of the Ritz block.
    """

    zeta: object = 0.0
    alpha: float = 0.0
    beta: float = 0.0
    zeta_ritz: float = 0.0


class _Factor:
    """Sparse LU of ``K - shift M`` with a singularity check."""

    def __init__(self, K, M, shift):
        A = (K - shift * M).tocsc() if shift else K.tocsc()
        try:
            self.lu = spla.splu(A)
        except RuntimeError:
            self.lu = None
        if self.lu is not None:
            u = np.abs(self.lu.U.diagonal())
            if u.size and u.min() <= 1e-11 * u.max():
                self.lu = None
        if self.lu is None:
            if shift:
                raise ReductionError(f"K - shift*M is singular for shift={shift}; choose "
                                     "another (negative) shift")
            raise ReductionError("the stiffness matrix is singular: the model has rigid-body "
                                 "modes or a mechanism; pass a negative shift (e.g. shift=-1.0) "
                                 "to reduce a free-free model, or fix more DOFs")

    def solve(self, b):
        return self.lu.solve(np.asarray(b, float))


def _check_mass(M, truss=None):
    d = M.diagonal()
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        where = f"free DOF {bad[0]}"
        if truss is not None:
            g = truss.free_dofs[bad[0]]
            where = f"node {g // 3} direction {'xyz'[g % 3]}"
        raise ReductionError(f"the mass matrix is not positive definite: {where} has no mass; "
                             "add a node mass or fix that DOF")


def eigenpairs(K, M, n_modes: int, shift: float = 0.0, truss=None):
    """Lowest eigenpairs by shift-invert Lanczos, mass-normalised.

    Parameters
    ----------
    K, M : scipy.sparse matrix, shape (n, n)
        Stiffness (N/m) and mass (kg).
    n_modes : int
        Number of eigenpairs.
    shift : float
        Shift ``sigma`` ((rad/s)^2); negative for free-free models.
    truss : Truss, optional
        Only to name a massless DOF in an error message.

    Returns
    -------
    lam : ndarray, shape (n_modes,)
        Eigenvalues ``omega^2`` ((rad/s)^2), ascending, rigid-body ones set to 0.
    phi : ndarray, shape (n, n_modes)
        Mass-normalised eigenvectors.
    fac : object
        Sparse LU of ``K - shift M``, reused by :func:`ritz_vectors`.
    """
    n = K.shape[0]
    if n_modes < 1:
        raise ReductionError(f"n_modes must be at least 1, got {n_modes}")
    if n_modes > n:
        raise ReductionError(f"{n_modes} modes requested but the model has only {n} free "
                             "DOFs")
    _check_mass(M, truss)
    fac = _Factor(K, M, shift)
    if n_modes >= n - 1 or n <= 200:
        # small problem: dense solve (eigsh needs k < n - 1)
        lam, phi = la.eigh(K.toarray(), M.toarray(), subset_by_index=[0, n_modes - 1])
    else:
        op = spla.LinearOperator((n, n), matvec=fac.solve, dtype=float)
        # a fixed start vector: ARPACK's default is random, and a basis drawn anew in each
        # run makes every build of a model with repeated or close modes differ
        v0 = np.random.default_rng(0).standard_normal(n)
        try:
            lam, phi = spla.eigsh(K, k=n_modes, M=M, sigma=shift, which="LM", OPinv=op,
                                  tol=1e-12, v0=v0)
        except spla.ArpackError as exc:  # pragma: no cover - rare
            raise ReductionError(f"the eigensolver did not converge ({exc}); check that the "
                                 "mass matrix is positive definite") from None
    order = np.argsort(lam)
    lam, phi = lam[order], phi[:, order]
    mn = np.sqrt(np.einsum("ij,ij->j", phi, M @ phi))
    phi = phi / mn
    scale = np.median(K.diagonal() / M.diagonal())
    lam = np.where(np.abs(lam) < 1e-10 * scale, 0.0, lam)
    if np.any(lam < 0):
        raise ReductionError(f"negative eigenvalue {lam.min():.3g}: the stiffness matrix is "
                             "not positive semi-definite")
    return lam, phi, fac


def ritz_vectors(K, M, phi, loads, fac, names=None):
    """Static Ritz vectors orthogonalised against the eigenvectors (Eq. 5).

    Returns ``T_o`` with ``T_o^T M T_o = I`` and ``phi^T M T_o = 0``.

    Parameters
    ----------
    K, M : scipy.sparse matrix, shape (n, n)
        Stiffness (N/m) and mass (kg) on the free DOFs.
    phi : ndarray, shape (n, n_m)
        Mass-normalised eigenvectors.
    loads : scipy.sparse matrix or ndarray, shape (n, n_r) or (n,)
        Load patterns, one column per Ritz vector (columns of ``E``).
    fac : object
        Factorisation of ``K - shift M`` returned third by :func:`eigenpairs`.
    names : sequence of str, optional
        The loads' names, for the message of a singular Ritz block.

    Returns
    -------
    T_o : ndarray, shape (n, n_r)
        Mass-orthonormal Ritz vectors.
    """
    X = fac.solve(loads.toarray() if sp.issparse(loads) else loads)
    if X.ndim == 1:
        X = X[:, None]
    ref = np.sqrt(np.einsum("ij,ij->j", X, M @ X))
    To = X.copy()
    for _ in range(2):  # Gram-Schmidt, twice for round-off ("twice is enough")
        To = To - phi @ (phi.T @ (M @ To))
    G = To.T @ (M @ To)
    G = 0.5 * (G + G.T)
    w = la.eigvalsh(G)
    if w.min() <= 1e-12 * max(ref.max() ** 2, 1e-300):
        # with many modes kept the residuals are small beside their static shapes (1e-6
        # of them at 280 EOS modes) yet independent: judge each by its own size (the
        # orthonormal vectors are those of the unscaled columns)
        norm = np.sqrt(np.maximum(np.diag(G), 0.0))
        spanned = int(np.sum(norm <= 1e-9 * ref))
        if spanned:
            raise ReductionError(f"the Ritz block is singular: the static shapes of "
                                 f"{spanned} of its {ref.size} loads lie in the span of the "
                                 f"{phi.shape[1]} retained eigenvectors; drop their Ritz "
                                 "vectors or keep fewer modes")
        G = G / np.outer(norm, norm)
        w, v = la.eigh(G)
        if w[0] <= 1e-12:   # the load that leads the most dependent combination
            j = int(np.argmax(np.abs(v[:, 0])))
            load = repr(names[j]) if names is not None else f"number {j}"
            n, n_m = K.shape[0], phi.shape[1]
            raise ReductionError(
                f"the Ritz block is singular: with {n_m} of the {n} free DOFs kept as "
                f"eigenvectors, the static shapes of the {ref.size} loads are linearly "
                f"dependent in what is left (their smallest Gram eigenvalue {w[0]:.1e} of "
                f"1); keep fewer modes, or drop the Ritz vector of load {load}")
        To = To / norm
    L = la.cholesky(G, lower=True)
    To = la.solve_triangular(L, To.T, lower=True).T
    # one more orthogonalisation pass after normalisation keeps phi^T M T_o at round-off
    To = To - phi @ (phi.T @ (M @ To))
    G = To.T @ (M @ To)
    L = la.cholesky(0.5 * (G + G.T), lower=True)
    return la.solve_triangular(L, To.T, lower=True).T


def reduce(truss: Truss, n_modes: int, *, ritz: bool = True, ritz_inputs=None,
           shift: float | None = None, damping: Damping | None = None,
           return_basis: bool = False):
    """Reduce a truss to eigenvectors plus Gram-Schmidt static Ritz vectors.

    Parameters
    ----------
    truss : Truss
        The full model.
    n_modes : int
        Number of eigenvectors (rigid-body modes included).
    ritz : bool
        Append one static Ritz vector per active member (Eq. 3-7).
    ritz_inputs : list of str, optional
        Input channels that get a Ritz vector (default: every ``fc_*`` actuator input).
    shift : float, optional
        Shift for shift-invert Lanczos ((rad/s)^2); default 0 (constrained model).
    damping : Damping, optional
        Damping specification (default undamped).
    return_basis : bool
        Also return the basis ``T = [T_e, T_o]`` on the free DOFs.

    Returns
    -------
    ReducedModel, or (ReducedModel, ndarray of shape (n_free, n_modes + n_ritz))
    """
    K, M = assemble(truss)
    names = [c.name for c in truss.input_channels]
    sel = []
    if ritz:
        sel = ritz_inputs if ritz_inputs is not None else [f"fc_{a.name}" for a in truss.active]
    meta = {"model": truss.name, "n_dof": int(truss.n_dof),
            "input_units": [c.unit for c in truss.input_channels],
            "actuators": {a.name: {"stack": getattr(a.stack, "name", ""),
                                   "ch": float(getattr(a.stack, "ch", 0.0))}
                          for a in truss.active}}
    return reduce_matrices(K, M, input_matrix(truss), output_matrix(truss), n_modes,
                           input_names=names,
                           output_names=[c.name for c in truss.outputs],
                           output_kinds=[c.kind for c in truss.outputs],
                           ritz_inputs=sel, shift=shift, damping=damping, name=truss.name,
                           meta=meta, return_basis=return_basis, truss=truss)


def reduce_matrices(K, M, E, H, n_modes: int, *, input_names, output_names, output_kinds,
                    ritz_inputs=(), shift: float | None = None,
                    damping: Damping | None = None, name: str = "reduced",
                    meta: dict | None = None, return_basis: bool = False, truss=None):
    """Reduce sparse ``K``, ``M`` with influence and sensor matrices (Eq. 3-8).

    The matrix form of :func:`reduce`, for models that come as matrices (a NASTRAN
    OUTPUT4 file, :mod:`structfmu.nastran`) rather than as a :class:`Truss`.

    Parameters
    ----------
    K, M : scipy.sparse matrix, shape (n, n)
        Stiffness (N/m, N m/rad) and mass (kg, kg m^2) on the free DOFs.
    E : scipy.sparse matrix, shape (n, n_in)
        Influence matrix: one column per input channel.
    H : scipy.sparse matrix, shape (n_out, n)
        Sensor matrix: one row per output channel.
    n_modes : int
        Number of eigenvectors (rigid-body modes included).
    input_names, output_names, output_kinds : sequence of str
        Channel names (``n_in``, ``n_out``) and output kinds (:data:`fem.OUTPUT_KINDS`).
    ritz_inputs : sequence of str
        Input channels that get a static Ritz vector (empty: eigenvectors only).
    shift : float, optional
        Shift for shift-invert Lanczos ((rad/s)^2); default 0 (constrained model).
    damping : Damping, optional
        Damping specification (default undamped).
    name : str
        Model name.
    meta : dict, optional
        Metadata merged into the model's (``n_free``, ``n_modes``, ``n_ritz``, ``shift``
        and ``damping`` are filled in here).
    return_basis : bool
        Also return the basis ``T = [T_e, T_o]``, shape (n, n_modes + n_ritz).
    truss : Truss, optional
        Only to name a massless DOF in an error message.

    Returns
    -------
    ReducedModel, or (ReducedModel, ndarray)
    """
    shift = 0.0 if shift is None else float(shift)
    lam, phi, fac = eigenpairs(K, M, n_modes, shift, truss)
    names = list(input_names)
    for s in ritz_inputs:
        if s not in names:
            raise ReductionError(f"no input channel {s!r} for a Ritz vector; inputs: "
                                 f"{', '.join(names)}")
    cols = [names.index(s) for s in ritz_inputs]
    To = (ritz_vectors(K, M, phi, E[:, cols], fac, list(ritz_inputs)) if cols
          else np.zeros((K.shape[0], 0)))
    model = reduced_from_basis(lam, phi, To, K, E, H, input_names=names,
                               output_names=output_names, output_kinds=output_kinds,
                               damping=damping, name=name,
                               meta={**(meta or {}), "n_free": int(K.shape[0]),
                                     "n_modes": int(n_modes), "shift": shift})
    if return_basis:
        return model, np.hstack([phi, To])
    return model


def reduced_from_basis(lam, phi, To, K, E, H, *, input_names, output_names, output_kinds,
                       damping: Damping | None = None, name: str = "reduced",
                       meta: dict | None = None) -> ReducedModel:
    """The reduced matrices of Eq. (7)-(8) from a basis ``[T_e, T_o]``.

    Parameters
    ----------
    lam : ndarray, shape (n_m,)
        Eigenvalues ``omega^2`` of the mass-normalised eigenvectors ((rad/s)^2).
    phi : ndarray, shape (n, n_m)
        Mass-normalised eigenvectors ``T_e``.
    To : ndarray, shape (n, n_r)
        Gram-Schmidt Ritz vectors, ``T_o^T M T_o = I`` (``n_r`` may be 0).
    K : scipy.sparse matrix, shape (n, n), or None
        Stiffness; needed only when ``n_r > 0``.
    E, H : scipy.sparse matrix or ndarray, shapes (n, n_in) and (n_out, n)
        Influence and sensor matrices.
    input_names, output_names, output_kinds, damping, name, meta
        As in :func:`reduce_matrices`.
    """
    damping = damping or Damping()
    omega = np.sqrt(lam)
    zeta = np.broadcast_to(np.asarray(damping.zeta, float), omega.shape)
    c_e = 2 * zeta * omega + damping.alpha + damping.beta * lam
    n_r = To.shape[1]
    Koo = To.T @ (K @ To) if n_r else np.zeros((0, 0))
    Koo = 0.5 * (Koo + Koo.T)
    Doo = damping.alpha * np.eye(n_r) + damping.beta * Koo
    if damping.zeta_ritz and n_r:
        w, V = la.eigh(Koo)
        Doo = Doo + (V * (2 * damping.zeta_ritz * np.sqrt(np.maximum(w, 0)))) @ V.T
    Ed = E.toarray() if sp.issparse(E) else np.asarray(E, float)
    return ReducedModel(
        omega=omega, modal_damping=c_e, B_e=phi.T @ Ed, C_e=(H @ phi),
        K_oo=Koo, D_oo=Doo, B_o=To.T @ Ed, C_o=(H @ To),
        input_names=tuple(input_names), output_names=tuple(output_names),
        output_kinds=tuple(output_kinds), name=name,
        meta={**(meta or {}), "n_ritz": int(n_r),
              "damping": {"zeta": np.asarray(damping.zeta).tolist(), "alpha": damping.alpha,
                          "beta": damping.beta, "zeta_ritz": damping.zeta_ritz}},
    )


def static_compliance(truss: Truss, inputs, outputs=None):
    """Full-FEM static response ``H K^-1 E`` for some inputs (constrained models).

    Parameters
    ----------
    truss : Truss
        The full model; constrained (``K`` not singular).
    inputs : list of str
        Input channel names.
    outputs : list of channels, optional
        Rows to read; default the elongations of the inputs' own channels.

    Returns
    -------
    ndarray, shape (n_rows, n_inputs)
    """
    K, M = assemble(truss)
    fac = _Factor(K, M, 0.0)
    chans = {c.name: c for c in truss.input_channels}
    E = channel_matrix([chans[n] for n in inputs], truss.n_dof).T.tocsr()[truss.free_dofs]
    X = fac.solve(E.toarray())
    rows = outputs if outputs is not None else [chans[n] for n in inputs]
    H = channel_matrix(rows, truss.n_dof).tocsc()[:, truss.free_dofs]
    return H @ X
