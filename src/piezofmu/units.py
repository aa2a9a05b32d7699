"""Unit conversions used at the edges (datasheets, reports). The core is SI."""

INCH = 0.0254  # m
MM = 1e-3  # m
LBF = 4.4482216152605  # N
LB = 0.45359237  # kg
LBF_PER_IN = LBF / INCH  # N/m
ARCSEC = 3.141592653589793 / (180.0 * 3600.0)  # rad
G0 = 9.80665  # m/s^2
