"""Attenuation design: the linear closed loop of a scenario, before any tuning.

A scenario's FMUs are replaced by the linear, exactly discretised models they step
(:func:`linearize`): the reduced structure (the FMU's own ``model.npz``, ZOH at its
period, accelerometer low-pass included), the piezo amplifiers (their low-pass over the
internal sub-steps, ``f = c h v``, rails and slew limit assumed inactive), the control
laws of Eq. (11) (the FMU's ``law.npz`` with its ``gain``; controllers assumed on) and
the attitude controller (PID with its one-sample delay).  Sources (disturbances,
excitation) become exogenous inputs.  The models are assembled tick by tick with the
master's Gauss–Seidel rules (:mod:`orchestrator.cosim`): an instance due at a tick
publishes its outputs at ``t_k``, reads its inputs in feedthrough order, then steps;
between its ticks its outputs hold.  Over one hyperperiod ``T`` of the periods this
gives an exact linear map ``X(T) = Phi X(0) + Gamma w`` of everything the co-simulation
carries, from which:

* :meth:`LinearScenario.poles` -- closed-loop poles, frequency and damping;
* :meth:`LinearScenario.gain_margins` -- the factor on one controller's ``gain`` at
  which the loop goes unstable (up and down), with every other loop closed;
* :meth:`LinearScenario.decay` -- cycles to 90 % decay of the pole nearest a mode;
* :meth:`LinearScenario.frequency_response` -- steady-state response to a harmonic
  exogenous input (the fundamental, exact for single-rate loops);
* :func:`ceiling` -- the ideal ceiling: the largest reduction of a performance output
  under a harmonic disturbance that any controller driving the chosen actuators could
  reach, either by cancelling the chosen sensor signals perfectly (``"cancel"``) or by
  the best actuator commands at each frequency (``"optimal"``, a bound no causal
  controller can beat).

``jitterfmu analyze SCENARIO`` prints these as a table.

Example
-------
>>> from orchestrator.analysis import linearize             # doctest: +SKIP
>>> lin = linearize("scenarios/truss10_closed_loop.toml")   # doctest: +SKIP
>>> lin.decay(8.4).cycles_to_90pct                          # doctest: +SKIP
"""

from __future__ import annotations

import ast
import importlib
import math
import tempfile
import warnings
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from orchestrator import prepare
from orchestrator.scenario import load_scenario
from piezofmu.amplifier import linear_map
from structfmu.discrete import discretize, step
from structfmu.statespace import first_order

__all__ = [
    "AnalysisError",
    "Block",
    "LinearScenario",
    "Pole",
    "Margins",
    "Decay",
    "Ceiling",
    "linearize",
    "ceiling",
    "report",
]

_LN10 = math.log(10.0)


class AnalysisError(ValueError):
    """A scenario cannot be analysed as a linear closed loop."""


# ---------------------------------------------------------------------------------------
# Blocks: one discrete LTI per FMU instance, at its own period


@dataclass(frozen=True, eq=False)
class Block:
    """One instance as a discrete linear system at its communication period.

    ``x+ = A x + B u``, ``y = C x + D u`` with ``u`` the inputs held over the step.

    Parameters
    ----------
    name : str
        Instance name.
    kind : str
        ``"structure"``, ``"piezo"``, ``"controller"``, ``"acs"`` or ``"source"``.
    period : int
        Period in base ticks.
    A, B, C, D : ndarray
        Shapes ``(n, n)``, ``(n, n_in)``, ``(n_out, n)``, ``(n_out, n_in)``.
    inputs, outputs : tuple of str
        FMU variable names of ``u`` and ``y``.
    feedthrough : ndarray of bool, shape (n_out,)
        Outputs the FMU declares as depending on an input (read after the inputs are
        set at the tick); the others are read as stamped at ``t_k``.
    rebuild : callable, optional
        ``rebuild(factor) -> Block`` with the controller's command scaled by ``factor``.
    continuous : tuple of ndarray, optional
        The continuous-time model the block samples, for the sampled-data reference
        (:mod:`orchestrator.reference`): ``(A, B, C, D)`` of a structure (Eq. 9-10), or
        ``(A, B, ch)`` of a piezo amplifier in force units (input ``ch v_cmd``, first
        state the force ``ch v`` on the structure).
    """

    name: str
    kind: str
    period: int
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    inputs: tuple
    outputs: tuple
    feedthrough: np.ndarray
    rebuild: Callable | None = field(default=None, repr=False)
    active: bool = True
    continuous: tuple | None = field(default=None, repr=False)

    @property
    def n(self) -> int:
        return self.A.shape[0]


def _lift(A, B, n):
    """``n`` steps of ``x+ = A x + B u`` with ``u`` held: ``(A^n, sum A^k B)``."""
    An, Bn = np.eye(A.shape[0]), np.zeros_like(B)
    for _ in range(n):
        Bn = A @ Bn + B
        An = A @ An
    return An, Bn


