"""What a run raises and warns: failures, normal early ends, and doubtful set-ups."""

from __future__ import annotations

__all__ = ["SimulationError", "DivergenceError", "EarlyEndWarning", "SaturationWarning", "TimebaseWarning", "JacobiLoopWarning",
           "UnconnectedInputWarning"]

#: FMI 2.0 status names by value.
STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


class SimulationError(RuntimeError):
    """An FMU failed, raised, or produced a non-finite value during a run.

    Attributes
    ----------
    instance : str or None
    time : float or None
        Communication point of the failing step (s).
    result : RunResult or None
        What was recorded up to the failure (set by :func:`orchestrator.run_scenario`).
    """

    def __init__(self, message, instance=None, time=None):
        super().__init__(message)
        self.instance = instance
        self.time = time
        self.result = None


class DivergenceError(SimulationError):
    """An exchanged value left the range its FMU declares (or grew without bound).

    The run ends there with status ``diverged``: an unstable loop or model, not a
    result.
    """


class TerminationRequested(Exception):
    """An FMU's fmi2DoStep returned Discard with fmi2Terminated true (a normal end)."""

    def __init__(self, instance, time, message=""):
        super().__init__(instance, time, message)
        self.instance = instance
        self.time = time
        self.message = message


class EarlyEndWarning(UserWarning):
    """An FMU ended the run before the stop time by asking to terminate (not an error)."""


class SaturationWarning(UserWarning):
    """Instances that ran at a rail or limit (``sat_*`` flags) for part of the run."""


class TimebaseWarning(UserWarning):
    """A run whose tick grid is much finer than its instances need."""


class JacobiLoopWarning(UserWarning):
    """An algebraic loop that the Jacobi algorithm leaves unsolved (one step late)."""


class UnconnectedInputWarning(UserWarning):
    """Inputs that no connection, parameter or action drives."""
