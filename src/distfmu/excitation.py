"""Sine-burst excitation signals (pure functions) and the ``excitation`` FMU slave.

The ten-bay truss tests drive the active members with sine voltages for a while and
then stop (free decay or control).  Channel ``i`` gives::

    v_i(t) = a_i sin(2 pi f_i (t - t_start))   for t_start <= t < t_stop, else 0

The FMU's outputs carry the value at the current communication point (a source: no
inputs, no feedthrough).
"""

from __future__ import annotations

import math

import numpy as np

from fmukit.slave import FmuSlave
from fmukit.timing import end_time, reached

N_CHANNELS = 2


def sine_burst(t, amplitude: float, frequency: float, t_start: float = 0.0,
               t_stop: float = math.inf, period: float = 0.0):
    """Sine burst ``a sin(2 pi f (t - t_start))`` on ``[t_start, t_stop)`` (arrays accepted).

    Parameters
    ----------
    t : float or ndarray
        Time (s).
    amplitude : float
        Amplitude (signal unit, e.g. V).
    frequency : float
        Frequency (Hz).
    t_start, t_stop : float
        Burst window (s).
    period : float
        Step of the times ``t`` (s): the window's edges are met within
        ``fmukit.timing.TIME_RTOL`` of it (a host's rounding of time); 0 for exact.
    """
    t = np.asarray(t, float)
    on = reached(t, t_start, period) & ~reached(t, t_stop, period)
    return np.where(on, amplitude * np.sin(2 * np.pi * frequency * (t - t_start)), 0.0)


class ExcitationSlave(FmuSlave):
    """Two sine-burst voltage channels ``v1``, ``v2`` (V).

    The FMU state is every variable plus ``x = [time]``, the time of the outputs.
    """

    state_attributes = ("x",)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for i in range(1, N_CHANNELS + 1):
            self.add_parameter(f"amp{i}", 0.0, unit="V", description=f"amplitude of v{i}",
                               tunable=True)
            self.add_parameter(f"freq{i}", 1.0, unit="Hz", description=f"frequency of v{i}",
                               tunable=True)
        self.add_parameter("t_start", 0.0, unit="s", description="burst start", tunable=True)
        self.add_parameter("t_stop", 1e30, unit="s", description="burst end", tunable=True)
        for i in range(1, N_CHANNELS + 1):
            self.add_output(f"v{i}", unit="V", depends_on=[], description=f"excitation {i}")
        self._t0 = 0.0
        self.x = np.zeros(1)

    def _write(self, t: float, period: float = 0.0) -> None:
        for i in range(1, N_CHANNELS + 1):
            value = sine_burst(t, getattr(self, f"amp{i}"), getattr(self, f"freq{i}"),
                               self.t_start, self.t_stop, period)
            setattr(self, f"v{i}", float(value))

    def series(self, times) -> np.ndarray:
        """Outputs ``v1, v2`` (V) at the communication points ``times`` (s), shape (n, 2).

        The open-loop series with the current parameters, for the linear engine.
        """
        t = np.asarray(times, float)
        return np.column_stack([
            sine_burst(t, getattr(self, f"amp{i}"), getattr(self, f"freq{i}"),
                       self.t_start, self.t_stop) for i in range(1, N_CHANNELS + 1)])

    def setup_experiment(self, start_time, stop_time, tolerance):
        """Record the start time; the initial outputs are taken there.

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

    def exit_initialization_mode(self):
        self.x[0] = self._t0
        self._write(self._t0)
        return True

    def do_step(self, current_time, step_size):
        """Write the burst voltages ``v1``, ``v2`` (V) at the step end.

        Parameters
        ----------
        current_time : float
            Communication point at the start of the step (s).
        step_size : float
            Step (s); outputs are evaluated at ``current_time + step_size``.

        Returns
        -------
        bool
            Always True.
        """
        self.x[0] = end_time(current_time, step_size, float(self.x[0]))
        self._write(float(self.x[0]), step_size)
        return True
