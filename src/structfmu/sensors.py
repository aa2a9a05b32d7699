"""Accelerometer bandwidth: a Butterworth low-pass on every acceleration output.

An acceleration output of a reduced model feeds the input through (``D u``) and carries
the local modes of the Ritz block (stack-fitting modes of kHz).  Sampled at a co-
simulation rate of 1 kHz, a zero-order-held force step rings those modes for several
samples and the ringing aliases into the band: on the EOS testbed the sampled payload
acceleration per strut force is then about 700 times the true 22 Hz response.  Real
accelerometers see none of it: the testbed's have a 150 Hz bandwidth (paper), and a
sampled sensor chain has an anti-aliasing filter.  :class:`SensorLowpass` models that
chain as part of the continuous structure, so the exact discretisation samples the
filtered signal.  A filtered acceleration output has no direct feedthrough.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

__all__ = ["SensorLowpass", "filter_blocks"]


@dataclass(frozen=True)
class SensorLowpass:
    """Butterworth low-pass of ``order`` with its -3 dB corner at ``cutoff_hz``.

    Parameters
    ----------
    order : int
        Filter order, at least 1.
    cutoff_hz : float
        Corner frequency (Hz), positive.
    """

    order: int
    cutoff_hz: float

    def __post_init__(self):
        if int(self.order) != self.order or self.order < 1:
            raise ValueError(f"sensor low-pass order must be a whole number >= 1, "
                             f"got {self.order!r}")
        if not (np.isfinite(self.cutoff_hz) and self.cutoff_hz > 0):
            raise ValueError(f"sensor low-pass corner must be positive and finite, "
                             f"got {self.cutoff_hz!r} Hz")
        object.__setattr__(self, "order", int(self.order))
        object.__setattr__(self, "cutoff_hz", float(self.cutoff_hz))

    def siso(self):
        """Real state-space ``(a, b, c)`` of the filter, unit DC gain, no feedthrough.

        Returns
        -------
        a : ndarray, shape (order, order)
        b : ndarray, shape (order, 1)
        c : ndarray, shape (1, order)
        """
        # the analog Butterworth prototype's poles scaled to the corner, and the
        # controllable canonical form of k / prod(s - p): what scipy.signal's butter and
        # zpk2ss give, bit for bit (tested), without importing scipy.signal (0.55 s of
        # every short command)
        n, wc = self.order, 2 * np.pi * self.cutoff_hz
        p = -np.exp(1j * np.pi * np.arange(-n + 1, n, 2) / (2 * n)) * wc
        den = np.poly(p).real
        a = np.zeros((n, n))
        a[0] = -den[1:] / den[0]
        a[1:, :-1] = np.eye(n - 1)
        b = np.zeros((n, 1))
        b[0, 0] = 1.0
        c = np.zeros((1, n))
        c[0, -1] = wc ** n / den[0]
        return a, b, c

    def response(self, freqs_hz) -> np.ndarray:
        """Complex frequency response at ``freqs_hz`` (Hz), shape (n_f,)."""
        a, b, c = self.siso()
        s = 2j * np.pi * np.asarray(freqs_hz, float)
        eye = np.eye(self.order)
        return np.array([(c @ np.linalg.solve(si * eye - a, b))[0, 0] for si in s])

    def to_json(self) -> list:
        return [self.order, self.cutoff_hz]


@functools.lru_cache(maxsize=32)
def filter_blocks(lowpass: SensorLowpass | None, n_channels: int):
    """Block-diagonal filter for ``n_channels`` signals (cached, read-only arrays).

    Parameters
    ----------
    lowpass : SensorLowpass or None
        The filter of each channel; ``None`` for none.
    n_channels : int
        Number of filtered signals (acceleration outputs).

    Returns
    -------
    (A_f, B_f, C_f) : ndarrays of shapes (n_f, n_f), (n_f, n_channels), (n_channels, n_f)
        ``n_f = order * n_channels`` (0 without a filter).
    """
    if lowpass is None or n_channels == 0:
        return np.zeros((0, 0)), np.zeros((0, n_channels)), np.zeros((n_channels, 0))
    a, b, c = lowpass.siso()
    eye = np.eye(n_channels)
    blocks = np.kron(eye, a), np.kron(eye, b), np.kron(eye, c)
    for m in blocks:
        m.setflags(write=False)
    return blocks
