"""Figs. 5-6: ten-bay truss decay, open loop and with 250 Hz strain feedback.

Both runs co-simulate the FMUs of ``scenarios/truss10_closed_loop.toml`` (structure,
two piezo amplifiers, two controllers, excitation): sine voltages on the diagonal
(8.4 Hz) and the longeron (9.5 Hz) for 4.5 s, then free decay (controller gain 0) or
control.  Damping is identified from the free decay by fitting two exponentially
decaying sinusoids to each gauge; "cycles to 90 %" is the time after 4.5 s until the
one-period running peak of the gauge strain stays below 10 % of its value over the last
excitation period, times the mode frequency.

The absorbers are tuned on that decay itself (:func:`tune`), on the scenario's linear
closed loop (:mod:`orchestrator.analysis`), which matches the co-simulation to about
1e-14.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from ctrlfmu.designs import truss10_strain_diag, truss10_strain_long
from distfmu.excitation import sine_burst
from fmukit.units import ARCSEC
from fmutools.ensure import ensure_fmus
from orchestrator import run_scenario
from orchestrator.progress import stage
from orchestrator.analysis import linearize

from . import SCENARIOS
from . import verdicts as vd

NAME = "truss-decay"
DESCRIPTION = "Figs. 5-6: ten-bay truss open-loop decay and 250 Hz strain-feedback control"

SCENARIO = SCENARIOS / "truss10_closed_loop.toml"
FMUS = ("truss10_structure", "piezo_p243_40", "piezo_p243_30",
        "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation")
T_EXC = 4.5
MODES = {"diagonal": ("structure.strain_diag", 8.4), "longeron": ("structure.strain_long", 9.5)}


def fit_two_modes(t, y, f_guess):
    """Fit ``sum_k a_k exp(-s_k t) cos(2 pi f_k t + p_k)`` to a decay.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s); the fit starts its clock at ``t[0]``.
    y : ndarray, shape (n,)
        The decaying signal (any unit, e.g. gauge strain).
    f_guess : (float, float)
        Starting guesses of the two frequencies (Hz).

    Returns
    -------
    freqs : ndarray, shape (2,)
        Damped frequencies (Hz), ascending.
    zetas : ndarray, shape (2,)
        Damping ratios.
    """
    # deferred: scipy takes about 1 s to load
    from scipy.optimize import least_squares

    t = t - t[0]
    scale = np.abs(y).max()
    yy = y / scale

    def model(p):
        out = np.zeros_like(t)
        for k in range(2):
            a, s, f, ph = p[4 * k:4 * k + 4]
            out += a * np.exp(-s * t) * np.cos(2 * np.pi * f * t + ph)
        return out

    best = None
    for ph1 in (0.0, np.pi / 2, np.pi, 3 * np.pi / 2):
        for ph2 in (0.0, np.pi):
            p0 = [0.5, 0.1, f_guess[0], ph1, 0.5, 0.2, f_guess[1], ph2]
            res = least_squares(lambda p: model(p) - yy, p0, method="lm", max_nfev=4000)
            if best is None or res.cost < best.cost:
                best = res
    p = best.x
    freqs = np.array([p[2], p[6]])
    sig = np.array([p[1], p[5]])
    wd = 2 * np.pi * np.abs(freqs)
    zetas = sig / np.sqrt(sig**2 + wd**2)
    order = np.argsort(np.abs(freqs))
    return np.abs(freqs)[order], zetas[order]


def cycles_to_fraction(t, y, f_hz, t0=T_EXC, fraction=0.1):
    """Cycles after ``t0`` until the running one-period peak of |y| falls below
    ``fraction`` of its value over the last period before ``t0``; None if never.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), evenly spaced.
    y : ndarray, shape (n,)
        The signal (any unit, e.g. gauge strain).
    f_hz : float
        Mode frequency (Hz); sets the period and converts time to cycles.
    t0 : float
        End of the excitation (s).
    fraction : float
        Threshold as a fraction of the reference peak (-).

    Returns
    -------
    float or None
        Cycles of ``f_hz`` from ``t0`` to the first time below the threshold.
    """
    peak, ref = envelope(t, y, f_hz, t0)
    after = np.flatnonzero((t >= t0) & (peak < fraction * ref))
    if not after.size:
        return None
    return float((t[after[0]] - t0) * f_hz)


def envelope(t, y, f_hz, t0=T_EXC):
    """Forward-looking one-period running peak of ``|y|`` and its reference value.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), evenly spaced.
    y : ndarray, shape (n,)
        The signal (any unit).
    f_hz : float
        Mode frequency (Hz): the running window is one period.
    t0 : float
        End of the excitation (s).

    Returns
    -------
    peak : ndarray, shape (n,)
        ``max |y|`` over the period starting at each sample (unit of ``y``).
    ref : float
        ``max |y|`` over the last period before ``t0``.
    """
    # deferred: scipy takes about 1 s to load
    from scipy.ndimage import maximum_filter1d

    dt = t[1] - t[0]
    n = max(1, int(round(1.0 / (f_hz * dt))))
    a = np.abs(y)
    ref = float(a[(t > t0 - 1.0 / f_hz) & (t <= t0)].max())
    return maximum_filter1d(a, size=n, origin=-(n // 2)), ref


CONTROLLERS = ("ctrl_diag", "ctrl_long")
RECORD = ("structure.strain_diag", "structure.strain_long", "ctrl_diag.u1", "ctrl_long.u1")


def linear_decay(lin, laws=None, after=3.0):
    """Cycles to 90 % decay of both gauges on the scenario's linear closed loop.

    The excitation of the co-simulation (10 V sines at 8.4 / 9.5 Hz for 4.5 s) drives
    the loop with both controllers off, then their states start from zero and the loop
    closes, exactly as ``t_on = 4.5`` does in the FMUs.

    Parameters
    ----------
    lin : orchestrator.analysis.LinearScenario
        ``linearize(SCENARIO)``.
    laws : dict of str to DiscreteLaw, optional
        Laws to use instead of the FMUs' (keys ``ctrl_diag``, ``ctrl_long``).
    after : float
        Simulated time after the switch-on (s).

    Returns
    -------
    cycles : dict of str to float or None
        ``{"diagonal": ..., "longeron": ...}``.
    peak_voltage : float
        Largest controller command after the switch-on (V).
    """
    for name, law in (laws or {}).items():
        lin = lin.with_law(name, law)
    off = lin
    for name in CONTROLLERS:
        off = off.with_gain(name, 0.0)
    n_exc = int(round(T_EXC / lin.base))

    def w(name, k):
        t = k * lin.base
        return np.array([sine_burst(t, 10.0, 8.4, 0.0, T_EXC),
                         sine_burst(t, 10.0, 9.5, 0.0, T_EXC)])

    y0, x = off.simulate(n_exc, w=w, record=RECORD)
    for name in CONTROLLERS:
        x[lin.slots[name][0]] = 0.0          # t_on: the law starts from rest
    y1, _ = lin.simulate(int(round(after / lin.base)), x0=x, record=RECORD)
    y = np.vstack([y0, y1])
    t = np.arange(len(y)) * lin.base
    cycles = {m: cycles_to_fraction(t, y[:, i], f0)
              for i, (m, (_, f0)) in enumerate(MODES.items())}
    return cycles, float(np.abs(y1[:, 2:]).max())


CAMPAIGN_SCENARIO = SCENARIO.parent / "truss10_campaign.toml"
#: Start of :func:`tune`: the earlier tuning (tuning, zeta, static loop gain), chosen on
#: each loop alone by ``ctrlfmu.analysis.optimise_gain``'s damping objective.
FORMER_TUNING = {"diag": [0.6, 1.0, 0.5 * 1.2399], "long": [0.8, 0.7, 0.5 * 0.6616]}
TIP = ("structure.los_tip_roll", "structure.los_tip_pitch", "structure.los_tip_yaw")


def forced_tip_jitter(camp, laws=None) -> float:
    """Steady-state tip jitter of the campaign set-up, RSS over its two events (arcsec).

    ``scenarios/truss10_campaign.toml``: controllers on from the start, one member
    driven by a 10 V sine at its mode (the diagonal at 8.4 Hz, the longeron at 9.5 Hz).
    Per tip axis, the peak-to-peak steady-state response of each event, RSS over the
    two events; the worst axis.

    Parameters
    ----------
    camp : orchestrator.analysis.LinearScenario
        Linear closed loop of the campaign scenario.
    laws : dict of str to DiscreteLaw, optional
        Laws to use instead of the FMUs' (keys ``ctrl_diag``, ``ctrl_long``).

    Returns
    -------
    float
        Worst-axis tip jitter (arcsec).
    """
    for name, law in (laws or {}).items():
        camp = camp.with_law(name, law)
    p2p = [2 * 10.0 * np.abs(camp.frequency_response([src], list(TIP), [f])[:, 0, 0]) / ARCSEC
           for src, f in (("excitation.v1", 8.4), ("excitation.v2", 9.5))]
    return float(np.sqrt(np.sum(np.square(p2p), axis=0)).max())


def tune(fmu_dir="fmus", maxfev=250):
    """Absorber tuning, damping and loop gain of both members, in two stages.

    Both stages run on the scenarios' linear closed loops (both loops and both
    amplifiers in the loop, Eq. 11's delay): :func:`linear_decay` for the paper's decay,
    :func:`forced_tip_jitter` for the campaign set-up.

    1. Decay: Nelder-Mead on all six parameters from :data:`FORMER_TUNING`, minimising
       the larger of the two gauges' cycles to 90 % (unstable loops and commands above
       900 V refused).
    2. Forced response: with the diagonal from stage 1 (rounded to two decimals), a grid
       over the longeron's tuning (1.2-2.0), damping (0.5-0.9) and loop gain
       (0.10-0.25); among the designs whose decay stays within 1.8 cycles, the one with
       the smallest forced tip jitter.

    About three minutes.  ``ctrlfmu.designs.TRUSS10_DIAG`` and ``TRUSS10_LONG`` store
    the result.

    Parameters
    ----------
    fmu_dir : path-like
        Folder of the FMUs (built there if missing or stale).
    maxfev : int
        Largest number of objective evaluations of the Nelder-Mead stage.

    Returns
    -------
    dict
        ``{"diag": {...}, "long": {...}, "cycles": {...}, "peak_voltage_v": float,
        "forced_tip_arcsec": float}``.
    """
    # deferred: scipy takes about 1 s to load
    from scipy.optimize import minimize

    ensure_fmus(FMUS, fmu_dir)
    lin = linearize(SCENARIO, fmu_dir=fmu_dir)
    on = {f"{c}.gain": 1.0 for c in CONTROLLERS}
    camp = linearize(CAMPAIGN_SCENARIO, overrides=on, fmu_dir=fmu_dir)
    keys = ("tuning", "zeta", "loop_gain")

    def laws(p):
        return {"ctrl_diag": truss10_strain_diag(**dict(zip(keys, p[:3]))),
                "ctrl_long": truss10_strain_long(**dict(zip(keys, p[3:])))}

    def decay(p):
        ls = laws(p)
        trial = lin.with_law("ctrl_diag", ls["ctrl_diag"]).with_law("ctrl_long", ls["ctrl_long"])
        if not trial.is_stable():
            return None, None
        return linear_decay(trial)

    def objective(p):
        if min(p) <= 0:
            return 1e3
        cycles, volts = decay(p)
        if cycles is None or None in cycles.values() or volts > 900:
            return 1e3
        return max(cycles.values()) + 0.01 * sum(cycles.values())

    start = FORMER_TUNING["diag"] + FORMER_TUNING["long"]
    stage1 = minimize(objective, start, method="Nelder-Mead",
                      options={"maxfev": maxfev, "xatol": 1e-3, "fatol": 1e-3})
    diag = list(np.round(stage1.x[:3], 2))
    best = None
    for p_long in itertools.product((1.2, 1.4, 1.6, 1.8, 2.0), (0.5, 0.6, 0.7, 0.8, 0.9),
                                    (0.10, 0.12, 0.14, 0.16, 0.20, 0.25)):
        p = diag + list(p_long)
        cycles, volts = decay(p)
        if cycles is None or None in cycles.values() or max(cycles.values()) > 1.8:
            continue
        forced = forced_tip_jitter(camp, laws(p))
        if best is None or forced < best[0]:
            best = (forced, p, cycles, volts)
    if best is None:
        raise RuntimeError("no longeron design keeps the decay within 1.8 cycles")
    forced, p, cycles, volts = best
    return {"diag": dict(zip(keys, p[:3])), "long": dict(zip(keys, p[3:])),
            "cycles": cycles, "peak_voltage_v": volts, "forced_tip_arcsec": forced}


def linear_prediction(fmu_dir="fmus") -> dict:
    """What the linear closed loop predicts for the shipped laws (see ``analyze``)."""
    lin = linearize(SCENARIO, fmu_dir=fmu_dir)
    cycles, volts = linear_decay(lin)
    margins = {c: lin.gain_margins(c) for c in CONTROLLERS}
    poles = [p for p in lin.poles() if 3.0 <= p.freq_hz <= 20.0 and p.z.imag > 0]
    return {"cycles_to_90pct": cycles, "peak_voltage_v": volts,
            "gain_margin_db": {c: m.upper_db for c, m in margins.items()},
            "lower_gain_factor": {c: m.lower for c, m in margins.items()},
            "poles_3_20_hz": [{"freq_hz": p.freq_hz, "damping": p.zeta} for p in poles]}


def _run(fmu_dir, stop: float, gain: float, fmu_kind="native"):
    res = run_scenario(SCENARIO, stop_time=stop, fmu_dir=fmu_dir, fmu_kind=fmu_kind,
                       overrides={"ctrl_diag.gain": gain, "ctrl_long.gain": gain})
    return res.table


def compute(fmu_dir="fmus", quick=False, fmu_kind="native"):
    """Co-simulate open and closed loop; identify the decay.

    Parameters
    ----------
    fmu_dir : path-like
        Folder of the FMUs (built there if missing or stale).
    quick : bool
        Shorter runs: 20 s open loop and 8 s closed loop instead of 40 s and 12 s.
    fmu_kind : {"native", "python"}
        Which build of the suite's FMUs the co-simulations run (``--python-fmus``).

    Returns
    -------
    dict
        ``"ol"`` and ``"cl"`` result tables (dict of column name to ndarray, ``"time"``
        in s), open-loop damping ratios and fits, cycles to 90 % decay, peak voltage (V)
        and whether any amplifier or stroke limit saturated.
    """
    ensure_fmus(FMUS, fmu_dir, kind=fmu_kind)
    ol = _run(fmu_dir, 20.0 if quick else 40.0, 0.0, fmu_kind)
    cl = _run(fmu_dir, 8.0 if quick else 12.0, 1.0, fmu_kind)
    t_ol = ol["time"]
    decay = t_ol > T_EXC + 0.2
    damping, fitted = {}, {}
    for member, (ref, f0) in MODES.items():
        freqs, zetas = fit_two_modes(t_ol[decay], ol[ref][decay], (8.4, 9.5))
        k = int(np.argmin(np.abs(freqs - f0)))
        damping[member] = float(zetas[k])
        fitted[member] = {"freqs_hz": freqs.tolist(), "zetas": zetas.tolist()}
    cycles = {m: cycles_to_fraction(cl["time"], cl[ref], f0) for m, (ref, f0) in MODES.items()}
    cycles_ol = {m: cycles_to_fraction(t_ol, ol[ref], f0) for m, (ref, f0) in MODES.items()}
    volts = max(np.abs(cl["piezo_diag.voltage"]).max(), np.abs(cl["piezo_long.voltage"]).max())
    sat = any(np.any(cl[k] > 0.5) for k in cl if ".sat_" in k)
    return {"ol": ol, "cl": cl, "open_loop_damping": damping, "fits": fitted,
            "closed_loop_cycles_to_90pct": cycles, "open_loop_cycles_to_90pct": cycles_ol,
            "peak_voltage_v": float(volts), "saturated": bool(sat)}


FIGURES = {"ol": ("open loop (Fig. 5)", "truss-decay-open-loop.png"),
           "cl": ("250 Hz strain feedback from 4.5 s (Fig. 6)", "truss-decay-closed-loop.png")}


def figures(data):
    """The gauge strains of both runs (Figs. 5 and 6), as Figures.

    Each panel draws the strain, its one-period envelope (:func:`envelope`), the 10 %
    level of the last excitation period's peak and where the envelope stays below it
    ("cycles to 90 %").  The controlled decay is drawn over its first cycles only (two
    periods before the switch-on to twice the decay, at least four cycles): on the
    whole record it would hide in a sliver of the axis.

    Parameters
    ----------
    data : dict
        The result of :func:`compute`.

    Returns
    -------
    dict
        ``{file name: Figure}``.
    """
    # deferred: plotting only
    from matplotlib.figure import Figure

    out = {}
    for key, (title, fname) in FIGURES.items():
        tab = data[key]
        t = np.asarray(tab["time"], float)
        cycles = data["closed_loop_cycles_to_90pct" if key == "cl"
                      else "open_loop_cycles_to_90pct"]
        fig = Figure(figsize=(8, 5.5), layout="constrained")
        axes = fig.subplots(2, 1, sharex=key == "ol")
        for ax, (member, (ref_var, f0)) in zip(axes, MODES.items()):
            y = np.asarray(tab[ref_var], float) * 1e6
            peak, ref = envelope(t, y, f0)
            c = cycles.get(member)
            ax.plot(t, y, lw=0.7, color="C0", label="strain")
            ax.plot(t[t >= T_EXC], peak[t >= T_EXC], lw=1.2, color="C1",
                    label="envelope (one-period peak)")
            ax.axhline(0.1 * ref, color="crimson", ls="--", lw=0.9, label="10 % level")
            ax.axhline(-0.1 * ref, color="crimson", ls="--", lw=0.9)
            ax.axvline(T_EXC, color="0.5", lw=0.8, ls="--")
            if c is not None:
                ax.axvline(T_EXC + c / f0, color="crimson", lw=0.8)
                ax.annotate(f"90 % decay: {c:.2f} cycles", (T_EXC + c / f0, 1.0),
                            xycoords=("data", "axes fraction"), xytext=(4, -12),
                            textcoords="offset points", fontsize=8, color="crimson")
            if key == "cl":
                span = max(4.0, 2 * (c or 2.0)) / f0
                ax.set_xlim(T_EXC - 2 / f0, T_EXC + span)
                ax.xaxis.set_major_formatter(lambda v, _: f"{v - T_EXC:+.2f}")
            ax.set_ylabel(f"{member} strain (µε)")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7.5, loc="lower left", bbox_to_anchor=(0, 1.0), ncol=3,
                       frameon=False)
        fig.suptitle(f"Ten-bay truss, {title}", fontsize=11)
        axes[-1].set_xlabel("time after the switch-on at 4.5 s (s)" if key == "cl"
                            else "time (s)")
        out[fname] = fig
    return out


def plot(data, out_dir):
    """Draw :func:`figures` into ``out_dir`` (PNG).

    Parameters
    ----------
    data : dict
        The result of :func:`compute`.
    out_dir : Path
        Folder for ``truss-decay-open-loop.png`` and ``truss-decay-closed-loop.png``.
    """
    # deferred: plotting only
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    for fname, fig in figures(data).items():
        FigureCanvasAgg(fig)
        fig.savefig(Path(out_dir) / fname, dpi=110)


def run(out_dir, quick: bool = False, fmu_dir="fmus", fmu_kind="native") -> dict:
    """Run the experiment and draw its figures; the JSON dict.

    Parameters
    ----------
    out_dir : path-like
        Folder for the figures.
    quick : bool
        Shorter runs (see :func:`compute`).
    fmu_dir : path-like
        Folder of the FMUs (built there if missing or stale).
    fmu_kind : {"native", "python"}
        Which build of the suite's FMUs the co-simulations run (``--python-fmus``).

    Returns
    -------
    dict
        Damping, cycles to 90 % decay, peak voltage (V), the linear prediction and the
        paper's values.
    """
    stage("truss-decay: co-simulating the free decay and the controlled decay")
    data = compute(fmu_dir, quick, fmu_kind)
    stage("truss-decay: drawing the figures and the linear prediction")
    plot(data, Path(out_dir))
    cycles = data["closed_loop_cycles_to_90pct"]
    verdicts = [vd.below(f"Fig. 6: cycles to 90 % decay with control, {m}", 2.0, c,
                         "cycles", "decays by 90 % in two cycles (read: at most 2)")
                for m, c in cycles.items()]
    reproduced = vd.all_reproduced(verdicts) and not data["saturated"]
    return {
        "verdicts": verdicts,
        # the model's modal damping is calibrated to the paper's measured 0.18 / 0.4 %:
        # identifying it from the free decay checks the identification, it is no result
        "model_input_damping": {"diagonal": 0.0018, "longeron": 0.004},
        "open_loop_damping": data["open_loop_damping"],
        "closed_loop_cycles_to_90pct": cycles,
        "open_loop_cycles_to_90pct": data["open_loop_cycles_to_90pct"],
        "peak_voltage_v": data["peak_voltage_v"],
        "saturated": data["saturated"],
        "fits": data["fits"],
        "linear_prediction": linear_prediction(fmu_dir),
        "paper": {"open_loop_damping_measured": {"diagonal": 0.0018, "longeron": 0.004},
                  "closed_loop_cycles_to_90pct": 2},
        "reproduces_paper_cycles": reproduced,
        "note": ("Both members decay to 10 % within the paper's two cycles with Eq. 11's "
                 "one-sample delay at 250 Hz, amplifiers in the loop and no saturation; "
                 "the absorbers are designed on this decay with both loops closed, "
                 "then on the forced tip jitter within 1.8 cycles (truss_decay.tune)." if reproduced else
                 "Not reproduced: see linear_prediction and docs/controllers.md."),
        "figures": ["truss-decay-open-loop.png", "truss-decay-closed-loop.png"],
    }
