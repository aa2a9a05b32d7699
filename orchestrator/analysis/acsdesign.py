"""The ACS of a scenario designed on its flexible plant, and checked on the scenario.

:func:`acs_plant` takes the plant the ACS sees from the exact sampled loop: the ACS is
replaced by a probe with its inputs, outputs and timing (it stores the six samples it
reads and publishes them one period later) and the loop is broken at the probe's
outputs (:func:`~orchestrator.analysis.loops.broken_loop`).  Every other loop stays
closed inside, so the plant holds the structure, its modes folded by the ACS's
sampling, the amplifiers and any faster control laws.  Closing it with the law of
:func:`acsfmu.law.law_state_space` gives back the scenario's loop with that ACS.

:func:`design_acs` reads the ACS's inertias, design phase, sample time and anti-alias
filter from the scenario, designs on that plant (:func:`acsfmu.flexible.
design_on_plant`: bandwidth, notch and low-pass per axis, the rigid-body phase margin
and every flexible mode gain- or phase-stabilised), then puts the design into the
scenario's loop and measures it there, as ``jitterfmu analyze`` does: the margins of
the three axes broken at their torques (:func:`~orchestrator.analysis.loops.margins_of`)
and the stability of the whole loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .blocks import AnalysisError, Block, acs_block

__all__ = ["AcsDesign", "acs_instance", "acs_plant", "acs_settings", "design_acs"]


@dataclass(frozen=True, eq=False)
class AcsDesign:
    """A flexible-plant ACS design and what it gives in the scenario.

    Attributes
    ----------
    design : acsfmu.flexible.FlexibleDesign
        Per-axis choices, rigid-body margins and per-mode verdicts.
    instance : str
        The ACS instance.
    overrides : dict of str to float
        ``{"acs.bandwidth_x": ..., ...}``: the ACS parameters that carry the design.
    lin : LinearScenario
        The scenario's loop with the designed ACS.
    margins : GroupMargins
        The three axes broken at their torques in that loop.
    stable : bool
        That loop's poles, everything closed.
    seconds : float
        Time taken (s).
    """

    design: object
    instance: str
    overrides: dict
    lin: object
    margins: object
    stable: bool
    seconds: float

    def as_dict(self) -> dict:
        """Plain numbers for JSON."""
        d = self.design
        return {"instance": self.instance, "overrides": dict(self.overrides),
                "stable": self.stable, "seconds": self.seconds,
                "axes": [a.as_dict() for a in d.axes],
                "mimo_disk_alpha": d.disk_alpha, "mimo_disk_db": d.disk_db,
                "mimo_disk_deg": d.disk_deg, "searched": d.searched,
                "margins": self.margins.as_dict()}


def acs_instance(lin, name: str | None = None) -> str:
    """The ACS instance of a scenario (the only one, or ``name``).

    Parameters
    ----------
    lin : LinearScenario
    name : str, optional
        Instance name when the scenario has several.

    Returns
    -------
    str
    """
    found = [n for n, b in lin.blocks.items() if b.kind == "acs"]
    if name is not None:
        if name not in found:
            raise AnalysisError(f"{name!r} is not an ACS of the scenario; its ACS instances: "
                                f"{', '.join(found) or 'none'}")
        return name
    if len(found) != 1:
        raise AnalysisError(f"the scenario has {len(found)} ACS instances "
                            f"({', '.join(found) or 'none'}); name the one to design")
    return found[0]


def acs_settings(lin, name: str) -> dict:
    """The ACS parameters the design keeps: inertias, design phase, sample time,
    anti-alias filter, torque limit (the scenario's values or the FMU's defaults).

    Parameters
    ----------
    lin : LinearScenario
    name : str
        The ACS instance.

    Returns
    -------
    dict
        ``inertia`` (3,) kg m^2, ``design_phase`` deg, ``sample_time`` s,
        ``antialias`` (Hz, -), ``torque_limit`` N m.
    """
    inst = next(i for i in lin.plan.scenario.instances if i.name == name)
    variables = lin.plan.fmus[name].variables

    def value(var):
        if var in inst.parameters:
            return float(inst.parameters[var])
        return float(variables[var].start)

    return {"inertia": np.array([value(f"inertia_{a}") for a in "xyz"]),
            "design_phase": math.degrees(value("phase_margin")),
            "sample_time": value("sample_time"),
            "antialias": (value("antialias_hz"), value("antialias_zeta")),
            "torque_limit": value("torque_limit")}


def acs_plant(lin, name: str | None = None):
    """The sampled plant the ACS sees, every other loop closed inside.

    Parameters
    ----------
    lin : LinearScenario
        The scenario's loop; the ACS must run at its hyperperiod.
    name : str, optional
        The ACS instance (default the only one).

    Returns
    -------
    acsfmu.flexible.AcsPlant
    """
    from acsfmu.flexible import AcsPlant

    from .loops import broken_loop

    name = acs_instance(lin, name)
    b = lin.blocks[name]
    probe = Block(name, "acs", b.period, np.zeros((6, 6)), np.eye(6), np.eye(6),
                  np.zeros((6, 6)), b.inputs, b.outputs, b.feedthrough)
    cut = broken_loop(lin.with_block(probe), [f"{name}.{o}" for o in b.outputs])
    if np.any(cut.Dl != 0):
        raise AnalysisError(f"the ACS {name!r} reads its inputs in the tick its torque is "
                            "applied; the design expects its one-sample delay")
    return AcsPlant(cut.Phi, cut.Gam[:, :3], cut.R, cut.period)


def design_acs(lin, name: str | None = None, *, phase_margin: float = 30.0,
               gain_margin_db: float = 6.0, bandwidths=(0.1, 0.01), steps: int = 21,
               lowpass_ratios=(4.0, 5.0, 6.25, 8.0), notch_hz=(),
               disk_margin_db: float = 0.0, progress=None, **options) -> AcsDesign:
    """Design a scenario's ACS on its flexible plant and measure it in the scenario.

    Parameters
    ----------
    lin : LinearScenario
        The scenario's loop (the ACS's present parameters are replaced).
    name : str, optional
        The ACS instance (default the only one).
    phase_margin : float
        Rigid-body and phase-stabilised margin required (deg), in (0, 90).
    gain_margin_db : float
        Gain-stabilised margin required (dB), at least 0.
    bandwidths : (float, float) or sequence of float
        Crossovers searched, ``(high, low)`` with ``steps`` log-spaced points (Hz).
    steps : int
        Crossovers in the range.
    lowpass_ratios : sequence of float
        Low-pass corners tried, in multiples of the crossover.
    notch_hz : sequence of float
        Notch centres tried (Hz); empty: the largest flexible peaks.
    disk_margin_db : float
        MIMO disk margin of the three axes required (dB; 0 for none).
    progress : callable, optional
        ``progress(done, total)``.
    **options
        Passed to :func:`acsfmu.flexible.design_on_plant` (``lowpass_zeta``,
        ``notch_zetas``, ``design_phase``, ``phase_stabilise``, ``passes``).

    Returns
    -------
    AcsDesign

    Raises
    ------
    acsfmu.filters.AcsConfigError
        A request refused before any computation, or the design refused in one
        sentence.
    """
    import time

    from acsfmu.flexible import check_request, design_on_plant

    from .loops import broken_loop, margins_of

    from ._threads import blas_threads_kept, one_blas_thread

    start = time.perf_counter()
    name = acs_instance(lin, name)
    st = acs_settings(lin, name)
    check_request(st["sample_time"], phase_margin=phase_margin, gain_margin_db=gain_margin_db,
                  bandwidths=bandwidths, lowpass_ratios=lowpass_ratios, notch_hz=notch_hz,
                  antialias_hz=st["antialias"][0], disk_margin_db=disk_margin_db)
    options.setdefault("design_phase", st["design_phase"])
    # small dense eigenproblems, many of them: one BLAS thread each is faster, and far
    # faster on a machine whose cores are busy
    with blas_threads_kept():
        one_blas_thread()
        plant = acs_plant(lin, name)
        d = design_on_plant(plant, st["inertia"], phase_margin=phase_margin,
                            gain_margin_db=gain_margin_db, bandwidths=bandwidths, steps=steps,
                            lowpass_ratios=lowpass_ratios, notch_hz=notch_hz,
                            antialias=st["antialias"], disk_margin_db=disk_margin_db,
                            progress=progress, **options)
        b = lin.blocks[name]
        cfg = d.config.replace(torque_limit=st["torque_limit"])
        out = lin.with_block(acs_block(cfg, name, b.period, b.period * lin.base))
        margins = margins_of(broken_loop(out, [f"{name}.{o}" for o in b.outputs[:3]]), name)
    overrides = {f"{name}.{k}": float(v) for k, v in d.parameters.items()}
    return AcsDesign(d, name, overrides, out, margins, out.is_stable(),
                     time.perf_counter() - start)