def _structure_block(slave, name, period, h, ft):
    stepper = slave.stepper
    model = stepper.model
    dm = discretize(model, h)
    n, m = model.n_states, model.n_inputs
    A = np.column_stack([step(dm, e, np.zeros(m)) for e in np.eye(n)]) if n else np.zeros((0, 0))
    B = np.column_stack([step(dm, np.zeros(n), e) for e in np.eye(m)])
    return Block(name, "structure", period, A, B, stepper.C_x.copy(), stepper.D.copy(),
                 tuple(model.input_names), tuple(model.output_names), ft,
                 continuous=first_order(model))


def _piezo_block(slave, name, period, h, ft):
    act = slave.actuator()
    if act.hysteresis is not None:
        raise AnalysisError(f"instance {name!r} has hysteresis on; the linear analysis "
                            "needs hysteresis=false")
    coupling = slave._coupling()
    if coupling == 1 and abs(h - float(slave.hold_step)) > 1e-9 * h:
        raise AnalysisError(f"instance {name!r} steps every {h} s but its hold_step is "
                            f"{slave.hold_step} s; set hold_step to its period")
    amp, stack = act.amplifier, act.stack
    ch = float(stack.force(1.0))
    cap = stack.capacitance
    ins = ("v_cmd", "elongation")
    outs = ("force", "voltage", "current", "free_stroke", "strain")
    gl = act.gauge.length
    A1, B1, cx, cu = linear_map(amp, h)
    A, B = A1, np.hstack([B1, np.zeros((A1.shape[0], 1))])
    if amp.order == 1:
        w = amp.omega
        C = np.array([[ch], [1.0], [-cap * w], [act.stroke_per_volt], [0.0]])
        D = np.array([[0, 0], [0, 0], [cap * w, 0], [0, 0], [0, 1.0 / gl]], dtype=float)
    else:
        C = np.array([[ch, 0], [1.0, 0], [0, cap], [act.stroke_per_volt, 0], [0, 0]])
        D = np.zeros((5, 2))
        D[4, 1] = 1.0 / gl
    if coupling == 1:
        # force = trapezoidal mean over the coming step (piezofmu.actuator.step_mean)
        C[0] = ch * cx
        D[0, 0] = ch * cu
    w = amp.omega
    if amp.order == 1:   # f' = w (ch v_cmd - f)
        amp_c = (np.array([[-w]]), np.array([[w]]), ch)
    else:                # f'' = w^2 (ch v_cmd - f) - 2 zeta w f'
        amp_c = (np.array([[0.0, 1.0], [-w * w, -2 * amp.damping * w]]),
                 np.array([[0.0], [w * w]]), ch)
    return Block(name, "piezo", period, A, B, C, D, ins, outs, ft, continuous=amp_c)


def _law_block(law, name, period, h, ft, factor=1.0):
    """Block of a ``ctrlfmu.law.DiscreteLaw`` with its command scaled by ``factor``."""
    n_samples = h / law.dt
    k = round(n_samples)
    if k < 1 or abs(n_samples - k) > 1e-9 * max(1.0, n_samples):
        raise AnalysisError(f"controller {name!r} runs at {h} s but its law samples every "
                            f"{law.dt} s; the linear analysis needs a period that is a "
                            "multiple of the law's sample time")
    a, b, c, d = law.A, law.B, law.C * factor, law.D * factor
    n, n_in, n_out = law.n_states, law.n_inputs, law.n_outputs
    if law.delayed:   # state [x; u]: u+ = C x + D y, output u
        As = np.block([[a, np.zeros((n, n_out))], [c, np.zeros((n_out, n_out))]])
        Bs = np.vstack([b, d])
        Cs = np.hstack([np.zeros((n_out, n)), np.eye(n_out)])
        Ds = np.zeros((n_out, n_in))
        As, Bs = _lift(As, Bs, k)
    else:
        if k != 1:
            raise AnalysisError(f"controller {name!r}: a non-delayed law must run at its "
                                "own sample time for the linear analysis")
        As, Bs, Cs, Ds = a, b, c, d
    ins = tuple(f"y{j + 1}" for j in range(n_in)) + tuple(f"r{i + 1}" for i in range(n_out))
    outs = tuple(f"u{i + 1}" for i in range(n_out))
    B = np.hstack([Bs, np.zeros((As.shape[0], n_out))])
    D = np.hstack([Ds, np.eye(n_out)])   # r is added after the law
    return Block(name, "controller", period, As, B, Cs, D, ins, outs, ft,
                 rebuild=lambda f: _law_block(law, name, period, h, ft, factor * f),
                 active=bool(factor != 0 and (np.any(law.C) or np.any(law.D))))


def _controller_block(slave, name, period, h, ft):
    slave._apply_parameters()
    return _law_block(slave.law, name, period, h, ft)


