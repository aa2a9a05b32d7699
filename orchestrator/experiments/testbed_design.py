"""The testbed isolation's linear design: the sampled plant, its loops and their bounds.

What :mod:`orchestrator.experiments.testbed_isolation` computes before any co-simulation,
as calls into the engine (:mod:`orchestrator.analysis.sampled`, ``.margins``, ``.frf``,
``.bounds``): the reduced structure of the FMU (``model.npz``, accelerometers through
their 150 Hz low-pass), sampled exactly with a zero-order hold at 1 kHz, the P-865.10
amplifier in series with each MISR strut, and the discrete isolation law with its
Eq. (11) delay closed on one or more mounts; gain margins, the upper bound on the
reduction (and the accelerometer null) at the disturbance harmonics, the best gain
directions and per-mount factors, the law's bus path as feedforward and the loop shape
at 22 Hz.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ctrlfmu.analysis import to_statespace
from ctrlfmu.designs import design
from distfmu.presets import get_preset
from fmutools import PYTHON_SUBDIR
from fmutools.ensure import ensure_fmus as _ensure
from structfmu.fmuspec import spec_from_model
from structfmu.models import eos_testbed
from structfmu.statespace import first_order

from ..analysis import stability_margin_db
from ..analysis.bounds import best_real_gain, harmonic_ceiling, harmonic_reduction_pct
from ..analysis.frf import closed_loop_frf, modal_frequency_response, statespace_response
from ..analysis.margins import (best_direction, is_stable, loop_gain_margins_db,
                                poles_outside, scaled_to_margins)
from ..analysis.sampled import (amplified, amplifier_step, feedback_channels, packed_model,
                                zoh)
from . import eos

DT = 1e-3
HYBRID_STRUCTURE = "eos_testbed_hybrid_structure"
VARIANTS = ("stiff", "hybrid")
#: Disturbance harmonics of the ``swir_cryocooler`` preset (Hz: N, full scale).
HARMONICS = {get_preset("swir_cryocooler").source.frequency * k: a
             for k, a in enumerate(get_preset("swir_cryocooler").source.amplitudes, 1)}
FREQS = np.geomspace(5.0, 300.0, 160)
_SENSORS = [f"acc_{s}_iso{i}" for i in (1, 2, 3) for s in ("pay", "bus")]
_OUT = _SENSORS + ["los_misr_roll", "los_misr_pitch", "acc_pay_iso3"]
_IN = ["fc_iso1", "fc_iso2", "fc_iso3", "swir_fz"]


# -- linear model ------------------------------------------------------------------------
def hybrid_model():
    """Reduced EOS testbed with the hybrid mount #3 (``ReducedModel``)."""
    return eos_testbed.reduced(truss=eos_testbed.build(iso3="hybrid"))


def ensure_fmus(fmu_dir="fmus", variant="stiff", kind="native") -> Path:
    """Build the FMUs of the experiment into ``fmu_dir`` (for ``variant="hybrid"`` also
    the structure with the hybrid mount #3, ``HYBRID_STRUCTURE``); the folder, resolved.

    Parameters
    ----------
    fmu_dir : path-like
        Folder of the FMUs (those missing or stale are built there).
    variant : str
        ``"stiff"`` or ``"hybrid"`` (``VARIANTS``).
    kind : str
        Build ``"native"`` or ``"python"`` FMUs.
    """
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
    (:func:`orchestrator.analysis.sampled.packed_model` of its Python build).

    Parameters
    ----------
    fmu_dir : path-like
        Folder of the FMUs (:func:`ensure_fmus`).
    variant : str
        ``"stiff"`` or ``"hybrid"`` (``VARIANTS``).
    """
    name = HYBRID_STRUCTURE if variant == "hybrid" else eos.STRUCTURE
    return packed_model(ensure_fmus(fmu_dir, variant) / PYTHON_SUBDIR / f"{name}.fmu")


def linear_plant(model, coupling=1):
    """Sampled structure + amplifier, inputs strut commands (V) and SWIR force (N).

    The FMU's structure (all its outputs, accelerometer low-pass included) sampled
    exactly (:func:`orchestrator.analysis.sampled.zoh`), the P-865.10 in series with
    each strut (:func:`~orchestrator.analysis.sampled.amplified`; ``coupling`` 1, the
    piezo FMUs' default: the structure holds the amplifier's mean force over the step
    for the command of that step; 0: the force at the end of the last step).

    Parameters
    ----------
    model : ReducedModel
        The reduced structure (:func:`linear_model`, :func:`hybrid_model`).
    coupling : int
        1: the amplifier's mean force over each step acts on the structure; 0: its force at
        the end of the last step.

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
    """:func:`linear_plant` with the isolation law closed on the ``mounts`` struts,
    payload and bus acceleration in, strut command out (positive feedback,
    :func:`orchestrator.analysis.sampled.feedback_channels`): ``law``, by default the design
    law (Eq. 11 delay included) times ``gain``; the closed loop (``control.StateSpace``,
    the plant's inputs and outputs).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    mounts : sequence of int
        The mounts whose loops are closed (1, 2, 3).
    gain : float or sequence of float
        Factor (-) on the design law's gains: one for every mount, or one per mount
        (iso1, iso2, iso3; :func:`per_mount`); unused when ``law`` is given.
    law : control.StateSpace or sequence of control.StateSpace, optional
        Discrete law (acceleration in m/s^2, payload and bus, to strut command in V): one for
        every mount, or one per mount; default the design law times ``gain``.
    """
    return feedback_channels(plant, _laws(gain, law), mounts)


