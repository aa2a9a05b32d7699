"""The assembled linear scenario: the master's Gauss-Seidel ticks as one linear map."""

from __future__ import annotations

import atexit
import functools
import json
import math
import shutil
import tempfile
import threading
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from orchestrator.cosim import prepare
from orchestrator.scenario import closest, load_scenario

from .blocks import AnalysisError, _instance_block, _law_block, _source_block

_LN10 = math.log(10.0)


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
        self._conns_to = {}   # per target, in connection order: what a tick sets
        for tgt, j, src, i, gain in self._conns:
            self._conns_to.setdefault(tgt, []).append((j, src, i, gain))

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
            raise AnalysisError(f"no instance {inst!r} in the scenario"
                                f"{closest(inst, self.blocks)}; instances: "
                                f"{', '.join(self.blocks)}")
        b = self.blocks[inst]
        if var not in b.outputs:
            raise AnalysisError(f"{ref} is not an output of {inst!r}"
                                f"{closest(var, b.outputs)}; outputs: "
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

    def with_block(self, block) -> "LinearScenario":
        """Copy with one instance's block replaced (same name, inputs and outputs).

        Parameters
        ----------
        block : Block
            E.g. :func:`~orchestrator.analysis.blocks.structure_block` of a perturbed
            model; it keeps the feedthrough of the block it replaces.

        Returns
        -------
        LinearScenario
        """
        old = self.blocks.get(block.name)
        if old is None or old.inputs != block.inputs or old.outputs != block.outputs:
            raise AnalysisError(f"block {block.name!r} does not replace an instance with the "
                                "same inputs and outputs")
        blocks = dict(self.blocks)
        blocks[block.name] = replace(block, feedthrough=old.feedthrough)
        return LinearScenario(self.plan, blocks, self.order)

    def opened(self, instances, period: int | None = None) -> "LinearScenario":
        """Copy with the named instances removed: their outputs become free inputs.

        Used for the ceiling (controllers), and to take a slow loop out of the analysis
        of fast ones: with a 10 Hz ACS the hyperperiod is 0.1 s and its poles resolve
        frequencies up to 5 Hz only.

        Parameters
        ----------
        instances : sequence of str
            Instances to take out.
        period : int, optional
            Ticks between the freed inputs' values (default each instance's own period).
            Inputs that stay zero may take 1: published every tick, they do not make the
            loop periodic (a time-invariant loop has one tick map, and its steady state
            one phasor per line).
        """
        blocks = dict(self.blocks)
        for name in instances:
            if name not in blocks:
                raise AnalysisError(f"no instance {name!r} in the scenario; instances: "
                                    f"{', '.join(blocks)}")
            blocks[name] = _source_block(name, period or blocks[name].period,
                                         blocks[name].outputs)
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
            for j, src, i, gain in self._conns_to.get(name, ()):
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

        The transfer of :func:`orchestrator.analysis.spectra.transfer` (its one home) on
        this loop as linearised: an instance whose noise or quantisation a record would
        refuse (:class:`~orchestrator.analysis.fast.FastResponse`) counts by its linear
        part.  A source slower than the loop's hyperperiod holds each value over its own
        period, as the co-simulation steps it.

        Parameters
        ----------
        inputs : sequence of str
            Source outputs ``instance.variable`` driven by ``exp(j 2 pi f t)``.
        outputs : sequence of str
            Published outputs ``instance.variable``.
        freqs_hz : array_like, shape (n_f,)
            Frequencies (Hz), none at a multiple of the steady state's rate on a neutral
            pole (a free rigid body at 0 Hz).

        Returns
        -------
        ndarray, shape (n_out, n_in, n_f)
            Fundamental component of each output per unit input (exact for a loop
            whose instances share one period; for mixed rates the component at ``f``
            of the periodic steady state, whose period is the hyperperiod of the loop and
            of the sources together).
        """
        # deferred: the compiled loop imports scipy
        from .fast import FastResponse
        from .spectra import transfer

        outputs = list(outputs)
        return transfer(FastResponse(self, outputs, strict=False), inputs, outputs,
                        freqs_hz).H


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
# Building


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
    blocks = {i.name: instance_block(plan, i) for i in sc.instances}
    return LinearScenario(plan, blocks, order)


def loop_key(data: dict, sources) -> str:
    """A scenario's data less its sources' parameters, as one string: runs that differ
    only there (a campaign's events) close the same loop.

    Parameters
    ----------
    data : dict
        The scenario as plain data (a case's scenario, ``Scenario.to_dict()``).
    sources : sequence of str
        The loop's source instances (``LinearScenario.sources``).

    Returns
    -------
    str
    """
    data = json.loads(json.dumps(data, default=str))
    for name in sources:
        data["fmus"].get(name, {}).pop("parameters", None)
    return json.dumps(data, sort_keys=True, default=str)


# one extraction per FMU file and content in a process, shared by its instances and by
# every loop it linearises (a campaign's configurations, a sweep's points): its folder
# lives as long as the process, at most _KEEP_EXTRACTED FMUs at a time
_EXTRACTED: dict = {}
_KEEP_EXTRACTED = 64
_FOLDER: list = []
_EXTRACTING = threading.Lock()


def instance_block(plan, inst):
    """The block of one instance, its FMU's resources extracted once in this process.

    Parameters
    ----------
    plan : orchestrator.cosim.Plan
        The prepared scenario (its FMUs, their digests and its time base).
    inst : orchestrator.scenario.Instance
        The instance, with its parameters.

    Returns
    -------
    Block
        As :func:`~orchestrator.analysis.blocks._instance_block`.
    """
    with _EXTRACTING:   # threads linearising at once share the index and its folder
        return _instance_block(plan, inst, *_extractions(),
                               live=functools.partial(_live_block, plan, inst))


def _live_block(plan, inst):
    """The block of one instance built from its FMU (nothing read from or kept in the
    process's or the store's blocks): a kept controller's ``rebuild`` on first use."""
    with _EXTRACTING:
        return _instance_block(plan, inst, *_extractions(), keep=False)


def _extractions() -> tuple:
    """The process's folder of extracted FMU resources and its index."""
    if _FOLDER and not _FOLDER[0].is_dir():   # removed under us: start again
        _FOLDER.clear()
        _EXTRACTED.clear()
    if len(_EXTRACTED) >= _KEEP_EXTRACTED:
        shutil.rmtree(_FOLDER.pop(), ignore_errors=True)
        _EXTRACTED.clear()
    if not _FOLDER:
        folder = Path(tempfile.mkdtemp(prefix="jitterfmu-analyze-"))
        atexit.register(shutil.rmtree, folder, True)
        _FOLDER.append(folder)
    return _FOLDER[0], _EXTRACTED


