"""Shared FMU plumbing bundled into every FMU of the project.

- :mod:`fmukit.slave`: :class:`~fmukit.slave.FmuSlave`, the slave base class
  (typed, unit-aware, array-backed variables; full FMU state save/restore).
- :mod:`fmukit.state`: serialized FMU state as a versioned, data-only byte layout
  (no pickle), validated on restore.
- :mod:`fmukit.modeldesc`: units, exact ModelStructure and capability flags in
  modelDescription.xml; the project's own checks.
- :mod:`fmukit.build`: :class:`~fmukit.build.FmuSpec` and :func:`~fmukit.build.build_fmu`.
- :mod:`fmukit.loader`: the C loader that lets C-only hosts run the FMUs.

This package must stay importable inside an FMU: it imports numpy and pythonfmu
only, never fmpy (except in :mod:`fmukit.testing` and :mod:`fmukit.registry`).
"""
