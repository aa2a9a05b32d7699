"""Piezoelectric stack datasheet model (pure numerics, SI units).

The embedded active member of the paper's Eq. (1) has

    m_e = m / 6,   k_e = k^d - c h^2,   f_c = c h v

with ``k^d`` the open-circuit stiffness, ``c`` the clamped capacitance and ``h`` the
force/charge constant.  Datasheets give neither ``c h`` nor ``k^d``; they give the free
stroke ``d0`` at the rated voltage ``V0`` and a stiffness.  We read the datasheet
stiffness as the stiffness seen by a voltage-driven stack (short circuit), i.e. ``k_e``,
because that is how stack stiffness is measured under a voltage amplifier.  Then:

* Free stroke: with no external load, Eq. (1) gives ``k_e * d = f_c`` so
  ``d0 = c h V0 / k_e`` and therefore ``c h = k_e d0 / V0`` (N/V).
* Open-circuit stiffness: ``k^d = k_e + c h^2 = k_e + (c h)^2 / c`` with the assumed
  clamped capacitance ``c``.
* Blocked force at the rated voltage: ``c h V0 = k_e d0``.
* Mass: the datasheet resonance ``f_r`` is taken for the stack fixed at one end and free
  at the other, ``2 pi f_r = sqrt(k_e / m_eff)`` with ``m_eff = m / 3`` (the usual
  stack-catalogue convention), so ``m = 3 k_e / (2 pi f_r)^2``.

The capacitances are assumptions (the paper does not give them), marked as such in
``PRESETS``; they only matter for the amplifier's current (slew) limit and ``k^d``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from fmukit.units import INCH, LBF, LBF_PER_IN


@dataclass(frozen=True)
class PiezoStack:
    """Datasheet of a piezo stack actuator.

    Parameters
    ----------
    name : str
        Model number, e.g. ``"P-243.30"``.
    stroke : float
        Free stroke at ``rated_voltage`` (m).
    rated_voltage : float
        Voltage giving ``stroke`` (V).
    stiffness : float
        Stiffness under voltage drive, ``k_e`` (N/m).
    max_force : float
        Maximum pushing force (N).
    resonance : float
        Resonant frequency, one end fixed (Hz).
    capacitance : float
        Clamped capacitance ``c`` (F). Assumed where the datasheet is silent.
    length : float
        Active length of the stack (m), used for strains.
    """

    name: str
    stroke: float
    rated_voltage: float
    stiffness: float
    max_force: float
    resonance: float
    capacitance: float
    length: float = 0.1

    def __post_init__(self):
        for field in ("stroke", "rated_voltage", "stiffness", "max_force", "resonance",
                      "capacitance", "length"):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(
                    f"piezo stack {self.name!r}: {field} must be a positive number, got {value!r}"
                )

    @property
    def ch(self) -> float:
        """Force per volt ``c h = k_e d0 / V0`` (N/V)."""
        return self.stiffness * self.stroke / self.rated_voltage

    @property
    def k_e(self) -> float:
        """Effective (voltage-driven) stiffness of Eq. (1) (N/m)."""
        return self.stiffness

    @property
    def k_d(self) -> float:
        """Open-circuit stiffness ``k^d = k_e + (c h)^2 / c`` (N/m)."""
        return self.stiffness + self.ch**2 / self.capacitance

    @property
    def h(self) -> float:
        """Force/charge constant ``h = (c h) / c`` (N/C)."""
        return self.ch / self.capacitance

    @property
    def mass(self) -> float:
        """Stack mass from the resonance, ``m = 3 k_e / (2 pi f_r)^2`` (kg)."""
        return 3.0 * self.stiffness / (2.0 * math.pi * self.resonance) ** 2

    @property
    def m_e(self) -> float:
        """Equivalent nodal mass of Eq. (1), ``m / 6`` (kg)."""
        return self.mass / 6.0

    @property
    def blocked_force(self) -> float:
        """Blocked force at the rated voltage, ``c h V0`` (N)."""
        return self.ch * self.rated_voltage

    def force(self, voltage):
        """Actuator force ``f_c = c h v`` (N) for a voltage (V); arrays accepted."""
        return self.ch * voltage

    def free_stroke(self, voltage):
        """Free stroke ``f_c / k_e`` (m) for a voltage (V)."""
        return self.force(voltage) / self.stiffness

    def replace(self, **changes) -> "PiezoStack":
        """Copy with some fields changed."""
        return replace(self, **changes)


# Table 1 of the paper and ARCHITECTURE.md; capacitances and lengths are assumptions
# chosen so that the electromechanical coupling is k33^2 = 0.5, typical of PZT stacks,
# i.e. k^d = 2 k_e and c = (c h)^2 / k_e: 336 nF and 504 nF for the 1000 V P-243 stacks,
# 10.7 uF for the 100 V P-845.37.
PRESETS: dict[str, PiezoStack] = {
    "P-243.30": PiezoStack("P-243.30", 40e-6, 1000.0, 1.1992e6 * LBF_PER_IN, 6750 * LBF,
                           4500.0, capacitance=336e-9, length=1.6 * INCH),
    "P-243.40": PiezoStack("P-243.40", 60e-6, 1000.0, 0.7995e6 * LBF_PER_IN, 6750 * LBF,
                           2200.0, capacitance=504e-9, length=2.4 * INCH),
    "P-845.37": PiezoStack("P-845.37", 40e-6, 100.0, 3.8258e5 * LBF_PER_IN, 300 * LBF,
                           9000.0, capacitance=10.7e-6, length=1.6 * INCH),
}


def preset(name: str) -> PiezoStack:
    """Return a preset stack by model number (``"P-243.30"``, ``"P-243.40"``, ``"P-845.37"``)."""
    key = name.upper().replace("P243", "P-243").replace("P845", "P-845")
    if key not in PRESETS:
        raise KeyError(f"unknown piezo stack {name!r}; known: {', '.join(PRESETS)}")
    return PRESETS[key]
