"""The testbed's instruments and the stacks' own servo loop, and what each changes.

The paper's testbed measured with instruments and drove its struts through a loop of
their own (paper, "EOS Dynamics Testbed"):

* the **optical scoring system** (OSS) measured the boresight roll and pitch of Figs.
  15-16: "a resolution of 0.2 arc-sec. and a bandwidth of 100 Hz".  :func:`optical_scoring`
  models it as a 2nd-order Butterworth low-pass at 100 Hz (the order is assumed; the paper
  gives the bandwidth) followed by quantisation to 0.2 arcsec (the resolution read as the
  step of its output; its noise is not stated and is taken as none);
* the **accelerometers** the law feeds back: "a resolution on the order of 10 micro-g's
  with a bandwidth of 150 Hz".  The 150 Hz band is in the structure FMU (a 4th-order
  Butterworth on every accelerometer, ``docs/eos_testbed.md``); the resolution is
  modelled by :func:`sensor_noise_boresight` as white noise of the quantisation of a
  10 micro-g step (``q / sqrt(12)`` RMS per 1 kHz sample, assumed white) on both inputs
  of every closed law, and its boresight RMS after the experiment's 5 Hz high-pass;
* the stacks' **built-in servo loop**: "a strain gage sensor mounted on its internal
  piezoceramic stack to measure the total expansion and contraction.  A built-in servo
  loop controller is used to help counter the hysteresis".  :func:`servo_plant` closes
  it in continuous time around each MISR strut: the amplifier (P-865.10, first order
  2 kHz, inside the loop) is driven by an integrator on the difference between the
  commanded expansion (the stack's free stroke per volt, 0.4 um/V, times the law's
  command) and the stack's measured expansion (the strut's elongation), with the
  integrator set for a servo crossover of ``servo_hz`` (assumed: the paper gives no
  servo bandwidth); the whole analog plant is then sampled exactly with a zero-order
  hold at 1 kHz on the commands and the disturbance.  With ``servo_hz=None`` the same
  construction without the servo is the analog reference of
  :func:`~orchestrator.experiments.testbed_design.linear_plant` (its amplifier
  continuous instead of the piezo FMU's step-mean force).

The testbed model has no hysteresis on the stacks (``docs/eos_testbed.md``), so the servo's
purpose in the hardware does not arise here; what it changes is the plant the law sees.
"""

from __future__ import annotations

import numpy as np

from ctrlfmu.designs import ISOLATOR_STROKE_PER_VOLT
from fmukit.units import ARCSEC, ARCSEC_PER_RAD, G0
from structfmu.statespace import first_order

from ..analysis.frf import statespace_response
from ..analysis.sampled import zoh
from .testbed_design import DT, _IN, _OUT, closed_frf, law_frf

#: The OSS (paper): resolution (rad) and bandwidth (Hz); the filter order is assumed.
OSS_RESOLUTION = 0.2 * ARCSEC
OSS_BANDWIDTH_HZ = 100.0
OSS_ORDER = 2
#: The accelerometers' resolution (paper: "on the order of 10 micro-g's"), m/s^2.
ACCEL_RESOLUTION = 10e-6 * G0
#: P-865.10 small-signal bandwidth (Hz): the piezo FMU's assumed first order.
AMPLIFIER_HZ = 2000.0


def optical_scoring(t, angle, resolution=OSS_RESOLUTION, bandwidth_hz=OSS_BANDWIDTH_HZ):
    """The optical scoring system's reading of a boresight angle (rad).

    A causal Butterworth low-pass of order ``OSS_ORDER`` at ``bandwidth_hz``, then the
    reading rounded to a whole number of ``resolution`` steps.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Equally spaced times (s).
    angle : ndarray, shape (n,)
        The boresight angle (rad).
    resolution : float
        Step of the reading (rad); 0 for none.
    bandwidth_hz : float
        Cut-off of the low-pass (Hz).

    Returns
    -------
    ndarray, shape (n,)
        The reading (rad).
    """
    # deferred: scipy takes about 1 s to load
    from scipy.signal import butter, sosfilt

    sos = butter(OSS_ORDER, bandwidth_hz, fs=1.0 / (t[1] - t[0]), output="sos")
    y = sosfilt(sos, np.asarray(angle, float))
    return np.round(y / resolution) * resolution if resolution > 0 else y


