"""Exact discretisation of the reduced model for zero-order-hold inputs.

For a step ``h`` each mode ``q'' + c q' + omega^2 q = f`` (``f`` held constant) is
advanced by closed-form 2x2 blocks::

    [q, v](k+1) = Phi [q, v](k) + Gamma f(k)

underdamped modes with ``omega h >= 1e-2`` use the analytic expressions, rigid-body
modes (``omega = 0``) their own closed form, and the rest (slow or over-damped modes)
the exponential of the 3x3 augmented matrix, batched.  The dense Ritz block uses
:func:`scipy.linalg.expm` of its augmented matrix, so its high, stiff frequencies are
handled exactly whatever ``h``.  This is the kernel the structure FMU steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la

from fmukit.timing import same_step
from structfmu.reduced import ReducedModel
from structfmu.sensors import filter_blocks
from structfmu.statespace import first_order


def modal_zoh(omega, c, h):
    """Exact ZOH blocks of ``q'' + c q' + omega^2 q = f`` for a step ``h``.

    Parameters
    ----------
    omega, c : ndarray, shape (n,)
        Natural frequencies (rad/s) and damping coefficients (1/s).
    h : float
        Step (s).

    Returns
    -------
    tuple of six ndarrays, shape (n,)
        ``a11, a12, a21, a22`` (``Phi``) and ``g1, g2`` (``Gamma``).
    """
    omega = np.asarray(omega, float)
    c = np.broadcast_to(np.asarray(c, float), omega.shape)
    n = omega.shape[0]
    a11, a12, a21, a22, g1, g2 = (np.empty(n) for _ in range(6))

    rigid = omega == 0.0
    under = (~rigid) & (c < 2 * omega) & (omega * h >= 1e-2)
    other = ~(rigid | under)

    if under.any():
        w, cc = omega[under], c[under]
        s = cc / 2
        wd = np.sqrt(w**2 - s**2)
        e = np.exp(-s * h)
        co, si = np.cos(wd * h), np.sin(wd * h)
        a11[under] = e * (co + s / wd * si)
        a12[under] = e * si / wd
        a21[under] = -(w**2) * e * si / wd
        a22[under] = e * (co - s / wd * si)
        g1[under] = (1.0 - a11[under]) / w**2
        g2[under] = a12[under]
    if rigid.any():
        cc = c[rigid]
        damped = cc > 0
        x = cc * h
        # (1 - e^{-ch})/c and (h - (1 - e^{-ch})/c)/c, with their c -> 0 limits
        em = np.where(damped, -np.expm1(-x) / np.where(damped, cc, 1.0), h)
        gg = np.where(damped, (h - em) / np.where(damped, cc, 1.0), h * h / 2)
        a11[rigid] = 1.0
        a12[rigid] = em
        a21[rigid] = 0.0
        a22[rigid] = np.exp(-x)
        g1[rigid] = gg
        g2[rigid] = em
    if other.any():
        k = int(other.sum())
        Aug = np.zeros((k, 3, 3))
        Aug[:, 0, 1] = 1.0
        Aug[:, 1, 0] = -omega[other] ** 2
        Aug[:, 1, 1] = -c[other]
        Aug[:, 1, 2] = 1.0
        E = la.expm(Aug * h)
        a11[other], a12[other] = E[:, 0, 0], E[:, 0, 1]
        a21[other], a22[other] = E[:, 1, 0], E[:, 1, 1]
        g1[other], g2[other] = E[:, 0, 2], E[:, 1, 2]
    return a11, a12, a21, a22, g1, g2


def block_zoh(K, D, h):
    """Exact ZOH ``(Phi, Gamma)`` of ``q'' + D q' + K q = f`` (dense block, M = I).

    Parameters
    ----------
    K, D : ndarray, shape (n, n)
        Block stiffness (1/s^2) and damping (1/s), e.g. ``K_oo`` and ``D_oo`` of the
        Ritz block.
    h : float
        Step (s).

    Returns
    -------
    Phi : ndarray, shape (2n, 2n)
        State transition on ``[q, v]``.
    Gamma : ndarray, shape (2n, n)
        Input matrix for the held ``f``; both are ``(0, 0)`` when ``n = 0``.
    """
    n = K.shape[0]
    if n == 0:
        return np.zeros((0, 0)), np.zeros((0, 0))
    Aug = np.zeros((3 * n, 3 * n))
    Aug[:n, n:2 * n] = np.eye(n)
    Aug[n:2 * n, :n] = -K
    Aug[n:2 * n, n:2 * n] = -D
    Aug[n:2 * n, 2 * n:] = np.eye(n)
    E = la.expm(Aug * h)
    return E[:2 * n, :2 * n], E[:2 * n, 2 * n:]


def _kept(store: dict, arrays: tuple, extra: tuple, make):
    """``make()``, kept in ``store`` for the same ``arrays`` (by identity: a modal
    perturbation of a model keeps its Ritz block's arrays, and the store holds them so
    that their ids stay theirs) and ``extra``; at most four entries.  The arrays made
    are read-only: every model with those arrays shares them."""
    key = (*map(id, arrays), *extra)
    hit = store.get(key)
    if hit is None or any(a is not b for a, b in zip(hit[0], arrays)):
        if len(store) >= 4:
            store.clear()
        made = make()
        for a in made:
            a.flags.writeable = False
        hit = store[key] = (arrays, made)
    return hit[1]


#: The Ritz block's exact ZOH per (its arrays, step).
_RITZ_ZOH: dict = {}


def _ritz_zoh(K, D, h):
    """:func:`block_zoh` of the Ritz block, kept for the next model with the same arrays
    (a Monte Carlo sample's modes: the exponential of the block is 5 ms of the EOS
    model's 6.6 ms discretisation).  Equal to a fresh one to round-off, not always to
    the bit (the BLAS thread count of the call that made it): the linear engine's
    alone."""
    return _kept(_RITZ_ZOH, (K, D), (float(h),), lambda: block_zoh(K, D, h))


@dataclass(frozen=True)
class DiscreteModel:
    """A reduced model discretised for one step ``h`` (ZOH inputs).

    State vector layout: ``x = [q_e (n_m), v_e (n_m), q_o (n_r), v_o (n_r), x_f (n_f)]``
    with ``x_f`` the accelerometer low-pass states (``n_f = 0`` without one), advanced
    by ``x_f+ = F_x x + F_u u`` from the whole state before the step.
    """

    h: float
    a11: np.ndarray
    a12: np.ndarray
    a21: np.ndarray
    a22: np.ndarray
    G1: np.ndarray  # (n_m, n_in) = g1 * B_e
    G2: np.ndarray  # (n_m, n_in) = g2 * B_e
    Phi_o: np.ndarray  # (2 n_r, 2 n_r)
    G_o: np.ndarray  # (2 n_r, n_in) = Gamma_o B_o
    model: ReducedModel
    F_x: np.ndarray | None = None  # (n_f, n_states)
    F_u: np.ndarray | None = None  # (n_f, n_in)

    @property
    def n_states(self) -> int:
        return self.model.n_states


def discretize(model: ReducedModel, h: float,
               blockwise_filter: bool = False) -> DiscreteModel:
    """Exact ZOH discretisation of a reduced model for the step ``h`` (s).

    Parameters
    ----------
    model : ReducedModel
        The continuous reduced model.
    h : float
        Step (s); positive and finite.
    blockwise_filter : bool
        The accelerometer filter's rows by :func:`filter_zoh` (block by block, equal to
        round-off) instead of one exponential of the whole model (what the FMU steps),
        and the Ritz block's exponential kept between models that share the block (a
        Monte Carlo sample's modes).  Without it every exponential is taken afresh: what
        an FMU packs, whose bits must not depend on what ran before in the process (the
        Ritz block's exponential under one BLAS thread differs from the one under two in
        its last bits: 2.7e-12 on the EOS model).

    Returns
    -------
    DiscreteModel
        The step matrices, state layout as documented there.
    """
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"discretisation step must be positive and finite, got {h!r}")
    a11, a12, a21, a22, g1, g2 = modal_zoh(model.omega, model.modal_damping, h)
    Phi_o, Gam_o = (_ritz_zoh if blockwise_filter else block_zoh)(model.K_oo, model.D_oo, h)
    G_o = Gam_o @ model.B_o if model.n_ritz else np.zeros((0, model.n_inputs))
    if model.n_filter_states == 0:
        F_x, F_u = None, None
    else:
        F_x, F_u = (filter_zoh if blockwise_filter else _filter_zoh)(model, h)
    return DiscreteModel(h, a11, a12, a21, a22, g1[:, None] * model.B_e,
                         g2[:, None] * model.B_e, Phi_o, G_o, model, F_x, F_u)


def accel_rows(model: ReducedModel):
    """Acceleration outputs as ``C x_s + D u`` on the structural states (layout above).

    Returns
    -------
    C : ndarray, shape (n_acc, n_s)
    D : ndarray, shape (n_acc, n_in)
    """
    acc = model.is_accel
    Ce, Co = model.C_e[acc], model.C_o[acc]
    C = np.hstack([-Ce * model.omega**2, -Ce * model.modal_damping,
                   -Co @ model.K_oo, -Co @ model.D_oo])
    return C, Ce @ model.B_e + Co @ model.B_o


def _filter_zoh(model: ReducedModel, h: float):
    """Exact ZOH rows of the accelerometer filter states, or two ``None``.

    One ``expm`` of :func:`structfmu.statespace.first_order` (structure and filter) with
    the held input, for ``x_f+ = F_x x + F_u u`` in the layout of :class:`DiscreteModel`.
    """
    if model.n_filter_states == 0:
        return None, None
    A, B, _, _ = first_order(model)
    n, n_in = A.shape[0], model.n_inputs
    M = np.zeros((n + n_in, n + n_in))
    M[:n, :n], M[:n, n:] = A, B
    E = la.expm(M * h)[model.n_struct_states:n]
    # dense layout [q_e, q_o, v_e, v_o, x_f] -> ours [q_e, v_e, q_o, v_o, x_f]
    n_m, n_r, ns = model.n_modes, model.n_ritz, model.n_struct_states
    ours = np.r_[0:n_m, n_m + n_r:2 * n_m + n_r, n_m:n_m + n_r, 2 * n_m + n_r:ns, ns:n]
    return E[:, ours], E[:, n:]


#: The Ritz block's part of the filter rows, per (model arrays, step): a modal
#: perturbation keeps its Ritz block (the arrays themselves, kept here so that their ids
#: stay theirs).
_RITZ_ROWS: dict = {}


def filter_zoh(model, h: float) -> tuple:
    """Exact ZOH rows ``(F_x, F_u)`` of the accelerometer filter, block by block.

    The filter of each acceleration channel is driven by ``sum_i C_e[c, i] q_i'' +
    C_o[c] q_o''`` and the structure's blocks are decoupled, so each mode contributes
    through the exponential of its own ``(q, v, filter, f)`` system (batched, size
    ``3 + order``) and the Ritz block through one of its ``(q_o, v_o, filters, f_o)``
    system (kept for the next perturbation of the modes).  The same matrices as
    :func:`_filter_zoh`'s one exponential of the whole model (what the FMU steps), to
    round-off, at a fraction of its cost.

    Parameters
    ----------
    model : ReducedModel
        With an accelerometer low-pass.
    h : float
        Step (s).

    Returns
    -------
    F_x : ndarray, shape (n_f, n_states)
    F_u : ndarray, shape (n_f, n_inputs)
    """
    acc = model.is_accel
    n_acc, n_m, n_r = int(acc.sum()), model.n_modes, model.n_ritz
    ns, n = model.n_struct_states, model.n_states
    a, b, _ = model.accel_lowpass.siso()
    o = a.shape[0]
    Ce, Co = model.C_e[acc], model.C_o[acc]
    F_x = np.zeros((n_acc * o, n))
    # each mode: states (q, v, x_f) and the held force f = B_e u, q'' = f - c v - w^2 q
    w2, c = model.omega ** 2, model.modal_damping
    Z = np.zeros((n_m, 3 + o, 3 + o))
    Z[:, 0, 1] = 1.0
    Z[:, 1, 0], Z[:, 1, 1], Z[:, 1, 2 + o] = -w2, -c, 1.0
    Z[:, 2:2 + o, 0] = -w2[:, None] * b[:, 0]
    Z[:, 2:2 + o, 1] = -c[:, None] * b[:, 0]
    Z[:, 2:2 + o, 2:2 + o] = a
    Z[:, 2:2 + o, 2 + o] = b[:, 0]
    E = la.expm(Z * h)[:, 2:2 + o]                                  # (n_m, o, 3 + o)
    # channel k's rows k o .. k o + o - 1 see C_e[k, i] times mode i's response
    F_x[:, :n_m] = (Ce[:, None, :] * E[:, :, 0].T[None]).reshape(n_acc * o, n_m)
    F_x[:, n_m:2 * n_m] = (Ce[:, None, :] * E[:, :, 1].T[None]).reshape(n_acc * o, n_m)
    F_u = (Ce[:, None, :] * E[:, :, 2 + o].T[None]).reshape(n_acc * o, n_m) @ model.B_e
    Ea = la.expm(a * h)
    for k in range(n_acc):   # the filter's own states
        F_x[k * o:(k + 1) * o, ns + k * o:ns + (k + 1) * o] = Ea
    if n_r:
        def ritz_rows():
            Af, Bf, _ = filter_blocks(model.accel_lowpass, n_acc)
            n_f = Af.shape[0]
            m = 3 * n_r + n_f
            Zo = np.zeros((m, m))
            F = slice(2 * n_r, 2 * n_r + n_f)
            Zo[:n_r, n_r:2 * n_r] = np.eye(n_r)
            Zo[n_r:2 * n_r, :n_r], Zo[n_r:2 * n_r, n_r:2 * n_r] = -model.K_oo, -model.D_oo
            Zo[n_r:2 * n_r, 2 * n_r + n_f:] = np.eye(n_r)
            Zo[F, :n_r] = Bf @ (-Co @ model.K_oo)
            Zo[F, n_r:2 * n_r] = Bf @ (-Co @ model.D_oo)
            Zo[F, F] = Af
            Zo[F, 2 * n_r + n_f:] = Bf @ Co
            Eo = la.expm(Zo * h)[F]
            return Eo[:, :2 * n_r], Eo[:, 2 * n_r + n_f:] @ model.B_o

        hit = _kept(_RITZ_ROWS, (model.K_oo, model.D_oo, model.B_o, model.C_o),
                    (float(h), acc.tobytes(), repr(model.accel_lowpass.to_json())),
                    ritz_rows)
        F_x[:, 2 * n_m:ns] = hit[0]
        F_u = F_u + hit[1]
    return F_x, F_u


def step_matrices(dm) -> tuple:
    """``(A, B)`` of ``x+ = A x + B u`` for a discretised reduced model, assembled from
    its blocks (layout of :class:`DiscreteModel`): the numbers :func:`step` multiplies,
    so that ``A x + B u`` is its step.

    Parameters
    ----------
    dm : DiscreteModel

    Returns
    -------
    A : ndarray, shape (n_states, n_states)
    B : ndarray, shape (n_states, n_inputs)
    """
    model = dm.model
    n, n_m, ns = model.n_states, model.n_modes, model.n_struct_states
    A = np.zeros((n, n))
    q, v = np.arange(n_m), n_m + np.arange(n_m)
    A[q, q], A[q, v], A[v, q], A[v, v] = dm.a11, dm.a12, dm.a21, dm.a22
    A[2 * n_m:ns, 2 * n_m:ns] = dm.Phi_o
    B = np.vstack([dm.G1, dm.G2, dm.G_o])
    if ns < n:
        A[ns:] = dm.F_x
        B = np.vstack([B, dm.F_u])
    return A, B


def step(dm: DiscreteModel, x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Advance the state one step with inputs ``u`` held (returns a new array).

    Parameters
    ----------
    dm : DiscreteModel
        The discretised model; the step is ``dm.h`` (s).
    x : ndarray, shape (n_states,)
        State at ``t_k`` in the layout of :class:`DiscreteModel`.
    u : ndarray, shape (n_in,)
        Inputs held over the step: forces (N) or torques (N.m), per input channel.

    Returns
    -------
    ndarray, shape (n_states,)
        State at ``t_k + h``.
    """
    n_m, ns = dm.model.n_modes, dm.model.n_struct_states
    q, v, xo, xf = x[:n_m], x[n_m:2 * n_m], x[2 * n_m:ns], x[ns:]
    qn = dm.a11 * q + dm.a12 * v + dm.G1 @ u
    vn = dm.a21 * q + dm.a22 * v + dm.G2 @ u
    xon = dm.Phi_o @ xo + dm.G_o @ u if xo.size else xo
    xfn = dm.F_x @ x + dm.F_u @ u if xf.size else xf
    return np.concatenate([qn, vn, xon, xfn])


