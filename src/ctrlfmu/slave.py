"""Controller FMU slave: a thin adapter over :func:`ctrlfmu.law.step`.

One FMU per control law (see :mod:`ctrlfmu.fmuspec`); the law is the resource file
``law.npz`` and fixes the number, names and units of the signals.

Variables
---------
inputs
    ``y1 .. yn`` (the law's input units: ``1`` for strain, ``m/s2`` for acceleration),
    held between communication points; ``enable`` (Boolean, default true);
    ``r1 .. rm`` (V) commands added to the outputs after the law and its limits (an
    excitation injected by the control computer, as in the ten-bay truss tests).
outputs
    ``u1 .. um`` (V), discrete.  ``u_i`` depends on ``r_i`` (added directly).  Delayed
    form (Eq. 11): no dependency on the measurements.  Non-delayed form: ``u_i`` depends
    on ``y_j`` wherever ``D[i, j] != 0``, and on ``enable``.
parameters
    ``gain`` (-) factor on the command, ``u_min``/``u_max`` (V) limits of every output
    (the law's by default; ``+/-1e30`` stands for none), ``t_on`` (s) activation time.

Timing
------
The law samples on its own clock ``t_k = t_start + k dt`` (integer ``k``, never an
accumulated time), ``dt`` being the law's period and ``t_start`` the experiment start.
``doStep(t, h)`` processes every sample with ``t <= t_k < t + h`` using the inputs
held over the step, then reports the command that applies at ``t + h``.  So:

* ``h = dt`` (the DefaultExperiment step): one sample per step; the outputs after the
  step are ``u(k+1)`` of Eq. (11);
* ``h = N dt``: ``N`` samples with the same held input (the master is slower);
* ``h`` smaller than, or not a multiple of, ``dt``: steps without a sample hold the
  last command, exactly as a sampled controller with a zero-order hold would.

Sample instants are matched with a tolerance of ``fmukit.timing.TIME_RTOL`` (1e-6) sample
periods, and ``t + h`` is taken with :func:`fmukit.timing.end_time`, so a host's rounding
or drift of time (1e-12 s over a run) never slips a sample.  In the
non-delayed form, at a sample instant the outputs are recomputed whenever an input is
set (direct feedthrough); between instants they hold.

The FMU state covers the controller state, the pending and previous commands, the
sample counter and the clock origin.
"""

from __future__ import annotations

import math

import numpy as np

from ctrlfmu.law import DiscreteLaw, LawState, load_law, output, step
from fmukit.slave import FmuSlave
from fmukit.timing import TIME_RTOL, end_time

__all__ = ["ControllerSlave", "ControllerParameterError", "NO_LIMIT"]

NO_LIMIT = 1e30
"""Output limit (V) standing for "none" (FMU start values must be finite)."""


class ControllerParameterError(ValueError):
    """An FMU parameter of the controller slave is out of range."""


def _finite_limit(value: float) -> float:
    return float(np.clip(value, -NO_LIMIT, NO_LIMIT))


