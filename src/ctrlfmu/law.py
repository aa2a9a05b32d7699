"""Discrete control law of the paper's Eq. (11) (pure numerics, numpy only).

The paper's digital controllers are

    x(k+1) = A x(k) + B y(k)
    u(k+1) = C x(k) + D y(k)                         (Eq. 11, "delayed" form)

so the command computed from the measurement ``y(k)`` taken at ``t_k = k dt`` is applied
one sample later, at ``t_{k+1}``: there is no direct feedthrough from ``y`` to ``u``.
The usual non-delayed form

    x(k+1) = A x(k) + B y(k)
    u(k)   = C x(k) + D y(k)

is available with ``delayed=False``; it has direct feedthrough wherever ``D != 0``.

Sample ``k`` of :func:`step`
---------------------------
With ``v = C x(k) + D y(k)`` (the unlimited command) and ``u = clip(v, u_min, u_max)``:

* ``x(k+1) = A x(k) + B y(k) + L (u - v)``: back-calculation anti-windup with gain
  ``L = aw_gain`` (zero by default, i.e. no anti-windup).  Unless an output limit is
  active, ``u - v = 0`` and the law is exactly Eq. (11).  ``L`` chosen so that
  ``A - L C`` is stable (see :func:`backcalculation_gain`) keeps the controller state
  consistent with the command the actuator really receives.
* delayed form: ``u`` is ``u(k+1)``, held from ``t_{k+1}`` to ``t_{k+2}``;
  non-delayed form: ``u`` is ``u(k)``, applied from ``t_k``.

Activation
----------
The law is *active* at sample ``k`` when the caller's ``enable`` flag is true and
``k dt >= t_on`` (sample index ``k >= first_active_sample``).  While inactive the
output is zero and the state is *reset* to zero at every sample, so that on activation
the controller starts from rest (the paper switches control on after the excitation
stops, and a state frozen at an old value would produce a kick).  In the delayed form
the first sample that can produce a non-zero command is therefore ``t_on + dt``.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

__all__ = [
    "DimensionError",
    "LawFileError",
    "DiscreteLaw",
    "LawState",
    "initial_state",
    "is_active",
    "step",
    "output",
    "simulate",
    "backcalculation_gain",
    "save_law",
    "law_bytes",
    "load_law",
]

_FORMAT = "ctrlfmu.DiscreteLaw/1"
_REL_TIME_TOL = 1e-9


class DimensionError(ValueError):
    """A matrix or signal of a control law has the wrong shape."""


class LawFileError(ValueError):
    """A control law file is not a valid ``.npz`` law."""


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def _matrix(name: str, value, expected: tuple[int, int], what: str) -> np.ndarray:
    arr = np.array(value, dtype=float, copy=True)
    if arr.ndim != 2 or arr.shape != expected:
        raise DimensionError(
            f"controller matrix {name} has shape {arr.shape}; expected {expected} for {what}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"controller matrix {name} has non-finite entries")
    arr.setflags(write=False)
    return arr


def _limit(name: str, value, n_out: int) -> np.ndarray:
    arr = np.array(value, dtype=float, copy=True)
    if arr.ndim == 0:
        arr = np.full(n_out, float(arr))
    if arr.shape != (n_out,):
        raise DimensionError(
            f"output limit {name} has shape {arr.shape}; expected a scalar or ({n_out},) "
            f"for {_plural(n_out, 'output')}"
        )
    if np.any(np.isnan(arr)):
        raise ValueError(f"output limit {name} contains NaN")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class DiscreteLaw:
    """Discrete state-space control law of Eq. (11).

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (-).
    B : array_like, shape (n, n_in)
        Input matrix (state units per input unit).
    C : array_like, shape (n_out, n)
        Output matrix (V per state unit).
    D : array_like, shape (n_out, n_in)
        Direct matrix (V per input unit).
    dt : float
        Sample period (s).
    delayed : bool, default True
        True for Eq. (11), where ``u(k+1) = C x(k) + D y(k)`` (no feedthrough); False for
        ``u(k) = C x(k) + D y(k)`` (feedthrough where ``D != 0``).
    u_min, u_max : float or array_like, shape (n_out,)
        Output limits (V); ``-inf``/``inf`` for none.
    aw_gain : array_like, shape (n, n_out), optional
        Back-calculation anti-windup gain ``L`` (state units per V); zero when omitted.
    t_on : float, default 0.0
        Activation time (s): the law is inactive (zero output, zero state) before it.
    name : str
        Design name.
    inputs, outputs : tuple of str
        Signal names, one per input/output; ``y1..`` and ``u1..`` when omitted.
    input_units, output_units : tuple of str
        Units of the signals (``"1"`` for strain); ``"1"`` and ``"V"`` when omitted.
    description : str
        One line on what the law does.

    Notes
    -----
    Arrays are copied and made read-only.  Use :func:`dataclasses.replace`, or the
    ``with_*`` methods, to derive a modified law; validation runs again.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float
    delayed: bool = True
    u_min: np.ndarray | float = -math.inf
    u_max: np.ndarray | float = math.inf
    aw_gain: np.ndarray | None = None
    t_on: float = 0.0
    name: str = "law"
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    input_units: tuple[str, ...] = ()
    output_units: tuple[str, ...] = ()
    description: str = ""

    def __post_init__(self):
        d = np.asarray(self.D, dtype=float)
        if d.ndim != 2:
            raise DimensionError(
                f"controller matrix D has {d.ndim} dimension(s); expected a 2-D (n_out, n_in) array"
            )
        n_out, n_in = d.shape
        if n_out == 0 or n_in == 0:
            raise DimensionError(
                f"controller matrix D has shape {d.shape}; expected at least one input and output"
            )
        a = np.asarray(self.A, dtype=float)
        if a.ndim != 2 or a.shape[0] != a.shape[1]:
            raise DimensionError(
                f"controller matrix A has shape {a.shape}; expected a square matrix"
            )
        n = a.shape[0]
        states = _plural(n, "state")
        set_ = object.__setattr__
        set_(self, "A", _matrix("A", a, (n, n), states))
        set_(self, "B", _matrix("B", self.B, (n, n_in),
                                f"{states} and {_plural(n_in, 'input')}"))
        set_(self, "C", _matrix("C", self.C, (n_out, n),
                                f"{_plural(n_out, 'output')} and {states}"))
        set_(self, "D", _matrix("D", d, (n_out, n_in),
                                f"{_plural(n_out, 'output')} and {_plural(n_in, 'input')}"))
        aw = np.zeros((n, n_out)) if self.aw_gain is None else self.aw_gain
        set_(self, "aw_gain", _matrix("aw_gain", aw, (n, n_out),
                                      f"{states} and {_plural(n_out, 'output')}"))
        dt = float(self.dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(
                f"sample period dt must be a positive number of seconds, got {self.dt!r}"
            )
        set_(self, "dt", dt)
        t_on = float(self.t_on)
        if not (math.isfinite(t_on) and t_on >= 0):
            raise ValueError(f"activation time t_on must be finite and >= 0 s, got {self.t_on!r}")
        set_(self, "t_on", t_on)
        set_(self, "delayed", bool(self.delayed))
        lo = _limit("u_min", self.u_min, n_out)
        hi = _limit("u_max", self.u_max, n_out)
        if np.any(lo > hi):
            raise ValueError(f"output limits have u_min > u_max: u_min={lo}, u_max={hi}")
        set_(self, "u_min", lo)
        set_(self, "u_max", hi)
        for attr, count, default in (("inputs", n_in, "y{}"), ("outputs", n_out, "u{}"),
                                     ("input_units", n_in, None), ("output_units", n_out, None)):
            names = tuple(str(s) for s in getattr(self, attr))
            if not names:
                if default is None:
                    names = ("1" if attr == "input_units" else "V",) * count
                else:
                    names = tuple(default.format(i + 1) for i in range(count))
            if len(names) != count:
                raise DimensionError(f"{attr} has {len(names)} entries; expected {count}")
            set_(self, attr, names)
        set_(self, "name", str(self.name))
        set_(self, "description", str(self.description))

    # -- sizes -----------------------------------------------------------------------
    @property
    def n_states(self) -> int:
        """Number of controller states ``n``."""
        return self.A.shape[0]

    @property
    def n_inputs(self) -> int:
        """Number of measured inputs ``n_in``."""
        return self.D.shape[1]

    @property
    def n_outputs(self) -> int:
        """Number of commands ``n_out``."""
        return self.D.shape[0]

    @property
    def first_active_sample(self) -> int:
        """Index of the first sample with ``k dt >= t_on`` (relative tolerance 1e-9)."""
        return max(0, math.ceil(self.t_on / self.dt - _REL_TIME_TOL))

    @property
    def feedthrough(self) -> np.ndarray:
        """Boolean matrix, shape (n_out, n_in): output i depends on input j at the same instant."""
        if self.delayed:
            return np.zeros(self.D.shape, dtype=bool)
        return self.D != 0

    # -- copies ------------------------------------------------------------------------
    def with_gain(self, gain: float) -> DiscreteLaw:
        """Scale the command by ``gain`` (C and D scaled; anti-windup kept consistent).

        Parameters
        ----------
        gain : float
            Factor on the output (-).

        Returns
        -------
        DiscreteLaw
            The scaled law; ``aw_gain`` is divided by ``gain`` so ``A - L C`` is unchanged.
        """
        g = float(gain)
        if not math.isfinite(g):
            raise ValueError(f"gain must be finite, got {gain!r}")
        aw = self.aw_gain / g if g != 0 else self.aw_gain
        return replace(self, C=g * self.C, D=g * self.D, aw_gain=aw)

    def with_limits(self, u_min, u_max) -> DiscreteLaw:
        """Return a copy with output limits ``u_min``, ``u_max`` (V).

        Parameters
        ----------
        u_min, u_max : float or array_like, shape (n_out,)
            Lower and upper output limits (V); ``-inf``/``inf`` for none.

        Returns
        -------
        DiscreteLaw
        """
        return replace(self, u_min=u_min, u_max=u_max)

    def with_t_on(self, t_on: float) -> DiscreteLaw:
        """Return a copy with activation time ``t_on`` (s)."""
        return replace(self, t_on=t_on)


@dataclass(frozen=True, eq=False)
class LawState:
    """State of a :class:`DiscreteLaw` between samples.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Controller state ``x(k)``.
    u : ndarray, shape (n_out,)
        Command held at the output (V): in the delayed form ``u(k)``, computed at sample
        ``k - 1``; in the non-delayed form the command of the last sample.
    k : int
        Index of the next sample to process (samples taken so far).
    """

    x: np.ndarray
    u: np.ndarray
    k: int = 0

    def __post_init__(self):
        for attr in ("x", "u"):
            arr = np.array(getattr(self, attr), dtype=float, copy=True)
            arr.setflags(write=False)
            object.__setattr__(self, attr, arr)
        object.__setattr__(self, "k", int(self.k))


def initial_state(law: DiscreteLaw, k: int = 0) -> LawState:
    """Zero state of ``law`` before sample ``k``.

    Parameters
    ----------
    law : DiscreteLaw
        The control law.
    k : int, default 0
        Index of the first sample to process.

    Returns
    -------
    LawState
        ``x = 0``, ``u = 0`` (V).
    """
    return LawState(np.zeros(law.n_states), np.zeros(law.n_outputs), k)


def _input(law: DiscreteLaw, y) -> np.ndarray:
    arr = np.asarray(y, dtype=float)
    if arr.ndim == 0 and law.n_inputs == 1:
        arr = arr.reshape(1)
    if arr.shape != (law.n_inputs,):
        raise DimensionError(
            f"measurement y has shape {arr.shape}; expected ({law.n_inputs},) "
            f"for law {law.name!r}"
        )
    return arr


def _check_state(law: DiscreteLaw, state: LawState) -> None:
    if state.x.shape != (law.n_states,) or state.u.shape != (law.n_outputs,):
        raise DimensionError(
            f"law state has x {state.x.shape} and u {state.u.shape}; expected "
            f"({law.n_states},) and ({law.n_outputs},) for law {law.name!r}"
        )


def _mv(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Matrix-vector product without BLAS.

    BLAS kernels differ between CPU code paths (OpenBLAS picks one per process), which
    changes the last bit of a sum; the elementwise product and numpy's pairwise row sum
    give the same bits in every process, so an FMU gives identical outputs in any host.
    """
    return (m * v).sum(axis=1)


def is_active(law: DiscreteLaw, k: int, enable: bool = True) -> bool:
    """True when ``law`` runs at sample ``k`` (``enable`` and ``k dt >= t_on``).

    Parameters
    ----------
    law : DiscreteLaw
        The control law.
    k : int
        Sample index (``t_k = k dt`` from the law's clock origin).
    enable : bool
        External enable.

    Returns
    -------
    bool
    """
    return bool(enable) and k >= law.first_active_sample


def step(law: DiscreteLaw, state: LawState, y, enable: bool = True) -> tuple[LawState, np.ndarray]:
    """Process one sample of Eq. (11).

    Parameters
    ----------
    law : DiscreteLaw
        The control law.
    state : LawState
        State before sample ``k = state.k``.
    y : array_like, shape (n_in,)
        Measurement ``y(k)`` (input units; strain is dimensionless).
    enable : bool, default True
        External enable; the law also waits for ``t_on``.

    Returns
    -------
    state : LawState
        State before sample ``k + 1``.
    u : ndarray, shape (n_out,)
        Limited command (V): ``u(k+1)`` in the delayed form (apply from ``t_{k+1}``),
        ``u(k)`` in the non-delayed form (apply from ``t_k``).  Zero when inactive.
    """
    _check_state(law, state)
    y = _input(law, y)
    if not is_active(law, state.k, enable):
        zero = np.zeros(law.n_outputs)
        return LawState(np.zeros(law.n_states), zero, state.k + 1), zero
    v = _mv(law.C, state.x) + _mv(law.D, y)
    u = np.clip(v, law.u_min, law.u_max)
    x_next = _mv(law.A, state.x) + _mv(law.B, y) + _mv(law.aw_gain, u - v)
    return LawState(x_next, u, state.k + 1), u


def output(law: DiscreteLaw, state: LawState, y=None, enable: bool = True) -> np.ndarray:
    """Command applied at sample ``k = state.k`` (V), shape (n_out,).

    Parameters
    ----------
    law : DiscreteLaw
        The control law.
    state : LawState
        State before sample ``k``.
    y : array_like, shape (n_in,), optional
        Measurement ``y(k)``; needed only by the non-delayed form.
    enable : bool, default True
        External enable (non-delayed form only; the delayed form holds ``state.u``).

    Returns
    -------
    ndarray, shape (n_out,)
        Delayed form: ``state.u`` (computed at sample ``k - 1``, independent of ``y``).
        Non-delayed form: ``clip(C x(k) + D y(k))``, or zero when inactive.
    """
    _check_state(law, state)
    if law.delayed:
        return state.u.copy()
    if y is None:
        raise ValueError(f"law {law.name!r} is non-delayed; its output needs the measurement y")
    y = _input(law, y)
    if not is_active(law, state.k, enable):
        return np.zeros(law.n_outputs)
    return np.clip(_mv(law.C, state.x) + _mv(law.D, y), law.u_min, law.u_max)


def simulate(law: DiscreteLaw, y, enable=True, state: LawState | None = None):
    """Run ``law`` over a measurement history and return the applied commands.

    Parameters
    ----------
    law : DiscreteLaw
        The control law.
    y : array_like, shape (N, n_in) or (N,) for one input
        Measurements ``y(0) .. y(N-1)`` at ``t_k = k dt``.
    enable : bool or array_like of bool, shape (N,)
        External enable per sample.
    state : LawState, optional
        Start state; zero at sample 0 when omitted.

    Returns
    -------
    u : ndarray, shape (N, n_out)
        Command applied at ``t_k`` (V): ``u[k] = output(...)`` before sample ``k``, so the
        delayed form gives ``u[k] = clip(C x(k-1) + D y(k-1))`` and ``u[0]`` from ``state``.
    state : LawState
        State after the last sample.
    """
    ys = np.asarray(y, dtype=float)
    if ys.ndim == 1:
        ys = ys.reshape(-1, 1) if law.n_inputs == 1 else ys.reshape(1, -1)
    enables = np.broadcast_to(np.asarray(enable, dtype=bool), (ys.shape[0],))
    state = initial_state(law) if state is None else state
    out = np.zeros((ys.shape[0], law.n_outputs))
    for k in range(ys.shape[0]):
        if law.delayed:
            out[k] = state.u
            state, _ = step(law, state, ys[k], enables[k])
        else:
            state, out[k] = step(law, state, ys[k], enables[k])
    return out, state


def backcalculation_gain(law: DiscreteLaw, poles=None) -> np.ndarray:
    """Anti-windup gain ``L`` placing the eigenvalues of ``A - L C``.

    Parameters
    ----------
    law : DiscreteLaw
        The control law; ``(A, C)`` must be observable.
    poles : array_like, shape (n,), optional
        Desired eigenvalues of ``A - L C``, inside the unit circle and closed under
        conjugation (-).  Default: ``n`` distinct real values spread over [0.2, 0.5], so a
        saturated controller forgets its excess state within a few samples.

    Returns
    -------
    ndarray, shape (n, n_out)
        Gain ``L`` for ``aw_gain`` (state units per V).
    """
    # deferred: scipy takes about 1 s to load
    from scipy.signal import place_poles

    n = law.n_states
    if n == 0:
        return np.zeros((0, law.n_outputs))
    poles = np.linspace(0.2, 0.5, n) if poles is None else np.asarray(poles)
    if poles.shape != (n,) or np.any(np.abs(poles) >= 1):
        raise ValueError(f"anti-windup poles must be {n} values inside the unit circle")
    gain = np.real(place_poles(law.A.T, law.C.T, poles).gain_matrix.T)
    placed = np.sort_complex(np.linalg.eigvals(law.A - gain @ law.C))
    if not np.allclose(placed, np.sort_complex(poles.astype(complex)), atol=1e-6):
        raise ValueError(
            f"cannot place the anti-windup poles of law {law.name!r}: (A, C) is too close to "
            "unobservable for these poles; give poles nearer the eigenvalues of A"
        )
    return gain


def save_law(law: DiscreteLaw, path) -> Path:
    """Write ``law`` to an ``.npz`` file (no pickles); the round trip is exact.

    Parameters
    ----------
    law : DiscreteLaw
        The control law.
    path : str or Path
        Target file; ``.npz`` is appended by numpy when missing.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    path.write_bytes(law_bytes(law))
    return path


def law_bytes(law: DiscreteLaw) -> bytes:
    """Contents of the ``.npz`` file :func:`save_law` writes (for FMU resources).

    Parameters
    ----------
    law : DiscreteLaw
        The control law.

    Returns
    -------
    bytes
        An uncompressed ``.npz`` archive without pickles.
    """
    buf = io.BytesIO()
    np.savez(
        buf,
        format=np.array(_FORMAT),
        A=law.A, B=law.B, C=law.C, D=law.D, aw_gain=law.aw_gain,
        u_min=law.u_min, u_max=law.u_max,
        dt=np.array(law.dt), t_on=np.array(law.t_on), delayed=np.array(law.delayed),
        name=np.array(law.name), description=np.array(law.description),
        inputs=np.array(law.inputs, dtype=str), outputs=np.array(law.outputs, dtype=str),
        input_units=np.array(law.input_units, dtype=str),
        output_units=np.array(law.output_units, dtype=str),
    )
    return buf.getvalue()


def load_law(path) -> DiscreteLaw:
    """Read a law written by :func:`save_law`.

    Parameters
    ----------
    path : str, Path or binary file object
        An ``.npz`` file.

    Returns
    -------
    DiscreteLaw
        The law, validated again.
    """
    not_a_law = (f"{path} is not a control law file (an .npz archive written by "
                 "ctrlfmu.law.save_law)")
    try:
        archive = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise
    except (ValueError, OSError, EOFError):   # text, a pickle, a damaged archive
        raise LawFileError(not_a_law) from None
    if not hasattr(archive, "files"):   # a bare .npy array
        raise LawFileError(not_a_law)
    with archive as f:
        if "format" not in f.files or str(f["format"]) != _FORMAT:
            raise LawFileError(f"{path} is not a control law file (format {_FORMAT!r} expected)")
        try:
            return DiscreteLaw(
                A=f["A"], B=f["B"], C=f["C"], D=f["D"], dt=float(f["dt"]),
                delayed=bool(f["delayed"]), u_min=f["u_min"], u_max=f["u_max"],
                aw_gain=f["aw_gain"], t_on=float(f["t_on"]), name=str(f["name"]),
                inputs=tuple(f["inputs"].tolist()), outputs=tuple(f["outputs"].tolist()),
                input_units=tuple(f["input_units"].tolist()),
                output_units=tuple(f["output_units"].tolist()),
                description=str(f["description"]),
            )
        except KeyError as exc:
            raise LawFileError(f"control law file {path} lacks the array {exc.args[0]!r}") from None

