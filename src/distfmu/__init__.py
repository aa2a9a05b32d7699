"""Disturbance sources, EOS AM-1 event presets, and the disturbance FMU slave."""
