"""The sampled-data reference: the hardware a scenario models, not its partition into FMUs.

In the hardware the piezo amplifiers drive the structure continuously: a command the
digital controller puts out at ``t_k`` (zero-order hold, after its Eq. (11) computation
delay) reaches the structure through the amplifier's lag alone.  In a co-simulation the
structure holds whatever force the piezo FMU published for a whole communication step,
and what that force is depends on the coupling (``coupling`` of the piezo FMU: the mean
over the coming step, or the force at the end of the last step, which adds one step).

:func:`sampled_data` builds the reference from a scenario's linear model
(:func:`orchestrator.analysis.linearize`): each structure and the amplifiers that drive
it become one continuous system (Eq. 9-10 with the amplifier low-passes in series on
their force inputs), sampled exactly (zero-order hold on the commands and the other
inputs, one matrix exponential) at the structure's period; the controllers, sources and
everything else stay as they are, at their own rates with their own delays.  The sensors
read the continuous signals at the sample instants.  Amplifier rails and slew limits are
assumed inactive, as in the linear model.

:func:`compare_loops` breaks each controller's loop in both models and reports what the
co-simulation adds at the reference's crossover: gain (dB), phase (deg) and the delay
that phase amounts to.  :func:`check` co-simulates the scenario as shipped (each
controller switching on at its ``t_on``) and compares its recorded outputs with the
linear model of its own coupling (round-off) and with the reference (the partition's
residual), both run with the same switch-ons (:func:`simulate_switched`), relative to
each output's peak.

``jitterfmu analyze SCENARIO --reference`` prints both.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as la

from .analysis import AnalysisError, LinearScenario, linearize

__all__ = ["LoopComparison", "OutputComparison", "ReferenceCheck", "sampled_data",
           "loop_transfer", "compare_loops", "switch_on_ticks", "simulate_switched", "check",
           "report"]


def sampled_data(lin: LinearScenario) -> LinearScenario:
    """The sampled-data reference of a linear scenario (module docstring).

    Parameters
    ----------
    lin : LinearScenario
        The scenario's linear model, as :func:`orchestrator.analysis.linearize` gives.

    Returns
    -------
    LinearScenario
        The same instances, order and rates; each structure sampled exactly together
        with the amplifiers that drive it, whose ``force`` output is then the command
        ``c h v_cmd`` the amplifier follows inside the structure.
    """
    blocks = dict(lin.blocks)
    for name, st in lin.blocks.items():
        if st.kind != "structure" or st.continuous is None:
            continue
        drives = [(j, src, i) for tgt, j, src, i, _ in lin._conns
                  if tgt == name and lin.blocks[src].kind == "piezo"
                  and lin.blocks[src].outputs[i] == "force"]
        if not drives:
            continue
        for _, src, _ in drives:
            if lin.blocks[src].continuous is None:
                raise AnalysisError(f"{src} has its stack's servo loop on (servo_bandwidth > "
                                    "0); the sampled-data reference models the amplifier "
                                    "alone: set servo_bandwidth = 0 to compare")
        A, B, C, D = st.continuous
        n, m = A.shape[0], B.shape[1]
        nz = sum(lin.blocks[src].continuous[0].shape[0] for _, src, _ in drives)
        N = n + nz
        Aa = np.zeros((N, N))
        Ba = np.zeros((N, m))
        Aa[:n, :n], Ba[:n] = A, B
        Ca = np.hstack([C, np.zeros((C.shape[0], nz))])
        Da = D.copy()
        off = n
        for j, src, i in drives:
            pz = lin.blocks[src]
            if not pz.feedthrough[i]:
                raise AnalysisError(f"{src}.force does not declare its dependency on v_cmd; "
                                    "rebuild the FMUs ('jitterfmu build')")
            Az, Bz, _ = pz.continuous
            k = Az.shape[0]
            Aa[off:off + k, off:off + k] = Az
            Aa[:n, off] += B[:, j]          # the amplifier's force drives input j
            Ba[:n, j] = 0.0
            Ba[off:off + k, j] = Bz[:, 0]   # input j is now the force command
            Ca[:, off] += D[:, j]
            Da[:, j] = 0.0
            off += k
        h = st.period * lin.base
        M = np.zeros((N + m, N + m))
        M[:N, :N], M[:N, N:] = Aa * h, Ba * h
        E = la.expm(M)
        blocks[name] = replace(st, A=E[:N, :N], B=E[:N, N:], C=Ca, D=Da)
        for _, src, i in drives:
            pz = blocks[src]
            Cp, Dp = pz.C.copy(), pz.D.copy()
            Cp[i] = 0.0
            Dp[i] = 0.0
            Dp[i, pz.inputs.index("v_cmd")] = pz.continuous[2]
            blocks[src] = replace(pz, C=Cp, D=Dp)
    if blocks == lin.blocks:
        raise AnalysisError("the scenario has no piezo amplifier driving a structure; the "
                            "sampled-data reference has nothing to compare")
    return LinearScenario(lin.plan, blocks, lin.order)


def _law_frf(block, base, freqs):
    """Frequency response of a controller block from its ``y`` inputs to its outputs,
    shape ``(n_u, n_y, n_f)``."""
    T = block.period * base
    ny = sum(1 for v in block.inputs if v.startswith("y"))
    out = np.zeros((len(block.outputs), ny, len(freqs)), complex)
    eye = np.eye(block.n)
    for k, f in enumerate(freqs):
        z = np.exp(2j * np.pi * f * T)
        B, D = block.B[:, :ny], block.D[:, :ny]
        out[:, :, k] = D if block.n == 0 else block.C @ np.linalg.solve(z * eye - block.A, B) + D
    return out


def loop_transfer(lin: LinearScenario, controller: str, freqs_hz) -> np.ndarray:
    """Loop transfer of one controller, the loop broken at its command, other loops closed.

    ``L(f) = K(f) P(f)`` with ``P`` the response of the signals the controller reads to
    its commands (connection gains included) and ``K`` its discrete law; the master's
    feedback is positive (``u = K y``), so the loop is unstable where ``L`` encircles +1.

    Parameters
    ----------
    lin : LinearScenario
    controller : str
        Controller instance.
    freqs_hz : array_like, shape (n_f,)

    Returns
    -------
    ndarray, shape (n_f,)
        ``L`` for a one-command controller; for more commands the eigenvalue of largest
        magnitude of the ``(n_u, n_u)`` loop.
    """
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    b = lin.blocks.get(controller)
    if b is None or b.kind != "controller":
        raise AnalysisError(f"{controller!r} is not a controller of the scenario; "
                            f"controllers: {', '.join(lin.controllers())}")
    sensors, cols = [], []
    for c in lin.plan.scenario.connections:
        if c.target == controller and c.target_var.startswith("y") \
                and c.target_var in b.inputs:
            sensors.append((c.start, float(c.gain)))
            cols.append(b.inputs.index(c.target_var))
    if not sensors:
        raise AnalysisError(f"controller {controller!r} reads no signal; it closes no loop")
    opened = lin.opened([controller])
    cmds = [f"{controller}.{o}" for o in b.outputs]
    P = opened.frequency_response(cmds, [s for s, _ in sensors], freqs)  # (n_s, n_u, n_f)
    P = P * np.array([g for _, g in sensors])[:, None, None]
    K = _law_frf(b, lin.base, freqs)                                       # (n_u, n_y, n_f)
    Ky = K[:, cols, :]
    L = np.einsum("isf,suf->iuf", Ky, P)
    if L.shape[0] == 1:
        return L[0, 0]
    ev = np.array([np.linalg.eigvals(L[:, :, k]) for k in range(freqs.size)])
    return ev[np.arange(freqs.size), np.argmax(np.abs(ev), axis=1)]


@dataclass(frozen=True)
class LoopComparison:
    """What the co-simulation adds to one loop, at the reference loop's crossover.

    Attributes
    ----------
    controller : str
    crossover_hz : float
        Where ``|L|`` of the reference crosses 1 with the smallest phase margin (or, with
        no crossing, where ``|L|`` is largest; ``crosses`` is then false).
    loop_gain : float
        ``|L|`` of the reference there.
    phase_margin_deg : float
        Reference phase margin there (deg; the loop feeds back positively).
    gain_db, phase_deg : float
        ``L_cosim / L_reference`` at that frequency.
    delay_s : float
        ``-phase / (2 pi f)``: the delay the co-simulation adds (s).
    crosses : bool
    """

    controller: str
    crossover_hz: float
    loop_gain: float
    phase_margin_deg: float
    gain_db: float
    phase_deg: float
    delay_s: float
    crosses: bool


def compare_loops(lin: LinearScenario, ref: LinearScenario | None = None, controllers=None,
                  freqs_hz=None, others: str = "open") -> list[LoopComparison]:
    """Each active loop of ``lin`` against the same loop of the reference.

    Parameters
    ----------
    lin : LinearScenario
        The co-simulation's linear model.
    ref : LinearScenario, optional
        Its reference; :func:`sampled_data` of ``lin`` by default.
    controllers : sequence of str, optional
        Loops to compare; every active controller by default.
    freqs_hz : array_like, optional
        Frequency grid; by default 400 points from 0.5 Hz to 0.95 of each controller's
        Nyquist frequency.
    others : {"open", "closed"}
        The other controllers at zero gain (each loop alone: what the partition adds to
        its own path) or closed as designed (the loop the margins are about).

    Returns
    -------
    list of LoopComparison
    """
    if others not in ("open", "closed"):
        raise AnalysisError(f"others is {others!r}; use 'open' or 'closed'")
    ref = sampled_data(lin) if ref is None else ref
    out = []
    loops = controllers or lin.controllers(active_only=True)
    for c in loops:
        T = lin.blocks[c].period * lin.base
        f = np.geomspace(0.5, 0.95 * 0.5 / T, 400) if freqs_hz is None \
            else np.asarray(freqs_hz, float)
        lc, lr = lin, ref
        if others == "open":
            for o in lin.controllers(active_only=True):
                if o != c:
                    lc, lr = lc.with_gain(o, 0.0), lr.with_gain(o, 0.0)
        Lc, Lr = loop_transfer(lc, c, f), loop_transfer(lr, c, f)
        mag = np.abs(Lr)
        # positive feedback: the phase margin is the angle of L from +1
        pm = np.degrees(np.abs(np.angle(Lr)))
        idx = np.flatnonzero(np.diff(np.sign(mag - 1.0)) != 0)
        crosses = idx.size > 0
        if crosses:
            cand = [k if abs(mag[k] - 1) < abs(mag[k + 1] - 1) else k + 1 for k in idx]
            k = min(cand, key=lambda q: pm[q])
        else:
            k = int(np.argmax(mag))
        r = Lc[k] / Lr[k]
        ph = float(np.degrees(np.angle(r)))
        out.append(LoopComparison(c, float(f[k]), float(mag[k]), float(pm[k]),
                                  float(20 * np.log10(abs(r))), ph,
                                  float(-np.radians(ph) / (2 * np.pi * f[k])), crosses))
    return out


def switch_on_ticks(lin: LinearScenario, scenario) -> dict:
    """The controllers that switch on after the start, and the base tick at which each
    first runs: its first sample ``k`` with ``k T >= t_on`` (``ctrlfmu.law``), ``T`` its
    period, counted from the experiment's start.

    Parameters
    ----------
    lin : LinearScenario
        The scenario's linear model.
    scenario : Scenario
        The scenario with its overrides (its controllers' ``t_on`` parameters; the FMU's
        start value where it sets none).

    Returns
    -------
    dict of str to int
        Controller instance -> base tick (> 0).
    """
    params = {i.name: i.parameters for i in scenario.instances}
    start = float(scenario.experiment.start)
    out = {}
    for c in lin.controllers():
        var = lin.plan.fmus[c].variables.get("t_on")
        if var is None:
            continue
        t_on = float(params.get(c, {}).get("t_on", var.start or 0.0))
        period = lin.blocks[c].period
        k = max(0, math.ceil((t_on - start) / (period * lin.base) - 1e-9)) * period
        if k > 0:
            out[c] = k
    return out


def simulate_switched(lin: LinearScenario, n: int, w, record, ticks) -> np.ndarray:
    """:meth:`LinearScenario.simulate` with controllers that switch on during the run.

    Until its tick a controller's command is zero and its state is reset, as the law
    does while inactive (``ctrlfmu.law``: on activation it starts from rest); from its
    tick it runs as designed.

    Parameters
    ----------
    lin : LinearScenario
        The linear model (or its :func:`sampled_data` reference).
    n : int
        Base ticks to simulate.
    w : callable
        ``w(instance, tick)``: what each source publishes at its due ticks.
    record : sequence of str
        Outputs to record.
    ticks : dict of str to int
        :func:`switch_on_ticks`.

    Returns
    -------
    ndarray, shape (n, len(record))
    """
    edges = sorted({k for k in ticks.values() if k < n} | {0, n})
    parts, x = [], None
    for k0, k1 in zip(edges[:-1], edges[1:]):
        m = lin
        for c, k in ticks.items():
            if k > k0:
                m = m.with_gain(c, 0.0)
            elif k == k0 and x is not None:
                x[lin.slots[c][0]] = 0.0
        y, x = m.simulate(k1 - k0, w=lambda name, k, k0=k0: w(name, k + k0), x0=x,
                          record=record)
        parts.append(y)
    return np.vstack(parts)


@dataclass(frozen=True)
class OutputComparison:
    """One recorded output: co-simulation against its linear model and the reference.

    ``linear`` and ``reference`` are ``max |y - y_cosim| / max |y_cosim|`` over the run;
    with controllers switching on during the run, ``reference_on`` is the same from the
    last switch-on to the end, relative to the peak there (None without a switch-on).
    """

    output: str
    peak: float
    linear: float
    reference: float
    reference_on: float | None = None


@dataclass(frozen=True)
class ReferenceCheck:
    """Result of :func:`check`: loops and outputs against the sampled-data reference."""

    loops: tuple
    outputs: tuple
    stop: float
    saturation: tuple = ()   # the co-simulation's run.json "saturation" entries

    def __iter__(self):
        return iter((self.loops, self.outputs))


def check(scenario, outputs=None, *, stop_time=None, overrides=None, fmu_dir=None,
          opened=(), loops=True) -> ReferenceCheck:
    """Co-simulate a scenario and compare it with its linear model and its reference.

    Parameters
    ----------
    scenario : path-like, dict or Scenario
    outputs : sequence of str, optional
        Outputs ``instance.variable`` to compare; the scenario's ``[record]`` by default.
    Controllers with a switch-on time ``t_on`` switch on then in the co-simulation and in
    both linear models (:func:`simulate_switched`).
    stop_time : float, optional
        Overrides the scenario's stop time (s).
    overrides : mapping, optional
        Start values, as :func:`orchestrator.run_scenario`.
    fmu_dir : path-like, optional
    opened : sequence of str
        Instances taken out of the loop comparison (e.g. a slow ACS, whose period would
        otherwise be the hyperperiod); they stay in the co-simulation and the output
        comparison.
    loops : bool
        Also compare the loops (:func:`compare_loops`).

    Returns
    -------
    ReferenceCheck
    """
    from orchestrator import run_scenario
    from orchestrator.scenario import load_scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = linearize(scenario, overrides=overrides, fmu_dir=fmu_dir)
    ref = sampled_data(lin)
    sc = load_scenario(scenario).with_overrides(overrides or {})
    ticks = switch_on_ticks(lin, sc)
    outs = list(outputs if outputs is not None else sc.record)
    outs = [o for o in outs if o.split(".", 1)[0] in lin.blocks
            and lin.blocks[o.split(".", 1)[0]].kind != "source"
            and o.split(".", 1)[1] in lin.blocks[o.split(".", 1)[0]].outputs]
    if not outs:
        raise AnalysisError("no output of a dynamic instance to compare; name some "
                            "(instance.variable)")
    srcs = sorted({(c.source, c.source_var) for c in sc.connections
                   if lin.blocks[c.source].kind == "source"})
    rec = outs + [f"{i}.{v}" for i, v in srcs]
    sc = replace(sc.with_experiment(output_interval=lin.base, stop=stop_time), record=tuple(rec))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = run_scenario(sc, fmu_dir=fmu_dir)
    table = run.table
    n = len(table["time"])
    src_rows = {}
    for name in lin.sources:
        b = lin.blocks[name]
        rows = np.zeros((n, len(b.outputs)))
        for i, v in srcs:
            if i == name:
                rows[:, b.outputs.index(v)] = table[f"{i}.{v}"]
        src_rows[name] = rows

    def w(name, k):
        return src_rows[name][k]

    y_lin = simulate_switched(lin, n, w, outs, ticks)
    y_ref = simulate_switched(ref, n, w, outs, ticks)
    comps = []
    k_on = max((k for k in ticks.values() if k < n), default=None)
    for j, o in enumerate(outs):
        y = np.asarray(table[o], float)
        peak = float(np.max(np.abs(y)))
        scale = peak if peak > 0 else 1.0
        on = None
        if k_on is not None:
            p_on = float(np.max(np.abs(y[k_on:])))
            on = float(np.max(np.abs(y_ref[k_on:, j] - y[k_on:]))) / (p_on if p_on > 0 else 1.0)
        comps.append(OutputComparison(o, peak, float(np.max(np.abs(y_lin[:, j] - y)) / scale),
                                      float(np.max(np.abs(y_ref[:, j] - y)) / scale), on))
    lc = ()
    if loops:
        lo = lin.opened(opened) if opened else lin
        lc = tuple(compare_loops(lo, sampled_data(lo)))
    return ReferenceCheck(lc, tuple(comps), float(sc.experiment.stop),
                          tuple(run.metadata.get("saturation", ())))


def report(result: ReferenceCheck) -> str:
    """A readable table of :func:`check`'s result, one line per row."""
    lines = []
    if result.loops:
        lines.append("each loop alone (the others at zero gain) against the sampled-data "
                     "reference, at its crossover")
        lines.append(f"  {'controller':<24} {'f (Hz)':>8} {'|L|':>7} {'PM (deg)':>9} "
                     f"{'gain (dB)':>10} {'phase (deg)':>12} {'delay (us)':>11}")
        for c in result.loops:
            mark = "" if c.crosses else "  (no crossover: largest |L|)"
            lines.append(f"  {c.controller:<24} {c.crossover_hz:8.2f} {c.loop_gain:7.3f} "
                         f"{c.phase_margin_deg:9.1f} {c.gain_db:10.3f} {c.phase_deg:12.3f} "
                         f"{1e6 * c.delay_s:11.1f}{mark}")
        lines.append("")
    lines.append(f"outputs over {result.stop:g} s, difference relative to the co-simulated peak")
    on = any(o.reference_on is not None for o in result.outputs)
    lines.append(f"  {'output':<32} {'peak':>11} {'linear model':>13} {'reference':>10}"
                 + (f" {'after switch-on':>16}" if on else ""))
    for o in result.outputs:
        lines.append(f"  {o.output:<32} {o.peak:11.4g} {o.linear:13.2e} "
                     f"{100 * o.reference:9.3f}%"
                     + (f" {100 * o.reference_on:15.3f}%" if o.reference_on is not None
                        else ""))
    if on:
        lines.append("  (after switch-on: from the last controller's switch-on to the end, "
                     "relative to the peak there)")
    for s in result.saturation:   # a limit the linear model and the reference leave out
        lines.append(f"  the co-simulation reached {s['instance']}.{s['flag']} for "
                     f"{s['seconds']:.4g} s from t = {s['first']:.6g} s, a limit the linear "
                     "model and the reference leave out: their differences include its effect")
    return "\n".join(lines)