def servo_plant(model, servo_hz=None, stroke_per_volt=ISOLATOR_STROKE_PER_VOLT,
                extra_outputs=()):
    """The testbed plant with each MISR strut in its stack's servo loop, sampled at 1 kHz.

    Parameters
    ----------
    model : ReducedModel
        The reduced testbed (:func:`~orchestrator.experiments.testbed_design.linear_model`).
    servo_hz : float or None
        Crossover of each strut's servo loop (Hz); None: no servo (the amplifier driven
        by the command directly).
    stroke_per_volt : float
        Commanded expansion per volt of the law's command (m/V): the stack's free stroke
        per volt.
    extra_outputs : sequence of str
        Outputs of ``model`` appended after those of ``linear_plant`` (e.g.
        ``elong_iso3``, m).

    Returns
    -------
    control.StateSpace
        Discrete (``DT``); inputs and outputs as
        :func:`~orchestrator.experiments.testbed_design.linear_plant`, then
        ``extra_outputs``.
    """
    # deferred: python-control takes about 1 s to load
    import control

    A, B, C, D = first_order(model)
    ins, outs = list(model.input_names), list(model.output_names)
    ii = [ins.index(n) for n in _IN]
    oo = [outs.index(n) for n in list(_OUT) + list(extra_outputs)]
    ee = [outs.index(f"elong_iso{k}") for k in (1, 2, 3)]
    ch = [model.meta["actuators"][f"iso{k}"]["ch"] for k in (1, 2, 3)]
    n = A.shape[0]
    wa = 2 * np.pi * AMPLIFIER_HZ
    ns = 3 if servo_hz else 0
    N = n + 3 + ns
    Ac = np.zeros((N, N))
    Bc = np.zeros((N, 4))
    Ac[:n, :n] = A
    for k in range(3):
        Ac[:n, n + k] = B[:, ii[k]] * ch[k]          # the amplifier's voltage pushes
        Ac[n + k, n + k] = -wa
    Bc[:n, 3] = B[:, ii[3]]
    if servo_hz:
        gains = servo_plant_gains(model)
        for k in range(3):
            ki = 2 * np.pi * servo_hz / gains[k]
            s = n + 3 + k
            Ac[n + k, s] = wa                        # the integrator drives the amplifier
            Ac[s, :n] = -ki * C[ee[k]]               # ... on the measured expansion
            Bc[s, k] = ki * stroke_per_volt          # ... against the commanded one
    else:
        for k in range(3):
            Bc[n + k, k] = wa
    Cc = np.hstack([C[oo], np.zeros((len(oo), N - n))])
    Ad, Bd = zoh(Ac, Bc, DT)
    return control.ss(Ad, Bd, Cc, np.zeros((len(oo), 4)), DT)


def servo_plant_gains(model, f_hz=5.0) -> list:
    """Each MISR strut's own expansion per volt (m/V), what its servo is set for.

    ``|c (s I - A)^-1 b ch|`` times the amplifier's gain at ``f_hz``, where the structure
    is quasi-static (above the rigid-body and below the flexible modes): the loop from
    the servo's integrator to the measured expansion at low frequency.  The piezo FMU's
    ``servo_plant_gain`` for ``iso1..3``.

    Parameters
    ----------
    model : ReducedModel
        The reduced testbed.
    f_hz : float
        Frequency of the quasi-static gain (Hz).

    Returns
    -------
    list of float
        Struts 1, 2, 3 (m/V).
    """
    A, B, C, _ = first_order(model)
    ins, outs = list(model.input_names), list(model.output_names)
    s = 2j * np.pi * f_hz
    wa = 2 * np.pi * AMPLIFIER_HZ
    out = []
    for k in (1, 2, 3):
        b = B[:, ins.index(_IN[k - 1])] * model.meta["actuators"][f"iso{k}"]["ch"]
        c = C[outs.index(f"elong_iso{k}")]
        out.append(float(abs(c @ np.linalg.solve(s * np.eye(A.shape[0]) - A, b))
                         * abs(wa / (s + wa))))
    return out