def output(model: ReducedModel, x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Outputs for state ``x`` and current inputs ``u`` (accelerations feed through).

    Parameters
    ----------
    model : ReducedModel
        The reduced model.
    x : ndarray, shape (n_states,)
        State in the layout of :class:`DiscreteModel`.
    u : ndarray, shape (n_in,)
        Current inputs: forces (N) or torques (N.m), per input channel.

    Returns
    -------
    y : ndarray, shape (n_out,)
        Outputs, each in the unit of its kind (m, rad, rad/s, m/s^2, strain 1).
    """
    n_m, n_r, ns = model.n_modes, model.n_ritz, model.n_struct_states
    q, v = x[:n_m], x[n_m:2 * n_m]
    qo, vo = x[2 * n_m:2 * n_m + n_r], x[2 * n_m + n_r:ns]
    y = model.C_e @ q + model.C_o @ qo
    rate = model.is_rate
    if rate.any():
        y[rate] = model.C_e[rate] @ v + model.C_o[rate] @ vo
    acc = model.is_accel
    if acc.any() and model.n_filter_states:
        _, _, Cf = filter_blocks(model.accel_lowpass, int(acc.sum()))
        y[acc] = Cf @ x[ns:]
    elif acc.any():
        qdd = model.B_e @ u - model.modal_damping * v - model.omega**2 * q
        qodd = model.B_o @ u - model.D_oo @ vo - model.K_oo @ qo
        y[acc] = model.C_e[acc] @ qdd + model.C_o[acc] @ qodd
    return y


def simulate(model: ReducedModel, h: float, u, x0=None):
    """Simulate with ZOH inputs; ``u`` has shape (n_steps, n_in).

    Parameters
    ----------
    model : ReducedModel
        The reduced model.
    h : float
        Step (s).
    u : array_like, shape (n_steps, n_in)
        Inputs held over each step: forces (N) or torques (N.m), per input channel.
    x0 : array_like, shape (n_states,), optional
        Initial state (layout of :class:`DiscreteModel`); zero by default.

    Returns
    -------
    y : ndarray, shape (n_steps, n_out)
        Outputs at ``t_k = k h`` (state at ``t_k``, input ``u[k]``).
    x : ndarray, shape (n_steps + 1, n_states)
        States at ``t_0 .. t_n``.
    """
    dm = discretize(model, h)
    u = np.atleast_2d(np.asarray(u, float))
    n = u.shape[0]
    x = np.zeros((n + 1, model.n_states))
    if x0 is not None:
        x[0] = x0
    y = np.empty((n, model.n_outputs))
    for k in range(n):
        y[k] = output(model, x[k], u[k])
        x[k + 1] = step(dm, x[k], u[k])
    return y, x


class ZohStepper:
    """Allocation-free stepping of a reduced model, one discretisation per step size.

    Holds the state ``x`` (layout of :class:`DiscreteModel`), caches
    :func:`discretize` for up to :attr:`CACHE` step sizes (a step within
    ``fmukit.timing.STEP_RTOL`` of a cached one is that step: the host's rounding of
    ``(k + 1) h - k h``, not a new step), and splits outputs into a state part and a
    direct-feedthrough part ``D u`` (acceleration rows only), so that a change of
    inputs updates feedthrough outputs without stepping.

    Parameters
    ----------
    model : ReducedModel
    """

    #: Number of step sizes whose discretisation is kept (the oldest is replaced first).
    CACHE = 8

    def __init__(self, model: ReducedModel):
        self.model = model
        n_m, n_r, ns = model.n_modes, model.n_ritz, model.n_struct_states
        self.x = np.zeros(model.n_states)
        self._cache: dict = {}
        self._q = self.x[:n_m]
        self._v = self.x[n_m:2 * n_m]
        self._xo = self.x[2 * n_m:ns]
        self._xf = self.x[ns:]
        self._tf = np.empty(model.n_filter_states)
        self._tq = np.empty(n_m)
        self._tv = np.empty(n_m)
        self._t1 = np.empty(n_m)
        acc, rate = model.is_accel, model.is_rate
        disp = ~(acc | rate)
        # y_state = Cq q + Cv v + Cqo q_o + Cvo v_o ; y = y_state + D u
        Cq = np.where(disp[:, None], model.C_e, 0.0)
        Cv = np.where(rate[:, None], model.C_e, 0.0)
        Cqo = np.where(disp[:, None], model.C_o, 0.0)
        Cvo = np.where(rate[:, None], model.C_o, 0.0)
        self.D = np.zeros((model.n_outputs, model.n_inputs))
        Cf = np.zeros((model.n_outputs, model.n_filter_states))
        if acc.any() and model.n_filter_states:
            Cf[acc] = filter_blocks(model.accel_lowpass, int(acc.sum()))[2]
        elif acc.any():
            Ca, self.D[acc] = accel_rows(model)
            Cq[acc], Cv[acc], Cqo[acc], Cvo[acc] = np.split(Ca, np.cumsum([n_m, n_m, n_r]),
                                                            axis=1)
        self.C_x = np.hstack([Cq, Cv, Cqo, Cvo, Cf])  # (n_out, n_states)
        self.has_feedthrough = bool(np.any(self.D))
        self.y_state = np.zeros(model.n_outputs)

    def discrete(self, h: float) -> DiscreteModel:
        """The discretisation for step ``h`` (s): a cached one that ``h`` is up to
        rounding (:func:`fmukit.timing.same_step`), else a new one, cached."""
        dm = self._cache.get(h)
        if dm is None:
            dm = next((d for known, d in self._cache.items() if same_step(h, known)), None)
        if dm is None:
            if len(self._cache) >= self.CACHE:
                del self._cache[next(iter(self._cache))]
            dm = self._cache[h] = discretize(self.model, h)
        return dm

    def step(self, u: np.ndarray, h: float) -> None:
        """Advance ``x`` in place by ``h`` with inputs ``u`` held.

        Parameters
        ----------
        u : ndarray, shape (n_in,)
            Inputs held over the step: forces (N) or torques (N.m), per input channel.
        h : float
            Step (s); see :meth:`discrete` for which discretisation it uses.
        """
        dm = self.discrete(h)
        if self._xf.size:  # the filter reads the state before the step
            np.dot(dm.F_x, self.x, out=self._tf)
            self._tf += dm.F_u @ u
        q, v = self._q, self._v
        np.dot(dm.G1, u, out=self._tq)
        np.dot(dm.G2, u, out=self._tv)
        np.multiply(dm.a11, q, out=self._t1)
        self._tq += self._t1
        np.multiply(dm.a12, v, out=self._t1)
        self._tq += self._t1
        np.multiply(dm.a21, q, out=self._t1)
        self._tv += self._t1
        np.multiply(dm.a22, v, out=self._t1)
        self._tv += self._t1
        q[:] = self._tq
        v[:] = self._tv
        if self._xo.size:
            self._xo[:] = dm.Phi_o @ self._xo + dm.G_o @ u
        if self._xf.size:
            self._xf[:] = self._tf

    def update_state_outputs(self) -> np.ndarray:
        """Recompute the state part of the outputs (after a step or a state change)."""
        np.dot(self.C_x, self.x, out=self.y_state)
        return self.y_state

    def outputs(self, u: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Outputs for the current state and inputs ``u``, written into ``out``.

        Uses the state part computed by :meth:`update_state_outputs`.

        Parameters
        ----------
        u : ndarray, shape (n_in,)
            Current inputs: forces (N) or torques (N.m), per input channel.
        out : ndarray, shape (n_out,)
            Buffer overwritten with the outputs.

        Returns
        -------
        ndarray, shape (n_out,)
            ``out``: outputs, each in the unit of its kind (m, rad, rad/s, m/s^2, strain 1).
        """
        if self.has_feedthrough:
            np.dot(self.D, u, out=out)
            out += self.y_state
        else:
            out[:] = self.y_state
        return out
