"""The stacks' built-in servo loops through the FMUs: what they change in the testbed result.

The paper's MISR struts are PI stacks with "a strain gage sensor mounted on its internal
piezoceramic stack" and "a built-in servo loop controller".  The piezo FMU closes that
loop itself (``servo_bandwidth`` > 0, :mod:`piezofmu.actuator`): an integrator on the
commanded expansion (0.4 um per volt of the law's command) less the measured one (the
strut's elongation, the FMU's ``elongation`` input) drives the amplifier.  This
experiment runs :mod:`.testbed_isolation` (its shipped gains, settled windows, both
measures) twice through the FMUs, the struts without and with the servo at ``servo_hz``
(``SERVO_HZ``, 100 Hz: assumed, the paper gives no servo bandwidth), each integrator set
for its strut's own expansion per volt
(:func:`~orchestrator.experiments.testbed_instruments.servo_plant_gains`).

In the hardware the servo is analog.  In a co-simulation its feedback, the elongation, is
held over the structure's communication step: at the shipped 1 ms that hold and the
force's step mean add about a millisecond inside a 100 Hz loop, and the linear engine
finds the loop unstable (``pole_radius.coupled_1ms``, per 0.1 s hyperperiod).  So both
runs here step the structure and the MISR piezos every ``SERVO_PERIOD`` (0.2 ms; the
laws, sources and the other FMUs stay at their rates), where the same loop is stable;
the no-servo run at that rate is the reference, so the difference is the servo's alone.
The loop must also be stable at ``FINE_PERIOD`` (0.05 ms, which resolves the struts'
1.3-1.9 kHz local modes): a 200 Hz servo, unstable through them in the analog design,
is stable at 0.2 ms and unstable at 0.1 and 0.05 ms, and is refused.
``jitterfmu reproduce testbed-servo [--servo-hz HZ]``.
"""

from __future__ import annotations

import tomllib
import warnings

import numpy as np
from pathlib import Path

from fmukit.units import ARCSEC_PER_RAD

from ..progress import stage
from ..run import run_scenario
from . import eos
from .testbed_instruments import servo_overrides, servo_plant, servo_plant_gains
from .testbed_isolation import (GAINS, MOUNTS, NOMINAL_GAINS, boresight_reduction,
                                boresight_rms, design_gains, ensure_fmus, gain_margin_db,
                                linear_model, linear_plant, per_mount, settled_off_run,
                                windows)

NAME = "testbed-servo"
DESCRIPTION = "The MISR stacks' built-in servo loops through the piezo FMUs: the testbed " \
              "reductions without and with them"

#: Crossover of the stacks' servo loops (Hz; assumed, the paper gives none).
SERVO_HZ = 100.0
#: Communication step of the structure and the MISR piezos in these runs (s).
SERVO_PERIOD = 2e-4
#: The shipped communication step (s), where the servo's pole radius is also reported.
SHIPPED_PERIOD = 1e-3
#: A step that resolves the struts' 1.3-1.9 kHz local modes (s): the loop must be stable
#: there too, or the runs at ``SERVO_PERIOD`` would hide an instability.
FINE_PERIOD = 5e-5


def servo_scenario(period=SERVO_PERIOD) -> dict:
    """``scenarios/eos_budget.toml`` with the structure and the MISR piezos stepped every
    ``period`` (s).

    Parameters
    ----------
    period : float
        Their communication step (s); the piezos' ``hold_step`` is set to it by
        :func:`overrides`.
    """
    sc = tomllib.loads(Path(eos.SCENARIO).read_text())
    sc["fmus"]["structure"]["period"] = period
    for k in (1, 2, 3):
        sc["fmus"][f"piezo_iso{k}"]["period"] = period
    return sc


def overrides(model, mounts, gain, t_on, servo_hz, period=SERVO_PERIOD) -> dict:
    """The testbed-isolation overrides of one run, with the servo on at ``servo_hz``.

    Parameters
    ----------
    model : ReducedModel
        The reduced testbed (the servos' plant gains).
    mounts : tuple of int
        The mounts whose laws are on.
    gain : float or sequence of float
        The laws' factors (``testbed_isolation.GAINS``).
    t_on : float
        Switch-on of the laws (s).
    servo_hz : float
        The servos' crossover (Hz); 0 for none.
    period : float
        Communication step of the MISR piezos (s).
    """
    ov = {"dist_swir.preset": "swir_cryocooler"}
    for i, g in zip((1, 2, 3), per_mount(gain)):
        ov[f"ctrl_iso{i}.gain"] = g if i in mounts else 0.0
        ov[f"ctrl_iso{i}.t_on"] = t_on
        ov[f"piezo_iso{i}.hold_step"] = period
    if servo_hz:
        ov.update(servo_overrides(model, servo_hz))
    return ov


