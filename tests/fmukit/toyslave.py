"""Toy slave for the fmukit tests: a discrete first-order filter.

x[k+1] = a x[k] + b u[k]
y_state[k] = c x[k]              (no feedthrough)
y_ft[k]    = c x[k] + d u[k]     (direct feedthrough of u)
"""

import numpy as np

from fmukit.slave import FmuSlave


class ToyFilter(FmuSlave):
    state_attributes = ("x", "n_steps")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.add_parameter("a", 0.9, unit="1", description="pole of the filter")
        self.add_parameter("b", 0.1, unit="1", description="input gain", tunable=True)
        self.add_parameter("d", 0.5, unit="m/V", description="feedthrough gain")
        self.add_parameter("gain_mode", 1, description="integer parameter")
        self.add_parameter("enabled", True, description="boolean parameter")
        self.add_parameter("label", "toy", description="string parameter")
        self.add_input("u", unit="V", description="input voltage")
        self.add_real_block("w", 2, causality="input", unit="rad", description="extra inputs")
        self.add_output("y_state", unit="m", depends_on=[], description="state output")
        self.add_output("y_ft", unit="m", depends_on=["u"], description="feedthrough output")
        self.add_real_block("angle", 2, causality="output", unit="rad",
                            depends_on=[["w[1]"], []], description="angles")
        self.x = np.zeros(3)
        self.n_steps = 0

    def _outputs(self):
        self.y_state = self.x[0]
        self.y_ft = self.x[0] + self.d * self.u
        self.angle[0] = self.x[1] + self.w[0]
        self.angle[1] = self.x[2]

    def exit_initialization_mode(self):
        self._outputs()

    def do_step(self, current_time, step_size):
        u = self.u if self.enabled else 0.0
        self.x[0] = self.a * self.x[0] + self.b * u * self.gain_mode
        self.x[1] = np.sin(self.x[0]) + 0.5 * self.x[1]
        self.x[2] = 0.99 * self.x[2] + 1e-3 * self.w[1]
        self.n_steps += 1
        self._outputs()
        return True
