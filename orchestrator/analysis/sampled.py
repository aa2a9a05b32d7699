"""Sampled structures and the piezo loops closed on them, as plain matrices.

The building blocks a design study needs before any co-simulation, for a structure of
the user's own (a :class:`structfmu.reduced.ReducedModel`):

* :func:`packed_model` -- the reduced structure a structure FMU packs;
* :func:`zoh` -- exact zero-order-hold discretisation of ``(A, B)``;
* :func:`sample_structure` -- the structure restricted to some inputs and outputs,
  sampled exactly (:class:`SampledStructure`, with the output matrices of mode subsets:
  the rigid body, the modes below a frequency);
* :func:`amplifier_step` and :func:`stack_force_per_volt` -- a piezo amplifier over one
  step and a stack's blocked force per volt, as the piezo FMU steps them;
* :func:`stack_loop` -- structure, control law(s) (Eq. 11 delay included) and amplifiers
  closed into one transition matrix, one law per stack or one law for all;
* :func:`amplified` and :func:`feedback_channels` -- the same with python-control
  systems: amplifiers in series with the structure, laws closed on sensor pairs;
* :func:`simulate_with_acs` -- a record of such a loop under a known disturbance, with
  the attitude controller sampled at its own rate in the loop.

Everything is linear: amplifier rails and slew limits are assumed inactive.  scipy and
python-control are imported where they are used (each costs about a second to load).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SampledStructure", "packed_model", "zoh", "sample_structure", "amplifier_step",
           "stack_force_per_volt", "stack_loop", "amplified", "feedback_channels",
           "simulate_with_acs"]


def packed_model(fmu):
    """The reduced structure packed in a structure FMU's ``resources/model.npz``.

    Parameters
    ----------
    fmu : path-like
        A Python-build structure FMU (the native twin packs its model in another form).

    Returns
    -------
    structfmu.reduced.ReducedModel
    """
    import tempfile
    import zipfile
    from pathlib import Path

    from structfmu.reduced import ReducedModel

    with zipfile.ZipFile(fmu) as z, tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.npz"
        path.write_bytes(z.read("resources/model.npz"))
        return ReducedModel.load(path)


def zoh(A, B, dt: float):
    """Exact zero-order-hold discretisation of ``dx/dt = A x + B u``.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        System matrix (1/s).
    B : ndarray, shape (n, n_u)
        Input matrix (state unit per input unit per s).
    dt : float
        Sample period (s).

    Returns
    -------
    Ad : ndarray, shape (n, n)
        ``exp(A dt)``.
    Bd : ndarray, shape (n, n_u)
        ``int_0^dt exp(A s) ds B``: the input held over the step.
    """
    # deferred: scipy takes about 1 s to load
    import scipy.linalg as la

    n, nu = A.shape[0], B.shape[1]
    M = np.zeros((n + nu, n + nu))
    M[:n, :n], M[:n, n:] = A, B
    E = la.expm(M * dt)
    return E[:n, :n], E[:n, n:]


@dataclass(frozen=True)
class SampledStructure:
    """A structure sampled with ZOH inputs, dense: ``x+ = A x + B u``, ``y = C x``.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Transition over one step ``dt``; states ``[q, dq/dt]`` of the modal and Ritz
        coordinates.
    B : ndarray, shape (n, n_in)
        Inputs ``inputs`` held over the step (forces in N, moments in N m).
    C : ndarray, shape (n_out, n)
        Outputs ``outputs`` (displacement, strain, angle and rate outputs).
    inputs, outputs : tuple of str
        Names, in column and row order.
    omega : ndarray, shape (n_modes,)
        Natural frequency of each mode (rad/s; 0 for a rigid-body mode); the static Ritz
        coordinates follow the modes.
    dt : float
        Sample period (s).
    n_coords : int
        Modal and Ritz coordinates: the states are ``[q, dq/dt]``, ``n = 2 n_coords``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    inputs: tuple
    outputs: tuple
    omega: np.ndarray
    dt: float
    n_coords: int

    def rows(self, prefix: str, names) -> list:
        """Rows of ``C`` of the outputs ``<prefix><name>``, in the order of ``names``.

        Parameters
        ----------
        prefix : str
            Common start of the output names (e.g. ``"strain_"``; ``""`` for none).
        names : iterable of str
            The rest of each output's name.
        """
        return _positions(self.outputs, prefix, names)

    def cols(self, prefix: str, names) -> list:
        """Columns of ``B`` of the inputs ``<prefix><name>``, in the order of ``names``.

        Parameters
        ----------
        prefix : str
            Common start of the input names (e.g. ``"fc_"``; ``""`` for none).
        names : iterable of str
            The rest of each input's name.
        """
        return _positions(self.inputs, prefix, names)

    def modal_output(self, modes) -> np.ndarray:
        """``C`` restricted to the displacement states of some modes.

        Parameters
        ----------
        modes : ndarray of bool, shape (n_modes,)
            The coordinates kept, e.g. ``omega == 0`` (rigid body) or
            ``omega < 2 pi f``.

        Returns
        -------
        ndarray, shape (n_out, n)
            Zero elsewhere (velocity states and the other modes).
        """
        sel = np.flatnonzero(modes)
        Cp = np.zeros_like(self.C)
        Cp[:, sel] = self.C[:, sel]
        return Cp

    @property
    def rigid_states(self) -> np.ndarray:
        """Displacement and velocity states of the rigid-body modes, shape (2 n_rigid,).

        They are decoupled from the rest, and self-equilibrated forces (a strut's, a
        stack's) do not reach them.
        """
        rig = np.flatnonzero(self.omega == 0.0)
        return np.concatenate([rig, self.n_coords + rig])


