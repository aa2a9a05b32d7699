"""One discrete LTI block per FMU instance, read from the FMU's own resources."""

from __future__ import annotations

import ast
import hashlib
import importlib
import json
import math
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from fmutools.archive import ArchiveError, unpack
from piezofmu.amplifier import substeps
from piezofmu.actuator import inner_rows, linear_map
from structfmu.discrete import discretize, step_matrices
from structfmu.statespace import first_order

from . import blockstore
from ._threads import blas_thread_counts


class AnalysisError(ValueError):
    """A scenario cannot be analysed as a linear closed loop."""


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
        state the force ``ch v`` on the structure); None for a piezo whose servo loop is
        on (the reference does not model it).
    t_on : float
        Time (s) from which a controller's command is on (its law's ``t_on``); before it
        the loop through the controller is open.
    inner : tuple
        Limits that act inside a step (a piezo amplifier's at each internal sub-step):
        ``(output, G, lo, hi, what)``, the values ``G @ [x, u]`` (one row per sub-step)
        of a step from the state ``x`` at its start and the inputs ``u`` held over it,
        each to stay within ``[lo, hi]``.
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
    series: Callable | None = field(default=None, repr=False)
    source: object = field(default=None, repr=False)
    limits: tuple = ()
    unmodelled: tuple = ()
    flags: tuple = ()
    model: object = field(default=None, repr=False)
    t_on: float = 0.0
    inner: tuple = ()

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
    return structure_block(slave.stepper.model, name, period, h, ft)


def structure_block(model, name: str, period: int, h: float, ft=None,
                    blockwise: bool = False) -> Block:
    """The block of a reduced structure stepped by ``h`` (exact ZOH, as its FMU).

    Parameters
    ----------
    model : structfmu.reduced.ReducedModel
        The reduced model (e.g. with perturbed modal frequencies).
    name : str
        Instance name.
    period : int
        Period in base ticks.
    h : float
        Step (s).
    ft : ndarray of bool, optional
        Feedthrough outputs (as the FMU declares them).
    blockwise : bool
        The accelerometer filter's rows block by block
        (:func:`structfmu.discrete.filter_zoh`: equal to round-off, the Ritz part kept
        between calls, for a Monte Carlo sample's modes) instead of the FMU's one
        exponential of the whole model.

    Returns
    -------
    Block
    """
    from structfmu.discrete import ZohStepper

    stepper = ZohStepper(model)
    A, B = step_matrices(discretize(model, h, blockwise_filter=blockwise))
    ft = np.zeros(model.n_outputs, bool) if ft is None else ft
    return Block(name, "structure", period, A, B, stepper.C_x.copy(), stepper.D.copy(),
                 tuple(model.input_names), tuple(model.output_names), ft,
                 continuous=first_order(model), model=model)


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
    # state [v] or [v, dv/dt], then the servo's integrator z when it is on
    A, B, cx, cu = linear_map(act, h)
    if amp.order == 1:
        w = amp.omega
        C = np.array([[ch], [1.0], [-cap * w], [act.stroke_per_volt], [0.0]])
        D = np.array([[0, 0], [0, 0], [cap * w, 0], [0, 0], [0, 1.0 / gl]], dtype=float)
    else:
        C = np.array([[ch, 0], [1.0, 0], [0, cap], [act.stroke_per_volt, 0], [0, 0]])
        D = np.zeros((5, 2))
        D[4, 1] = 1.0 / gl
    servo = act.servo_bandwidth > 0
    if servo:
        C = np.hstack([C, np.zeros((5, 1))])
        if amp.order == 1:
            # the rate of the last sub-step: w (command - v), its command z - dz / 2
            _, hs = substeps(h, amp.internal_step)
            kd = hs * act.servo_gain * np.array([act.stroke_per_volt, -1.0])
            C[2, -1] = cap * w
            D[2] = -0.5 * cap * w * kd
    if coupling == 1:
        # force = trapezoidal mean over the coming step (piezofmu.actuator.step_mean)
        C[0] = ch * cx
        D[0] = ch * cu
    w = amp.omega
    if amp.order == 1:   # f' = w (ch v_cmd - f)
        amp_c = (np.array([[-w]]), np.array([[w]]), ch)
    else:                # f'' = w^2 (ch v_cmd - f) - 2 zeta w f'
        amp_c = (np.array([[0.0, 1.0], [-w * w, -2 * amp.damping * w]]),
                 np.array([[0.0], [w * w]]), ch)
    limits = [("voltage", float(amp.v_min), float(amp.v_max), "voltage rail"),
              ("current", -float(amp.i_max), float(amp.i_max), "current (slew) limit")]
    if math.isfinite(act.stroke_limit):
        limits.append(("free_stroke", -act.stroke_limit, act.stroke_limit, "stroke limit"))
    # the rails and the current limit act at every internal sub-step, not at the ticks
    rows = inner_rows(act, h)
    inner = tuple((o, rows[o], lo, hi, what) for o, lo, hi, what in limits[:2]
                  if math.isfinite(hi) or math.isfinite(lo))
    unmodelled = []
    if act.gauge.noise_std > 0:
        unmodelled.append(f"instance {name!r} has strain-gauge noise on (noise_std = "
                          f"{act.gauge.noise_std}); set noise_std = 0")
    if act.gauge.resolution > 0:
        unmodelled.append(f"instance {name!r} quantises its strain (resolution = "
                          f"{act.gauge.resolution}); set resolution = 0")
    return Block(name, "piezo", period, A, B, C, D, ins, outs, ft,
                 continuous=None if servo else amp_c,
                 limits=tuple(limits), unmodelled=tuple(unmodelled),
                 flags=("sat_voltage", "sat_slew", "sat_stroke"), inner=inner)


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
                 active=bool(factor != 0 and (np.any(law.C) or np.any(law.D))),
                 t_on=float(law.t_on))


