"""Attenuation design: the linear closed loop of a scenario, before any tuning.

A scenario's FMUs are replaced by the linear, exactly discretised models they step
(:func:`linearize`): the reduced structure (the FMU's own ``model.npz``, ZOH at its
period, accelerometer low-pass included), the piezo amplifiers (their low-pass over the
internal sub-steps, ``f = c h v``, rails and slew limit assumed inactive), the control
laws of Eq. (11) (the FMU's ``law.npz`` with its ``gain``; controllers assumed on) and
the attitude controller (PID with its one-sample delay).  Sources (disturbances,
excitation) become exogenous inputs.  The models are assembled tick by tick with the
master's Gauss–Seidel rules (:mod:`orchestrator.cosim`): an instance due at a tick
publishes its outputs at ``t_k``, reads its inputs in feedthrough order, then steps;
between its ticks its outputs hold.  Over one hyperperiod ``T`` of the periods this
gives an exact linear map ``X(T) = Phi X(0) + Gamma w`` of everything the co-simulation
carries, from which:

* :meth:`LinearScenario.poles` -- closed-loop poles, frequency and damping;
* :meth:`LinearScenario.gain_margins` -- the factor on one controller's ``gain`` at
  which the loop goes unstable (up and down), with every other loop closed;
* :meth:`LinearScenario.decay` -- cycles to 90 % decay of the pole nearest a mode;
* :meth:`LinearScenario.frequency_response` -- steady-state response to a harmonic
  exogenous input (the fundamental, exact for single-rate loops;
  :func:`~orchestrator.analysis.spectra.transfer` on the compiled loop);
* :func:`ceiling` -- the upper bound on the reduction of a performance output under a
  harmonic disturbance by any controller driving the chosen actuators: the best
  actuator commands at each frequency (``"optimal"``, which no controller, causal or
  not, beats in steady state); and, as a reference point that is not a bound, what
  cancelling the chosen sensor signals perfectly gives (``"cancel"``, infinite gain).

``jitterfmu analyze SCENARIO`` prints these as a table.

For a loop assembled from matrices instead of a scenario (a design study on a reduced
structure of one's own), the modules :mod:`~orchestrator.analysis.sampled` (sampled
structures, stack loops, records with the ACS in the loop), :mod:`.margins` (margins
and gain designs at a margin), :mod:`.frf` (frequency responses, transmissibility),
:mod:`.bounds` (upper bounds and least-squares optima) and :mod:`.lqg` (one law on many
stacks) hold the tools; ``docs/linear_engine.md`` lists them.

Example
-------
>>> from orchestrator.analysis import linearize             # doctest: +SKIP
>>> lin = linearize("scenarios/truss10_closed_loop.toml")   # doctest: +SKIP
>>> lin.decay(8.4).cycles_to_90pct                          # doctest: +SKIP
"""

from __future__ import annotations

from .blocks import AnalysisError, Block
from .design import Ceiling, ceiling, report
from .scenario import Decay, LinearScenario, Margins, Pole, linearize, stability_margin_db

__all__ = [
    "AnalysisError",
    "Block",
    "LinearScenario",
    "Pole",
    "Margins",
    "Decay",
    "Ceiling",
    "linearize",
    "ceiling",
    "report",
    "stability_margin_db",
]