def sample_structure(model, inputs, outputs, dt: float) -> SampledStructure:
    """A reduced structure restricted to some inputs and outputs, sampled exactly.

    Parameters
    ----------
    model : structfmu.reduced.ReducedModel
        The structure (Eq. 9-10); displacement, strain, angle and rate outputs.
    inputs, outputs : sequence of str
        Names kept, in that order.
    dt : float
        Sample period (s).

    Returns
    -------
    SampledStructure
    """
    from structfmu.statespace import first_order

    ms = model.select(list(inputs), list(outputs))
    A, B, C, _ = first_order(ms)
    Ad, Bd = zoh(A, B, dt)
    return SampledStructure(Ad, Bd, C, tuple(inputs), tuple(outputs), ms.omega, dt,
                            ms.n_modes + ms.n_ritz)


def amplifier_step(amplifier: str, dt: float, coupling: int = 1) -> tuple:
    """A first-order piezo amplifier over one step ``dt``, linear: ``(a, cx, cu)``.

    With the amplifier voltage ``v`` and the command ``u`` held over the step,
    ``v+ = a v + (1 - a) u``, and the voltage the structure holds over the step is
    ``cx v + cu u``: the trapezoidal mean over the amplifier's internal sub-steps
    (``coupling = 1``, the piezo FMU's default) or its state, the command one step late
    (``coupling = 0``: ``cx = 1, cu = 0``).

    Parameters
    ----------
    amplifier : str
        Amplifier preset (``piezofmu.amplifier.amplifier_preset``), e.g. ``"P-865.10"``.
    dt : float
        Step (s).
    coupling : {1, 0}
        The piezo FMU's coupling.

    Returns
    -------
    (a, cx, cu) : tuple of float
        Dimensionless.
    """
    from piezofmu.amplifier import amplifier_preset, linear_map

    A, _, cx, cu = linear_map(amplifier_preset(amplifier), dt)
    a = float(A[0, 0])
    return (a, 1.0, 0.0) if coupling == 0 else (a, float(cx[0]), float(cu))


def stack_force_per_volt(stack: str) -> float:
    """Blocked force per volt ``c h = k_e stroke / rated voltage`` of a stack (N/V).

    Parameters
    ----------
    stack : str
        Stack preset (``piezofmu.preset``), e.g. ``"P-845.37"``.
    """
    from piezofmu import preset

    s = preset(stack)
    return s.k_e * s.stroke / s.rated_voltage


