"""Presets for the twelve EOS AM-1 disturbance events (plus ``"none"``).

The paper names the events but gives no amplitudes.  Every value below says where it
comes from: a public instrument description, the paper, or an assumption with its
reasoning (one order-of-magnitude argument each).  ``docs/disturbances.md`` has the single
table of events, frequency content, amplitudes, what each implies on the spacecraft,
mounts and sources; keep the two in step.

Body axes: x roll (along track), y pitch (cross track), z yaw (nadir).  Cross-track
scanners and pointers rotate about x.

Frequency content follows the paper: VNIR pointing and the SWIR cryocooler are high
frequency (short acceleration pulses; a 22 Hz cooler line, the "cryocooler-like"
disturbance of the testbed), while the CERES scan and the solar array drive are below
about 2 Hz and excite rigid-body and solar-array (0.5 Hz) response.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from distfmu.sources import (
    BandLimitedRandom,
    Chopper,
    Harmonic,
    ScanMirror,
    Slew,
    Source,
    SourceError,
    SpeedProfile,
    Stepper,
    Sum,
    WheelImbalance,
    Zero,
)

MOUNTS = ("CERES", "MISR", "MODIS", "MOPITT", "SWIR", "TIR", "VNIR", "RWA", "SAD")
"""Symbolic mount location names."""

_DEG = math.pi / 180.0
_RPM = 2.0 * math.pi / 60.0

RWA_SPEED = 1000.0 * _RPM
"""Nominal wheel speed of the RWA preset (rad/s), used unless a speed input drives it."""

CERES_SCALE = 1.0 / 60.0
"""Factor on the CERES scan inertias (a whole scan head: 0.6 kg m^2 elevation, 4 kg m^2
azimuth): the net momentum exchanged with the bus is set so the CERES scan gives about
1 arcsec per 1.8 s, the order of the paper's other primary contributors, instead of 81
arcsec (an assumption calibrated to the paper's ranking; docs/disturbances.md)."""


VNIR_STEP_TIME = 0.005
"""Acceleration (and braking) time of the VNIR pointing step (s): content to ~200 Hz,
the paper's "high frequency" VNIR event (assumption)."""

VNIR_STEP_ACCEL = 0.93
"""Angular acceleration of the VNIR pointing step (rad/s^2): with J = 4 kg m^2 it gives
about 1 arcsec per 1.8 s on the SWIR axes isolation off (geometric mean of roll, pitch and
yaw; paper: "about 1 arcsec/1.8 sec. of jitter in all three axes of SWIR").  A calibration
to the paper's statement, not VNIR data (``jitterfmu reproduce swir-isolation``)."""


class PresetError(KeyError):
    """An unknown disturbance preset name was requested."""

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0])


@dataclass(frozen=True)
class Preset:
    """A named disturbance event.

    Parameters
    ----------
    name : str
        Preset key, e.g. ``"vnir_pointing"``.
    event : str
        Event name as in the paper.
    mount : str
        Symbolic mount location (one of :data:`MOUNTS`, or ``""`` for ``"none"``).
    source : Source
        The disturbance source.
    """

    name: str
    event: str
    mount: str
    source: Source

    @property
    def is_wheel(self) -> bool:
        """True when the source is a wheel imbalance (it accepts a speed input)."""
        return isinstance(self.source, WheelImbalance)


