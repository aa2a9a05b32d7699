"""Build and validation tooling of the suite's FMUs; never bundled into an FMU.

- :mod:`fmutools.build`: :class:`~fmutools.build.FmuSpec` and
  :func:`~fmutools.build.build_fmu` (a pythonfmu FMU with the C loader).
- :mod:`fmutools.loader`: the C loader that lets C-only hosts run the FMUs, compiled
  once per configuration.
- :mod:`fmutools.registry`: which package provides which FMU; build them all, or only
  the missing and stale ones.
- :mod:`fmutools.validate`: FMI 2.0 errors (fmpy) and the project's conventions.
- :mod:`fmutools.fmucache`: the current user's private cache (extracted FMU and SSP
  archives, compiled loaders).

What an FMU carries at run time is :mod:`fmukit` (and the slave's own packages).

An FMU folder holds each suite FMU in two builds: the native (C99) one in the folder
itself, its Python (pythonfmu) twin in :data:`PYTHON_SUBDIR`; :data:`FMU_KINDS` names
them.
"""

#: Subfolder of an FMU folder that holds the Python build of the suite's FMUs.
PYTHON_SUBDIR = "python"
#: The two builds of a suite FMU.
FMU_KINDS = ("native", "python")