def stack_loop(A, Bf, Cs, law, *, gain: float = 1.0, force_per_volt: float,
               amplifier: tuple):
    """Structure, law(s) and stack amplifiers closed into one discrete loop.

    State ``[x_structure, x_law (Eq. 11 delay included), v]``: the law maps the sensors
    at ``t_k`` to the commands ``u`` applied at ``t_{k+1}``, the amplifier voltages
    ``v`` follow them (``v+ = a v + (1 - a) u``) and the structure holds the stack
    forces ``c h (cx v + cu u)`` over each step (:func:`amplifier_step`).

    Parameters
    ----------
    A : ndarray, shape (n_s, n_s)
        Sampled structure (:class:`SampledStructure`).
    Bf : ndarray, shape (n_s, n_c)
        Its columns of the stack forces (N), one per channel.
    Cs : ndarray, shape (n_c, n_s)
        Its rows of the sensors the law reads, one per channel (e.g. stack strain).
    law : ctrlfmu.law.DiscreteLaw
        One sensor in and one command (V) out, copied on every channel (independent
        loops), or ``n_c`` in and ``n_c`` out (one law for all channels).
    gain : float
        Factor on the law's commands (-), the same on every channel.
    force_per_volt : float
        Stack blocked force per volt ``c h`` (N/V, :func:`stack_force_per_volt`).
    amplifier : (a, cx, cu)
        The amplifier over one step (:func:`amplifier_step`).

    Returns
    -------
    A_cl : ndarray, shape (n, n)
        Closed-loop transition, ``n = n_s + n_law + n_c``; the first ``n_s`` states are
        the structure's.
    C_force : ndarray, shape (n_c, n)
        Stack forces (N) of the closed loop.
    """
    # deferred: scipy and python-control take about 1 s each to load
    from scipy.linalg import block_diag

    from ctrlfmu.analysis import to_statespace

    k = to_statespace(law, include_delay=True)
    Ak, Bk, Ck, Dk = (np.asarray(m) for m in (k.A, k.B, k.C, k.D))
    nl, ns = Bf.shape[1], A.shape[0]
    if Bk.shape[1] == 1:        # one SISO law per channel: independent blocks
        Ak, Bk, Ck, Dk = (block_diag(*[m] * nl) for m in (Ak, Bk, Ck, Dk))
    elif Bk.shape[1] != nl or Ck.shape[0] != nl:
        raise ValueError(f"the law has {Bk.shape[1]} inputs and {Ck.shape[0]} outputs; "
                         f"give one per leg (1 and 1) or one for all legs ({nl} and {nl})")
    nk = Ak.shape[0]
    a, cx, cu = amplifier
    ch = force_per_volt
    n = ns + nk + nl
    # command u = gain (Ck x_law + Dk Cs x); force f = ch (cx v + cu u); v+ = a v + (1-a) u
    U = np.zeros((nl, n))
    U[:, ns:ns + nk] = gain * Ck
    U[:, :ns] = gain * Dk @ Cs
    C_force = ch * cu * U
    C_force[:, ns + nk:] += ch * cx * np.eye(nl)
    Acl = np.zeros((n, n))
    Acl[:ns, :ns] = A
    Acl[:ns] += Bf @ C_force
    Acl[ns:ns + nk, ns:ns + nk] = Ak
    Acl[ns:ns + nk, :ns] = Bk @ Cs
    Acl[ns + nk:] = (1.0 - a) * U
    Acl[ns + nk:, ns + nk:] += a * np.eye(nl)
    return Acl, C_force


def amplified(G, force_per_volt, amplifier: tuple, n_passthrough: int = 1):
    """Amplifiers in series with a sampled structure's first inputs (python-control).

    Parameters
    ----------
    G : control.StateSpace
        Discrete structure; its first ``len(force_per_volt)`` inputs are stack forces
        (N), the last ``n_passthrough`` other inputs (e.g. a disturbance force).
    force_per_volt : sequence of float
        Blocked force per volt ``c h`` of each stack (N/V).
    amplifier : (a, cx, cu)
        The amplifier over one step (:func:`amplifier_step`).
    n_passthrough : int
        Inputs passed through unchanged.

    Returns
    -------
    control.StateSpace
        Inputs the amplifier commands (V) then the passed-through inputs; outputs those of
        ``G``.
    """
    # deferred: python-control takes about 1 s to load
    import control

    a, cx, cu = amplifier
    acts = [control.ss([[a]], [[1 - a]], [[ch * cx]], [[ch * cu]], G.dt)
            for ch in force_per_volt]
    acts += [control.ss([], [], [], [[1.0]], G.dt)] * n_passthrough
    return control.series(control.append(*acts), G)