def _acs_block(slave, name, period, h, ft):
    cfg = slave.config()
    T = cfg.sample_time
    if abs(h - T) > 1e-9 * T:
        raise AnalysisError(f"ACS {name!r} communicates every {h} s but samples every {T} s; "
                            "the linear analysis needs the two equal")
    g = cfg.gains
    kp, ki, kd = (np.asarray(v, float) * np.ones(3) for v in (g.kp, g.ki, g.kd))
    # state [z (3), u (3)]: z+ = z + T e, u+ = -(kp e + kd r + ki z); torque = u
    A = np.zeros((6, 6))
    A[:3, :3] = np.eye(3)
    A[3:, :3] = -np.diag(ki)
    B = np.zeros((6, 6))
    B[:3, :3] = T * np.eye(3)
    B[3:, :3] = -np.diag(kp)
    B[3:, 3:] = -np.diag(kd)
    C = np.zeros((6, 6))
    C[:3, 3:] = np.eye(3)
    C[3:, :] = 0.0   # wheel speeds: not fed back in the linear analysis
    ins = ("roll", "pitch", "yaw", "rate_x", "rate_y", "rate_z")
    outs = ("Tx", "Ty", "Tz", "wheel_speed_x", "wheel_speed_y", "wheel_speed_z")
    return Block(name, "acs", period, A, B, C, np.zeros((6, 6)), ins, outs, ft)


_KINDS = {
    "structfmu.slave:StructureSlave": _structure_block,
    "piezofmu.slave:PiezoSlave": _piezo_block,
    "ctrlfmu.slave:ControllerSlave": _controller_block,
    "acsfmu.slave:AcsSlave": _acs_block,
}
_SOURCES = ("distfmu.slave:DisturbanceSlave", "distfmu.excitation:ExcitationSlave")


def _slave_class(resources: Path, fmu_name: str):
    """The project slave class of an extracted FMU, read from its generated module.

    The module is parsed, never executed: its base-class import names a class of this
    project's packages, imported from the installed packages; its class attributes
    (plain literals) are set on a subclass.
    """
    scripts = sorted(resources.glob("fmuslave_*.py"))
    if not scripts and any(resources.glob("*.dat")):
        raise AnalysisError(f"FMU {fmu_name} is a native build and its Python twin is not "
                            "beside it in python/; the linear analysis reads the Python "
                            "build: run 'jitterfmu build' (it writes both)")
    if not scripts:
        raise AnalysisError(f"FMU {fmu_name} was not built by this project (no generated "
                            "slave module); the linear analysis knows only its own FMUs")
    tree = ast.parse(scripts[0].read_text())
    base, attrs = None, {}
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and any(a.asname == "Fmi2Slave" for a in node.names):
            base = f"{node.module}:{[a.name for a in node.names if a.asname == 'Fmi2Slave'][0]}"
        if isinstance(node, ast.ClassDef):
            for st in node.body:
                if isinstance(st, ast.Assign) and len(st.targets) == 1 \
                        and isinstance(st.targets[0], ast.Name):
                    try:
                        attrs[st.targets[0].id] = ast.literal_eval(st.value)
                    except ValueError:
                        pass
    if base not in _KINDS and base not in _SOURCES:
        raise AnalysisError(f"FMU {fmu_name} has slave class {base}; the linear analysis "
                            f"knows {', '.join(list(_KINDS) + list(_SOURCES))}")
    if base in _SOURCES:
        return base, None
    module, cls = base.split(":")
    klass = getattr(importlib.import_module(module), cls)
    attrs.pop("default_experiment", None)
    return base, type(attrs.get("model_identifier", cls), (klass,), attrs)


def _source_block(name, period, outputs) -> Block:
    """An instance whose outputs are exogenous (a source, or one taken out of the loop)."""
    m = len(outputs)
    return Block(name, "source", period, np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((m, 0)),
                 np.zeros((m, 0)), (), tuple(outputs), np.zeros(m, bool))


def _instance_block(plan, inst, tmp: Path) -> Block:
    info = plan.fmus[inst.name]
    res = tmp / inst.name
    path = info.path  # the Python twin where there is one (fmu_kind = "python")
    with zipfile.ZipFile(path) as z:
        for member in z.namelist():
            if member.startswith("resources/") and not member.endswith("/"):
                target = res / member[len("resources/"):]
                if not target.resolve().is_relative_to(res.resolve()):
                    raise AnalysisError(f"FMU {info.path.name} has an unsafe path {member!r}")
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(z.read(member))
    base, klass = _slave_class(res, path.name)
    period = plan.timebase.period_ticks[inst.name]
    h = float(inst.period)
    outs = [n for n, v in info.variables.items() if v.causality == "output"]
    if klass is None:
        return _source_block(inst.name, period, outs)
    slave = klass(instance_name=inst.name, resources=str(res))
    for pname, value in inst.parameters.items():
        setattr(slave, pname, value)
    slave.setup_experiment(float(plan.scenario.experiment.start), None, None)
    block = _KINDS[base](slave, inst.name, period, h, None)
    ft = np.array([bool(info.feedthrough.get(o)) for o in block.outputs])
    return replace(block, feedthrough=ft)


# ---------------------------------------------------------------------------------------
# The assembled scenario


@dataclass(frozen=True)
class Pole:
    """A closed-loop pole: z-plane value, natural frequency (Hz), damping ratio (-)."""

    z: complex
    freq_hz: float
    zeta: float


