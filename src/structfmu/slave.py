"""The structure FMU: steps a ReducedModel with the exact ZOH discretisation.

Inputs are the model's load channels and one force per active member (``fc_<name>``,
N).  Outputs are its named sensors: LOS angles (rad), angular rates (rad/s), gauge
strains, member elongations (m) and accelerations (m/s^2).  Only accelerations have
direct feedthrough, and each declares exactly the inputs it depends on; a model whose
accelerometers have a bandwidth (``ReducedModel.accel_lowpass``) has none.  Any
communication step is accepted; discretisations are cached by step size, and a step
within the host's rounding of a cached one is that step (``ZohStepper.discrete``).
"""

from __future__ import annotations

import numpy as np

from fmukit.slave import FmuSlave
from fmukit.units import MAX_ANGLE, MAX_STRAIN
from structfmu.discrete import ZohStepper
from structfmu.fem import UNITS
from structfmu.reduced import ReducedModel


class StructureSlave(FmuSlave):
    """FMI slave over :class:`structfmu.discrete.ZohStepper` (model in ``model.npz``)."""

    state_attributes = ("_x",)
    model_file = "model.npz"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        model = ReducedModel.load(self.resource_path(self.model_file))
        self.stepper = ZohStepper(model)
        self._x = self.stepper.x  # the state vector (restored in place by set-state)
        units = model.meta.get("input_units") or ["N"] * model.n_inputs
        self.u = self.add_real_block(
            "u", names=list(model.input_names), causality="input", unit=list(units),
            start=0.0, description="load (force N or torque N.m) / actuator force")
        deps = []
        for i in range(model.n_outputs):
            deps.append([model.input_names[j] for j in np.flatnonzero(self.stepper.D[i])])
        self.y = self.add_real_block(
            "y", names=list(model.output_names), causality="output",
            unit=[UNITS[k] for k in model.output_kinds], depends_on=deps,
            description="structural output")
        limits = {"strain": MAX_STRAIN, "angle": MAX_ANGLE}
        for name, kind in zip(model.output_names, model.output_kinds):
            if kind in limits:
                self.declare_range(name, -limits[kind], limits[kind])

    def exit_initialization_mode(self):
        self.stepper.update_state_outputs()
        self.stepper.outputs(self.u, self.y)
        return True

    def set_real(self, vrs, values):
        """Set Real variables; refresh the feedthrough outputs.

        Parameters
        ----------
        vrs : list of int
            Value references.
        values : list of float
            Values, one per reference, in each variable's unit (inputs: N or N.m).
        """
        super().set_real(vrs, values)
        if self.stepper.has_feedthrough:
            self.stepper.outputs(self.u, self.y)

    def do_step(self, current_time, step_size):
        """Advance the structure one step with the inputs held.

        Parameters
        ----------
        current_time : float
            Communication point at the start of the step (s); not used.
        step_size : float
            Step (s); a step within rounding of a cached one reuses its discretisation.

        Returns
        -------
        bool
            Always True.
        """
        self.stepper.step(self.u, step_size)
        self.stepper.update_state_outputs()
        self.stepper.outputs(self.u, self.y)
        return True

    def _fmu_state_restored(self):
        self.stepper.update_state_outputs()
