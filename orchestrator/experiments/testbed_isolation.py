"""Figs. 13-16: EOS Dynamics Testbed, MISR payload isolation against a 22 Hz disturbance.

Co-simulation of ``scenarios/eos_budget.toml`` with the ``swir_cryocooler`` preset at the
SWIR location (22, 44, 66 Hz, vertical) and the MISR strut controllers (the paper's law:
2nd-order Butterworth band-pass 20-60 Hz, two zeros at 100 rad/s, two poles at 1 rad/s,
1 kHz, payload- and bus-side acceleration, each mount independent) switched on at
t = 2.4 s, with isolator mount #3 alone and with all three.  The jitter reduction is
computed from the co-simulated MISR boresight roll and pitch (the gimballed body; the
optical scoring system measures roll and pitch): RMS over the last 1.2 s, isolation on
against a third run with isolation off (the same window, so the start-up transient of the
lightly damped 23 Hz bus mode, still decaying before 2.4 s, does not count as isolation),
after a zero-phase 5 Hz high-pass that removes the slow rigid-body drift of the
free-free model (the suspended testbed has no ACS).  The paper's way, [1.2, 2.4) s before
against the last 1.2 s after switch-on in one run, is reported as well.

Design first, on the linear model (:func:`linear_plant`): the reduced structure of the
FMU (``model.npz``, accelerometers through their 150 Hz low-pass), sampled exactly with a
zero-order hold at 1 kHz, the P-865.10 amplifier (its first-order lag, exact at 1 kHz;
the structure holds its mean force over each step, for the command of that step, as the
piezo FMUs' ``coupling = 1`` gives it), ``f = c h v``
and the discrete law with its Eq. (11) delay (``delayed=False`` in
``ctrlfmu.designs.testbed_isolation`` acts on the current sample instead).  On it:

* :func:`ideal_ceiling` -- the reduction of the boresight if the payload accelerometers at
  the chosen mounts were held at exactly zero at 22, 44 and 66 Hz (perfect cancellation),
  and the least-squares optimum over any strut forces (no controller can do better);
* :func:`gain_margin_db` -- the factor on the gains (all active mounts together) that
  first makes the sampled closed loop unstable, from its eigenvalues;
  :func:`loop_margins_db` adds each loop scaled alone with the others closed (the
  reported margin is the smallest);
* :func:`design_gains` -- the gain direction (payload, bus) that removes the most
  boresight jitter at 6 dB gain margin (the stored gains come from it);
  :func:`design_mount_gains` -- one factor per mount for all three closed;
* :func:`feedforward_bound` -- the most the law's bus path could do as pure feedforward.

``variant="hybrid"`` (``jitterfmu reproduce testbed-isolation --variant hybrid``) runs the
same with mount #3 a hybrid isolator (``eos_testbed.build(iso3="hybrid")``: stack +
elastomer stage, structure FMU ``HYBRID_STRUCTURE``) and the law at ``HYBRID_GAINS`` times
its own gains (docs/eos_experiments.md).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from ctrlfmu.analysis import to_statespace
from ctrlfmu.designs import design
from distfmu.presets import get_preset
from fmukit.units import ARCSEC_PER_RAD
from fmutools import PYTHON_SUBDIR
from fmutools.ensure import ensure_fmus as _ensure
from structfmu.fmuspec import spec_from_model
from structfmu.models import eos_testbed
from structfmu.statespace import first_order

from ..analysis import stability_margin_db
from ..analysis.bounds import best_real_gain, harmonic_ceiling, harmonic_reduction_pct
from ..analysis.frf import (closed_loop_frf, isolation_bandwidth, modal_frequency_response,
                            statespace_response, transmissibility_bands)
from ..analysis.margins import (best_direction, is_stable, loop_gain_margins_db,
                                poles_outside, scaled_to_margins)
from ..analysis.sampled import (amplified, amplifier_step, feedback_channels, packed_model,
                                zoh)
from ..run import run_scenario
from . import eos
from . import verdicts as vd
from .figures import testbed_figure

NAME = "testbed-isolation"
DESCRIPTION = "Figs. 13-16: MISR active isolator struts against a 22 Hz SWIR-location " \
              "disturbance, switched on at 2.4 s"

T_ON = 2.4
DT = 1e-3
#: Multiplier of the design's gains (ctrlfmu.designs.TESTBED_ISOLATION_GAINS, the mount-#3
#: design) per configuration: 1 for mount #3 alone (6 dB margin); for all three mounts one
#: factor per mount (iso1, iso2, iso3), each mount independent as in the paper, from
#: design_mount_gains (every loop closed; 6 dB with the three scaled together and with
#: each scaled alone, the others closed), on the step-mean coupling.
GAINS = {"mount3": 1.0, "all_mounts": (0.262, -0.105, 1.049)}
#: The same for the hybrid mount #3 (``variant="hybrid"``: ``eos_testbed.build(iso3=
#: "hybrid")``, its stack in series with an elastomer stage): the design law (the stiff
#: strut's gain direction) at the largest factor of 0.05 steps that keeps 6 dB on the
#: hybrid plant (6.2 dB at 2.95); all three mounts from design_mount_gains as above.  The
#: elastomer was calibrated (stiffness, loss factor) with the earlier coupling and law
#: direction to give the paper's 80 %; in its own best direction the hybrid plant allows
#: much more (docs/eos_experiments.md).
HYBRID_GAINS = {"mount3": 2.95, "all_mounts": (-0.313, 0.313, 3.134)}
HYBRID_STRUCTURE = "eos_testbed_hybrid_structure"
VARIANTS = ("stiff", "hybrid")
MOUNTS = {"mount3": (3,), "all_mounts": (1, 2, 3)}
#: Disturbance harmonics of the ``swir_cryocooler`` preset (Hz: N, full scale).
HARMONICS = {get_preset("swir_cryocooler").source.frequency * k: a
             for k, a in enumerate(get_preset("swir_cryocooler").source.amplitudes, 1)}
HP_HZ = 5.0
FREQS = np.geomspace(5.0, 300.0, 160)
PAPER = {"mount3": 80.0, "all_mounts": (50.0, 80.0), "bandwidth_hz": 45.0}
_SENSORS = [f"acc_{s}_iso{i}" for i in (1, 2, 3) for s in ("pay", "bus")]
_OUT = _SENSORS + ["los_misr_roll", "los_misr_pitch", "acc_pay_iso3"]
_IN = ["fc_iso1", "fc_iso2", "fc_iso3", "swir_fz"]


# -- linear model ------------------------------------------------------------------------
def hybrid_model():
    """Reduced EOS testbed with the hybrid mount #3 (``ReducedModel``)."""
    return eos_testbed.reduced(truss=eos_testbed.build(iso3="hybrid"))