def _build() -> dict[str, Preset]:
    p = [
        Preset("none", "no disturbance", "", Zero()),
        Preset(
            "ceres_scan", "CERES biaxial scan", "CERES",
            Sum((
                # elevation: 6.6 s scan cycle and +-78 deg (public); the inertias are the
                # net momentum the scan exchanges with the bus per unit rate, scaled to the
                # paper's ranking (CERES one of four primary contributors, of the order of
                # VNIR's ~1 arcsec/1.8 s), not CERES data: 0.6 and 4 kg m^2 (a whole head)
                # gave 81 arcsec of roll, 60x that (docs/disturbances.md)
                ScanMirror(inertia=CERES_SCALE * 0.6, period=6.6, amplitude=78.0 * _DEG,
                           retrace_fraction=0.5, turnaround=0.3, axis=(1.0, 0.0, 0.0)),
                # azimuth: 90 deg back and forth at 6 deg/s every 32 s (assumption)
                Slew(angle=90.0 * _DEG, max_rate=6.0 * _DEG, max_accel=6.0 * _DEG,
                     inertia=CERES_SCALE * 4.0, start=0.0, axis=(0.0, 0.0, 1.0),
                     repeat=32.0),
            )),
        ),
        Preset(
            "misr_calibration", "MISR calibration", "MISR",
            # diffuser panel deployment and stow, 90 deg (assumption); J of a ~1 kg panel
            # about a hinge on its 0.3 m edge, m L^2 / 3 = 0.03 kg m^2 (assumption)
            Slew(angle=90.0 * _DEG, max_rate=10.0 * _DEG, max_accel=20.0 * _DEG,
                 inertia=0.03, start=1.0, axis=(0.0, 1.0, 0.0), repeat=30.0),
        ),
        Preset(
            "modis_scan", "MODIS scan mirror imbalance", "MODIS",
            # 20.3 rpm double-sided mirror (public); imbalance torques assumed: the
            # residual of a balanced, continuously turning mirror (not ranked in the paper)
            Harmonic(frequency=20.3 / 60.0, amplitudes=(0.01, 0.004), harmonics=(1.0, 2.0),
                     direction=(0.0, 0.0, 1.0), kind="torque"),
        ),
        Preset(
            "mopitt_scan", "MOPITT scan", "MOPITT",
            # +-26.1 deg cross-track scan (public); period, retrace and J assumed (a ~1 kg
            # mirror with its rotor at 0.14 m radius of gyration)
            ScanMirror(inertia=0.02, period=12.0, amplitude=26.1 * _DEG,
                       retrace_fraction=0.1, turnaround=0.1, axis=(1.0, 0.0, 0.0)),
        ),
        Preset(
            "swir_pointing", "ASTER-SWIR pointing", "SWIR",
            # +-8.55 deg cross-track pointing mirror (public); rate, acceleration and
            # J = 0.02 kg m^2 (a ~2 kg flat mirror with its rotor) assumed
            Slew(angle=8.55 * _DEG, max_rate=2.0 * _DEG, max_accel=40.0 * _DEG,
                 inertia=0.02, start=1.0, axis=(1.0, 0.0, 0.0), repeat=30.0),
        ),
        Preset(
            "tir_chopper", "ASTER-TIR chopper", "TIR",
            # about 7 Hz mirror oscillation (ASTER handbook); torque amplitude assumed:
            # J (2 pi f)^2 theta for J ~ 2e-4 kg m^2 swinging +-3 deg at 7 Hz
            Chopper(frequency=7.0, amplitude=0.02, direction=(1.0, 0.0, 0.0),
                    kind="torque", rise_time=0.005),
        ),
        Preset(
            "vnir_pointing", "ASTER-VNIR pointing", "VNIR",
            # one step of the pointing drive about roll (the cross-track pointing axis):
            # J = 4 kg m^2 (assumption), 5 ms acceleration then 5 ms braking at
            # VNIR_STEP_ACCEL, no coast.  Sized to the paper's "about 1 arcsec/1.8 s of
            # SWIR jitter in all three axes" and its "high frequency content"; a 24 deg
            # slew with 50 ms pulses and an 8 s coast drifts the bus 16 arcsec in roll
            # per 1.8 s instead (docs/disturbances.md, docs/eos_experiments.md)
            # (start half a 1 kHz sample after 1 s: every sampler then sees two whole
            # 5-sample pulses, no net impulse from where a boundary sample falls)
            Slew(angle=VNIR_STEP_ACCEL * VNIR_STEP_TIME**2, max_rate=0.05,
                 max_accel=VNIR_STEP_ACCEL, inertia=4.0, start=1.0005,
                 axis=(1.0, 0.0, 0.0), repeat=60.0),
        ),
        Preset(
            "mopitt_cryocooler", "MOPITT cryocooler", "MOPITT",
            # assumed: balanced Stirling-class residual, 0.1-1 N; harmonics 30 %, 10 %
            Harmonic(frequency=40.0, amplitudes=(0.2, 0.06, 0.02),
                     direction=(0.0, 1.0, 0.0), kind="force"),
        ),
        Preset(
            "swir_cryocooler", "ASTER-SWIR cryocooler", "SWIR",
            # 22 Hz: the paper's "cryocooler-like" testbed disturbance, harmonics 30 %,
            # 10 % as MOPITT's.  Amplitude calibrated to one fact, the paper's ranking of
            # primary contributors (Fig. 8: VNIR pointing, the SWIR cryocooler, the CERES
            # scan and the SAD): 4 N, the smallest of 1-N steps that made it one of the
            # four largest of the twelve events on SWIR (the worst axis of each) with the
            # earlier 0.1 Hz ACS; 0.5 N gave 0.11 arcsec, tenth.  With the shipped ACS it
            # ranks fourth, and 3 N would too (tests/orchestrator/test_eos_experiments.py,
            # docs/eos_experiments.md).
            Harmonic(frequency=22.0, amplitudes=(4.0, 1.2, 0.4),
                     direction=(0.0, 0.0, 1.0), kind="force"),
        ),
        Preset(
            "tir_cryocooler", "ASTER-TIR cryocooler", "TIR",
            # frequency and amplitudes assumed as for MOPITT
            Harmonic(frequency=26.0, amplitudes=(0.4, 0.12, 0.04),
                     direction=(0.0, 0.0, 1.0), kind="force"),
        ),
        Preset(
            "rwa", "reaction wheel assembly", "RWA",
            # Masterson form; Us = 2 g cm, Ud = 20 g cm^2 class values; harmonic ratios
            # after the wheel-test literature (assumption)
            WheelImbalance(harmonics=(1.0, 2.0, 2.9, 3.9),
                           force_coeffs=(2.0e-7, 2.0e-8, 1.0e-8, 5.0e-9),
                           torque_coeffs=(2.0e-6, 2.0e-7, 1.0e-7, 5.0e-8),
                           axial_coeffs=(2.0e-8, 1.0e-8, 5.0e-9, 2.0e-9),
                           speed=RWA_SPEED, axis=(1.0, 0.0, 0.0)),
        ),
        Preset(
            "sad", "solar array drive", "SAD",
            # stepper at 0.5 steps/s, 0.5 s half-sine pulse pairs of 0.5 N m (assumption,
            # consistent with the paper ranking the SAD primary: about 1 arcsec per 1.8 s);
            # content below about 3 Hz, near the 0.5 Hz solar-array mode
            Stepper(step_rate=0.5, peak_torque=0.5, pulse_width=0.5, axis=(0.0, 1.0, 0.0)),
        ),
    ]
    return {q.name: q for q in p}


