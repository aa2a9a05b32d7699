"""Piezo stack datasheet model, amplifier, hysteresis, and the piezo FMU slave."""

from piezofmu.stack import PRESETS, PiezoStack, preset

__all__ = ["PRESETS", "PiezoStack", "preset"]