def ensure_fmus(fmu_dir="fmus", variant="stiff", kind="native") -> Path:
    """Build the FMUs of the experiment (``kind`` "native" or "python"; for
    ``variant="hybrid"`` also the structure with the hybrid mount #3,
    ``HYBRID_STRUCTURE``) into ``fmu_dir``; the folder, resolved."""
    if variant not in VARIANTS:
        raise ValueError(f"variant is {variant!r}; testbed-isolation takes one of "
                         f"{', '.join(VARIANTS)}")
    fdir = eos.ensure_fmus(fmu_dir, kind=kind)
    if variant == "hybrid":
        _ensure([HYBRID_STRUCTURE], fdir, extra={
            HYBRID_STRUCTURE: lambda: spec_from_model(
                hybrid_model(), HYBRID_STRUCTURE,
                "EOS testbed, MISR mount #3 a hybrid isolator (stack + elastomer)")},
                kind=kind)
    return fdir


def linear_model(fmu_dir="fmus", variant="stiff"):
    """The reduced structure the structure FMU of ``variant`` (``eos.STRUCTURE``, or
    ``HYBRID_STRUCTURE``) packs, built into ``fmu_dir`` first if needed
    (:func:`orchestrator.analysis.sampled.packed_model` of its Python build)."""
    name = HYBRID_STRUCTURE if variant == "hybrid" else eos.STRUCTURE
    return packed_model(ensure_fmus(fmu_dir, variant) / PYTHON_SUBDIR / f"{name}.fmu")


