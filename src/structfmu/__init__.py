"""Truss finite elements with embedded piezo members, reduction, state space.

Pipeline: model (``fem``) -> reduce (``reduce``) -> state space (``statespace``)
-> discretise (``discrete``) -> FMU (``slave``).  Pure numerics on numpy/scipy in SI
units; nothing here imports pythonfmu or fmpy (the FMU slave module aside).
"""
