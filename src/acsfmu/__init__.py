"""Attitude control (PID per axis, reaction wheels) and the ACS FMU slave."""