def linear_plant(model, coupling=1):
    """Sampled structure + amplifier, inputs strut commands (V) and SWIR force (N).

    The FMU's structure (all its outputs, accelerometer low-pass included) sampled
    exactly (:func:`orchestrator.analysis.sampled.zoh`), the P-865.10 in series with
    each strut (:func:`~orchestrator.analysis.sampled.amplified`; ``coupling`` 1, the
    piezo FMUs' default: the structure holds the amplifier's mean force over the step
    for the command of that step; 0: the force at the end of the last step).

    Returns
    -------
    control.StateSpace
        Discrete (1 kHz) system; inputs ``v_iso1..3`` (V, amplifier commands) and
        ``swir_fz`` (N); outputs the six MISR strut accelerometers (payload, bus per
        strut, m/s^2), ``los_misr_roll``, ``los_misr_pitch`` (rad) and ``acc_pay_iso3``.
    """
    # deferred: python-control takes about 1 s to load
    import control

    A, B, C, D = first_order(model)
    ins, outs = list(model.input_names), list(model.output_names)
    ii = [ins.index(n) for n in _IN]
    oo = [outs.index(n) for n in _OUT]
    Ad, Bd = zoh(A, B[:, ii], DT)
    G = control.ss(Ad, Bd, C[oo], D[np.ix_(oo, ii)], DT)
    ch = [model.meta["actuators"][f"iso{k}"]["ch"] for k in (1, 2, 3)]
    return amplified(G, ch, amplifier_step("P-865.10", DT, coupling))


def _law(gain):
    # deferred: python-control takes about 1 s to load
    import control

    law = to_statespace(design("testbed_isolation"))
    return control.ss(law.A, law.B, gain * law.C, gain * law.D, DT)


def per_mount(gain) -> tuple:
    """``gain`` as one factor per mount (iso1, iso2, iso3): a number is the same factor at
    every mount, a sequence of three is one factor each (each mount independent)."""
    g = tuple(float(x) for x in np.atleast_1d(gain))
    if len(g) == 1:
        return g * 3
    if len(g) != 3:
        raise ValueError(f"gain has {len(g)} factors; give one, or one per mount (3)")
    return g


def _laws(gain, law):
    """One discrete law per mount: ``law`` (one for all, or a sequence of three) or the
    design law times each mount's factor of ``gain``."""
    if law is None:
        return [_law(g) for g in per_mount(gain)]
    return list(law) if isinstance(law, (list, tuple)) else [law] * 3


def closed_loop(plant, mounts, gain=1.0, law=None):
    """:func:`linear_plant` with the isolation law closed on the ``mounts`` (1, 2, 3)
    struts, payload and bus acceleration in, strut command out (positive feedback,
    :func:`orchestrator.analysis.sampled.feedback_channels`): ``law`` (a discrete
    python-control system, or one per mount), by default the design law (Eq. 11 delay
    included) times ``gain`` (one factor, or one per mount: :func:`per_mount`)."""
    return feedback_channels(plant, _laws(gain, law), mounts)


def gain_margin_db(plant, mounts, gain=1.0, law=None, max_factor=64.0) -> float:
    """Gain margin (dB) of the loops on ``mounts``, scaled together: the largest factor
    (doubled from 1 up to ``max_factor``, then bisection to 0.5 %) at which the sampled
    closed loop is still stable (``20 log10(max_factor)`` past it, ``-inf`` if the
    nominal loop is unstable); ``gain``, ``law`` as in :func:`closed_loop`."""
    base = _laws(gain, law)

    def stable(g):
        # deferred: python-control takes about 1 s to load
        import control
        scaled = [control.ss(b.A, b.B, g * b.C, g * b.D, DT) for b in base]
        return is_stable(closed_loop(plant, mounts, law=scaled).A)

    return stability_margin_db(stable, 2.0, max_factor, 1.005, 20 * np.log10(max_factor))


def loop_margins_db(plant, mounts, gain=1.0) -> dict:
    """Gain margins (dB) of the closed ``mounts``: all loops scaled together (``"all"``)
    and, with more than one, each scaled alone with the others closed (``"iso<k>"``)
    (:func:`orchestrator.analysis.margins.loop_gain_margins_db`)."""
    return loop_gain_margins_db(lambda g: is_stable(closed_loop(plant, mounts, g).A),
                                per_mount(gain), mounts, prefix="iso")


def limiting_modes(plant, mounts, gain=1.0, margin_db=None) -> list:
    """The closed-loop poles outside the unit circle with every loop scaled by its gain
    margin plus 0.1 dB (:func:`orchestrator.analysis.margins.poles_outside`): the modes
    that set the margin."""
    gm = gain_margin_db(plant, mounts, gain) if margin_db is None else margin_db
    f = 10 ** ((gm + 0.1) / 20)
    return poles_outside(closed_loop(plant, mounts, [f * x for x in per_mount(gain)]).A, DT)