@dataclass(frozen=True)
class Margins:
    """Gain margins of one loop: factors on its gain at the stability limits.

    ``upper`` > 1 (``inf`` if none found up to the search limit), ``lower`` < 1
    (``-inf`` when the loop stays stable down to and through zero gain, i.e. also with
    the sign flipped, within the search limit).  In dB: ``20 log10(upper)``.
    """

    instance: str
    upper: float
    lower: float
    stable: bool

    @property
    def upper_db(self) -> float:
        return 20 * math.log10(self.upper) if self.upper > 0 else -math.inf

    @property
    def lower_db(self) -> float:
        return 20 * math.log10(self.lower) if self.lower > 0 else -math.inf


@dataclass(frozen=True)
class Decay:
    """Decay of the closed-loop pole nearest a mode."""

    mode_hz: float
    pole: Pole
    cycles_to_90pct: float


@dataclass(frozen=True)
class Ceiling:
    """Ideal ceiling of one performance output under one harmonic disturbance.

    Attributes
    ----------
    performance : tuple of str
    method : str
        ``"cancel"`` or ``"optimal"``.
    sensors : tuple of str
        Signals cancelled (``"cancel"``).
    freqs_hz : ndarray, shape (n_f,)
    open_loop : ndarray, shape (n_f,)
        RMS over the performance outputs of the response without control, per frequency.
    ideal : ndarray, shape (n_f,)
        Same with the ideal actuator commands.
    reduction_pct : float
        ``100 (1 - |ideal| / |open_loop|)`` over all frequencies (RSS, weighted by the
        disturbance amplitudes).
    """

    performance: tuple
    method: str
    sensors: tuple
    freqs_hz: np.ndarray
    open_loop: np.ndarray
    ideal: np.ndarray
    reduction_pct: float


