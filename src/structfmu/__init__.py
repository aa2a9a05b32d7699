"""Truss finite elements with embedded piezo members, reduction, state space.

Pipeline: model (``fem``) -> reduce (``reduce``) -> state space (``statespace``)
-> discretise (``discrete``) -> FMU (``slave``); ``placement`` ranks a truss's members
by modal strain energy, to choose where an active member goes.  Pure numerics on
numpy/scipy in SI units; nothing here imports pythonfmu or fmpy (the FMU slave module
aside).
"""