def plant_frf(plant, freqs) -> np.ndarray:
    """Frequency response of :func:`linear_plant` at ``freqs`` (Hz), shape (n_freq, 9, 4):
    outputs (m/s^2, rad) per input (V, N)."""
    return statespace_response(plant, freqs)


def accel_frf(plant, freqs) -> np.ndarray:
    """:func:`plant_frf` from one eigendecomposition, the angle rows NaN, shape
    (n_freq, 9, 4) (:func:`orchestrator.analysis.frf.modal_frequency_response`: the
    rigid-body Jordan blocks spoil the angles; the accelerations agree to 1e-8)."""
    H = modal_frequency_response(*(np.asarray(m) for m in (plant.A, plant.B, plant.C)),
                                 freqs, DT, np.asarray(plant.D))
    H[:, 6:8] = np.nan
    return H


def closed_frf(Gf, law_f, mounts) -> np.ndarray:
    """Closed-loop response to ``swir_fz`` (n_freq, 9) from :func:`plant_frf` ``Gf`` and
    the law's response ``law_f`` (n_freq, 1 or 3, 2: the same at every mount, or row
    ``k - 1`` at mount ``k``; :func:`law_frf`) on the ``mounts``
    (:func:`orchestrator.analysis.frf.closed_loop_frf`)."""
    K = np.zeros((len(Gf), 3, 6), complex)
    for m in mounts:
        K[:, m - 1, 2 * (m - 1):2 * m] = law_f[:, (m - 1) % law_f.shape[1]]
    return closed_loop_frf(Gf, K, 6, 3, 3)


def law_frf(freqs, gain=1.0, law=None) -> np.ndarray:
    """Response of the isolation law at each mount (``gain``, ``law`` as in
    :func:`closed_loop`), shape (n_freq, 3, 2): strut command of mount ``k`` (row
    ``k - 1``) per payload and per bus acceleration (V per m/s^2)."""
    return np.concatenate([statespace_response(w, freqs) for w in _laws(gain, law)], axis=1)


def boresight_reduction(plant, mounts, gain=1.0, law=None, Gh=None) -> float:
    """Steady-state reduction (%) of the boresight RMS (roll, pitch) over ``HARMONICS``,
    weighted by their amplitudes (:func:`orchestrator.analysis.bounds.
    harmonic_reduction_pct`); ``Gh``: :func:`plant_frf` at ``HARMONICS``."""
    f = np.array(list(HARMONICS))
    Gh = plant_frf(plant, f) if Gh is None else Gh
    yc = closed_frf(Gh, law_frf(f, gain, law), mounts)
    return harmonic_reduction_pct(Gh[:, 6:8, 3], yc[:, 6:8], list(HARMONICS.values()))


def ideal_ceiling(plant, mounts, Gh=None) -> dict:
    """Most any controller at the ``mounts`` struts could remove from the boresight (%,
    :func:`orchestrator.analysis.bounds.harmonic_ceiling` at ``HARMONICS``):
    ``accel_null`` holds their payload accelerometers at zero, ``optimal`` is the
    least-squares best strut commands."""
    cols = [k - 1 for k in mounts]
    rows = [2 * (k - 1) for k in mounts]
    Gh = plant_frf(plant, list(HARMONICS)) if Gh is None else Gh
    c = harmonic_ceiling(Gh[:, 6:8, 3], Gh[:, 6:8][:, :, cols], list(HARMONICS.values()),
                         Gh[:, rows, 3], Gh[:, rows][:, :, cols])
    return {"accel_null": c["cancel"], "optimal": c["optimal"]}


def _design_law(kp, kb, delayed=True):
    return to_statespace(design("testbed_isolation", payload_gain=kp, bus_gain=kb,
                                delayed=delayed))


def design_gains(plant, mounts, n_dir=36, margin_db=6.0, delayed=True):
    """Best (payload, bus) gains at ``margin_db`` gain margin over ``n_dir`` directions
    (:func:`orchestrator.analysis.margins.best_direction`; slow: ~n_dir x 12 eigs);
    ``(reduction %, payload, bus)``, ``delayed=False``: the law without its Eq. (11)
    sample."""
    # unit gains: 100 V per m/s^2 is already unstable in every direction on the stiff
    # model (gain_margin_db then gives -inf and the scan returned zeros)
    return best_direction(
        lambda kp, kb: gain_margin_db(plant, mounts, law=_design_law(kp, kb, delayed),
                                      max_factor=1e6),
        lambda kp, kb: boresight_reduction(plant, mounts, law=_design_law(kp, kb, delayed)),
        n_dir, margin_db)


