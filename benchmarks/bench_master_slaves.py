"""The two FMU slaves of ``bench_master.py``, carried by the benchmark itself.

- :class:`Integrator`: ``x(t+h) = x(t) + h k u`` (no direct feedthrough).
- :class:`Gain`: ``y = k u + b + c n`` (direct feedthrough from ``u`` and ``n``), with a
  state ``acc`` (running integral of ``u``).

The same variables as the master's test FMUs (``tests/orchestrator/fmus``), so the
benchmark measures what it always measured.
"""

from fmukit.slave import FmuSlave


class Integrator(FmuSlave):
    """Forward-Euler integrator with gain, no direct feedthrough."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.add_parameter("k", 1.0, unit="1", tunable=True, description="gain")
        self.add_parameter("x0", 0.0, unit="1", description="initial state")
        self.add_input("u", unit="1")
        self.add_output("x", unit="1", depends_on=[])
        self.add_output("xm", unit="m", depends_on=[], description="x with a unit")
        self.add_integer("steps", 0, causality="output", variability="discrete",
                         depends_on=[])

    def exit_initialization_mode(self):
        self.x = self.x0
        self.xm = self.x0

    def do_step(self, current_time, step_size):
        self.x = self.x + step_size * self.k * self.u
        self.xm = self.x
        self.steps = self.steps + 1
        return True


class Gain(FmuSlave):
    """Static gain with direct feedthrough and an integral state."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.add_parameter("k", 1.0, unit="1", tunable=True)
        self.add_parameter("b", 0.0, unit="1", tunable=True)
        self.add_parameter("c", 0.0, unit="1")
        self.add_input("u", unit="1")
        self.add_integer("n", 0, causality="input", variability="discrete")
        self.add_boolean("enable", True, causality="input", variability="discrete")
        self.add_output("y", unit="1", depends_on=["u", "n", "enable"])
        self.add_output("acc", unit="1", depends_on=[])

    def _out(self):
        return (self.k * self.u + self.b + self.c * self.n) if self.enable else 0.0

    def exit_initialization_mode(self):
        self.y = self._out()

    # FMI 2.0: an output with direct feedthrough reflects the inputs just set
    def set_real(self, vrs, values):
        super().set_real(vrs, values)
        self.y = self._out()

    def set_integer(self, vrs, values):
        super().set_integer(vrs, values)
        self.y = self._out()

    def set_boolean(self, vrs, values):
        super().set_boolean(vrs, values)
        self.y = self._out()

    def do_step(self, current_time, step_size):
        self.y = self._out()
        self.acc = self.acc + step_size * self.u
        return True