PRESETS: dict[str, Preset] = _build()
"""All presets by name; ``"none"`` first, then the twelve events."""


def preset_names() -> list[str]:
    """Names of all presets, ``"none"`` first."""
    return list(PRESETS)


def get_preset(name: str) -> Preset:
    """Look up a preset by name.

    Parameters
    ----------
    name : str
        Preset key (see :func:`preset_names`).

    Returns
    -------
    Preset

    Raises
    ------
    PresetError
        If ``name`` is not a preset.
    """
    try:
        return PRESETS[name]
    except KeyError:
        raise PresetError(
            f"disturbance preset {name!r} is unknown; expected one of {preset_names()}"
        ) from None


def randomized(source: Source, seed: int) -> Source:
    """Copy of a source with its phases drawn from ``seed`` (0: unchanged).

    Harmonic and wheel sources get phases uniform in ``[0, 2 pi)``, the chopper a
    uniform phase offset, a band-limited random source the seed itself; sums are
    randomised term by term with independent streams.  Scan mirrors, slews and steppers
    keep their deterministic timing.

    Parameters
    ----------
    source : Source
        A preset source.
    seed : int
        Non-negative seed; 0 leaves the source as it is.

    Returns
    -------
    Source
    """
    if not (isinstance(seed, int) and seed >= 0):
        raise ValueError(f"disturbance seed must be a non-negative integer, got {seed!r}")
    if seed == 0:
        return source
    rng = np.random.default_rng(seed)
    if isinstance(source, Sum):
        children = np.random.SeedSequence(seed).spawn(len(source.sources))
        return Sum(tuple(randomized(s, int(c.generate_state(1)[0]) or 1)
                         for s, c in zip(source.sources, children)))
    if isinstance(source, Harmonic):
        phases = tuple(rng.uniform(0, 2 * np.pi, len(source.amplitudes)).tolist())
        return dataclasses.replace(source, phases=phases)
    if isinstance(source, WheelImbalance):
        phases = tuple(rng.uniform(0, 2 * np.pi, len(source.harmonics)).tolist())
        return dataclasses.replace(source, phases=phases)
    if isinstance(source, Chopper):
        return dataclasses.replace(source, phase=float(rng.uniform()))
    if isinstance(source, BandLimitedRandom):
        return dataclasses.replace(source, seed=seed)
    return source


