"""The co-simulation engine: FMU information, the checked plan, the bus, the schedule
and the simulation that steps FMI 2.0 co-simulation FMUs through fmpy.

Semantics
---------
Time is an integer tick on an exact rational base step (:mod:`orchestrator.timebase`).
An instance with period ``p`` ticks steps at every tick ``k`` with ``k % p == 0`` from
``t_k`` to ``t_k + p·base``; its inputs are set just before and held over the step
(zero-order hold).  A connection carries ``gain * output + offset``.

After a step from ``t_k`` to ``t_k + h`` an output is the value at ``t_k + h``; it is
*stamped* ``t_k + h`` and becomes the source's value at communication points from then
on.  The one exception is an output with direct feedthrough (ModelStructure
``dependencies`` on a connected input): it is computed from the inputs of the step at
``t_k`` and is used at once, as a discrete controller's output ``u_k = C x_k + D y_k``
is applied over its own sample interval.  At a tick, every due instance reads its
connected inputs and steps:

* ``gauss-seidel`` (default): a feedthrough output is read after its source stepped in
  this tick (sources before sinks, topological order of the feedthrough graph); any
  other output is read at its value at ``t_k`` (the latest value stamped ``<= t_k``),
  so independent instances never depend on the order they step in, and a slow
  source's output is never seen before its time.  A cycle of feedthrough is an
  algebraic loop: it is iterated to a fixed point, rolling the members back with
  ``fmi2SetFMUstate`` between iterations, when every member can get and set its state.
* ``jacobi``: every input reads its source's value at ``t_k`` (stamped ``<= t_k``).
  For periods that divide one another this is exactly libcosim's fixed-step algorithm
  (libcosim exchanges values only at common multiples of the two periods, so it
  differs when neither period divides the other).

Recorded rows are the values at ticks that are multiples of the output interval: each
variable's value at ``t_k`` (the latest stamped ``<= t_k``), read before that tick's steps.

The rooms, in pipeline order: :mod:`.fmuinfo` (what an FMU declares, where it is found),
:mod:`.plan` (a scenario checked against its FMUs), :mod:`.graph` (feedthrough order and
algebraic loops), :mod:`.instance` (one FMU bound to the raw FMI calls), :mod:`.bus`
(the exchanged values and the functions that move them), :mod:`.schedule` (the calls of
each tick) and :mod:`.simulation` (initialise, run, record).
"""

from .errors import (
    DivergenceError,
    EarlyEndWarning,
    JacobiLoopWarning,
    SaturationWarning,
    SimulationError,
    TimebaseWarning,
    UnconnectedInputWarning,
)
from .fmuinfo import FmuInfo, Variable, find_fmu, read_fmu_info
from .graph import AlgebraicLoopError
from .plan import Plan, prepare
from .simulation import Simulation

__all__ = [
    "SimulationError",
    "AlgebraicLoopError",
    "UnconnectedInputWarning",
    "TimebaseWarning",
    "JacobiLoopWarning",
    "EarlyEndWarning",
    "DivergenceError",
    "SaturationWarning",
    "FmuInfo",
    "Variable",
    "Plan",
    "find_fmu",
    "read_fmu_info",
    "prepare",
    "Simulation",
]