def _controller_block(slave, name, period, h, ft):
    slave._apply_parameters()
    return _law_block(slave.law, name, period, h, ft)


def _acs_block(slave, name, period, h, ft):
    return acs_block(slave.config(), name, period, h, ft)


def acs_block(config, name: str, period: int, h: float, ft=None) -> Block:
    """Block of an ACS: state ``[z (3), input filters, notch, low-pass, u (3)]``.

    The law is :func:`acsfmu.law.delayed_law` (the one the FMU steps, without
    saturation).  Each filter switched on adds its two direct-form-II-transposed states
    (the six anti-alias filters in input order, then the notches and low-passes of the
    axes that have one), so with every filter off the state is ``[z, u]``.  ``model``
    holds the filter set (:class:`acsfmu.filters.AcsFilters`).

    Parameters
    ----------
    config : acsfmu.pid.AcsConfig
        Gains, sample time, limits and filters.
    name : str
        Instance name.
    period : int
        Period in base ticks.
    h : float
        Communication period (s); must equal the controller's sample time.
    ft : ndarray of bool, shape (6,), optional
        Feedthrough of the outputs (none by default).

    Returns
    -------
    Block
    """
    from acsfmu.law import delayed_law

    T = config.sample_time
    if abs(h - T) > 1e-9 * T:
        raise AnalysisError(f"ACS {name!r} communicates every {h} s but samples every {T} s; "
                            "the linear analysis needs the two equal")
    A, B, Cu = delayed_law(config)
    n = A.shape[0]
    C = np.zeros((6, n))
    C[:3] = Cu                  # wheel speeds: not fed back in the linear analysis
    ins = ("roll", "pitch", "yaw", "rate_x", "rate_y", "rate_z")
    outs = ("Tx", "Ty", "Tz", "wheel_speed_x", "wheel_speed_y", "wheel_speed_z")
    tl = np.broadcast_to(np.asarray(config.torque_limit, float), (3,))
    limits = tuple((o, -float(t), float(t), "torque limit") for o, t in zip(outs[:3], tl))
    return Block(name, "acs", period, A, B, C, np.zeros((6, 6)), ins, outs,
                 np.zeros(6, bool) if ft is None else ft, limits=limits,
                 model=config.filters, unmodelled=tuple(
                     f"output {name}.{o} (the wheel speeds are not in the linear model)"
                     for o in outs[3:]))


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
    module, cls = base.split(":")
    klass = getattr(importlib.import_module(module), cls)
    attrs.pop("default_experiment", None)
    return base, type(attrs.get("model_identifier", cls), (klass,), attrs)


def _source_block(name, period, outputs) -> Block:
    """An instance whose outputs are exogenous (a source, or one taken out of the loop)."""
    m = len(outputs)
    return Block(name, "source", period, np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((m, 0)),
                 np.zeros((m, 0)), (), tuple(outputs), np.zeros(m, bool))


def _series(slave, outs, name):
    """``series(times)`` of a source slave in the order ``outs``, or None."""
    try:
        slave.series(np.zeros(1))   # reads the source now, while its resources exist
    except Exception:            # e.g. an input-driven wheel: no open-loop series
        return None
    own = list(_output_names(slave))
    cols = [own.index(o) for o in outs]

    def series(times):
        return np.asarray(slave.series(times), float)[:, cols]
    return series


def _output_names(slave):
    """Output variable names of a slave in the order its ``series`` returns them."""
    from distfmu.excitation import N_CHANNELS, ExcitationSlave
    from distfmu.sources import WRENCH_NAMES
    if isinstance(slave, ExcitationSlave):
        return [f"v{i}" for i in range(1, N_CHANNELS + 1)]
    return list(WRENCH_NAMES)