def servo_overrides(model, servo_hz) -> dict:
    """The scenario overrides that turn the MISR struts' servo loops on at ``servo_hz``.

    Parameters
    ----------
    model : ReducedModel
        The reduced testbed (:func:`servo_plant_gains`).
    servo_hz : float
        Crossover of each strut's servo (Hz).

    Returns
    -------
    dict of str to float
        ``piezo_iso{k}.servo_bandwidth`` and ``piezo_iso{k}.servo_plant_gain``.
    """
    ov = {}
    for k, g in zip((1, 2, 3), servo_plant_gains(model)):
        ov[f"piezo_iso{k}.servo_bandwidth"] = float(servo_hz)
        ov[f"piezo_iso{k}.servo_plant_gain"] = g
    return ov


def sensor_noise_boresight(plant, mounts, gain, noise_rms=ACCEL_RESOLUTION / np.sqrt(12),
                           f_lo=5.0, n_freq=2000) -> float:
    """Boresight RMS (arcsec) from white noise on every closed law's accelerometer inputs.

    Each input of each law on ``mounts`` reads its accelerometer plus independent white
    noise of ``noise_rms`` per sample (1 kHz); the boresight (roll and pitch, as
    :func:`~orchestrator.experiments.testbed_isolation.boresight_rms`) is integrated from
    ``f_lo`` (the experiment's 5 Hz high-pass) to the Nyquist frequency.

    Parameters
    ----------
    plant : control.StateSpace
        Discrete plant (:func:`~orchestrator.experiments.testbed_design.linear_plant` or
        :func:`servo_plant`).
    mounts : sequence of int
        The mounts whose laws are closed.
    gain : float or sequence of float
        Factor on the design law (per mount or one for all).
    noise_rms : float
        RMS of the noise per sample (m/s^2).
    f_lo : float
        Lowest frequency counted (Hz).
    n_freq : int
        Frequencies of the integration (log spaced).
    """
    f = np.geomspace(f_lo, 0.499 / DT, n_freq)
    G = statespace_response(plant, f)
    K = law_frf(f, gain)
    psd = 2 * noise_rms ** 2 * DT                     # one-sided, per Hz
    power = np.zeros(len(f))
    for m in mounts:
        for j in range(2):
            # a noise on sensor j of mount m enters as the law's response to it: the
            # closed loop's response to an input at that strut's command
            Gn = G.copy()
            Gn[:, :, 3] = G[:, :, m - 1] * K[:, m - 1, j][:, None]
            y = closed_frf(Gn, K, mounts)
            power += np.sum(np.abs(y[:, 6:8]) ** 2, axis=1) * psd
    return float(np.sqrt(np.trapezoid(power, f)) * ARCSEC_PER_RAD)


def oss_reductions(off, runs, windows, measure, scale=1.0) -> dict:
    """The before/after measurement read through the optical scoring system.

    Every record's boresight roll and pitch, times ``scale``, through
    :func:`optical_scoring`, then measured as the experiment measures them
    (``measure`` over its windows).

    Parameters
    ----------
    off : dict of str to ndarray
        The isolation-off result table (``time``, ``structure.los_misr_roll``,
        ``structure.los_misr_pitch``).
    runs : dict of str to dict
        The isolated runs' tables, per configuration.
    windows : dict
        ``{"before": (t0, t1), "after": (t0, t1)}`` (s).
    measure : callable
        ``measure(t, roll, pitch, t0, t1)``: the boresight RMS over a window (rad;
        :func:`~orchestrator.experiments.testbed_isolation.boresight_rms`).
    scale : float
        Factor on the records (the system is linear: the same test at a larger
        disturbance).

    Returns
    -------
    dict
        ``off_before_arcsec`` (the isolation-off before-window through the OSS, arcsec),
        and per configuration ``paper_way_pct`` and ``two_runs_pct`` (%; None when the
        OSS reads nothing in a window).
    """
    def rms(tab, w):
        t = tab["time"]
        r, p = (optical_scoring(t, scale * tab[f"structure.los_misr_{a}"])
                for a in ("roll", "pitch"))
        return measure(t, r, p, *w)

    ref = rms(off, windows["after"])
    out = {"off_before_arcsec": rms(off, windows["before"]) * ARCSEC_PER_RAD}
    for k, tab in runs.items():
        b, a = rms(tab, windows["before"]), rms(tab, windows["after"])
        out[k] = {"paper_way_pct": 100 * (1 - a / b) if b > 0 else None,
                  "two_runs_pct": 100 * (1 - a / ref) if ref > 0 else None}
    return out