class ControllerSlave(FmuSlave):
    """Discrete controller of Eq. (11) read from the resource ``law.npz``."""

    state_attributes = ("_x", "_u", "_u_prev", "_k", "_t0", "_tau", "_ready")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        law = load_law(self.resource_path("law.npz"))
        if np.any(law.u_min != law.u_min[0]) or np.any(law.u_max != law.u_max[0]):
            raise ControllerParameterError(
                f"law {law.name!r} has different limits per output; the FMU needs equal limits"
            )
        self._base = law
        self.add_parameter("gain", 1.0, unit="1", description="factor on the command")
        self.add_parameter("u_min", _finite_limit(law.u_min[0]), unit="V",
                           description="lower command limit of every output")
        self.add_parameter("u_max", _finite_limit(law.u_max[0]), unit="V",
                           description="upper command limit of every output")
        self.add_parameter("t_on", float(law.t_on), unit="s",
                           description="activation time: zero command and state before it")
        for j in range(law.n_inputs):
            self.add_input(f"y{j + 1}", unit=law.input_units[j],
                           description=f"measurement {law.inputs[j]}")
        self.add_boolean("enable", True, causality="input", variability="discrete",
                         description="controller on; off gives zero command and resets the state")
        for i in range(law.n_outputs):
            self.add_input(f"r{i + 1}", unit=law.output_units[i],
                           description=f"command added to {law.outputs[i]} (excitation)")
        self._r_names = [f"r{i + 1}" for i in range(law.n_outputs)]
        ft = law.feedthrough
        for i in range(law.n_outputs):
            deps = [f"y{j + 1}" for j in range(law.n_inputs) if ft[i, j]] + [f"r{i + 1}"]
            if not law.delayed:
                deps.append("enable")
            self.add_output(f"u{i + 1}", unit=law.output_units[i], depends_on=deps,
                            variability="discrete",
                            description=f"command {law.outputs[i]}")
        self._y_names = [f"y{j + 1}" for j in range(law.n_inputs)]
        self._u_names = [f"u{i + 1}" for i in range(law.n_outputs)]
        self._law = law
        self._x = np.zeros(law.n_states)
        self._u = np.zeros(law.n_outputs)
        self._u_prev = np.zeros(law.n_outputs)
        self._k = 0
        self._t0 = 0.0
        self._tau = 0.0
        self._ready = False

    # ---------------------------------------------------------------- helpers
    @property
    def law(self) -> DiscreteLaw:
        """The law with the FMU parameters applied (after initialisation)."""
        return self._law

    def _inputs(self) -> np.ndarray:
        return np.array([getattr(self, n) for n in self._y_names], dtype=float)

    def _samples_before(self, tau: float) -> int:
        """Number of samples ``k`` with ``t_k < tau`` (sample-instant tolerance)."""
        return max(0, math.ceil((tau - self._t0) / self._law.dt - TIME_RTOL))

    def _at_instant(self, tau: float, k: int) -> bool:
        return abs((tau - self._t0) / self._law.dt - k) <= TIME_RTOL

    def _write_outputs(self) -> None:
        law, tau, k = self._law, self._tau, self._k
        if self._at_instant(tau, k):
            if law.delayed:
                u = self._u
            else:
                u = output(law, LawState(self._x, self._u, k), self._inputs(), self.enable)
        else:
            u = self._u_prev if law.delayed else self._u
        for name, rname, value in zip(self._u_names, self._r_names, u):
            setattr(self, name, float(value) + getattr(self, rname))

    # ---------------------------------------------------------------- FMI
    def setup_experiment(self, start_time, stop_time, tolerance):
        """Set the law's clock origin ``t_start`` to ``start_time``.

        Parameters
        ----------
        start_time : float
            Experiment start (s).
        stop_time : float or None
            Stop time (s); not used.
        tolerance : float or None
            Not used.
        """
        self._t0 = float(start_time)
        self._tau = float(start_time)

    def _apply_parameters(self) -> None:
        if not (math.isfinite(self.gain) and self.u_min <= self.u_max):
            raise ControllerParameterError(
                f"controller {self.instance_name!r} has gain {self.gain!r} and limits "
                f"[{self.u_min!r}, {self.u_max!r}] V; expected a finite gain and u_min <= u_max"
            )
        if not (math.isfinite(self.t_on) and self.t_on >= 0):
            raise ControllerParameterError(
                f"parameter t_on of {self.instance_name!r} is {self.t_on!r}; expected >= 0 s"
            )
        law = self._base.with_gain(self.gain).with_limits(self.u_min, self.u_max)
        self._law = law.with_t_on(max(0.0, self.t_on - self._t0))

    def exit_initialization_mode(self):
        self._apply_parameters()
        self._ready = True
        self._write_outputs()

    def _fmu_state_restored(self):
        if not (type(self._k) is int and self._k >= 0 and type(self._ready) is bool):
            raise ControllerParameterError(f"sample counter {self._k!r} and ready flag "
                                           f"{self._ready!r} are not a controller state")
        if self._ready:
            self._apply_parameters()    # parameters and clock origin come with the state

    def do_step(self, current_time, step_size):
        """Process every sample ``t <= t_k < t + h`` with the held inputs.

        The outputs are then the commands that apply at ``t + h``.

        Parameters
        ----------
        current_time : float
            Communication point ``t`` at the start of the step (s).
        step_size : float
            Step ``h`` (s); need not be a multiple of the sample period.

        Returns
        -------
        bool
            Always True.
        """
        law = self._law
        tau = end_time(current_time, step_size, self._tau)
        k_end = self._samples_before(tau)
        if self._k < k_end:
            y = self._inputs()
            state = LawState(self._x, self._u, self._k)
            u_prev = self._u_prev
            for _ in range(self._k, k_end):
                u_prev = state.u
                state, _u = step(law, state, y, self.enable)
            self._x[...] = state.x
            self._u[...] = state.u
            self._u_prev[...] = u_prev
            self._k = state.k
        self._tau = tau
        self._write_outputs()
        return True

    def set_real(self, vrs, values):
        """Set Real variables; once initialised, recompute the outputs.

        Parameters
        ----------
        vrs : list of int
            Value references.
        values : list of float
            Values, one per reference, in each variable's unit.
        """
        super().set_real(vrs, values)
        if self._ready:
            self._write_outputs()

    def set_boolean(self, vrs, values):
        """Set Boolean variables (``enable``); recompute the outputs.

        Outputs are recomputed only for a non-delayed law, after initialisation.

        Parameters
        ----------
        vrs : list of int
            Value references.
        values : list of bool
            Values, one per reference.
        """
        super().set_boolean(vrs, values)
        if self._ready and not self._law.delayed:
            self._write_outputs()
