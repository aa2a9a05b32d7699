"""Unit constants of the suite, used at the edges (datasheets, reports); the core is SI.

Each length, force, mass or angle constant is the value of one unit in SI (``INCH`` is
0.0254 m): multiply to convert into SI, divide to convert out of it.  The ``*_PER_RAD``
factors convert radians into display units (FMI ``DisplayUnit`` factors).
"""

INCH = 0.0254  # m
MM = 1e-3  # m
LBF = 4.4482216152605  # N
LB = 0.45359237  # kg
LBF_PER_IN = LBF / INCH  # N/m
ARCSEC = 3.141592653589793 / (180.0 * 3600.0)  # rad
G0 = 9.80665  # m/s^2
MICRO_G = 9.80665e-6  # m/s^2

#: rad -> arcsec (180 * 3600 / pi).
ARCSEC_PER_RAD = 206264.80624709636
#: rad -> deg (180 / pi).
DEG_PER_RAD = 57.29577951308232

# Physical ranges the FMUs declare on their outputs (FMI ``min``/``max``): a value beyond
# one means the model has left its validity, in practice a loop that diverges.
#: Strain magnitude (-) no member material of the suite survives: aluminium yields near
#: 0.4 %, steel near 0.2 %, piezo ceramics crack near 0.1 %.
MAX_STRAIN = 0.01
#: Angle magnitude (rad) beyond which a small-angle pointing model means nothing.
MAX_ANGLE = 3.141592653589793