def pole_radius(fdir, model, servo_hz, period, mounts=(3,)) -> float:
    """Largest pole radius of the scenario's linear loop (per hyperperiod, 0.1 s), the
    servo at ``servo_hz`` and the laws of ``mounts`` on from the start.

    Parameters
    ----------
    fdir : path-like
        Folder of the FMUs.
    model : ReducedModel
        The reduced testbed.
    servo_hz : float
        The servos' crossover (Hz).
    period : float
        Communication step of the structure and the MISR piezos (s).
    mounts : tuple of int
        Mounts whose laws are closed (at ``GAINS["mount3"]`` for mount #3 alone).
    """
    # deferred: the linear engine loads python-control and scipy
    from ..analysis import linearize

    key = "mount3" if tuple(mounts) == (3,) else "all_mounts"
    ov = overrides(model, mounts, GAINS[key], 0.0, servo_hz, period)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the scenario's unconnected inputs
        lin = linearize(servo_scenario(period), overrides=ov, fmu_dir=fdir)
    return float(max(abs(p.z) for p in lin.poles()))


def _rms(tab, window):
    return boresight_rms(tab["time"], tab["structure.los_misr_roll"],
                         tab["structure.los_misr_pitch"], *window)


def measured(fdir, model, servo_hz, quick, fmu_kind="native", period=SERVO_PERIOD) -> dict:
    """The testbed-isolation measurement through the FMUs with the servo at ``servo_hz``.

    Parameters
    ----------
    fdir : path-like
        Folder of the FMUs.
    model : ReducedModel
        The reduced testbed.
    servo_hz : float
        The servos' crossover (Hz); 0 for none.
    quick : bool
        The quick run's shorter after-window.
    fmu_kind : str
        ``"native"`` or ``"python"``.
    period : float
        Communication step of the structure and the MISR piezos (s).

    Returns
    -------
    dict
        ``t_on_s``, ``off_change_pct``, ``off_before_arcsec`` (arcsec RMS), and per
        configuration ``two_runs_pct`` and ``paper_way_pct`` (%).
    """
    sc = servo_scenario(period)

    def cosim(mounts, gain, stop, t_on):
        return run_scenario(sc, stop_time=stop, fmu_dir=fdir, fmu_kind=fmu_kind,
                            overrides=overrides(model, mounts, gain, t_on, servo_hz,
                                                period)).table

    off, t_on, stop, change = settled_off_run(lambda ton, end: cosim((), 0.0, end, ton),
                                              quick)
    w = windows(t_on, stop)
    ref = _rms(off, w["after"])
    out = {"t_on_s": t_on, "off_change_pct": change,
           "off_before_arcsec": _rms(off, w["before"]) * ARCSEC_PER_RAD}
    for k, mounts in MOUNTS.items():
        tab = cosim(mounts, GAINS[k], stop, t_on)
        b, a = _rms(tab, w["before"]), _rms(tab, w["after"])
        out[k] = {"two_runs_pct": 100.0 * (1.0 - a / ref),
                  "paper_way_pct": 100.0 * (1.0 - a / b)}
    return out


def design_numbers(model, servo_hz, redesign=True) -> dict:
    """The servo in the linear design (``servo_plant``: the analog loop sampled exactly).

    Mount #3's reduction (%) and nominal gain margin (dB) with the shipped and the
    nominal-only gains on the analog plant without the servo, with it at ``servo_hz`` and
    at half of it, and the step-mean plant (``linear_plant``); the largest pole radius
    of the servo loop alone at twice ``servo_hz``; with ``redesign`` the best reduction
    at 6 dB on each analog plant (36 gain directions, ``design_gains``; about a minute
    each).

    Parameters
    ----------
    model : ReducedModel
        The reduced testbed.
    servo_hz : float
        The servo's crossover (Hz).
    redesign : bool
        Also re-design the law's gains on each plant.
    """
    plants = {"no_servo": servo_plant(model), f"servo_{servo_hz:g}hz":
              servo_plant(model, servo_hz), f"servo_{servo_hz / 2:g}hz":
              servo_plant(model, servo_hz / 2), "step_mean_no_servo": linear_plant(model)}
    out = {}
    for key, plant in plants.items():
        out[key] = {f"{which}_gains": {
            "reduction_pct": boresight_reduction(plant, (3,), gains["mount3"]),
            "gain_margin_db": gain_margin_db(plant, (3,), gains["mount3"])}
            for which, gains in (("shipped", GAINS), ("nominal", NOMINAL_GAINS))}
        if redesign and key != "step_mean_no_servo":
            stage(f"testbed-servo: re-designing mount #3's gains on the plant {key}")
            out[key]["redesigned_6db_pct"] = design_gains(plant, (3,))[0]
    out[f"servo_alone_{2 * servo_hz:g}hz_pole_radius"] = float(
        np.abs(np.linalg.eigvals(servo_plant(model, 2 * servo_hz).A)).max())
    return out