def feedforward_bound(plant, mount=3, Gh=None) -> float:
    """Most the stated law could remove (%) as pure feedforward of the bus-side
    accelerometer of ``mount``: its shape on the *open-loop* bus acceleration times the
    best real gain of either sign (:func:`orchestrator.analysis.bounds.best_real_gain`),
    the harmonics weighted as in :func:`boresight_reduction`; whatever the margin."""
    f = np.array(list(HARMONICS))
    a = np.array(list(HARMONICS.values()))
    Gh = plant_frf(plant, f) if Gh is None else Gh
    c = statespace_response(_design_law(0.0, 1.0), f)[:, 0, 1]
    # boresight with gain k: b + k e, e = G_yu c a_bus
    b = (a[:, None] * Gh[:, 6:8, 3]).ravel()
    e = (a[:, None] * Gh[:, 6:8, mount - 1] * (c * Gh[:, 2 * mount - 1, 3])[:, None]).ravel()
    return best_real_gain(b, e)[1]


#: Relative factors of iso1 and iso2 (to mount #3's) that :func:`design_mount_gains` scans;
#: no zero, so that "all three mounts" has all three loops closed.
MOUNT_RATIOS = (-1.0, -0.5, -0.25, -0.1, 0.1, 0.25, 0.5, 1.0)


def design_mount_gains(plant, gain3=1.0, ratios=MOUNT_RATIOS, margin_db=6.0, Gh=None):
    """Per-mount factors for all three loops closed, each mount independent (slow).

    For every pair ``(r1, r2)`` of ``ratios`` the factors ``(r1, r2, 1) gain3`` are
    scaled until every margin of :func:`loop_margins_db` is at least ``margin_db``
    (:func:`orchestrator.analysis.margins.scaled_to_margins`); the pair removing the most
    boresight jitter wins: ``(reduction %, factors)``, ``(-inf, (0, 0, 0))`` if none.
    """
    Gh = plant_frf(plant, list(HARMONICS)) if Gh is None else Gh
    best = (-np.inf, (0.0, 0.0, 0.0))
    for r1 in ratios:
        for r2 in ratios:
            g = scaled_to_margins(
                np.array([r1, r2, 1.0]) * gain3,
                lambda g: gain_margin_db(plant, (1, 2, 3), g, max_factor=1e6),
                lambda g: loop_margins_db(plant, (1, 2, 3), g), margin_db)
            if g is not None:
                best = max(best, (boresight_reduction(plant, (1, 2, 3), g, Gh=Gh), g))
    return best


def loop_shape(Gf, freqs=FREQS, mount=3) -> dict:
    """Why payload-acceleration feedback through the stated law stays weak at 22 Hz.

    The loop ``L`` (law with unit payload gain and no bus gain x amplifier x structure,
    the other mounts open; positive-feedback convention, ``L = -|L|`` attenuates) at
    22 Hz, the first frequency above 30 Hz where its phase crosses 0 (there ``|L| = 1`` is
    the stability limit), ``|L|`` there, their ratio, and ``|L(22 Hz)|`` at 6 dB gain
    margin (``0.5 / ratio``).  ``Gf``: :func:`plant_frf` or :func:`accel_frf` at
    ``freqs`` (Hz, ascending).
    """
    rows = [2 * (mount - 1), 2 * (mount - 1) + 1]
    lf = statespace_response(_design_law(1.0, 0.0), freqs)
    vals = np.array([(k @ g[rows, mount - 1])[0] for k, g in zip(lf, Gf)])
    l22 = np.interp(22.0, freqs, vals.real) + 1j * np.interp(22.0, freqs, vals.imag)
    cross = np.flatnonzero((freqs > 30.0)[1:] & (np.sign(vals.imag[1:]) != np.sign(vals.imag[:-1]))
                           & (vals.real[1:] > 0))
    if not cross.size:
        return {"loop_phase_22hz_deg": float(np.degrees(np.angle(l22))),
                "phase_crossover_hz": None}
    lc = abs(vals[cross[0] + 1])
    ratio = float(lc / abs(l22))
    return {"loop_phase_22hz_deg": float(np.degrees(np.angle(l22))),
            "phase_crossover_hz": float(freqs[cross[0] + 1]),
            "crossover_to_22hz_ratio": ratio, "max_loop_gain_22hz_at_6db": 0.5 / ratio}