def gain_margin_db(plant, mounts, gain=1.0, law=None, max_factor=64.0) -> float:
    """Gain margin (dB) of the loops on ``mounts``, scaled together: the largest factor
    (doubled from 1 up to ``max_factor``, then bisection to 0.5 %) at which the sampled
    closed loop is still stable (``20 log10(max_factor)`` past it, ``-inf`` if the
    nominal loop is unstable).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    mounts : sequence of int
        The mounts whose loops are closed (1, 2, 3).
    gain : float or sequence of float
        Factor (-) on the design law's gains: one for every mount, or one per mount
        (iso1, iso2, iso3; :func:`per_mount`); unused when ``law`` is given.
    law : control.StateSpace or sequence of control.StateSpace, optional
        Discrete law (acceleration in m/s^2, payload and bus, to strut command in V): one for
        every mount, or one per mount; default the design law times ``gain``.
    max_factor : float
        Largest factor on the gains searched (-).
    """
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
    (:func:`orchestrator.analysis.margins.loop_gain_margins_db`).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    mounts : sequence of int
        The mounts whose loops are closed (1, 2, 3).
    gain : float or sequence of float
        Factor (-) on the design law's gains: one for every mount, or one per mount
        (iso1, iso2, iso3; :func:`per_mount`).
    """
    return loop_gain_margins_db(lambda g: is_stable(closed_loop(plant, mounts, g).A),
                                per_mount(gain), mounts, prefix="iso")


def limiting_modes(plant, mounts, gain=1.0, margin_db=None) -> list:
    """The closed-loop poles outside the unit circle with every loop scaled by its gain
    margin plus 0.1 dB (:func:`orchestrator.analysis.margins.poles_outside`, list of
    dict): the modes that set the margin.

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    mounts : sequence of int
        The mounts whose loops are closed (1, 2, 3).
    gain : float or sequence of float
        Factor (-) on the design law's gains: one for every mount, or one per mount
        (iso1, iso2, iso3; :func:`per_mount`).
    margin_db : float, optional
        The loops' gain margin (dB) when already known; default :func:`gain_margin_db`.
    """
    gm = gain_margin_db(plant, mounts, gain) if margin_db is None else margin_db
    f = 10 ** ((gm + 0.1) / 20)
    return poles_outside(closed_loop(plant, mounts, [f * x for x in per_mount(gain)]).A, DT)


def plant_frf(plant, freqs) -> np.ndarray:
    """Frequency response of :func:`linear_plant` at ``freqs``, shape (n_freq, 9, 4)
    complex: outputs (m/s^2, rad) per input (V, N).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) system: :func:`linear_plant`, or :func:`closed_loop` of it.
    freqs : array_like, shape (n_freq,)
        Frequencies (Hz).
    """
    return statespace_response(plant, freqs)


def accel_frf(plant, freqs) -> np.ndarray:
    """:func:`plant_frf` from one eigendecomposition, the angle rows NaN, shape
    (n_freq, 9, 4) (:func:`orchestrator.analysis.frf.modal_frequency_response`: the
    rigid-body Jordan blocks spoil the angles; the accelerations agree to 1e-8).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    freqs : array_like, shape (n_freq,)
        Frequencies (Hz).
    """
    H = modal_frequency_response(*(np.asarray(m) for m in (plant.A, plant.B, plant.C)),
                                 freqs, DT, np.asarray(plant.D))
    H[:, 6:8] = np.nan
    return H


def closed_frf(Gf, law_f, mounts) -> np.ndarray:
    """Closed-loop response to ``swir_fz``, shape (n_freq, 9) complex (m/s^2 or rad per
    N), with the law closed on the ``mounts``
    (:func:`orchestrator.analysis.frf.closed_loop_frf`).

    Parameters
    ----------
    Gf : ndarray, shape (n_freq, 9, 4)
        :func:`plant_frf` (complex; m/s^2 or rad per V or N).
    law_f : ndarray, shape (n_freq, 1 or 3, 2)
        The law's response (complex, V per m/s^2, payload then bus acceleration): the same
        at every mount, or row ``k - 1`` at mount ``k`` (:func:`law_frf`).
    mounts : sequence of int
        The mounts whose loops are closed (1, 2, 3).
    """
    K = np.zeros((len(Gf), 3, 6), complex)
    for m in mounts:
        K[:, m - 1, 2 * (m - 1):2 * m] = law_f[:, (m - 1) % law_f.shape[1]]
    return closed_loop_frf(Gf, K, 6, 3, 3)


def law_frf(freqs, gain=1.0, law=None) -> np.ndarray:
    """Response of the isolation law at each mount, shape (n_freq, 3, 2) complex: strut
    command of mount ``k`` (row ``k - 1``) per payload and per bus acceleration (V per
    m/s^2).

    Parameters
    ----------
    freqs : array_like, shape (n_freq,)
        Frequencies (Hz).
    gain : float or sequence of float
        Factor (-) on the design law's gains: one for every mount, or one per mount
        (iso1, iso2, iso3; :func:`per_mount`); unused when ``law`` is given.
    law : control.StateSpace or sequence of control.StateSpace, optional
        Discrete law (acceleration in m/s^2, payload and bus, to strut command in V): one for
        every mount, or one per mount; default the design law times ``gain``.
    """
    return np.concatenate([statespace_response(w, freqs) for w in _laws(gain, law)], axis=1)


def boresight_reduction(plant, mounts, gain=1.0, law=None, Gh=None) -> float:
    """Steady-state reduction (%) of the boresight RMS (roll, pitch) over ``HARMONICS``,
    weighted by their amplitudes, with the law closed on ``mounts``
    (:func:`orchestrator.analysis.bounds.harmonic_reduction_pct`).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    mounts : sequence of int
        The mounts whose loops are closed (1, 2, 3).
    gain : float or sequence of float
        Factor (-) on the design law's gains: one for every mount, or one per mount
        (iso1, iso2, iso3; :func:`per_mount`); unused when ``law`` is given.
    law : control.StateSpace or sequence of control.StateSpace, optional
        Discrete law (acceleration in m/s^2, payload and bus, to strut command in V): one for
        every mount, or one per mount; default the design law times ``gain``.
    Gh : ndarray, shape (n_harmonics, 9, 4), optional
        :func:`plant_frf` at ``HARMONICS`` (complex; computed when not given).
    """
    f = np.array(list(HARMONICS))
    Gh = plant_frf(plant, f) if Gh is None else Gh
    yc = closed_frf(Gh, law_frf(f, gain, law), mounts)
    return harmonic_reduction_pct(Gh[:, 6:8, 3], yc[:, 6:8], list(HARMONICS.values()))


def strut_bounds(plant, mounts, Gh=None) -> dict:
    """What the ``mounts`` struts could remove from the boresight at ``HARMONICS`` (%,
    :func:`orchestrator.analysis.bounds.harmonic_ceiling`), each named for what it is.

    ``upper_bound``: the least-squares best strut commands at each line; no controller
    driving these struts, causal or not, removes more in steady state.  ``accel_null``:
    the commands that hold the payload accelerometers at exactly zero, what a loop of
    infinite gain on them would do; a reference point, not a bound (a finite-gain law
    can remove more: the hybrid mount's own-direction design does).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    mounts : sequence of int
        The mounts whose struts act (1, 2, 3).
    Gh : ndarray, shape (n_harmonics, 9, 4), optional
        :func:`plant_frf` at ``HARMONICS`` (complex; computed when not given).

    Returns
    -------
    dict of str to float
        ``upper_bound`` and ``accel_null`` (%).
    """
    cols = [k - 1 for k in mounts]
    rows = [2 * (k - 1) for k in mounts]
    Gh = plant_frf(plant, list(HARMONICS)) if Gh is None else Gh
    c = harmonic_ceiling(Gh[:, 6:8, 3], Gh[:, 6:8][:, :, cols], list(HARMONICS.values()),
                         Gh[:, rows, 3], Gh[:, rows][:, :, cols])
    return {"upper_bound": c["optimal"], "accel_null": c["cancel"]}


def _design_law(kp, kb, delayed=True, band=(20.0, 60.0)):
    return to_statespace(design("testbed_isolation", payload_gain=kp, bus_gain=kb,
                                delayed=delayed, band_hz=band))


def design_gains(plant, mounts, n_dir=36, margin_db=6.0, delayed=True):
    """Best (payload, bus) gains at ``margin_db`` gain margin over ``n_dir`` directions
    (:func:`orchestrator.analysis.margins.best_direction`; slow: ~n_dir x 12 eigs):
    ``(reduction %, payload, bus)``, the gains in V per m/s^2.

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    mounts : sequence of int
        The mounts whose loops are closed (1, 2, 3).
    n_dir : int
        Number of gain directions, evenly spaced over the circle.
    margin_db : float
        Gain margin the gains keep (dB).
    delayed : bool
        The law with its Eq. (11) delay of one sample; ``False``: without it.
    """
    # unit gains: 100 V per m/s^2 is already unstable in every direction on the stiff
    # model (gain_margin_db then gives -inf and the scan returned zeros)
    return best_direction(
        lambda kp, kb: gain_margin_db(plant, mounts, law=_design_law(kp, kb, delayed),
                                      max_factor=1e6),
        lambda kp, kb: boresight_reduction(plant, mounts, law=_design_law(kp, kb, delayed)),
        n_dir, margin_db)


def feedforward_best_gain(plant, mount=3, Gh=None) -> float:
    """Most the stated law's bus path could remove (%) as pure feedforward of the bus-side
    accelerometer of ``mount``: its shape on the *open-loop* bus acceleration times the
    best real gain of either sign (:func:`orchestrator.analysis.bounds.best_real_gain`),
    the harmonics weighted as in :func:`boresight_reduction`, whatever the margin.  It
    bounds that feedforward only, not the closed loop (whose payload path and feedback
    change the bus acceleration).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    mount : int
        The mount (1, 2, 3) whose bus accelerometer feeds its own strut.
    Gh : ndarray, shape (n_harmonics, 9, 4), optional
        :func:`plant_frf` at ``HARMONICS`` (complex; computed when not given).
    """
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

    Parameters
    ----------
    plant : control.StateSpace
        Discrete (``DT``) plant of :func:`linear_plant`.
    gain3 : float
        Starting factor (-) of mount #3 on the design law (the scaling then sets the
        size).
    ratios : sequence of float
        Factors of iso1 and iso2 relative to mount #3's (-) that are scanned.
    margin_db : float
        Gain margin every loop keeps (dB), together and each alone.
    Gh : ndarray, shape (n_harmonics, 9, 4), optional
        :func:`plant_frf` at ``HARMONICS`` (complex; computed when not given).
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
    margin (``0.5 / ratio``).

    Parameters
    ----------
    Gf : ndarray, shape (n_freq, 9, 4)
        :func:`plant_frf` or :func:`accel_frf` at ``freqs`` (complex; m/s^2 or rad per V
        or N).
    freqs : ndarray, shape (n_freq,)
        Frequencies of ``Gf`` (Hz, ascending).
    mount : int
        The mount (1, 2, 3) whose loop is shaped.
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
    and closed loop (row 1), (m/s^2)/N, shape (2, n_freq) complex.

    Parameters
    ----------
    Gf : ndarray, shape (n_freq, 9, 4)
        :func:`plant_frf` or :func:`accel_frf` at ``freqs`` (complex; m/s^2 or rad per V
        or N).
    mounts : sequence of int
        The mounts whose loops are closed (1, 2, 3).
    gain : float or sequence of float
        Factor (-) on the design law's gains: one for every mount, or one per mount
        (iso1, iso2, iso3; :func:`per_mount`).
    freqs : ndarray, shape (n_freq,)
        Frequencies of ``Gf`` (Hz).
    """
    return np.array([Gf[:, 8, 3], closed_frf(Gf, law_frf(freqs, gain), mounts)[:, 8]])
