"""Design answers on a linear scenario: the upper bound on a reduction, and the report."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .blocks import AnalysisError
from .loops import disk_to_gain_phase, scenario_margins
from .scenario import LinearScenario, _cycles


@dataclass(frozen=True)
class Ceiling:
    """What free actuator commands remove from one performance output under one harmonic
    disturbance: with ``method="optimal"`` the upper bound, with ``"cancel"`` the
    infinite-gain reference point (not a bound); see :func:`ceiling`.

    Attributes
    ----------
    performance : tuple of str
    method : str
        ``"optimal"`` (upper bound) or ``"cancel"`` (sensors held at zero).
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



def ceiling(lin: LinearScenario, performance, disturbance: str, freqs_hz, *,
            actuators, sensors=None, method: str = "optimal", amplitudes=None) -> Ceiling:
    """Upper bound on the reduction of ``performance`` under a harmonic disturbance (or,
    with ``method="cancel"``, what holding the controllers' sensors at zero gives).

    The named controllers are removed (their command outputs become free actuator
    commands ``v``).  With ``method="optimal"`` (the default), ``v`` minimises the
    performance outputs at each frequency (least squares): no controller driving these
    actuators, causal or not, can do better in steady state -- the upper bound.  With
    ``"cancel"``, ``v`` zeroes the signals the removed controllers measured
    (``sensors``; by default their connected inputs): what a loop of infinite gain on
    those sensors would do.  That is a reference point, not a bound: a finite-gain law
    can remove more (or less).

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
    method : {"optimal", "cancel"}
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
    """A readable table: poles (in ``band`` Hz), decay of ``modes``, loop margins.

    Parameters
    ----------
    lin : LinearScenario
        The linear closed loop.
    modes : sequence of float
        Mode frequencies (Hz) whose nearby closed-loop poles are reported with their
        decay.
    margins : bool or list of GroupMargins
        Add the margins of every loop (:func:`~.loops.scenario_margins`), or these.
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
        off = [c for c in lin.controllers() if c not in lin.controllers(active_only=True)]
        lines.extend(margins_table(margins if isinstance(margins, list)
                                   else scenario_margins(lin), off))
    return "\n".join(lines)


def margins_table(groups, off=()) -> list:
    """Lines of the loop margins table, one row per loop and one per group.

    Parameters
    ----------
    groups : list of GroupMargins
        From :func:`~.loops.scenario_margins`.
    off : sequence of str
        Controllers at gain 0 (listed as not analysed).

    Returns
    -------
    list of str
    """
    lines = ["loop margins (each loop broken at its command, the others closed; gain up / "
             "down and disk in dB, phase in deg)",
             f"  {'loop':<24} {'crossover Hz':>12} {'gain up':>8} {'down':>7} {'phase':>7} "
             f"{'disk dB':>8} {'disk deg':>8}  stabilised"]
    if not groups:
        lines.append("  (no active loop)")

    def num(v, fmt):
        return "inf" if v == math.inf else ("-" if not math.isfinite(v) else format(v, fmt))
    for g in groups:
        for m in g.loops:
            fc = f"{m.crossovers_hz[0]:.4g}" if m.crossovers_hz else "-"
            if not m.stable:
                how = "UNSTABLE as it is"
            elif m.phase_stabilised:
                how = "phase-stabilised at " + ", ".join(
                    f"{f:.3g} Hz (+{p:.1f} dB)" for f, p in m.phase_stabilised[:4])
            else:
                how = "gain-stabilised above crossover"
            lines.append(f"  {m.loop:<24} {fc:>12} {num(m.gain_up_db, '8.2f'):>8} "
                         f"{num(m.gain_down_db, '7.2f'):>7} {num(m.phase_deg, '7.1f'):>7} "
                         f"{num(m.disk_db, '8.2f'):>8} {num(m.disk_deg, '8.1f'):>8}  {how}")
        gd, pd = disk_to_gain_phase(g.disk_alpha)
        note = f"; {', '.join(g.opened)} opened" if g.opened else ""
        lines.append(f"  {'group ' + g.name:<24} {'':>12} {num(g.common_up_db, '8.2f'):>8} "
                     f"{num(g.common_down_db, '7.2f'):>7} {'':>7} {num(gd, '8.2f'):>8} "
                     f"{num(pd, '8.1f'):>8}  MIMO disk, common gain{note}")
    if off:
        lines.append(f"  (gain 0, not analysed: {', '.join(off)})")
    return lines