def frequency_responses(Gf, mounts, gain, freqs=FREQS):
    """Accelerometer #6 (payload side of mount #3) per SWIR vertical force, open (row 0)
    and closed loop (row 1), (m/s^2)/N, shape (2, n_freq) complex; ``Gf`` from
    :func:`plant_frf` or :func:`accel_frf` at ``freqs``."""
    return np.array([Gf[:, 8, 3], closed_frf(Gf, law_frf(freqs, gain), mounts)[:, 8]])



# -- co-simulation -----------------------------------------------------------------------
def _scenario(variant):
    """``scenarios/eos_budget.toml``; for the hybrid variant with its structure FMU."""
    if variant == "stiff":
        return eos.SCENARIO
    sc = tomllib.loads(Path(eos.SCENARIO).read_text())
    sc["fmus"]["structure"] = {**sc["fmus"]["structure"], "fmu": HYBRID_STRUCTURE}
    return sc


def _cosim(fmu_dir, mounts, gain, stop, variant="stiff", fmu_kind="native"):
    ov = {"dist_swir.preset": "swir_cryocooler"}
    for i, g in zip((1, 2, 3), per_mount(gain)):
        ov[f"ctrl_iso{i}.gain"] = g if i in mounts else 0.0
        ov[f"ctrl_iso{i}.t_on"] = T_ON
    return run_scenario(_scenario(variant), stop_time=stop, overrides=ov,
                        fmu_dir=fmu_dir, fmu_kind=fmu_kind).table


def _highpassed(t, x):
    # deferred: scipy takes about 1 s to load
    from scipy.signal import butter, sosfiltfilt

    sos = butter(2, HP_HZ, "highpass", fs=1.0 / (t[1] - t[0]), output="sos")
    return sosfiltfilt(sos, x)


def boresight_rms(t, roll, pitch, t0, t1):
    """RMS ``sqrt(mean(roll^2 + pitch^2))`` (rad) over [t0, t1) (s) of the boresight
    angles (rad) at the equally spaced times ``t`` (s), after a zero-phase 2nd-order
    Butterworth high-pass at ``HP_HZ`` (5 Hz) of the whole record."""
    m = (t >= t0) & (t < t1)
    r, p = _highpassed(t, roll), _highpassed(t, pitch)
    return float(np.sqrt(np.mean(r[m] ** 2 + p[m] ** 2)))


def _off_rms(Gh):
    """Steady isolation-off boresight RMS (arcsec) of the linear model over the harmonics."""
    a = np.array(list(HARMONICS.values()))
    return float(np.sqrt(np.sum(a[:, None] ** 2 * np.abs(Gh[:, 6:8, 3]) ** 2) / 2)
                 * ARCSEC_PER_RAD)


def testbed_verdicts(data) -> list:
    """One verdict per Figs. 13-15 target (:mod:`orchestrator.experiments.verdicts`).

    The paper reads its reductions the way Fig. 15 shows them: the boresight jitter
    before and after the switch-on at 2.4 s in one run, so the verdicts compare that
    (``before_after_reduction_pct``); the two-run measure (the last 1.2 s against an
    isolation-off run, which removes the isolation-off run's own decay between the two
    windows) is reported beside it in each verdict as ``two_runs``.  ``data``:
    :func:`compute`'s result.
    """
    ba, red = data["before_after"], data["reduction"]
    lo, hi = PAPER["all_mounts"]
    out = [vd.about("Fig. 15: mount #3 alone, boresight jitter reduction", PAPER["mount3"],
                    ba["mount3"]["before_after_reduction_pct"]),
           vd.between("tests overall (all three mounts), boresight jitter reduction", lo, hi,
                      ba["all_mounts"]["before_after_reduction_pct"]),
           vd.about("Fig. 13: isolation bandwidth, mount #3", PAPER["bandwidth_hz"],
                    data["bandwidth"], "Hz")]
    out[0]["two_runs"] = red["mount3"]
    out[1]["two_runs"] = red["all_mounts"]
    return out


