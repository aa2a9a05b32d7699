"""The SWIR experiment's linear design: the sampled plant, the loops and the bounds.

What :mod:`orchestrator.experiments.swir_isolation` computes before any co-simulation,
as calls into the engine (:mod:`orchestrator.analysis.sampled`, ``.margins``,
``.bounds``, ``.lqg``): the EOS testbed structure with every SWIR and VNIR mount leg
active sampled exactly at ``H``, the paper's mount law (or one LQG on all twelve
strains), gain margins, the upper bound, the modes that carry SWIR pitch and what 5 %
damping would give.  Forces are at testbed scale (``LOAD_SCALE``); ``FULL_SCALE`` gives
EOS AM-1's.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ctrlfmu.analysis import mode_damping
from ctrlfmu.designs import design
from fmukit.units import ARCSEC, LBF
from orchestrator.analysis import stability_margin_db
from orchestrator.analysis.bounds import record_ceiling
from orchestrator.analysis.frf import modal_frequency_response
from orchestrator.analysis.lqg import lqg_law, stack_lqg
from orchestrator.analysis.margins import channel_margins, spectral_radius, without_states
from orchestrator.analysis.sampled import (SampledStructure, amplifier_step,
                                           sample_structure, simulate_with_acs,
                                           stack_force_per_volt, stack_loop)
from orchestrator.metrics import peak_to_peak
from piezofmu import preset
from structfmu.models import eos_testbed

from . import eos
from .eos import mounts_structure_model as structure_model

GAIN = 1.0          # factor on controller_eos_isolation (its defaults are the design)
H = 1e-3            # structure, law and stack period (s)
WINDOW = 1.8        # paper: jitter per 1.8 s
SKIP = 0.5          # s dropped before the jitter windows
LOW_HZ = 5.0        # modes below: rigid body, solar array, antenna (first bus mode 23 Hz)
AXES = ("roll", "pitch", "yaw")
MOUNTS = ("swir", "vnir")
LEGS = tuple(f"{m}_mount{k}" for m in MOUNTS for k in range(1, 7))
FULL_SCALE = 10.0   # force factor testbed -> EOS AM-1 (scenario loads x 0.1)
LOAD_SCALE = 0.1
STRUCTURE = eos.MOUNTS_STRUCTURE
OTHER_FMUS = ("disturbance", "acs", "piezo_p845_37", "controller_eos_isolation")
AMPLIFIER, STACK = "P-865.10", "P-845.37"
W = 9               # plant inputs: the VNIR wrench and ACS torques, then the stack forces

#: Weights of :func:`central_law` (control effort, input-noise robustness, strain noise;
#: relative), chosen on the linear model for >= 6 dB gain margin both ways with pitch
#: >= 50 % (docs/eos_experiments.md lists the trade-off).
CENTRAL_WEIGHTS = {"rho": 5.0, "q": 0.5, "snr": 1e-2}


# -- the model ------------------------------------------------------------------------------
def law(gain: float = GAIN):
    """The mount law: ``eos_isolation`` defaults times ``gain`` (``DiscreteLaw``)."""
    return design("eos_isolation").with_gain(gain)


def _amp(coupling: int = 1):   # the stack FMU's P-865.10 over a step (1: its mean force)
    return amplifier_step(AMPLIFIER, H, coupling)


def linear_plant(model=None) -> SampledStructure:
    """The structure sampled at ``H`` (ZOH): inputs the VNIR wrench (N, N m), the ACS
    torques (N m) and the stack forces of ``LEGS`` (N); outputs the SWIR and MISR lines
    of sight, attitude, rate, and each leg's strain and elongation
    (:func:`orchestrator.analysis.sampled.sample_structure`)."""
    model = structure_model() if model is None else model
    ins = ([f"vnir_{c}" for c in ("fx", "fy", "fz", "mx", "my", "mz")]
           + [f"acs_t{a}" for a in "xyz"] + [f"fc_{leg}" for leg in LEGS])
    outs = ([f"los_{i}_{a}" for i in ("swir", "misr") for a in AXES]
            + [f"att_{a}" for a in AXES] + [f"rate_{a}" for a in AXES]
            + [f"strain_{leg}" for leg in LEGS] + [f"elong_{leg}" for leg in LEGS])
    return sample_structure(model, ins, outs, H)


def _parts(plant):
    """``C`` restricted to the modes below ``LOW_HZ`` and to the rigid-body modes."""
    return (plant.modal_output(plant.omega < 2 * np.pi * LOW_HZ),
            plant.modal_output(plant.omega == 0.0))


def closed_loop(plant, law_, gain: float = 1.0, coupling: int = 1):
    """Dense discrete closed loop of the twelve legs: ``(A, Bw, C, C_low, C_rigid, C_force)``.

    :func:`orchestrator.analysis.sampled.stack_loop` on the strains and stack forces of
    ``LEGS`` (``law_``: one law per leg, :func:`law`, or one for all, :func:`central_law`;
    ``gain`` on every leg; the stack FMUs' ``coupling``); ``Bw`` the VNIR wrench and ACS
    torques, the output matrices padded with zeros for the law and amplifier states.

    Parameters
    ----------
    plant : SampledStructure
        From :func:`linear_plant`.
    law_ : DiscreteLaw
        One law per leg (:func:`law`) or one for all twelve (:func:`central_law`).
    gain : float
        Factor on every leg's law.
    coupling : int
        The stack FMU's coupling: 1 its mean force over a step, 0 the force at its end.

    Returns
    -------
    tuple of ndarray
        ``A`` (n, n), ``Bw`` (n, 9), then ``C``, ``C_low``, ``C_rigid`` (n_out, n) and
        ``C_force`` (12, n: stack forces, N).
    """
    A, C_force = stack_loop(plant.A, plant.B[:, W:], plant.C[plant.rows("strain_", LEGS)],
                            law_, gain=gain, force_per_volt=stack_force_per_volt(STACK),
                            amplifier=_amp(coupling))
    ns = plant.A.shape[0]
    Bw = np.vstack([plant.B[:, :W], np.zeros((A.shape[0] - ns, W))])
    pad = np.zeros((plant.C.shape[0], A.shape[0] - ns))
    return (A, Bw, *(np.hstack([c, pad]) for c in (plant.C, *_parts(plant))), C_force)


def central_gains(plant, rho: float = CENTRAL_WEIGHTS["rho"],
                  q: float = CENTRAL_WEIGHTS["q"], snr: float = CENTRAL_WEIGHTS["snr"],
                  sensors=LEGS, actuators=LEGS) -> dict:
    """:func:`central_law`'s LQG (``stack_lqg``), ``sensors``, ``actuators`` as indices.

    Parameters
    ----------
    plant : SampledStructure
        From :func:`linear_plant`.
    rho, q, snr : float
        Control effort, input-noise robustness and strain-noise weights (relative).
    sensors, actuators : sequence of str
        Legs whose strains are read and whose stacks are driven.

    Returns
    -------
    dict
        :func:`orchestrator.analysis.lqg.stack_lqg`'s gains, and ``sensors`` and
        ``actuators`` as indices into ``LEGS``.
    """
    si = [LEGS.index(leg) for leg in sensors]
    ai = [LEGS.index(leg) for leg in actuators]
    keep = np.setdiff1d(np.arange(plant.A.shape[0]), plant.rigid_states)
    Bf = plant.B[:, W:][np.ix_(keep, ai)]
    Cs = plant.C[np.ix_(plant.rows("strain_", sensors), keep)]
    Cp = (plant.C - _parts(plant)[0])[np.ix_(plant.rows("los_swir_", ["pitch"]), keep)]
    # the event's wrench direction (its dominant right singular vector)
    w = vnir_wrench(np.arange(0.0, 1.1, H))
    bw = plant.B[keep, :6] @ np.linalg.svd(w, full_matrices=False)[2][0]
    g = stack_lqg(without_states(plant.A, plant.rigid_states), Bf, Cs, Cp, bw,
                  amplifier=_amp(), rho=rho, q=q, snr=snr)
    return {**g, "sensors": si, "actuators": ai}


def central_law(plant, rho: float = CENTRAL_WEIGHTS["rho"],
                q: float = CENTRAL_WEIGHTS["q"], snr: float = CENTRAL_WEIGHTS["snr"],
                sensors=LEGS, actuators=LEGS):
    """One controller for all twelve legs: LQG on the twelve stack strains (DiscreteLaw).

    Can the same strain gauges attenuate SWIR pitch when their signals are combined?
    Designed (:func:`orchestrator.analysis.lqg.stack_lqg`, weights ``rho``, ``q``,
    ``snr``, default ``CENTRAL_WEIGHTS``) on the flexible part of ``plant``
    (:func:`linear_plant`) for SWIR pitch from the modes above ``LOW_HZ`` (the rigid
    body, array and antenna are left to the ACS), process noise along the VNIR event's
    wrench, with the stack FMU's amplifier lag and mean force, in Eq. (11) form; it reads
    the strains of the legs ``sensors`` and drives the stacks of ``actuators`` (e.g. the
    VNIR legs' strains and the SWIR legs' stacks).  Inputs the twelve strains
    ``strain_<leg>``, outputs the twelve commands ``v_<leg>`` (V), within the stack's
    rated voltage.

    Parameters
    ----------
    plant : SampledStructure
        From :func:`linear_plant`.
    rho, q, snr : float
        Control effort, input-noise robustness and strain-noise weights (relative).
    sensors, actuators : sequence of str
        Legs whose strains are read and whose stacks are driven.

    Returns
    -------
    DiscreteLaw
    """
    g = central_gains(plant, rho, q, snr, sensors, actuators)
    nl = len(LEGS)
    return lqg_law(g, nl, g["sensors"], g["actuators"],
                   force_per_volt=stack_force_per_volt(STACK),
                   u_max=preset(STACK).rated_voltage, dt=H, name="swir_central",
                   inputs=tuple(f"strain_{leg}" for leg in LEGS),
                   outputs=tuple(f"v_{leg}" for leg in LEGS),
                   input_units=("1",) * nl, output_units=("V",) * nl,
                   description="LQG on the twelve SWIR/VNIR mount stack strains "
                               "(swir_isolation.central_law)")


def vnir_wrench(t, preset="vnir_pointing"):
    """The preset's wrench at the times ``t`` (s), ``LOAD_SCALE`` applied (:func:`eos.wrench`).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times (s).
    preset : str
        Disturbance preset.

    Returns
    -------
    ndarray, shape (n, 6)
        ``Fx .. Mz`` (N, N m), testbed scale.
    """
    return eos.wrench(t, preset, LOAD_SCALE)


def simulate_linear(plant, law_=None, gain: float = 0.0, stop: float = 6.0,
                    preset="vnir_pointing") -> dict:
    """Linear loop under the VNIR event for ``stop`` s, the ACS in the loop at 10 Hz
    (:func:`orchestrator.analysis.sampled.simulate_with_acs`); legs passive without a law
    or with ``gain = 0``.  Columns ``"time"`` (s), the outputs by name, ``low:<name>``
    (modes below ``LOW_HZ``), ``rigid:<name>`` (rigid-body modes), ``force_<leg>`` (N).

    Parameters
    ----------
    plant : SampledStructure
        From :func:`linear_plant`.
    law_ : DiscreteLaw or None
        One law per leg (:func:`law`) or one for all twelve (:func:`central_law`).
    gain : float
        Factor on every leg's law (0: legs passive).
    stop : float
        Length of the record (s).
    preset : str
        Disturbance preset at the VNIR station.

    Returns
    -------
    dict of str to ndarray
    """
    if law_ is None or gain == 0.0:
        A, Bw, C = plant.A, plant.B[:, :W], plant.C
        Cl, Cr = _parts(plant)
        Cf = np.zeros((len(LEGS), A.shape[0]))
    else:
        A, Bw, C, Cl, Cr, Cf = closed_loop(plant, law_, gain)
    n = int(round(stop / H)) + 1
    t = np.arange(n) * H
    Y, L, R, F = simulate_with_acs(A, Bw, vnir_wrench(t, preset), eos.acs_config(),
                                   plant.rows("att_", AXES), plant.rows("rate_", AXES), H,
                                   (C, Cl, Cr, Cf))
    out = {"time": t}
    for i, name in enumerate(plant.outputs):
        out[name] = Y[:, i]
        out["low:" + name] = L[:, i]
        out["rigid:" + name] = R[:, i]
    for i, leg in enumerate(LEGS):
        out[f"force_{leg}"] = F[:, i]
    return out


def jitter(tab, inst, prefix="structure.") -> dict:
    """Windowed peak-to-peak (arcsec, window ``WINDOW``) per axis after ``SKIP`` s of the
    columns ``<prefix>los_<inst>_<axis>`` (rad) of ``tab`` (``"structure."`` for a
    co-simulation table; ``""``, ``"low:"`` or ``"rigid:"`` for :func:`simulate_linear`).

    Parameters
    ----------
    tab : dict of str to ndarray
        A record with ``"time"`` (s).
    inst : str
        Instrument, ``"swir"`` or ``"misr"``.
    prefix : str
        Column prefix.

    Returns
    -------
    dict of str to float
        Per axis (arcsec).
    """
    t = np.asarray(tab["time"])
    m = t >= SKIP - 1e-9
    dt = float(t[1] - t[0])
    return {a: float(peak_to_peak(np.asarray(tab[f"{prefix}los_{inst}_{a}"])[m], dt, WINDOW))
            / ARCSEC for a in AXES}


def _pct(off, on):
    return {a: 100.0 * (1.0 - on[a] / off[a]) for a in off}


def _norm_pct(off, on):
    return float(100.0 * (1.0 - np.linalg.norm(list(on.values()))
                          / np.linalg.norm(list(off.values()))))


def mode_shares(lin_off: dict, lin_on: dict | None = None) -> dict:
    """Shares of the isolation-off SWIR LOS by kind of mode (linear, %, arcsec): the
    rigid-body modes' share (mount forces are self-equilibrated: only the ACS moves
    them), 100 - that share, and the share of the modes below ``LOW_HZ`` (with ``lin_on``
    also isolation on: mount forces do move those).  Peak-to-peak is not additive, so a
    controller can beat either number.

    Parameters
    ----------
    lin_off : dict of str to ndarray
        :func:`simulate_linear` without control.
    lin_on : dict of str to ndarray, optional
        The same with control.

    Returns
    -------
    dict
    """
    tot = jitter(lin_off, "swir", prefix="")
    rig = jitter(lin_off, "swir", prefix="rigid:")
    low = jitter(lin_off, "swir", prefix="low:")
    out = {"rigid_body_share_pct": {a: 100.0 * rig[a] / tot[a] for a in AXES},
           "flexible_cancelled_pct": {a: max(0.0, 100.0 * (1 - rig[a] / tot[a]))
                                      for a in AXES},
           "rigid_part_arcsec": rig,
           "low_share_pct": {a: 100.0 * low[a] / tot[a] for a in AXES},
           "low_part_arcsec": low}
    if lin_on is not None:
        out["low_part_on_arcsec"] = jitter(lin_on, "swir", prefix="low:")
    return out


def ls_cancellation(plant, lin_off: dict, stroke_limit=5e-6,
                    force_limit=15.0 * LBF / FULL_SCALE) -> dict:
    """Stack forces that cancel the SWIR line of sight, knowing the disturbance
    (:func:`orchestrator.analysis.bounds.record_ceiling` on the isolation-off record:
    non-causal, periodic, least squares).

    ``"unconstrained"``: exact cancellation of the three axes (reduction %, stroke um,
    force lbf) -- the upper bound, 100 %, and the stroke and force it takes.
    ``"within_limits"``: per axis, the best of the Tikhonov-regularised least-squares
    inputs that keep a leg elongation below ``stroke_limit`` (m) and a stack force below
    ``force_limit`` (N, testbed scale) (None when none fits).  Those are *achievable*
    reductions within the limits, not a bound on them: each minimises one axis's squared
    error with a uniform penalty on the forces, not its peak to peak under the limits,
    and a controller within the limits can remove more (the central law does on roll).

    Parameters
    ----------
    plant : SampledStructure
        From :func:`linear_plant`.
    lin_off : dict of str to ndarray
        :func:`simulate_linear` without control.
    stroke_limit : float
        Largest leg elongation allowed (m).
    force_limit : float
        Largest stack force allowed (N, testbed scale).

    Returns
    -------
    dict
    """
    t = np.asarray(lin_off["time"])
    keep = np.setdiff1d(np.arange(plant.A.shape[0]), plant.rigid_states)
    rows = plant.rows("los_swir_", AXES) + plant.rows("elong_", LEGS)
    # forces to LOS and elongations; the rigid-body states are left out (the forces do
    # not reach them; their Jordan blocks at z = 1 have no eigenvector basis)
    G = modal_frequency_response(without_states(plant.A, plant.rigid_states),
                                 plant.B[keep, W:], plant.C[np.ix_(rows, keep)],
                                 np.fft.rfftfreq(t.size, H), H)
    m = t >= SKIP - 1e-9
    lim = {"stroke_um": stroke_limit * 1e6, "force_lbf": force_limit * FULL_SCALE / LBF}

    def units(r):
        return {"rho": r["rho"], "reduction_pct": dict(zip(AXES, r["reduction_pct"])),
                "max_stroke_um": r["others_max"] * 1e6,
                "max_force_lbf": r["inputs_max"] * FULL_SCALE / LBF}

    c = record_ceiling(G, np.array([lin_off[f"los_swir_{a}"] for a in AXES]),
                       [0.0] + list(np.geomspace(1e-6, 1e3, 28)),
                       lambda r: peak_to_peak(r[m], H, WINDOW),
                       np.array([lin_off[f"elong_{leg}"] for leg in LEGS]),
                       lambda r: (units(r)["max_stroke_um"] < lim["stroke_um"]
                                  and units(r)["max_force_lbf"] < lim["force_lbf"]))
    per_axis = {a: None if b is None else {
        "reduction_pct": b["reduction_pct"][i], "max_stroke_um": units(b)["max_stroke_um"],
        "max_force_lbf": units(b)["max_force_lbf"]} for i, (a, b) in enumerate(zip(AXES, c["best"]))}
    return {"unconstrained": units(c["exact"]),
            "within_limits_pct": {a: (None if v is None else v["reduction_pct"])
                                  for a, v in per_axis.items()},
            "within_limits": per_axis, "limits": lim}


# -- loop analysis ----------------------------------------------------------------------------
def margins(plant, law_, gain: float = GAIN) -> dict:
    """Per-leg SISO margins (other loops open,
    :func:`orchestrator.analysis.margins.channel_margins`) and the MIMO gain margins
    (:func:`mimo_gain_margin` up and down), dB and deg; no per-leg margins for one law
    on all legs.

    Parameters
    ----------
    plant : SampledStructure
        From :func:`linear_plant`.
    law_ : DiscreteLaw
        One law per leg (:func:`law`) or one for all twelve (:func:`central_law`).
    gain : float
        Factor on every leg's law.

    Returns
    -------
    dict
    """
    mimo = {"mimo_gain_margin_db": mimo_gain_margin(plant, law_, gain),
            "mimo_gain_reduction_margin_db": mimo_gain_margin(plant, law_, gain, down=True)}
    if law_.n_inputs != 1:      # one law for all legs: no loop of one leg alone
        return {"per_leg": None, "min_gain_margin_db": None, "min_phase_margin_deg": None,
                **mimo}
    per = channel_margins(plant.A, plant.B[:, W:], plant.C[plant.rows("strain_", LEGS)],
                          law_, gain=gain, force_per_volt=stack_force_per_volt(STACK), dt=H,
                          freqs_hz=np.geomspace(0.5, 499.0, 3000))
    legs = {leg: {"gain_margin_db": gm, "phase_margin_deg": pm, "phase_crossover_hz": wgc,
                  "gain_crossover_hz": wpc} for leg, (gm, pm, wgc, wpc) in zip(LEGS, per)}
    return {"per_leg": legs,
            "min_gain_margin_db": min(v["gain_margin_db"] for v in legs.values()),
            "min_phase_margin_deg": min(abs(v["phase_margin_deg"]) for v in legs.values()),
            **mimo}


RIGID_TOL = 1e-9    # rigid-body poles sit at z = 1 (the loops neither see nor move them)


def mimo_gain_margin(plant, law_, gain: float = GAIN, down: bool = False) -> float:
    """Common factor on all twelve loops (dB over ``gain``) at which a flexible pole leaves
    the unit circle (``down``: the factor below ``gain``, for a law with unstable poles of
    its own, as an LQG may have; a positive dB); ``-inf`` if unstable at ``gain``,
    ``inf`` if stable to ``1e4`` (down ``1e-4``) times ``gain``.

    Parameters
    ----------
    plant : SampledStructure
        From :func:`linear_plant`.
    law_ : DiscreteLaw
        One law per leg (:func:`law`) or one for all twelve (:func:`central_law`).
    gain : float
        Factor on every leg's law.
    down : bool
        The margin below ``gain`` instead of above.

    Returns
    -------
    float
        dB.
    """
    def stable(g):
        A = without_states(closed_loop(plant, law_, g)[0], plant.rigid_states)
        return spectral_radius(A) < 1.0 + RIGID_TOL

    # 1.0002: twelve bisections of a factor-2 bracket
    return stability_margin_db(lambda f: stable(gain * f), 0.5 if down else 2.0, 1e4, 1.0002)


def modal_breakdown(model, plant, law_, axis="pitch", stop=3.5, top=4) -> list:
    """The ``top`` flexible modes carrying most of the isolation-off SWIR ``axis``
    peak-to-peak: per mode its frequency (Hz), its own windowed peak-to-peak in the LOS
    (arcsec), the share of its strain energy in the twelve legs (%), and its damping
    open and closed loop (``law_`` at ``GAIN``); largest contribution first.

    Parameters
    ----------
    model : ReducedModel
        The structure (:func:`orchestrator.experiments.eos.mounts_structure_model`).
    plant : SampledStructure
        From :func:`linear_plant`.
    law_ : DiscreteLaw
        One law per leg (:func:`law`) or one for all twelve (:func:`central_law`).
    axis : str
        SWIR axis.
    stop : float
        Length of the record (s).
    top : int
        Modes listed.

    Returns
    -------
    list of dict
    """
    n = int(round(stop / H)) + 1
    t = np.arange(n) * H
    nx = plant.A.shape[0]
    _, X = simulate_with_acs(plant.A, plant.B[:, :W], vnir_wrench(t), eos.acs_config(),
                             plant.rows("att_", AXES), plant.rows("rate_", AXES), H,
                             (plant.C, np.eye(nx)))
    r = plant.rows("los_swir_", [axis])[0]
    m = t >= SKIP - 1e-9
    flex = np.flatnonzero(model.omega > 0)
    p2p = np.array([peak_to_peak((plant.C[r, i] * X[m, i]), H, WINDOW) for i in flex])
    truss = eos_testbed.build(active_legs="all")
    _, phi = eos_testbed.modes(truss, model.n_modes)
    sef = eos_testbed.strain_energy_fractions(truss, phi)
    legs = np.nan_to_num(sef.get("mount_swir", 0) + sef.get("mount_vnir", 0))
    fz, zz = mode_damping(np.linalg.eigvals(closed_loop(plant, law_, GAIN)[0]), H)
    out = []
    for k in np.argsort(p2p)[::-1][:top]:
        i = flex[k]
        f = model.omega[i] / (2 * np.pi)
        near = np.argmin(np.abs(fz - f) + 1e3 * (zz > 0.5))
        out.append({"mode": int(i + 1), "f_hz": float(f), "p2p_arcsec": float(p2p[k] / ARCSEC),
                    "active_leg_strain_energy_pct": float(100 * legs[i]),
                    "zeta_open": float(model.modal_damping[i] / (2 * model.omega[i])),
                    "zeta_closed": float(zz[near])})
    return out


def reduction_with_damping(model, zeta: float = 0.05, above_hz: float = 20.0,
                           stop: float = 3.5) -> dict:
    """SWIR reduction per axis (%, linear, ``stop`` s) if every mode of ``model`` above
    ``above_hz`` (Hz) had the damping ratio ``zeta``, no control.

    A collocated leg damper adds at most about ``nu / 4`` to a mode with a fraction ``nu``
    of its strain energy in that leg (the largest in the twelve legs is 17 %: about 4 %),
    so this is more damping than any strain/strain-rate loop on the legs can add.

    Parameters
    ----------
    model : ReducedModel
        The structure.
    zeta : float
        Damping ratio given to the modes above ``above_hz``.
    above_hz : float
        Frequency above which (Hz).
    stop : float
        Length of the record (s).

    Returns
    -------
    dict of str to float
        Reduction per axis (%).
    """
    base = jitter(simulate_linear(linear_plant(model), stop=stop), "swir", "")
    f = model.omega / (2 * np.pi)
    z = np.where(f > above_hz, zeta, model.modal_damping / np.maximum(2 * model.omega, 1e-300))
    damped = replace(model, modal_damping=2 * z * model.omega)
    return _pct(base, jitter(simulate_linear(linear_plant(damped), stop=stop), "swir", ""))