def feedback_channels(plant, laws, closed, n_sensors: int = 2, n_passthrough: int = 1):
    """Close one law per channel on its sensors (positive feedback, python-control).

    Channel ``k`` reads the plant outputs ``n_sensors k ... n_sensors (k + 1) - 1`` and
    drives plant input ``k``; a channel not in ``closed`` stays open.

    Parameters
    ----------
    plant : control.StateSpace
        Discrete; inputs one command per channel then ``n_passthrough`` exogenous inputs,
        its first ``n_sensors n_channels`` outputs the sensors.
    laws : sequence of control.StateSpace
        One discrete law per channel (``n_sensors`` in, one out).
    closed : collection of int
        Channels closed, numbered from 1.
    n_sensors : int
        Sensors per channel.
    n_passthrough : int
        Plant outputs beyond the sensors are not fed back; this many plant inputs get no
        feedback either.

    Returns
    -------
    control.StateSpace
        Closed loop ``u = r + K y``, inputs and outputs as ``plant``.
    """
    # deferred: python-control takes about 1 s to load
    import control

    n_ch = len(laws)
    off = control.ss([], [], [], np.zeros((1, n_sensors)), plant.dt)
    n_rest = plant.noutputs - n_sensors * n_ch
    K = control.append(*[laws[k - 1] if k in closed else off for k in range(1, n_ch + 1)],
                       control.ss([], [], [], np.zeros((n_passthrough, n_rest)), plant.dt))
    return control.feedback(plant, K, sign=+1)


def simulate_with_acs(A, Bw, w, acs, att, rate, dt: float, record) -> list:
    """Record a discrete loop under a known input, the attitude controller in the loop.

    Every ``acs.sample_time`` the attitude controller's torque at ``t_k`` is read and
    held over its period, then the controller steps on the attitude and rate at ``t_k``,
    as the master steps the ACS FMU.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Transition over one step ``dt`` (e.g. :func:`stack_loop`).
    Bw : ndarray, shape (n, n_w + 3)
        Inputs: the disturbance channels of ``w``, then the three ACS torques (N m).
    w : ndarray, shape (n_t, n_w)
        Disturbance at each step (N, N m).
    acs : acsfmu.pid.AcsConfig
        The attitude controller.
    att, rate : sequence of int
        Rows of ``record[0]`` holding the attitude (rad) and rate (rad/s) per axis.
    dt : float
        Step (s); ``acs.sample_time`` is a whole number of steps.
    record : sequence of ndarray, shape (n_r, n)
        Output matrices recorded at every step; the first gives the ACS its inputs.

    Returns
    -------
    list of ndarray, shape (n_t, n_r)
        One record per matrix of ``record``, starting at rest at ``t = 0``.
    """
    from acsfmu.pid import acs_advance, acs_outputs, initial_state

    n = w.shape[0]
    st = initial_state(acs)
    x = np.zeros(A.shape[0])
    out = [np.empty((n, M.shape[0])) for M in record]
    u = np.zeros(Bw.shape[1])
    nw = w.shape[1]
    every = int(round(acs.sample_time / dt))
    torque = np.zeros(3)
    C = record[0]
    for k in range(n):
        y = C @ x
        out[0][k] = y
        for M, o in zip(record[1:], out[1:]):
            o[k] = M @ x
        if k % every == 0:   # as the master: read the torque at t_k, then step the ACS
            torque = acs_outputs(acs, st)[0]
            st = acs_advance(acs, st, acs.sample_time, y[att], y[rate])
        u[:nw], u[nw:] = w[k], torque
        x = A @ x + Bw @ u
    return out


def _positions(all_names, prefix: str, names) -> list:
    """Positions in ``all_names`` of ``<prefix><name>`` for each of ``names``, in order."""
    idx = {n: i for i, n in enumerate(all_names)}
    return [idx[f"{prefix}{n}"] for n in names]