class LinearScenario:
    """The linear closed loop of a scenario (see the module docstring).

    Build with :func:`linearize`.  The lifted state ``X`` holds, per instance, its state,
    its held inputs and its published outputs; exogenous inputs ``w`` are the outputs of
    source instances at their due ticks.
    """

    def __init__(self, plan, blocks: dict, order: list):
        self.plan = plan
        self.blocks = blocks
        self.order = order                      # Gauss-Seidel step order
        self.base = float(plan.timebase.base)
        # sources (and instances taken out of the loop) carry no state: the hyperperiod
        # is that of the dynamic instances
        periods = [b.period for b in blocks.values() if b.kind != "source"]
        self.hyper = int(np.lcm.reduce(periods)) if periods else 1
        self.T = self.hyper * self.base
        self._layout()
        self._conns = []
        for c in plan.scenario.connections:
            src, dst = blocks[c.source], blocks[c.target]
            if c.target_var not in dst.inputs:
                continue   # e.g. a Boolean enable: constant in the analysis
            if c.source_var not in src.outputs:
                continue
            self._conns.append((c.target, dst.inputs.index(c.target_var), c.source,
                                src.outputs.index(c.source_var), float(c.gain)))

    # ------------------------------------------------------------------ layout
    def _layout(self):
        off = 0
        self.slots = {}
        for name, b in self.blocks.items():
            nx, nu, ny = b.n, len(b.inputs), len(b.outputs)
            self.slots[name] = (slice(off, off + nx), slice(off + nx, off + nx + nu),
                                slice(off + nx + nu, off + nx + nu + ny))
            off += nx + nu + ny
        self.n = off
        self.sources = [n for n, b in self.blocks.items() if b.kind == "source"]

    def index(self, ref: str) -> int:
        """Row of ``X`` holding the published output ``instance.variable``."""
        inst, var = ref.split(".", 1)
        if inst not in self.blocks:
            raise AnalysisError(f"no instance {inst!r} in the scenario; instances: "
                                f"{', '.join(self.blocks)}")
        b = self.blocks[inst]
        if var not in b.outputs:
            raise AnalysisError(f"{ref} is not an output of {inst!r}; outputs: "
                                f"{', '.join(b.outputs[:12])}{' ...' if len(b.outputs) > 12 else ''}")
        return self.slots[inst][2].start + b.outputs.index(var)

    def with_gain(self, instance: str, factor: float) -> "LinearScenario":
        """Copy with controller ``instance``'s command scaled by ``factor``.

        Parameters
        ----------
        instance : str
            Controller instance name.
        factor : float
            Factor on the controller's command (-); negative flips its sign.

        Returns
        -------
        LinearScenario
        """
        b = self.blocks.get(instance)
        if b is None or b.rebuild is None:
            raise AnalysisError(f"{instance!r} is not a controller of the scenario; "
                                f"controllers: {', '.join(self.controllers())}")
        blocks = dict(self.blocks)
        blocks[instance] = replace(b.rebuild(factor), feedthrough=b.feedthrough)
        return LinearScenario(self.plan, blocks, self.order)

    def with_law(self, instance: str, law) -> "LinearScenario":
        """Copy with controller ``instance`` running ``law`` (a ``DiscreteLaw``) instead.

        Parameters
        ----------
        instance : str
            Controller instance name; it keeps its period.
        law : ctrlfmu.law.DiscreteLaw
            The law to run.

        Returns
        -------
        LinearScenario
        """
        b = self.blocks.get(instance)
        if b is None or b.kind != "controller":
            raise AnalysisError(f"{instance!r} is not a controller of the scenario; "
                                f"controllers: {', '.join(self.controllers())}")
        blocks = dict(self.blocks)
        blocks[instance] = _law_block(law, instance, b.period, b.period * self.base,
                                      b.feedthrough)
        return LinearScenario(self.plan, blocks, self.order)

    def opened(self, instances) -> "LinearScenario":
        """Copy with the named instances removed: their outputs become free inputs.

        Used for the ceiling (controllers), and to take a slow loop out of the analysis
        of fast ones: with a 10 Hz ACS the hyperperiod is 0.1 s and its poles resolve
        frequencies up to 5 Hz only.
        """
        blocks = dict(self.blocks)
        for name in instances:
            if name not in blocks:
                raise AnalysisError(f"no instance {name!r} in the scenario; instances: "
                                    f"{', '.join(blocks)}")
            blocks[name] = _source_block(name, blocks[name].period, blocks[name].outputs)
        return LinearScenario(self.plan, blocks, self.order)

    def controllers(self, active_only: bool = False) -> list:
        """Controller instances (those whose gain is not zero with ``active_only``)."""
        return [n for n, b in self.blocks.items()
                if b.kind == "controller" and (b.active or not active_only)]

    # ------------------------------------------------------------------ stepping
    def _tick(self, X, k, w_next):
        """Advance ``X`` (rows = lifted state, any number of columns) over tick ``k``.

        ``w_next(name)`` returns the rows to publish for a due source.
        """
        due = [n for n in self.order if k % self.blocks[n].period == 0]
        for name in due:
            b = self.blocks[name]
            sx, su, sy = self.slots[name]
            if b.kind == "source":
                X[sy] = w_next(name)
            else:
                X[sy] = b.C @ X[sx] + b.D @ X[su]
        dueset = set(due)
        for name in due:
            b = self.blocks[name]
            if b.kind == "source":
                continue
            sx, su, sy = self.slots[name]
            X[su] = 0.0      # unconnected inputs keep their start values: no perturbation
            for tgt, j, src, i, gain in self._conns:
                if tgt == name:
                    X[su.start + j] = gain * X[self.slots[src][2].start + i]
            if b.feedthrough.any():
                rows = np.flatnonzero(b.feedthrough)
                X[sy.start + rows] = b.C[rows] @ X[sx] + b.D[rows] @ X[su]
        for name in dueset:
            b = self.blocks[name]
            if b.kind == "source" or b.n == 0:
                continue
            sx, su, _ = self.slots[name]
            X[sx] = b.A @ X[sx] + b.B @ X[su]
        return X

    def lifted(self) -> np.ndarray:
        """``Phi`` (n, n): the map of ``X`` over one hyperperiod from tick 0, ``w = 0``."""
        X = np.eye(self.n)

        def w_next(name):
            return np.zeros((len(self.blocks[name].outputs), self.n))

        for k in range(self.hyper):
            X = self._tick(X, k, w_next)
        return X

    def _harmonic(self, X, inputs, w_rad, out_rows=None, n_ticks=None):
        """Run ``n_ticks`` (one hyperperiod by default) from ``X`` (n, n_in) with
        ``exp(j w t)`` on ``inputs``.

        Returns the final ``X`` and, with ``out_rows``, the fundamental of those rows.
        """
        n_ticks = self.hyper if n_ticks is None else n_ticks
        cols = len(inputs)
        acc = None if out_rows is None else np.zeros((len(out_rows), cols), complex)
        k_now = [0]

        def w_next(name):
            b = self.blocks[name]
            rows = np.zeros((len(b.outputs), cols), complex)
            for j, ref in enumerate(inputs):
                inst, var = ref.split(".", 1)
                if inst == name:
                    rows[b.outputs.index(var), j] = np.exp(1j * w_rad * k_now[0] * self.base)
            return rows

        for k in range(n_ticks):
            k_now[0] = k
            X = self._tick(X, k % self.hyper, w_next)
            if acc is not None:
                acc += X[out_rows] * np.exp(-1j * w_rad * k * self.base)
        return X, (None if acc is None else acc / n_ticks)

    def simulate(self, n_ticks: int, w: Callable | None = None, x0=None, record=()):
        """Tick-by-tick linear simulation.

        Parameters
        ----------
        n_ticks : int
            Number of base ticks.
        w : callable, optional
            ``w(instance, tick) -> ndarray (n_outputs,)`` values a source publishes at
            its due ticks; zero when omitted.
        x0 : ndarray, shape (n,), optional
        record : sequence of str
            Outputs ``instance.variable`` to record at every tick (value at ``t_k``
            after the tick's inputs are set, before it steps).

        Returns
        -------
        ndarray, shape (n_ticks, len(record)), and the final ``X``.
        """
        X = np.zeros((self.n, 1)) if x0 is None else np.asarray(x0, float).reshape(-1, 1).copy()
        rows = [self.index(r) for r in record]
        out = np.empty((n_ticks, len(rows)))
        k_now = [0]

        def w_next(name):
            if w is None:
                return np.zeros((len(self.blocks[name].outputs), 1))
            return np.asarray(w(name, k_now[0]), float).reshape(-1, 1)

        for k in range(n_ticks):
            k_now[0] = k
            X = self._tick(X, k % self.hyper, w_next)
            # _tick leaves the published values of tick k in X (states already advanced)
            out[k] = X[rows, 0]
        return out, X[:, 0]

    # ------------------------------------------------------------------ analysis
    def poles(self) -> list[Pole]:
        """Closed-loop poles (z over one hyperperiod), origin poles left out."""
        return _poles(np.linalg.eigvals(self.lifted()), self.T)

    def is_stable(self, tol: float = 1e-9) -> bool:
        """All poles inside the unit circle; rigid-body poles at exactly 1 allowed."""
        return _stable(np.linalg.eigvals(self.lifted()), tol)

    def gain_margins(self, instance: str, limit: float = 1e3, rtol: float = 1e-3) -> Margins:
        """Gain margins of controller ``instance``, the other loops closed.

        The factor on the controller's gain is searched on a logarithmic grid up to
        ``limit`` and down to ``-limit`` (through zero, i.e. with the sign flipped), then
        refined by bisection to ``rtol``.

        Parameters
        ----------
        instance : str
            Controller instance name.
        limit : float
            Largest factor magnitude searched (-).
        rtol : float
            Relative tolerance of the bisection on the factor.

        Returns
        -------
        Margins
        """
        def stable(f):
            return self.with_gain(instance, f).is_stable()

        ok = stable(1.0)
        up = _boundary(stable, 1.0, np.geomspace(1.0, limit, 19)[1:], rtol)
        downs = np.r_[np.geomspace(1.0, 1e-2, 7)[1:], 0.0, -np.geomspace(1e-2, limit, 16)]
        lo = _boundary(stable, 1.0, downs, rtol)
        return Margins(instance, up, lo, ok)

    def decay(self, mode_hz: float) -> Decay:
        """Cycles to 90 % decay of the closed-loop pole nearest ``mode_hz``.

        ``ln(10) sqrt(1 - zeta^2) / (2 pi zeta)`` damped cycles; poles whose frequency
        aliases (above half the hyperperiod rate) are not resolved.
        """
        ps = [p for p in self.poles() if p.freq_hz > 0]
        if not ps:
            raise AnalysisError("the closed loop has no oscillatory pole")
        p = min(ps, key=lambda q: abs(q.freq_hz - mode_hz))
        return Decay(mode_hz, p, _cycles(p.zeta))

    def frequency_response(self, inputs, outputs, freqs_hz) -> np.ndarray:
        """Steady-state response to harmonic exogenous inputs.

        Parameters
        ----------
        inputs : sequence of str
            Source outputs ``instance.variable`` driven by ``exp(j 2 pi f t)``.
        outputs : sequence of str
            Published outputs ``instance.variable``.
        freqs_hz : array_like, shape (n_f,)

        Returns
        -------
        ndarray, shape (n_out, n_in, n_f)
            Fundamental component of each output per unit input (exact for a loop
            whose instances share one period; for mixed rates the component at ``f``
            of the periodic steady state, whose period is the hyperperiod of the loop and
            of the driving sources together).
        """
        freqs = np.atleast_1d(np.asarray(freqs_hz, float))
        inputs = list(inputs)
        period = self.hyper   # the steady state's period: the sources' periods included
        for ref in inputs:
            inst, var = ref.split(".", 1)
            if inst not in self.sources or var not in self.blocks[inst].outputs:
                raise AnalysisError(f"{ref} is not an output of a source instance; sources: "
                                    f"{', '.join(self.sources)}")
            period = int(np.lcm(period, self.blocks[inst].period))
        Phi = np.linalg.matrix_power(self.lifted(), period // self.hyper)
        T = period * self.base
        rows = [self.index(r) for r in outputs]
        H = np.zeros((len(rows), len(inputs), freqs.size), complex)
        eye = np.eye(self.n)
        for fi, f in enumerate(freqs):
            w = 2 * np.pi * f
            # periodic steady state: X(T) = exp(j w T) X(0)
            forced, _ = self._harmonic(np.zeros((self.n, len(inputs)), complex), inputs, w,
                                       n_ticks=period)
            try:
                X0 = np.linalg.solve(np.exp(1j * w * T) * eye - Phi, forced)
            except np.linalg.LinAlgError:
                raise AnalysisError(f"the loop has a pole at {f} Hz (a multiple of the "
                                    "hyperperiod rate on a neutral mode); choose another "
                                    "frequency") from None
            _, H[:, :, fi] = self._harmonic(X0, inputs, w, rows, n_ticks=period)
        return H


def _cycles(zeta: float) -> float:
    """Damped cycles for a pole's envelope to fall to 10 %."""
    if zeta >= 1:
        return 0.0
    return math.inf if zeta <= 0 else _LN10 * math.sqrt(1 - zeta**2) / (2 * math.pi * zeta)


def _poles(ev, T) -> list[Pole]:
    out = []
    for z in ev:
        if abs(z) < 1e-12:
            continue
        s = np.log(complex(z)) / T
        wn = abs(s)
        out.append(Pole(complex(z), wn / (2 * np.pi), -s.real / wn if wn > 0 else 1.0))
    out.sort(key=lambda p: (p.freq_hz, p.zeta))
    return out


def _stable(ev, tol=1e-9) -> bool:
    """All eigenvalues inside the unit circle; rigid-body ones at 1 allowed."""
    ev = np.asarray(ev)
    rigid = np.abs(ev - 1.0) < 1e-7
    return bool(np.all(rigid | (np.abs(ev) < 1.0 - tol)))


def _boundary(stable, start, grid, rtol):
    """First factor along ``grid`` (from ``start``) where stability changes, bisected."""
    prev, s_prev = start, stable(start)
    for g in grid:
        s = stable(g)
        if s != s_prev:
            a, b = prev, g
            while abs(b - a) > rtol * max(abs(a), abs(b), 1e-6):
                m = 0.5 * (a + b)
                if stable(m) == s_prev:
                    a = m
                else:
                    b = m
            return float(0.5 * (a + b))
        prev = g
    return math.inf if grid[-1] > start else -math.inf


def stability_margin_db(stable: Callable[[float], bool], step: float = 2.0,
                        limit: float = 1e4, tol: float = 1.005,
                        beyond: float = math.inf) -> float:
    """Gain margin (dB) from a stability test on a factor on the loop gain(s).

    From factor 1, ``step`` by ``step`` (> 1 up, < 1 down) until ``stable`` fails, then
    geometric bisection until the bracket's ratio is at most ``tol``; the margin is
    ``|20 log10|`` of the last stable factor.

    Parameters
    ----------
    stable : callable
        ``stable(factor)``: is the closed loop stable with the gains times ``factor``?
    step : float
        Factor between search points: 2 for the upper margin, 0.5 for the lower one.
    limit : float
        Largest factor (or smallest, ``1 / limit``, going down) searched (-).
    tol : float
        Ratio of the final bracket (-), e.g. 1.005 for 0.5 %.
    beyond : float
        Returned (dB) when the loop is still stable past ``limit``.

    Returns
    -------
    float
        Margin (dB); ``-inf`` if unstable at factor 1.
    """
    if not stable(1.0):
        return -math.inf
    lo, hi = 1.0, step
    while stable(hi):
        lo, hi = hi, hi * step
        if abs(math.log10(hi)) > math.log10(limit):
            return beyond
    while max(hi / lo, lo / hi) > tol:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return abs(20 * math.log10(lo))


# ---------------------------------------------------------------------------------------
# Building, ceiling, report


def linearize(scenario, *, overrides=None, fmu_dir=None) -> LinearScenario:
    """The linear closed loop of a scenario.

    Parameters
    ----------
    scenario : path-like, dict or Scenario
        As :func:`orchestrator.run_scenario`.
    overrides : mapping of str to value, optional
        ``{"instance.parameter": value}`` start values.
    fmu_dir : path-like, optional
        Folder searched first for FMUs; the Python build of the suite's FMUs is read
        (its ``python/`` subfolder first), whatever the scenario's ``fmu_kind``.

    Returns
    -------
    LinearScenario
    """
    # the models are read from the Python FMUs' resources (model.npz, law.npz), which
    # the native twins carry in another form: the same FMUs, their Python build
    sc = load_scenario(scenario).with_overrides(overrides or {}) \
        .with_experiment(fmu_kind="python")
    if sc.experiment.algorithm != "gauss-seidel":
        raise AnalysisError("the linear analysis follows the Gauss-Seidel master; the "
                            f"scenario uses {sc.experiment.algorithm!r}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plan = prepare(sc, fmu_dir)
    order = []
    for group in plan.groups:
        if len(group) > 1:
            raise AnalysisError(f"the scenario has an algebraic loop {group}; the linear "
                                "analysis needs a loop with a delay")
        order.append(group[0])
    with tempfile.TemporaryDirectory(prefix="jitterfmu-analyze-") as tmp:
        blocks = {i.name: _instance_block(plan, i, Path(tmp)) for i in sc.instances}
    return LinearScenario(plan, blocks, order)


def ceiling(lin: LinearScenario, performance, disturbance: str, freqs_hz, *,
            actuators, sensors=None, method: str = "cancel", amplitudes=None) -> Ceiling:
    """Ideal ceiling of the reduction of ``performance`` under a harmonic disturbance.

    The named controllers are removed (their command outputs become free actuator
    commands ``v``).  With ``method="cancel"``, ``v`` zeroes the signals the removed
    controllers measured (``sensors``; by default their connected inputs): what a loop
    of infinite gain on those sensors would do.  With ``"optimal"``, ``v`` minimises the
    performance outputs at each frequency (least squares): no controller driving these
    actuators, causal or not, can do better in steady state.

    Parameters
    ----------
    lin : LinearScenario
    performance : sequence of str
        Outputs whose RMS is to be reduced (e.g. ``structure.los_misr_roll``).
    disturbance : str
        Source output ``instance.variable`` carrying the disturbance.
    freqs_hz : array_like, shape (n_f,)
        Disturbance lines (Hz).
    actuators : sequence of str
        Controller instances whose commands are free.
    sensors : sequence of str, optional
        Signals to cancel (``instance.variable``); default: the outputs connected to the
        removed controllers' measurement inputs.
    method : {"cancel", "optimal"}
    amplitudes : array_like, shape (n_f,), optional
        Disturbance amplitude per line; 1 by default.

    Returns
    -------
    Ceiling
    """
    if method not in ("cancel", "optimal"):
        raise AnalysisError(f"ceiling method {method!r} is unknown; use 'cancel' or 'optimal'")
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    amps = np.ones_like(freqs) if amplitudes is None else np.asarray(amplitudes, float)
    performance = list(performance)
    opened = lin.opened(actuators)
    v = [f"{a}.{o}" for a in actuators for o in lin.blocks[a].outputs]
    if sensors is None:
        sensors = []
        for c in lin.plan.scenario.connections:
            if c.target in actuators and c.target_var.startswith("y"):
                sensors.append(c.start)
    sensors = list(sensors)
    outs = performance + sensors
    Hd = opened.frequency_response([disturbance], outs, freqs)[:, 0, :]   # (n_o, n_f)
    Hv = opened.frequency_response(v, outs, freqs)                        # (n_o, n_v, n_f)
    npf = len(performance)
    ol, ideal = np.zeros(freqs.size), np.zeros(freqs.size)
    for i in range(freqs.size):
        zd, zv = Hd[:npf, i], Hv[:npf, :, i]
        if method == "cancel":
            yd, yv = Hd[npf:, i], Hv[npf:, :, i]
            vopt = -np.linalg.lstsq(yv, yd, rcond=None)[0]
        else:
            vopt = -np.linalg.lstsq(zv, zd, rcond=None)[0]
        ol[i] = np.linalg.norm(zd) * amps[i]
        ideal[i] = np.linalg.norm(zd + zv @ vopt) * amps[i]
    if not np.any(ol > 0):
        raise AnalysisError(f"{disturbance} does not reach {', '.join(performance)} once "
                            f"{', '.join(actuators)} are removed (it may enter through "
                            "them); choose a disturbance that acts on the structure")
    red = 100.0 * (1.0 - math.sqrt(np.sum(ideal**2)) / math.sqrt(np.sum(ol**2)))
    return Ceiling(tuple(performance), method, tuple(sensors), freqs, ol, ideal, float(red))


def report(lin: LinearScenario, *, modes=(), margins=True, band=None) -> str:
    """A readable table: poles (in ``band`` Hz), decay of ``modes``, gain margins.

    Parameters
    ----------
    lin : LinearScenario
        The linear closed loop.
    modes : sequence of float
        Mode frequencies (Hz) whose nearby closed-loop poles are reported with their
        decay.
    margins : bool
        Add the gain margins of every active controller.
    band : (float, float), optional
        Pole frequency band (Hz); default 0 to half the hyperperiod rate.

    Returns
    -------
    str
        The report, one line per row.
    """
    lines = [f"linear closed loop: {len(lin.blocks)} instances, {lin.n} lifted states, "
             f"hyperperiod {lin.T * 1e3:g} ms"]
    poles = lin.poles()
    nyq = 0.5 / lin.T
    lo, hi = band if band else (0.0, nyq)
    if hi > nyq:
        lines.append(f"warning: the hyperperiod resolves pole frequencies up to {nyq:g} Hz "
                     "only; take slow instances out (--open) to resolve faster ones")
    sel = [p for p in poles if lo <= p.freq_hz <= hi and p.z.imag >= 0]
    lines.append("")
    lines.append(f"closed-loop poles {lo:g}-{hi:g} Hz")
    lines.append(f"  {'freq (Hz)':>10}  {'damping (%)':>11}  {'|z|':>8}")
    for p in sel:
        lines.append(f"  {p.freq_hz:10.3f}  {100 * p.zeta:11.3f}  {abs(p.z):8.5f}")
    lines.append(f"  stable: {'yes' if lin.is_stable() else 'NO'}")
    for m in modes:
        near = [p for p in poles if 0.75 * m <= p.freq_hz <= 1.25 * m and p.z.imag >= 0]
        if not near:
            lines.append(f"mode {m:g} Hz: no closed-loop pole within 0.75-1.25x")
        for p in near:
            cyc = _cycles(p.zeta)
            lines.append(f"mode {m:g} Hz: pole {p.freq_hz:.3f} Hz, damping {100 * p.zeta:.2f} %, "
                         f"{cyc:.2f} cycles to 90 % decay of its own response")
    if margins:
        lines.append("")
        lines.append("gain margins (factor on each active controller's gain, other loops "
                     "closed)")
        lines.append(f"  {'controller':<24} {'upper':>9} {'(dB)':>7} {'lower':>9}")
        off = [c for c in lin.controllers() if c not in lin.controllers(active_only=True)]
        if off:
            lines.append(f"  (gain 0, not analysed: {', '.join(off)})")
        for c in lin.controllers(active_only=True):
            g = lin.gain_margins(c)
            lines.append(f"  {c:<24} {g.upper:9.3g} {g.upper_db:7.2f} {g.lower:9.3g}")
    return "\n".join(lines)
