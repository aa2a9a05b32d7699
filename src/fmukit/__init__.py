"""Shared FMU runtime bundled into every FMU of the project.

- :mod:`fmukit.slave`: :class:`~fmukit.slave.FmuSlave`, the slave base class
  (typed, unit-aware, array-backed variables; full FMU state save/restore).
- :mod:`fmukit.state`: serialized FMU state as a versioned, data-only byte layout
  (no pickle), validated on restore.
- :mod:`fmukit.modeldesc`: units, exact ModelStructure and capability flags in
  modelDescription.xml; the project's own checks.
- :mod:`fmukit.units`: the unit constants of the whole suite (inch, lbf, arcsec, ...).

This package must stay importable inside an FMU: it imports numpy and pythonfmu
only, never fmpy.  Building, validating and testing FMUs is :mod:`fmutools`' job
(never bundled).
"""