def compute(quick=False, fmu_dir="fmus", variant="stiff", fmu_kind="native"):
    """Linear design numbers and the two co-simulations (mount #3, all mounts); the
    arguments as :func:`run`'s.

    Returns
    -------
    dict
        ``runs`` (per configuration, ``"mount3"`` and ``"all_mounts"``, its result table,
        dict of str to ndarray), ``off`` (the table with isolation off), ``stop`` (s),
        ``reduction`` (%), ``before_after`` (arcsec RMS, %), ``max_voltage`` (V),
        ``linear`` (the smallest of :func:`loop_margins_db` and all of them, in dB,
        reduction in %, :func:`ideal_ceiling`), ``frf``
        (:func:`frequency_responses` at ``FREQS``), ``ratio`` (open/closed, mount #3),
        ``bandwidth`` (Hz or None), ``loop_shape``, ``gains``, ``feedforward_bound_pct``
        (%, :func:`feedforward_bound` at mount #3) and
        ``off_linear_full_scale_arcsec_rms`` (arcsec).
    """
    fdir = ensure_fmus(fmu_dir, variant, fmu_kind)
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
                  "ceiling": ideal_ceiling(plant, mounts, Gh=Gh)}
    Gf = accel_frf(plant, FREQS)
    frf = {k: frequency_responses(Gf, MOUNTS[k], gains[k]) for k in MOUNTS}
    ratio = np.abs(frf["mount3"][0]) / np.abs(frf["mount3"][1])
    bw = isolation_bandwidth(FREQS, ratio, 22.0)
    shape = loop_shape(Gf)
    ff = feedforward_bound(plant, 3, Gh)
    stop = 6.0 if quick else 9.6
    runs = {k: _cosim(fdir, MOUNTS[k], gains[k], stop, variant, fmu_kind) for k in MOUNTS}
    off = _cosim(fdir, (), 0.0, stop, variant, fmu_kind)
    t = off["time"]
    ref = boresight_rms(t, off["structure.los_misr_roll"], off["structure.los_misr_pitch"],
                        stop - 1.2, stop)
    red, before_after, vmax = {}, {}, {}
    for k, tab in runs.items():
        r, p = tab["structure.los_misr_roll"], tab["structure.los_misr_pitch"]
        b = boresight_rms(t, r, p, T_ON - 1.2, T_ON)
        a = boresight_rms(t, r, p, stop - 1.2, stop)
        before_after[k] = {"before_arcsec_rms": b * ARCSEC_PER_RAD,
                           "after_arcsec_rms": a * ARCSEC_PER_RAD,
                           "before_after_reduction_pct": 100.0 * (1.0 - a / b)}
        red[k] = 100.0 * (1.0 - a / ref)
        vmax[k] = float(max(np.abs(tab[f"piezo_iso{i}.voltage"]).max() for i in (1, 2, 3)))
    before_after["off"] = {"after_arcsec_rms": ref * ARCSEC_PER_RAD}
    return {"runs": runs, "off": off, "stop": stop, "reduction": red, "before_after": before_after,
            "max_voltage": vmax, "linear": lin, "frf": frf, "ratio": ratio,
            "bandwidth": bw, "loop_shape": shape, "gains": gains, "feedforward_bound_pct": ff,
            "limiting": limiting,
            "off_linear_full_scale_arcsec_rms": _off_rms(Gh)}


