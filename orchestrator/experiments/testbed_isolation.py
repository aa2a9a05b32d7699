"""Figs. 13-16: EOS Dynamics Testbed, MISR payload isolation against a 22 Hz disturbance.

Co-simulation of ``scenarios/eos_budget.toml`` with the ``swir_cryocooler`` preset at the
SWIR location (22, 44, 66 Hz, vertical) and the MISR strut controllers (the paper's law:
2nd-order Butterworth band-pass 20-60 Hz, two zeros at 100 rad/s, two poles at 1 rad/s,
1 kHz, payload- and bus-side acceleration, each mount independent), with isolator mount
#3 alone and with all three.  The jitter reduction is computed from the co-simulated
MISR boresight roll and pitch (the gimballed body; the optical scoring system measures
roll and pitch): RMS over 1.2 s windows after a zero-phase 5 Hz high-pass that removes
the slow rigid-body drift of the free-free model (the suspended testbed has no ACS).

A before/after measurement starts on a settled response, and the experiment proves it.
The paper's Fig. 15 shows a steady 22 Hz response before the isolation turns on at 2.4 s
of its record; here the disturbance starts at t = 0 and the lightly damped modes (the
23 Hz bus mode, the 8 and 9.7 Hz payload modes) ring down for seconds, so the isolation
switches on at ``T_ON`` = 8.4 s (2.4 s of the paper's record: the figure shifts its time
axis by the difference).  The before-window is the 1.2 s before switch-on, the
after-window the 1.2 s ending ``TAIL`` before the end of the record (the zero-phase
filter's end effect stays out of it).  The isolation-off run's own change between the
same two windows, ``off_change_pct``, must be within ``SETTLED_PCT`` (2 %): when it is
not, the experiment moves the switch-on later by ``SETTLE_STEP`` up to ``MAX_T_ON`` and
refuses past it.  Two measures, both on those windows: the paper's way (before and
after switch-on in one run) and two runs (the after-window against the isolation-off
run's).

Design first, on the linear model (:mod:`orchestrator.experiments.testbed_design`,
:func:`linear_plant`): the reduced structure of the
FMU (``model.npz``, accelerometers through their 150 Hz low-pass), sampled exactly with a
zero-order hold at 1 kHz, the P-865.10 amplifier (its first-order lag, exact at 1 kHz;
the structure holds its mean force over each step, for the command of that step, as the
piezo FMUs' ``coupling = 1`` gives it), ``f = c h v``
and the discrete law with its Eq. (11) delay (``delayed=False`` in
``ctrlfmu.designs.testbed_isolation`` acts on the current sample instead).  On it:

* :func:`strut_bounds` -- the upper bound: the least-squares best strut forces at 22, 44
  and 66 Hz (no controller at those struts removes more in steady state); and, as a
  reference point that is not a bound, the reduction if the payload accelerometers at the
  chosen mounts were held at exactly zero (a loop of infinite gain);
* :func:`gain_margin_db` -- the factor on the gains (all active mounts together) that
  first makes the sampled closed loop unstable, from its eigenvalues;
  :func:`loop_margins_db` adds each loop scaled alone with the others closed (the
  reported margin is the smallest);
* :func:`design_gains` -- the gain direction (payload, bus) that removes the most
  boresight jitter at 6 dB gain margin (the stored gains come from it);
  :func:`design_mount_gains` -- one factor per mount for all three closed;
* :func:`feedforward_best_gain` -- the most the law's bus path could do as pure
  feedforward with one real gain (a bound on that feedforward, not on the loop).

``variant="hybrid"`` (``jitterfmu reproduce testbed-isolation --variant hybrid``) runs the
same with mount #3 a hybrid isolator (``eos_testbed.build(iso3="hybrid")``: stack +
elastomer stage, structure FMU ``HYBRID_STRUCTURE``) and the law at ``HYBRID_GAINS`` times
its own gains (docs/eos_experiments.md).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from fmukit.units import ARCSEC_PER_RAD

from ..analysis.frf import isolation_bandwidth, transmissibility_bands
from ..progress import stage
from ..run import run_scenario
from . import eos
from . import verdicts as vd
from .figures import testbed_figure
from .testbed_instruments import oss_reductions, servo_plant
from .testbed_robust import perturbed_plants, robust_factor
from .testbed_design import (  # noqa: F401  (the experiment's names, defined with the design)
    DT, FREQS, HARMONICS, HYBRID_STRUCTURE, MOUNT_RATIOS, VARIANTS, accel_frf,
    boresight_reduction, closed_frf, closed_loop, design, design_gains, design_mount_gains,
    ensure_fmus, feedforward_best_gain, frequency_responses, gain_margin_db, hybrid_model,
    strut_bounds, law_frf, limiting_modes, linear_model, linear_plant, loop_margins_db,
    loop_shape, per_mount, plant_frf, to_statespace)

NAME = "testbed-isolation"
DESCRIPTION = "Figs. 13-16: MISR active isolator struts against a 22 Hz SWIR-location " \
              "disturbance, switched on at 2.4 s"

#: Switch-on of the isolation in the paper's record (Fig. 15, s).
PAPER_T_ON = 2.4
#: Switch-on in the simulation (s): the isolation-off response has settled by then
#: (``off_change_pct`` within ``SETTLED_PCT``), 2.4 s of the paper's record.
T_ON = 8.4
WINDOW = 1.2          # s: the before- and after-windows
TAIL = 0.5            # s of record after the after-window (the zero-phase filter's ends)
#: Switch-on to the end of the after-window (s), quick and full run.
AFTER = {True: 3.6, False: 7.2}
SETTLED_PCT = 2.0     # %: largest change of the isolation-off run between the windows
SETTLE_STEP = 2.4     # s: how much later the switch-on moves when it is not settled
MAX_T_ON = 13.2       # s: past it the experiment refuses
#: Multiplier of the design's gains (ctrlfmu.designs.TESTBED_ISOLATION_GAINS, the mount-#3
#: direction of the nominal design) per configuration, set for 6 dB gain margin over the
#: testbed's uncertainty (testbed_robust: modal frequencies x0.95-1.05, damping x0.5-2;
#: the nine common corners and 40 per-mode points, seed 2026): mount #3 alone 0.288 of the
#: nominal 6 dB design (its stability limit is 2.008 nominal, 0.576 at the worst point, a
#: per-mode draw; 0.653 at the worst corner, damping x0.5); all three mounts the
#: nominal per-mount factors of design_mount_gains (0.262, -0.105, 1.049; each mount
#: independent as in the paper) times 0.2866 (limit 2.027 nominal, 0.573 worst).  At the
#: nominal factors (1 and the per-mount ones) the loops were unstable at points of the set
#: (-4.8 dB).  ``jitterfmu reproduce testbed-robust`` recomputes these limits and factors.
GAINS = {"mount3": 0.288, "all_mounts": (0.0751, -0.0301, 0.3007)}
#: Nominal-only factors (6 dB on the nominal plant, unstable over the set), for comparison.
NOMINAL_GAINS = {"mount3": 1.0, "all_mounts": (0.262, -0.105, 1.049)}
#: The same for the hybrid mount #3 (``variant="hybrid"``: ``eos_testbed.build(iso3=
#: "hybrid")``, its stack in series with an elastomer stage): the design law (the stiff
#: strut's gain direction), set for 6 dB over the testbed's uncertainty on the hybrid plant
#: as GAINS (the worst of the 49 points a corner, frequencies x0.95 and damping x0.5):
#: mount #3 1.128, all three (-0.1204, 0.1204, 1.2055), the nominal factors (2.95 and
#: -0.313, 0.313, 3.134, 6 dB on the nominal hybrid plant) times 0.382 and 0.385.  The
#: elastomer was calibrated (stiffness, loss factor) with the earlier coupling and law
#: direction to give the paper's 80 %; in its own best direction the hybrid plant allows
#: much more (docs/eos_experiments.md).
HYBRID_GAINS = {"mount3": 1.128, "all_mounts": (-0.1204, 0.1204, 1.2055)}
HYBRID_NOMINAL_GAINS = {"mount3": 2.95, "all_mounts": (-0.313, 0.313, 3.134)}
MOUNTS = {"mount3": (3,), "all_mounts": (1, 2, 3)}
HP_HZ = 5.0
#: Crossover of the stacks' built-in servo loops (Hz; assumed, the paper gives none) and
#: the isolation-off before-window RMS (arcsec) at which the OSS reading is also given.
SERVO_HZ = 100.0
OSS_LEVEL_ARCSEC = 1.0
PAPER = {"mount3": 80.0, "all_mounts": (50.0, 80.0), "bandwidth_hz": 45.0}


# -- co-simulation -----------------------------------------------------------------------
def _scenario(variant):
    """``scenarios/eos_budget.toml``; for the hybrid variant with its structure FMU."""
    if variant == "stiff":
        return eos.SCENARIO
    sc = tomllib.loads(Path(eos.SCENARIO).read_text())
    sc["fmus"]["structure"] = {**sc["fmus"]["structure"], "fmu": HYBRID_STRUCTURE}
    return sc


def _cosim(fmu_dir, mounts, gain, stop, variant="stiff", fmu_kind="native", t_on=T_ON):
    ov = {"dist_swir.preset": "swir_cryocooler"}
    for i, g in zip((1, 2, 3), per_mount(gain)):
        ov[f"ctrl_iso{i}.gain"] = g if i in mounts else 0.0
        ov[f"ctrl_iso{i}.t_on"] = t_on
    return run_scenario(_scenario(variant), stop_time=stop, overrides=ov,
                        fmu_dir=fmu_dir, fmu_kind=fmu_kind).table


def _highpassed(t, x):
    # deferred: scipy takes about 1 s to load
    from scipy.signal import butter, sosfiltfilt

    sos = butter(2, HP_HZ, "highpass", fs=1.0 / (t[1] - t[0]), output="sos")
    return sosfiltfilt(sos, x)


def boresight_rms(t, roll, pitch, t0, t1):
    """RMS ``sqrt(mean(roll^2 + pitch^2))`` (rad) over [t0, t1) of the boresight angles,
    after a zero-phase 2nd-order Butterworth high-pass at ``HP_HZ`` (5 Hz) of the whole
    record.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Equally spaced times (s).
    roll : ndarray, shape (n,)
        Boresight roll at ``t`` (rad).
    pitch : ndarray, shape (n,)
        Boresight pitch at ``t`` (rad).
    t0 : float
        Start of the window (s, included).
    t1 : float
        End of the window (s, excluded).
    """
    m = (t >= t0) & (t < t1)
    r, p = _highpassed(t, roll), _highpassed(t, pitch)
    return float(np.sqrt(np.mean(r[m] ** 2 + p[m] ** 2)))


def windows(t_on, stop) -> dict:
    """The before- and after-windows (s) of a run switched on at ``t_on`` and ending at
    ``stop``: ``{"before": (t_on - WINDOW, t_on), "after": (stop - TAIL - WINDOW,
    stop - TAIL)}``.

    Parameters
    ----------
    t_on : float
        Switch-on time of the isolation (s).
    stop : float
        End of the record (s).
    """
    return {"before": (t_on - WINDOW, t_on), "after": (stop - TAIL - WINDOW, stop - TAIL)}


def _rms_in(tab, window):
    t = tab["time"]
    return boresight_rms(t, tab["structure.los_misr_roll"], tab["structure.los_misr_pitch"],
                         *window)


def settled_off_run(run_off, quick, t_on=T_ON):
    """The isolation-off run on a settled response: ``(table, t_on, stop, off_change_pct)``.

    ``run_off(t_on, stop)`` co-simulates the isolation off to ``stop``; its boresight RMS
    changes by ``off_change_pct`` (%) from the before- to the after-window
    (:func:`windows`).  Beyond ``SETTLED_PCT`` the switch-on moves ``SETTLE_STEP`` later
    and the run is repeated, up to ``MAX_T_ON``; past it a ``RuntimeError`` says so.

    Parameters
    ----------
    run_off : callable
        ``run_off(t_on, stop)``: the isolation-off result table (dict of str to ndarray).
    quick : bool
        The quick run's shorter after-window (``AFTER``).
    t_on : float
        First switch-on time tried (s).
    """
    while True:
        stop = t_on + AFTER[quick] + TAIL
        off = run_off(t_on, stop)
        w = windows(t_on, stop)
        change = 100.0 * (_rms_in(off, w["after"]) / _rms_in(off, w["before"]) - 1.0)
        if abs(change) <= SETTLED_PCT:
            return off, t_on, stop, change
        if t_on + SETTLE_STEP > MAX_T_ON + 1e-9:
            raise RuntimeError(
                f"testbed-isolation: with isolation off the boresight RMS still changes by "
                f"{change:+.1f} % between the windows before and after a switch-on at "
                f"{t_on:g} s (at most {SETTLED_PCT:g} % is a settled response); the "
                f"structure's damping is too light for {MAX_T_ON:g} s of settling: raise "
                f"MAX_T_ON or check the model")
        stage(f"testbed-isolation: isolation off changes {change:+.1f} % between the "
              f"windows; switch-on moved from {t_on:g} s to {t_on + SETTLE_STEP:g} s")
        t_on += SETTLE_STEP


def _off_rms(Gh):
    """Steady isolation-off boresight RMS (arcsec) of the linear model over the harmonics."""
    a = np.array(list(HARMONICS.values()))
    return float(np.sqrt(np.sum(a[:, None] ** 2 * np.abs(Gh[:, 6:8, 3]) ** 2) / 2)
                 * ARCSEC_PER_RAD)


def testbed_verdicts(data) -> list:
    """One verdict per Figs. 13-15 target (:mod:`orchestrator.experiments.verdicts`).

    The paper reads its reductions the way Fig. 15 shows them: the boresight jitter
    before and after the switch-on in one run, so the verdicts compare that
    (``before_after_reduction_pct``) on the settled windows (:func:`settled_off_run`:
    the isolation-off run changes by ``off_change_pct``, within ``SETTLED_PCT``, between
    them); the two-run measure (the after-window against the isolation-off run's) is
    reported beside it in each verdict as ``two_runs``.

    Parameters
    ----------
    data : dict
        :func:`compute`'s result.
    """
    ba, red = data["before_after"], data["reduction"]
    lo, hi = PAPER["all_mounts"]
    out = [vd.about("Fig. 15: mount #3 alone, boresight jitter reduction", PAPER["mount3"],
                    ba["mount3"]["before_after_reduction_pct"], better="higher"),
           vd.between("tests overall (all three mounts), boresight jitter reduction", lo, hi,
                      ba["all_mounts"]["before_after_reduction_pct"], better="higher"),
           vd.about("Fig. 13: isolation bandwidth, mount #3", PAPER["bandwidth_hz"],
                    data["bandwidth"], "Hz", better="higher")]
    out[0]["two_runs"] = red["mount3"]
    out[1]["two_runs"] = red["all_mounts"]
    return out


def compute(quick=False, fmu_dir="fmus", variant="stiff", fmu_kind="native"):
    """Linear design numbers and the two co-simulations (mount #3, all mounts).

    Parameters
    ----------
    quick : bool
        The after-window ends 3.6 s instead of 7.2 s after switch-on (``AFTER``).
    fmu_dir : path-like
        Folder of the FMUs, built there when missing or stale.
    variant : str
        ``"stiff"`` (the struts as documented) or ``"hybrid"`` (mount #3 a hybrid isolator,
        gains ``HYBRID_GAINS``).
    fmu_kind : str
        Run ``"native"`` or ``"python"`` FMUs (``--python-fmus``).

    Returns
    -------
    dict
        ``runs`` (per configuration, ``"mount3"`` and ``"all_mounts"``, its result table,
        dict of str to ndarray), ``off`` (the table with isolation off), ``stop`` and
        ``t_on`` (s), ``windows`` (:func:`windows`), ``off_change_pct`` (%, the
        isolation-off run's change between them), ``reduction`` (two runs, %),
        ``before_after`` (arcsec RMS, %; per configuration also ``after_change_pct``,
        the run's own change from the window before the after-window to it),
        ``robust`` (per configuration the margin of its gains over the uncertainty's
        nine corners, ``testbed_robust.robust_factor`` less its limits, dB, and the
        worst corner; the nominal-only gains' linear reductions), ``instruments`` (the
        reductions read through the optical scoring system at the
        simulated level and at ``OSS_LEVEL_ARCSEC``, ``oss_reductions``; mount #3 with
        the stored gains on the analog plant without and with the stacks' servo loops at
        ``SERVO_HZ``, ``servo_plant``; :mod:`.testbed_instruments`), ``max_voltage``
        (V),
        ``linear`` (the smallest of :func:`loop_margins_db` and all of them, in dB,
        reduction in %, ``bounds``: :func:`strut_bounds`), ``frf``
        (:func:`frequency_responses` at ``FREQS``), ``ratio`` (open/closed, mount #3),
        ``bandwidth`` (Hz or None), ``loop_shape``, ``gains``, ``feedforward_pct``
        (%, :func:`feedforward_best_gain` at mount #3) and
        ``off_linear_full_scale_arcsec_rms`` (arcsec).
    """
    fdir = ensure_fmus(fmu_dir, variant, fmu_kind)
    stage(f"testbed-isolation: linear design of the mount loops ({variant} struts)")
    model = linear_model(fdir, variant)
    plant = linear_plant(model)
    gains = HYBRID_GAINS if variant == "hybrid" else GAINS
    Gh = plant_frf(plant, list(HARMONICS))
    lin, limiting = {}, {}
    for k, mounts in MOUNTS.items():
        loops = loop_margins_db(plant, mounts, gains[k])
        limiting[k] = limiting_modes(plant, mounts, gains[k], loops["all"])
        lin[k] = {"gain_margin_db": min(loops.values()), "loop_gain_margins_db": loops,
                  "reduction_pct": boresight_reduction(plant, mounts, gains[k], Gh=Gh),
                  "bounds": strut_bounds(plant, mounts, Gh=Gh)}
    Gf = accel_frf(plant, FREQS)
    frf = {k: frequency_responses(Gf, MOUNTS[k], gains[k]) for k in MOUNTS}
    ratio = np.abs(frf["mount3"][0]) / np.abs(frf["mount3"][1])
    bw = isolation_bandwidth(FREQS, ratio, 22.0)
    shape = loop_shape(Gf)
    ff = feedforward_best_gain(plant, 3, Gh)
    stage("testbed-isolation: co-simulating isolation off until its response has settled "
          f"(switch-on at {T_ON:g} s or later)")
    off, t_on, stop, off_change = settled_off_run(
        lambda ton, end: _cosim(fdir, (), 0.0, end, variant, fmu_kind, ton), quick)
    stage(f"testbed-isolation: co-simulating {stop:g} s twice (mount #3, all three mounts; "
          f"switch-on at {t_on:g} s)")
    runs = {k: _cosim(fdir, MOUNTS[k], gains[k], stop, variant, fmu_kind, t_on)
            for k in MOUNTS}
    w = windows(t_on, stop)
    ref = _rms_in(off, w["after"])
    red, before_after, vmax = {}, {}, {}
    for k, tab in runs.items():
        b, a = _rms_in(tab, w["before"]), _rms_in(tab, w["after"])
        # the on-run's own change over its last two windows: the after-window is settled
        a0 = _rms_in(tab, (w["after"][0] - WINDOW, w["after"][0]))
        before_after[k] = {"before_arcsec_rms": b * ARCSEC_PER_RAD,
                           "after_arcsec_rms": a * ARCSEC_PER_RAD,
                           "before_after_reduction_pct": 100.0 * (1.0 - a / b),
                           "after_change_pct": 100.0 * (a / a0 - 1.0)}
        red[k] = 100.0 * (1.0 - a / ref)
        vmax[k] = float(max(np.abs(tab[f"piezo_iso{i}.voltage"]).max() for i in (1, 2, 3)))
    before_after["off"] = {"before_arcsec_rms": _rms_in(off, w["before"]) * ARCSEC_PER_RAD,
                           "after_arcsec_rms": ref * ARCSEC_PER_RAD}
    stage("testbed-isolation: the loops over the uncertainty's nine corners")
    corners = perturbed_plants(model)
    robust = {k: {kk: v for kk, v in robust_factor(corners, MOUNTS[k], gains[k]).items()
                  if kk != "limits"} for k in MOUNTS}
    nominal = NOMINAL_GAINS if variant == "stiff" else HYBRID_NOMINAL_GAINS
    robust["nominal_gains_linear_reduction_pct"] = {
        k: boresight_reduction(plant, MOUNTS[k], nominal[k], Gh=Gh) for k in MOUNTS}
    stage("testbed-isolation: the instruments (optical scoring) and the stacks' servo loops")
    scale = OSS_LEVEL_ARCSEC / before_after["off"]["before_arcsec_rms"]
    analog, servo = servo_plant(model), servo_plant(model, SERVO_HZ)
    instruments = {
        "oss_simulated_level": oss_reductions(off, runs, w, boresight_rms),
        "oss_scale": scale,
        "oss_at_level": oss_reductions(off, runs, w, boresight_rms, scale),
        "servo_hz": SERVO_HZ,
        "analog_no_servo": {"reduction_pct": boresight_reduction(analog, (3,), gains["mount3"]),
                            "gain_margin_db": gain_margin_db(analog, (3,), gains["mount3"])},
        "servo": {"reduction_pct": boresight_reduction(servo, (3,), gains["mount3"]),
                  "gain_margin_db": gain_margin_db(servo, (3,), gains["mount3"]),
                  "upper_bound_pct": strut_bounds(servo, (3,))["upper_bound"]}}
    return {"runs": runs, "off": off, "stop": stop, "t_on": t_on, "windows": w,
            "off_change_pct": off_change, "reduction": red, "before_after": before_after,
            "instruments": instruments, "robust": robust,
            "max_voltage": vmax, "linear": lin, "frf": frf, "ratio": ratio,
            "bandwidth": bw, "loop_shape": shape, "gains": gains, "feedforward_pct": ff,
            "limiting": limiting,
            "off_linear_full_scale_arcsec_rms": _off_rms(Gh)}


def run(out_dir, quick: bool = False, fmu_dir="fmus", variant="stiff",
        fmu_kind="native") -> dict:
    """Run the experiment into ``out_dir`` (figure ``testbed-isolation.png``, the hybrid
    variant ``testbed-isolation-hybrid.png``); the JSON-able result: co-simulated and
    linear reductions (%), gain margins (dB), isolation bandwidth (Hz), strut voltages
    (V), boresight RMS (arcsec), the paper's values, ``reproduced`` and a ``note``.

    Parameters
    ----------
    out_dir : path-like
        Folder of the figure (must exist).
    quick : bool
        The after-window ends 3.6 s instead of 7.2 s after switch-on (``AFTER``); the
        before-window is the same settled one.
    fmu_dir : path-like
        Folder of the FMUs, built there when missing or stale.
    variant : str
        ``"stiff"`` (the struts as documented) or ``"hybrid"`` (mount #3 a hybrid isolator,
        gains ``HYBRID_GAINS``).
    fmu_kind : str
        Run ``"native"`` or ``"python"`` FMUs (``--python-fmus``).
    """
    data = compute(quick, fmu_dir, variant, fmu_kind)
    testbed_figure(data, out_dir, "testbed-isolation" + ("-hybrid" if variant == "hybrid" else ""),
                   freqs=FREQS, t_on=data["t_on"], highpass=_highpassed,
                   record_t_on=PAPER_T_ON)
    red, lin = data["reduction"], data["linear"]
    verdicts = testbed_verdicts(data)
    reproduced = vd.all_reproduced(verdicts)
    upper = {k: lin[k]["bounds"]["upper_bound"] for k in MOUNTS}
    null = {k: lin[k]["bounds"]["accel_null"] for k in MOUNTS}
    ba = data["before_after"]
    words = "; ".join(vd.outcome_words(v) for v in verdicts)
    bounds_txt = (f"Upper bound (least-squares best strut forces at the harmonics; no "
                  f"controller at these struts removes more in steady state): mount #3 "
                  f"{upper['mount3']:.0f} %, all three {upper['all_mounts']:.0f} %; holding "
                  f"the payload accelerometers at zero (infinite gain, not a bound) would "
                  f"remove {null['mount3']:.0f} % / {null['all_mounts']:.0f} %.")
    if variant == "hybrid":
        note = (f"{vd.overall(verdicts).capitalize()}.  {words}.  {bounds_txt}  Hybrid "
                f"mount #3 (stack + elastomer, build(iso3='hybrid'); its "
                f"elastomer stiffness and loss factor were calibrated, on the earlier "
                f"coupling and law direction, to give the paper's 80 %): the stated law in "
                f"the stiff design's direction with 6 dB over the testbed's uncertainty "
                f"({data['robust']['mount3']['margin_db']:.1f} dB over its corners) "
                f"removes {red['mount3']:.0f} % in two runs, "
                f"{ba['mount3']['before_after_reduction_pct']:.0f} % the paper's way "
                f"(linear {lin['mount3']['reduction_pct']:.0f} %); a law designed in "
                f"its own best direction does much better (docs/eos_experiments.md).")
    else:
        rob = data["robust"]
        note = (f"{vd.overall(verdicts).capitalize()}.  {words}.  {bounds_txt}  Mount #3 "
                f"is in the dominant 22 Hz path.  With gains that keep 6 dB over the "
                f"testbed's uncertainty (modal frequencies x0.95-1.05, damping x0.5-2; "
                f"{rob['mount3']['margin_db']:.1f} dB over its nine corners) the stated "
                f"law removes {lin['mount3']['reduction_pct']:.1f} % on the linear model "
                f"({red['mount3']:.1f} % co-simulated, two runs; "
                f"{ba['mount3']['before_after_reduction_pct']:.1f} % the paper's way, "
                f"before and after switch-on in one run, on a settled response: "
                f"isolation off changes {data['off_change_pct']:+.2f} % between the same "
                f"windows).  At 6 dB on the nominal plant alone it would remove "
                f"{rob['nominal_gains_linear_reduction_pct']['mount3']:.1f} %, what the "
                f"law's bus path gives as pure feedforward with the best real gain "
                f"({data['feedforward_pct']:.1f} %), and be unstable at points of the set "
                f"(damping halved: the worst corner is {rob['mount3']['worst']}).  What stops "
                f"the gap to the upper bound is that uncertainty, measured in "
                f"docs/eos_experiments.md (the paper's structure with its corners and "
                f"gains free reaches 78.6 % at 6 dB on the nominal plant).")
    bounds = [
        {"name": "upper bound", "pct": upper, "is_bound": True,
         "bounds": "the steady-state boresight reduction at 22, 44 and 66 Hz of any "
                   "controller, causal or not, driving these struts (least-squares best "
                   "strut commands at each line)"},
        {"name": "payload accelerometers held at zero", "pct": null, "is_bound": False,
         "bounds": "nothing: what a loop of infinite gain on the payload accelerometers "
                   "gives at the harmonics; a finite-gain law can remove more"},
        {"name": "the law's bus path as pure feedforward, best real gain",
         "pct": {"mount3": data["feedforward_pct"]}, "is_bound": True,
         "bounds": "feedforward of the stated law's bus-path shape with one real gain; "
                   "not the closed loop"}]
    return {
        "verdicts": verdicts,
        "jitter_reduction_pct": red,
        "paper_way_reduction_pct": {k: data["before_after"][k]["before_after_reduction_pct"]
                                    for k in MOUNTS},
        "margin_limiting_poles": data["limiting"],
        "upper_bound_pct": upper,
        "accel_null_pct": null,
        "bounds": bounds,
        "linear_reduction_pct": {k: lin[k]["reduction_pct"] for k in MOUNTS},
        "gain_margin_db": {k: lin[k]["gain_margin_db"] for k in MOUNTS},
        "loop_gain_margins_db": {k: lin[k]["loop_gain_margins_db"] for k in MOUNTS},
        "isolation_bandwidth_hz": data["bandwidth"],
        "loop_shape_mount3": data["loop_shape"],
        "feedforward_best_gain_mount3_pct": data["feedforward_pct"],
        "max_voltage_v": max(data["max_voltage"].values()),
        "max_strut_voltage_v": data["max_voltage"],
        "boresight_rms": data["before_after"],
        "gain": data["gains"],
        "variant": variant,
        "off_linear_full_scale_arcsec_rms": data["off_linear_full_scale_arcsec_rms"],
        "instruments": data["instruments"],
        "robust": data["robust"],
        "t_on_s": data["t_on"],
        "paper_t_on_s": PAPER_T_ON,
        "windows_s": {k: list(v) for k, v in data["windows"].items()},
        "off_change_pct": data["off_change_pct"],
        "settled_pct": SETTLED_PCT,
        "after_change_pct": {k: data["before_after"][k]["after_change_pct"] for k in MOUNTS},
        "paper": {"jitter_reduction_pct": {"mount3": PAPER["mount3"],
                                           "all_mounts": list(PAPER["all_mounts"])},
                  "isolation_bandwidth_hz": PAPER["bandwidth_hz"]},
        "reproduced": reproduced,
        "verdict": vd.overall(verdicts),
        "note": note,
        # closed over open loop (below 1: isolating); data["ratio"] is its inverse
        "transmissibility": {"freq_hz": FREQS, "mount3": 1.0 / data["ratio"]},
        "transmissibility_bands_mount3": transmissibility_bands(FREQS, data["ratio"]),
    }
