"""First-order form (Eq. 9-10), frequency responses, full-FEM reference FRFs.

State ordering for the dense form: ``x = [z_e, z_o, z_e', z_o', x_f]`` with ``x_f`` the
accelerometer low-pass states (:mod:`structfmu.sensors`), if the model has one.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from structfmu.fem import Truss, assemble, input_matrix, output_matrix
from structfmu.reduced import ReducedModel
from structfmu.sensors import filter_blocks


def reduced_matrices(model: ReducedModel):
    """Dense ``(K_hat, D_hat, B_hat, C_hat)`` of Eq. (7) with ``M_hat = I``."""
    n_m, n_r = model.n_modes, model.n_ritz
    n = n_m + n_r
    K = np.zeros((n, n))
    D = np.zeros((n, n))
    K[:n_m, :n_m] = np.diag(model.omega**2)
    D[:n_m, :n_m] = np.diag(model.modal_damping)
    K[n_m:, n_m:] = model.K_oo
    D[n_m:, n_m:] = model.D_oo
    B = np.vstack([model.B_e, model.B_o])
    C = np.hstack([model.C_e, model.C_o])
    return K, D, B, C


def first_order(model: ReducedModel):
    """Matrices ``(A, B, C, D)`` of Eq. (9)-(10).

    Returns
    -------
    A : ndarray, shape (2n, 2n)
    B : ndarray, shape (2n, n_in)
    C : ndarray, shape (n_out, 2n)
    D : ndarray, shape (n_out, n_in)
        Non-zero only on acceleration rows, and zero there too when the model has an
        accelerometer low-pass (its states are appended to ``x``).
    """
    K, Dm, Bh, Ch = reduced_matrices(model)
    n = K.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -Dm]])
    B = np.vstack([np.zeros((n, model.n_inputs)), Bh])
    acc = model.is_accel
    C = np.hstack([Ch, np.zeros_like(Ch)])
    rate = model.is_rate
    if rate.any():
        C[rate] = np.hstack([np.zeros_like(Ch[rate]), Ch[rate]])
    D = np.zeros((model.n_outputs, model.n_inputs))
    if acc.any():
        C[acc] = np.hstack([-Ch[acc] @ K, -Ch[acc] @ Dm])
        D[acc] = Ch[acc] @ Bh
    if model.n_filter_states:
        Af, Bf, Cf = filter_blocks(model.accel_lowpass, int(acc.sum()))
        nf = Af.shape[0]
        A = np.block([[A, np.zeros((2 * n, nf))], [Bf @ C[acc], Af]])
        B = np.vstack([B, Bf @ D[acc]])
        C = np.hstack([C, np.zeros((model.n_outputs, nf))])
        C[acc] = 0.0
        C[np.ix_(acc, np.arange(2 * n, 2 * n + nf))] = Cf
        D[acc] = 0.0
    return A, B, C, D


def to_statespace(model: ReducedModel):
    """The reduced model as a python-control ``StateSpace`` with named signals."""
    # deferred: python-control takes about 1 s to load
    import control

    A, B, C, D = first_order(model)
    return control.ss(A, B, C, D, inputs=list(model.input_names),
                      outputs=list(model.output_names), name=model.name)


def frf(model: ReducedModel, freqs_hz, outputs=None, inputs=None):
    """Frequency response, O(n_modes) per frequency for the modal block.

    Parameters
    ----------
    model : ReducedModel
    freqs_hz : array_like, shape (n_f,)
        Frequencies (Hz).
    outputs, inputs : list of str, optional
        Channel names (default all).

    Returns
    -------
    ndarray of complex, shape (n_f, n_out, n_in)
        Output per input (output unit per N).
    """
    sub = model.select(inputs, outputs)
    w = 2 * np.pi * np.asarray(freqs_hz, float)
    # modal block: diagonal receptances, (n_m, n_f)
    g = 1.0 / (sub.omega[:, None] ** 2 - w[None] ** 2 + 1j * sub.modal_damping[:, None] * w)
    H = np.einsum("ok,kf,ki->foi", sub.C_e, g, sub.B_e)
    if sub.n_ritz:
        n_r = sub.n_ritz
        Z = (sub.K_oo[None] - (w**2)[:, None, None] * np.eye(n_r)[None]
             + 1j * w[:, None, None] * sub.D_oo[None])
        X = np.linalg.solve(Z, np.broadcast_to(sub.B_o, (len(w), *sub.B_o.shape)))
        H = H + np.einsum("or,fri->foi", sub.C_o, X)
    acc = sub.is_accel
    if acc.any():
        H[:, acc] *= -(w**2)[:, None, None]
        if sub.accel_lowpass is not None:
            H[:, acc] *= sub.accel_lowpass.response(np.asarray(freqs_hz, float))[:, None, None]
    rate = sub.is_rate
    if rate.any():
        H[:, rate] *= (1j * w)[:, None, None]
    return H


def full_frf(truss: Truss, freqs_hz, outputs, inputs, alpha=0.0, beta=0.0):
    """Full-FEM frequency response with damping ``alpha M + beta K``.

    One sparse LU per frequency; for reference and validation.

    Parameters
    ----------
    truss : Truss
        The full model.
    freqs_hz : array_like, shape (n_f,)
        Frequencies (Hz).
    outputs : sequence of str
        Output channel names (``n_out``); rate and acceleration outputs are
        differentiated once and twice.
    inputs : sequence of str
        Input channel names (``n_in``).
    alpha : float
        Mass-proportional damping (1/s).
    beta : float
        Stiffness-proportional damping (s).

    Returns
    -------
    ndarray of complex, shape (n_f, n_out, n_in)
        Output per unit input, in the output unit per input unit (e.g. m/N, rad/N).
    """
    K, M = assemble(truss)
    E = input_matrix(truss)
    H = output_matrix(truss)
    in_names = [c.name for c in truss.input_channels]
    out_names = [c.name for c in truss.outputs]
    kinds = [c.kind for c in truss.outputs]
    ii = [in_names.index(n) for n in inputs]
    oo = [out_names.index(n) for n in outputs]
    Ei = E[:, ii].toarray()
    Ho = H[oo]
    acc = np.array([kinds[o] == "accel" for o in oo])
    rate = np.array([kinds[o] == "rate" for o in oo])
    w = 2 * np.pi * np.asarray(freqs_hz, float)
    out = np.empty((len(w), len(oo), len(ii)), complex)
    K = K.astype(complex)
    M = M.astype(complex)
    for f, wf in enumerate(w):
        Z = (K * (1 + 1j * wf * beta) + M * (-(wf**2) + 1j * wf * alpha)).tocsc()
        X = spla.splu(Z).solve(Ei.astype(complex))
        y = Ho @ X
        if acc.any():
            y[acc] *= -(wf**2)
        if rate.any():
            y[rate] *= 1j * wf
        out[f] = y
    return out