def run(out_dir, quick: bool = False, fmu_dir="fmus", fmu_kind="native",
        servo_hz: float = SERVO_HZ) -> dict:
    """Run the testbed measurement without and with the stacks' servo loops.

    Parameters
    ----------
    out_dir : path-like
        Folder of the experiment's output (the JSON only).
    quick : bool
        The quick run's shorter after-window (testbed-isolation's ``AFTER``).
    fmu_dir : path-like
        Folder of the FMUs, built there when missing or stale.
    fmu_kind : str
        ``"native"`` or ``"python"`` FMUs.
    servo_hz : float
        Crossover of the servo loops (Hz), > 0.

    Returns
    -------
    dict
        ``no_servo`` and ``servo`` (:func:`measured`), ``change_points`` (servo less
        no servo, percentage points, per configuration and measure), ``pole_radius``
        (the servo's linear loop at ``SERVO_PERIOD``, ``FINE_PERIOD`` and the shipped
        1 ms, mount #3 closed), ``linear_design`` (:func:`design_numbers`; no re-design in a quick
        run), the servos' ``servo_plant_gain_m_per_v`` and a ``note``.
    """
    if not servo_hz > 0:
        raise ValueError(f"servo_hz is {servo_hz!r}; give the servo's crossover in Hz (> 0)")
    fdir = ensure_fmus(fmu_dir, "stiff", fmu_kind)
    model = linear_model(fdir)
    stage(f"testbed-servo: the linear loop with the {servo_hz:g} Hz servo at "
          f"{SERVO_PERIOD * 1e3:g} ms and at {SHIPPED_PERIOD * 1e3:g} ms")
    radius = {"servo_period": pole_radius(fdir, model, servo_hz, SERVO_PERIOD),
              "fine_period": pole_radius(fdir, model, servo_hz, FINE_PERIOD),
              "coupled_1ms": pole_radius(fdir, model, servo_hz, SHIPPED_PERIOD)}
    for key, step in (("servo_period", SERVO_PERIOD), ("fine_period", FINE_PERIOD)):
        if radius[key] > 1 + 1e-6:
            raise RuntimeError(
                f"testbed-servo: a {servo_hz:g} Hz servo makes the testbed's loop unstable "
                f"at a {step * 1e3:g} ms step (pole radius {radius[key]:.4g} per 0.1 s; "
                "the struts' 1.3-1.9 kHz local modes, as in the analog design); try a "
                "lower --servo-hz")
    stage("testbed-servo: the servo in the linear design (analog loop sampled exactly)"
          + ("" if quick else "; re-designing the gains on each plant (minutes)"))
    design = design_numbers(model, servo_hz, redesign=not quick)
    res = {}
    for key, hz in (("no_servo", 0.0), ("servo", servo_hz)):
        what = f"with the {hz:g} Hz servo" if hz else "without the servo"
        stage(f"testbed-servo: co-simulating the testbed {what} (structure and MISR "
              f"struts every {SERVO_PERIOD * 1e3:g} ms)")
        res[key] = measured(fdir, model, hz, quick, fmu_kind)
    change = {k: {m: res["servo"][k][m] - res["no_servo"][k][m]
                  for m in ("two_runs_pct", "paper_way_pct")} for k in MOUNTS}
    note = (f"The stacks' servo loops at {servo_hz:g} Hz (assumed) change mount #3's "
            f"reduction by {change['mount3']['paper_way_pct']:+.1f} points the paper's way "
            f"({res['no_servo']['mount3']['paper_way_pct']:.1f} -> "
            f"{res['servo']['mount3']['paper_way_pct']:.1f} %), "
            f"{change['mount3']['two_runs_pct']:+.1f} in two runs; all three mounts "
            f"{change['all_mounts']['paper_way_pct']:+.1f} / "
            f"{change['all_mounts']['two_runs_pct']:+.1f} points.  At the shipped 1 ms "
            f"coupling the held elongation makes the same servo loop "
            f"{'unstable' if radius['coupled_1ms'] > 1 + 1e-6 else 'stable'} (pole radius "
            f"{radius['coupled_1ms']:.4g} per 0.1 s); these runs step the structure and the "
            f"MISR struts every {SERVO_PERIOD * 1e3:g} ms.")
    return {"servo_hz": servo_hz, "period_s": SERVO_PERIOD, **res, "change_points": change,
            "linear_design": design,
            "pole_radius": radius, "servo_plant_gain_m_per_v": servo_plant_gains(model),
            "gains": GAINS, "note": note}


def summary(result) -> str:
    """The lines ``jitterfmu reproduce testbed-servo`` prints."""
    lines = [result["note"]]
    for key in ("no_servo", "servo"):
        r = result[key]
        lines.append(f"{key}: off_change {r['off_change_pct']:+.2f} %, mount #3 "
                     f"{r['mount3']['paper_way_pct']:.1f} % paper's way / "
                     f"{r['mount3']['two_runs_pct']:.1f} % two runs, all three "
                     f"{r['all_mounts']['paper_way_pct']:.1f} / "
                     f"{r['all_mounts']['two_runs_pct']:.1f} %")
    return "\n".join(lines)
