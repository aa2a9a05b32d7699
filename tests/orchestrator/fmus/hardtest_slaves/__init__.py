"""A test slave that fails where the master must not crash afterwards.

:class:`InitFails` raises in ``exit_initialization_mode`` when its parameter ``bad``
is true; pythonfmu then reports fmi2Fatal and frees the Python object behind the
instance, so any later call into that instance would crash the host.
"""

from fmukit.slave import FmuSlave


class InitFails(FmuSlave):
    """Outputs its input; refuses to initialise when ``bad`` is true."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.add_parameter("bad", False, description="raise in initialisation")
        self.add_input("u", unit="1")
        self.add_output("y", unit="1", depends_on=[])

    def exit_initialization_mode(self):
        if self.bad:
            raise ValueError("parameter bad is true: refusing to initialise")

    def do_step(self, current_time, step_size):
        self.y = self.u
        return True