def retimed(source: Source, factor: float) -> Source:
    """Copy of a source with its line and repetition frequencies times ``factor``.

    What a disturbance's frequency uncertainty means for each source that repeats:
    a harmonic's and a chopper's fundamental, a wheel's speed (constant or every
    point of its profile: the Masterson forces follow the speed squared), a
    stepper's step rate, a scan mirror's scan (period divided by ``factor``: the
    same angle faster, so larger turnaround pulses) and a repeating slew's interval
    (divided).  The shapes in time (edges, pulses, turnarounds, a slew's profile) are
    kept.  No disturbance (``Zero``) stays none.  A source that does not repeat (a
    single slew, a table, band-limited random) has no frequency to scale and is
    refused unless ``factor`` is 1.

    Parameters
    ----------
    source : Source
        A preset or custom source.
    factor : float
        Positive, finite; 1 returns ``source`` itself.

    Returns
    -------
    Source

    Raises
    ------
    SourceError
        A factor that is not positive and finite, or a source without a frequency.
    """
    factor = float(factor)
    if not (math.isfinite(factor) and factor > 0):
        raise SourceError(f"disturbance frequency_scale must be a positive finite number, "
                          f"got {factor!r}")
    if factor == 1.0 or isinstance(source, Zero):
        return source
    if isinstance(source, Sum):
        return Sum(tuple(retimed(s, factor) for s in source.sources))
    if isinstance(source, (Harmonic, Chopper)):
        return dataclasses.replace(source, frequency=source.frequency * factor)
    if isinstance(source, WheelImbalance):
        speed = source.speed
        if isinstance(speed, SpeedProfile):
            speed = dataclasses.replace(speed, speeds=tuple(v * factor for v in speed.speeds))
        else:
            speed = speed * factor
        return dataclasses.replace(source, speed=speed)
    if isinstance(source, Stepper):
        return dataclasses.replace(source, step_rate=source.step_rate * factor)
    if isinstance(source, ScanMirror):
        return dataclasses.replace(source, period=source.period / factor)
    if isinstance(source, Slew) and source.repeat is not None:
        return dataclasses.replace(source, repeat=source.repeat / factor)
    raise SourceError(f"a {type(source).__name__} source does not repeat, so it has no "
                      "frequency for frequency_scale to scale; leave frequency_scale at 1 "
                      "for this disturbance")