def extract_resources(path: Path, res: Path) -> Path:
    """Extract an FMU's ``resources/`` into a folder (no member may leave it).

    Parameters
    ----------
    path : Path
        The ``.fmu`` file.
    res : Path
        Target folder (created).

    Returns
    -------
    Path
        ``res``.
    """
    def target_of(name: str):
        return res.joinpath(*name.split("/")[1:]) if name.startswith("resources/") else None

    try:
        with zipfile.ZipFile(path) as z:
            unpack(z, f"FMU {path.name!r}", target_of)
    except ArchiveError as exc:
        raise AnalysisError(str(exc)) from None
    return res


# blocks kept per extraction index (a campaign's instances several times over)
_KEEP_BLOCKS = 256


def _json_value(v):
    """``json.dumps``'s ``default`` for a parameter: arrays whole (their repr elides),
    numpy numbers as numbers, a mapping as a dict, anything else by its repr."""
    if isinstance(v, np.ndarray):
        return [str(v.dtype), list(v.shape), v.tolist()]
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, Mapping):
        return dict(v)
    return repr(v)


def _block_key(plan, inst) -> tuple:
    """What a block depends on: its FMU file and content, the instance's name,
    parameters, periods and start time (parameters hashed by value, arrays whole), and
    the calling thread's BLAS thread count (the structure's exponential moves in its
    last bits with it: a block built in a campaign's one-thread worker is not the one
    the main thread builds, and a Monte Carlo sample's is compared with it bit for bit)."""
    info = plan.fmus[inst.name]
    params = json.dumps(dict(inst.parameters), sort_keys=True, default=_json_value)
    return (info.path, info.sha256, inst.name, str(inst.period),
            plan.timebase.period_ticks[inst.name], str(plan.scenario.experiment.start),
            hashlib.sha256(params.encode()).hexdigest(), tuple(blas_thread_counts()))


def _disk_key(plan, inst) -> str:
    """The block's entry in the store of built blocks (:mod:`.blockstore`): what
    :func:`_block_key` names, with the FMU's digest and not its path."""
    return blockstore.entry_key(_block_key(plan, inst)[1:])


def _instance_block(plan, inst, tmp: Path, extracted=None, live=None,
                    keep: bool = True) -> Block:
    """The block of one instance, its FMU's resources extracted under ``tmp``.

    ``extracted`` (a dict) caches ``(FMU path, SHA-256) -> (resources folder, slave
    class)`` across calls that share ``tmp``: a file rebuilt in place is extracted again.
    It also keeps the blocks of the instances that are not sources, by
    :func:`_block_key`: a campaign's configurations share most of their instances (the
    structure's discretisation, the amplifiers' and controllers' models), and those are
    built once.  Blocks are frozen and their matrices never written, so sharing them is
    safe; a source's block keeps its slave for its series and is built each time.
    With ``live`` (``live() -> Block``, the block built again, nothing kept), blocks
    are also read from and written to the store of built blocks of other processes
    (:mod:`.blockstore`); ``live`` is a kept controller's ``rebuild``.  With ``keep``
    false no block is read or kept (the extractions still are).
    """
    info = plan.fmus[inst.name]
    path = info.path  # the Python twin where there is one (fmu_kind = "python")
    bkey = blocks = dkey = None
    if extracted is not None and keep:
        blocks = extracted.setdefault("blocks", {})
        bkey = _block_key(plan, inst)
        got = blocks.get(bkey)
        if got is None and live is not None:
            dkey = _disk_key(plan, inst)
            fields = blockstore.load(dkey, live)
            if fields is not None:
                got = blocks[bkey] = Block(**fields)
        if got is not None:
            return got
    key = (path, info.sha256)
    cached = None if extracted is None else extracted.get(key)
    if cached is None:
        res = extract_resources(path, tmp / f"{inst.name}-{len(extracted or ())}")
        cached = (res, _slave_class(res, path.name))
        if extracted is not None:
            extracted[key] = cached
    res, (base, klass) = cached
    period = plan.timebase.period_ticks[inst.name]
    h = float(inst.period)
    outs = [n for n, v in info.variables.items() if v.causality == "output"]
    slave = klass(instance_name=inst.name, resources=str(res))
    for pname, value in inst.parameters.items():
        setattr(slave, pname, value)
    slave.setup_experiment(float(plan.scenario.experiment.start), None, None)
    if base in _SOURCES:
        block = _source_block(inst.name, period, outs)
        config = slave._config() if hasattr(slave, "_config") else None
        return replace(block, series=_series(slave, outs, inst.name), source=config)
    block = _KINDS[base](slave, inst.name, period, h, None)
    ft = np.array([bool(info.feedthrough.get(o)) for o in block.outputs])
    block = replace(block, feedthrough=ft)
    if blocks is not None:
        if len(blocks) >= _KEEP_BLOCKS:
            blocks.clear()
        blocks[bkey] = block
        if dkey is not None:
            blockstore.save(dkey, block)
    return block


