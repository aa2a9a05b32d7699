"""Piezo stack datasheet model, amplifier, hysteresis, and the piezo FMU slave."""

from piezofmu.actuator import ACTUATORS, PiezoActuator, StrainGauge, actuator_preset
from piezofmu.amplifier import AMPLIFIERS, Amplifier, amplifier_preset
from piezofmu.hysteresis import BoucWen
from piezofmu.stack import PRESETS, PiezoStack, preset

__all__ = [
    "ACTUATORS",
    "AMPLIFIERS",
    "Amplifier",
    "BoucWen",
    "PRESETS",
    "PiezoActuator",
    "PiezoStack",
    "StrainGauge",
    "actuator_preset",
    "amplifier_preset",
    "preset",
]
