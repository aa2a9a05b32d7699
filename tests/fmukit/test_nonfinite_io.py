"""Python FMUs never report a NaN or infinite output with OK.

Before, a NaN or inf on a Real input of the Python controller, structure or ACS FMU came
back as NaN (or inf) outputs with status OK.  Now ``setReal`` sets nothing and logs an
error naming the input and its value (pythonfmu makes an exception there Fatal), and the
next ``doStep`` ends with Discard (pythonfmu's status for a step that returns False) saying
the same, stepping nothing; an output that a step leaves
non-finite ends the step with an error naming it.  Reference: IEEE (a finite value is one
``math.isfinite`` accepts) and the FMI status the host sees.
"""

from __future__ import annotations

import ctypes
import math

import fmpy.fmi2 as f2
import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.logging import addLoggerProxy

from orchestrator.cosim import instance as ci

pytestmark = pytest.mark.slow

MODELS = ("controller_truss10_strain_diag", "truss10_structure", "acs", "piezo_p243_40",
          "eos_testbed_structure")
_KEEP: list = []   # callback structs outlive the instances (fmpy's logger proxy)


class Instance:
    """A Python FMU initialised at t = 0 whose log messages are kept."""

    def __init__(self, path):
        md = read_model_description(str(path))
        self.inputs = [v for v in md.modelVariables
                       if v.causality == "input" and v.type == "Real"]
        self.outputs = [v.valueReference for v in md.modelVariables
                        if v.causality == "output" and v.type == "Real"]
        de = md.defaultExperiment
        self.h = float(de.stepSize) if de is not None and de.stepSize else 1e-3
        self.fmu = f2.FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)),
                                modelIdentifier=md.coSimulation.modelIdentifier,
                                instanceName="t")
        key, self.messages = next(ci._LOG_KEYS), []
        ci._LOG_SINKS[key] = self.messages
        cb = f2.fmi2CallbackFunctions()
        cb.logger = ci._shared_logger(f2.fmi2CallbackLoggerTYPE)
        cb.allocateMemory = f2.defaultCallbacks.allocateMemory
        cb.freeMemory = f2.defaultCallbacks.freeMemory
        cb.componentEnvironment = ctypes.c_void_p(key)
        addLoggerProxy(ctypes.byref(cb))
        _KEEP.append(cb)
        self.fmu.instantiate(callbacks=cb, loggingOn=True)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def step(self, k, value=None):
        if value is not None:
            self.fmu.setReal([v.valueReference for v in self.inputs], [value] * len(self.inputs))
        self.fmu.doStep(k * self.h, self.h)
        return np.array(self.fmu.getReal(self.outputs))

    def text(self) -> str:
        return " | ".join(text for _, text in self.messages)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("model", MODELS)
def test_a_non_finite_input_ends_the_step_with_an_error_naming_it(suite_fmus, model, value):
    inst = Instance(suite_fmus(model, kind="python")[model])
    assert np.all(np.isfinite(inst.step(0, 0.0)))
    with pytest.raises(FMICallException, match=r"status [23] \((discard|error)\)"):
        inst.step(1, value)
    first = inst.inputs[0].name
    said = f"{first} = {value!r} is not a finite number"
    assert f"setReal: {said}; nothing was set (set a finite value)" in inst.text()
    assert f"s: {said} (refused by setReal); nothing was stepped" in inst.text()
    assert np.all(np.isfinite(inst.fmu.getReal(inst.outputs)))   # nothing computed from it


@pytest.mark.parametrize("model", MODELS)
def test_finite_inputs_step_ok_with_finite_outputs(suite_fmus, model):
    """The check refuses nothing finite: 1e300 on every input steps (as before)."""
    inst = Instance(suite_fmus(model, kind="python")[model])
    inst.step(0, 0.0)
    y = inst.step(1, 1e300)
    assert np.all(np.isfinite(y)) and inst.text() == ""


@pytest.mark.parametrize("model, output", [("controller_truss10_strain_diag", "u1"),
                                           ("piezo_p243_40", "strain")])
def test_an_output_left_non_finite_by_a_step_ends_it_with_an_error(suite_fmus, model, output):
    """1.7e308 on the inputs, finite, overflows the controller's state (u1 = nan by the
    second sample) and the piezo's strain (inf): the step says which output, not OK."""
    inst = Instance(suite_fmus(model, kind="python")[model])
    inst.step(0, 0.0)
    with pytest.raises(FMICallException, match=r"status [23] \((discard|error)\)"):
        for k in range(1, 6):
            inst.step(k, 1.7e308)
    assert f"output {output} = " in inst.text()
    assert "after the step is not a finite number" in inst.text()
