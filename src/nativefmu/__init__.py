"""Native FMUs: the project's FMUs as self-contained C99 co-simulation FMUs (FMI 2.0 or 3.0).

A native FMU swaps in place for its Python twin (same file name, modelIdentifier,
variables, value references, units and ModelStructure) and runs without Python:
``sources/`` (libc and libm only), ``binaries/linux64`` (and ``win64`` when a
mingw-w64 cross compiler is installed), model data in ``resources/``.

- :mod:`nativefmu.build`: :func:`~nativefmu.build.build_native` (one spec) and
  :func:`~nativefmu.build.build_all_native` (every model with a C kernel).
- :mod:`nativefmu.data`: the plain-text model data the C kernels read.
- :mod:`nativefmu.fmi3xml`: the FMI 3.0 model description made from the FMI 2.0 one
  (``build_native(..., fmi=3)``).
- ``csrc/``: the shared core (``jfcore.c``: variables, phases, state layout documented
  there), the FMI 2.0 and 3.0 layers over it (``fmi2.c``, ``fmi3.c``) and one C kernel
  per slave: ``structure.c``, ``piezo.c``, ``controller.c``, ``excitation.c``, ``acs.c``,
  ``disturbance.c``.

This package is build tooling: it is never bundled into an FMU.
"""

from nativefmu.build import NativeBuildError, build_all_native, build_native
from nativefmu.data import NativeUnsupportedError

__all__ = ["NativeBuildError", "NativeUnsupportedError", "build_all_native", "build_native"]