def run(out_dir, quick: bool = False, fmu_dir="fmus", variant="stiff",
        fmu_kind="native") -> dict:
    """Run the experiment into ``out_dir`` (figure ``testbed-isolation.png``, the hybrid
    variant ``testbed-isolation-hybrid.png``); the JSON-able result: co-simulated and
    linear reductions (%), gain margins (dB), isolation bandwidth (Hz), strut voltages
    (V), boresight RMS (arcsec), the paper's values, ``reproduced`` and a ``note``.

    ``quick``: 6.0 s instead of 9.6 s of co-simulation (the last 1.2 s are measured: 2.4 s
    or 6 s after switch-on; the 23 Hz bus mode, 0.5 % damped, settles in about 1.4 s);
    the FMUs are built into ``fmu_dir`` when missing or stale and run as ``fmu_kind``
    ("native" or "python", ``--python-fmus``); ``variant``: the stiff struts as
    documented, or the hybrid mount #3 (``eos_testbed.build(iso3="hybrid")``, gains
    ``HYBRID_GAINS``).
    """
    data = compute(quick, fmu_dir, variant, fmu_kind)
    testbed_figure(data, out_dir, "testbed-isolation" + ("-hybrid" if variant == "hybrid" else ""))
    red, lin = data["reduction"], data["linear"]
    verdicts = testbed_verdicts(data)
    reproduced = vd.all_reproduced(verdicts)
    ceil = {k: lin[k]["ceiling"]["accel_null"] for k in MOUNTS}
    ba = data["before_after"]
    lim = data["limiting"]["mount3"]
    lim_txt = (f"a closed-loop pole at {lim[0]['freq_hz']:.1f} Hz" if lim
               else "no pole found")
    words = "; ".join(f"{v['target']}: {v['ours']:.1f} {v['unit']} (paper {v['paper']}, "
                      f"{'reproduced' if v['reproduced'] else 'missed'})" for v in verdicts)
    if variant == "hybrid":
        note = (f"{words}.  Hybrid mount #3 (stack + elastomer, build(iso3='hybrid'); its "
                f"elastomer stiffness and loss factor were calibrated, on the earlier "
                f"coupling and law direction, to give the paper's 80 %): the stated law in "
                f"the stiff design's direction at the largest factor that keeps 6 dB "
                f"removes {red['mount3']:.0f} % in two runs, "
                f"{ba['mount3']['before_after_reduction_pct']:.0f} % the paper's way "
                f"(linear {lin['mount3']['reduction_pct']:.0f} %); a law designed in "
                f"its own best direction does much better (docs/eos_experiments.md).")
    else:
        note = (f"{words}.  Mount #3 is in the dominant 22 Hz path (holding its payload "
                f"accelerometer at zero would remove {ceil['mount3']:.0f} %, the "
                f"least-squares best strut force {lin['mount3']['ceiling']['optimal']:.0f} %), "
                f"and the stated law at 6 dB removes {lin['mount3']['reduction_pct']:.0f} % "
                f"on the linear model ({red['mount3']:.0f} % co-simulated, two runs; "
                f"{ba['mount3']['before_after_reduction_pct']:.0f} % the paper's way, "
                f"before and after switch-on in one run, which also counts the "
                f"isolation-off run's own decay).  That is what the law's bus path gives as "
                f"pure feedforward with the best real gain "
                f"({data['feedforward_bound_pct']:.0f} %): the law is a feedforward whose "
                f"phase at the harmonics, not its margin, limits it.  The 6 dB margin is "
                f"set by {lim_txt} (the 0.5 %-damped bus modes there).")
    return {
        "verdicts": verdicts,
        "jitter_reduction_pct": red,
        "paper_way_reduction_pct": {k: data["before_after"][k]["before_after_reduction_pct"]
                                    for k in MOUNTS},
        "margin_limiting_poles": data["limiting"],
        "ideal_ceiling_pct": ceil,
        "optimal_bound_pct": {k: lin[k]["ceiling"]["optimal"] for k in MOUNTS},
        "linear_reduction_pct": {k: lin[k]["reduction_pct"] for k in MOUNTS},
        "gain_margin_db": {k: lin[k]["gain_margin_db"] for k in MOUNTS},
        "loop_gain_margins_db": {k: lin[k]["loop_gain_margins_db"] for k in MOUNTS},
        "isolation_bandwidth_hz": data["bandwidth"],
        "loop_shape_mount3": data["loop_shape"],
        "feedforward_bound_mount3_pct": data["feedforward_bound_pct"],
        "max_voltage_v": max(data["max_voltage"].values()),
        "max_strut_voltage_v": data["max_voltage"],
        "boresight_rms": data["before_after"],
        "gain": data["gains"],
        "variant": variant,
        "off_linear_full_scale_arcsec_rms": data["off_linear_full_scale_arcsec_rms"],
        "t_on_s": T_ON,
        "paper": {"jitter_reduction_pct": {"mount3": PAPER["mount3"],
                                           "all_mounts": list(PAPER["all_mounts"])},
                  "isolation_bandwidth_hz": PAPER["bandwidth_hz"]},
        "reproduced": reproduced,
        "note": note,
        "transmissibility": {"freq_hz": FREQS, "mount3": data["ratio"]},
        "transmissibility_bands_mount3": transmissibility_bands(FREQS, data["ratio"]),
    }
