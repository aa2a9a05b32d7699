"""Wheel-speed sweeps: the steady-state jitter of a reaction wheel over its speed range.

At a constant speed ``Omega`` a wheel-imbalance source is a sum of spectral lines
(:meth:`distfmu.sources.WheelImbalance.lines`: harmonics ``h_i Omega`` with amplitudes
``~ Omega^2``).  The closed loop answers each line with its periodic steady state
(:meth:`~orchestrator.analysis.fast.FastResponse.steady_state`, exact with mixed rates),
so the record at every speed is a sum of a few known sequences; the jitter metrics of
the campaign are computed on that record, over the campaign's record length, as a
co-simulated case that had settled would give them.

A loop with an unstable pole has no steady state: the sweep says so, naming the pole.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import metrics as M
from .blocks import AnalysisError
from .fast import FastResponse
from .steady import loop_eigenvalues
from .structpoles import unstable_count

__all__ = ["WheelSweep", "steady_jitter", "unstable_poles", "wheel_sweep"]

RPM = 2 * math.pi / 60.0   # rad/s per rpm


@dataclass(frozen=True)
class WheelSweep:
    """The steady-state jitter at each wheel speed.

    Attributes
    ----------
    speeds_rpm : ndarray, shape (n_s,)
    refs : tuple of str
        Recorded outputs, ``instance.variable``.
    metrics : tuple of (str, float or None)
        ``(kind, window)`` as a campaign's.
    values : ndarray, shape (n_s, n_refs, n_metrics)
        Metric values (unit of the outputs, e.g. rad).
    """

    speeds_rpm: np.ndarray
    refs: tuple
    metrics: tuple
    values: np.ndarray

    def worst(self, ref: str, metric=None) -> tuple[float, float]:
        """``(speed_rpm, value)`` of the largest value of ``ref``.

        Parameters
        ----------
        ref : str
            A recorded output of the sweep.
        metric : tuple of (str, float or None), optional
            One of :attr:`metrics` (default the first).

        Returns
        -------
        tuple of float
        """
        j = self.refs.index(ref)
        m = 0 if metric is None else self.metrics.index(metric)
        i = int(np.argmax(self.values[:, j, m]))
        return float(self.speeds_rpm[i]), float(self.values[i, j, m])


def unstable_poles(fr: FastResponse, tol: float = 1e-6) -> list:
    """Poles of the loop over its super-period with ``|z| > 1 + tol`` (none if stable).

    A free rigid body is a double pole at 1, which a solver finds only to about
    ``sqrt(eps)``: ``tol`` sits above that.  A structured loop whose super-period map is
    its modes' own powers plus a low-rank coupling is counted from that form
    (:func:`.structpoles.unstable_count`); the dense eigenvalues give the poles where it
    finds any, and decide where it does not apply or is not certain.

    Parameters
    ----------
    fr : FastResponse
        The compiled loop.
    tol : float
        Margin above ``|z| = 1`` (-).

    Returns
    -------
    list of complex
        Largest magnitude first.
    """
    return _pole_verdict(fr, tol)[0]


def _pole_verdict(fr: FastResponse, tol: float = 1e-6) -> tuple:
    """``(poles, how)``: :func:`unstable_poles` and what decided them, ``"counted"``
    (the count from the structure; where it found poles, the dense eigenvalues then
    gave them) or ``"eigenvalues"`` (the dense eigenvalues, or the Schur form of a
    solved steady state)."""
    if fr._schur is not None:   # a steady state has been solved on this loop
        ev, how = np.diag(fr._schur[0]), "eigenvalues"
    else:
        count = unstable_count(fr, tol)
        if count == 0:   # from the structure: no dense eigenvalues
            return [], "counted"
        how = "eigenvalues" if count is None else "counted"
        ev = loop_eigenvalues(fr.period_map())
    return sorted((z for z in ev if abs(z) > 1 + tol), key=abs, reverse=True), how


def steady_jitter(fr: FastResponse, freqs_hz, phasors, refs, metrics, duration: float, *,
                  chunk: int = 25) -> np.ndarray:
    """The campaign's metrics of the steady-state record at each point of a sweep.

    Point ``i`` drives the sources with ``sum_h Re(phasors[i, h] exp(j 2 pi f_ih t))``;
    its record (ticks ``0, every, ...`` over ``duration``, ``y(t_(nP+p)) = Re(sum_h
    z_h^n Y_h[p])``, exact with mixed rates) gets the metrics.

    Parameters
    ----------
    fr : FastResponse
        The compiled closed loop; it must be stable.
    freqs_hz : array_like, shape (n_p, n_h)
        Frequencies of the lines at each point (Hz).
    phasors : array_like, shape (n_p, n_h, m), complex
        Their amplitudes on every source channel.
    refs : sequence of str
        Recorded outputs.
    metrics : sequence of (str, float or None)
        ``(kind, window)`` pairs.
    duration : float
        Record length (s).
    chunk : int
        Points reconstructed together.

    Returns
    -------
    ndarray, shape (n_p, len(refs), len(metrics))
    """
    fr.period_schur()   # the steady state needs it; the poles are read from it
    bad = unstable_poles(fr)
    if bad:
        z = bad[0]
        T = fr.P * float(fr.lin.plan.timebase.base)
        raise AnalysisError(
            f"the closed loop is unstable (a pole at |z| = {abs(z):.6f} per {T:g} s, "
            f"{abs(np.angle(z)) / (2 * np.pi * T):.3g} Hz or an alias of it): it has no "
            "steady state; take the slow loop out (open = [\"acs\"]) or fix the design")
    freqs = np.asarray(freqs_hz, float)
    n_p, n_h = freqs.shape
    refs = tuple(refs)
    tb = fr.lin.plan.timebase
    every = tb.output_ticks
    dt = every * float(tb.base)
    n_samples = int(round(duration / dt)) + 1
    n_blocks = -(-((n_samples - 1) * every + 1) // fr.P)    # super-periods the record spans
    Y = fr.steady_state(freqs.ravel(), np.asarray(phasors).reshape(-1, fr.m), refs)
    Y = Y.reshape(fr.P, n_p, n_h, len(refs)).transpose(1, 2, 0, 3)      # (n_p, n_h, P, r)
    Yr = np.ascontiguousarray(Y.real).reshape(n_p, n_h, -1)             # (n_p, n_h, P r)
    Yi = np.ascontiguousarray(Y.imag).reshape(n_p, n_h, -1)
    values = np.zeros((n_p, len(refs), len(metrics)))
    # z_h^n = exp(j 2 pi f_h T n), T the hyperperiod, the phase taken in turns modulo 1
    # (exact to ~1e-13 of a turn over the record) so that Re(z^n Y) is two real products
    turns = freqs * (fr.P * float(tb.base))                            # (n_p, n_h)
    blocks = np.arange(n_blocks, dtype=float)

    def one_chunk(sl):
        ang = 2 * np.pi * np.mod(turns[sl, :, None] * blocks, 1.0)     # (c, n_h, n_b)
        c_, s_ = np.cos(ang).transpose(0, 2, 1), np.sin(ang).transpose(0, 2, 1)
        x = np.matmul(c_, Yr[sl]) - np.matmul(s_, Yi[sl])              # (c, n_b, P r)
        x = x.reshape(x.shape[0], n_blocks * fr.P, len(refs))[:, ::every][:, :n_samples]
        values[sl] = M.metric_values(x.transpose(0, 2, 1), dt, metrics)

    for c0 in range(0, n_p, chunk):
        one_chunk(slice(c0, c0 + chunk))
    return values


def wheel_sweep(fr: FastResponse, instance: str, speeds_rpm, refs, metrics, duration: float,
                *, chunk: int = 25) -> WheelSweep:
    """Steady-state jitter of ``refs`` with the wheel ``instance`` at each speed.

    Parameters
    ----------
    fr : FastResponse
        The compiled closed loop (other sources are ignored: only the wheel drives).
    instance : str
        Source instance whose source is a :class:`~distfmu.sources.WheelImbalance`
        (its scale applies; its own speed is replaced by each swept speed).
    speeds_rpm : array_like, shape (n_s,)
        Wheel speeds (rpm).
    refs : sequence of str
        Recorded outputs (e.g. lines of sight, rad).
    metrics : sequence of (str, float or None)
        ``(kind, window)`` pairs, as a campaign's.
    duration : float
        Record length the metrics see (s), e.g. the campaign's ``stop - skip``.
    chunk : int
        Speeds reconstructed together (memory ``~ chunk x n_samples x n_refs``).

    Returns
    -------
    WheelSweep

    Raises
    ------
    AnalysisError
        When ``instance`` is not a wheel source, or the loop is unstable.
    """
    from distfmu.sources import WheelImbalance

    b = fr.lin.blocks.get(instance)
    cfg = None if b is None else b.source
    if cfg is None or not isinstance(cfg.source, WheelImbalance):
        raise AnalysisError(f"{instance!r} is not a wheel-imbalance source of the scenario "
                            "(set its preset to a wheel, e.g. 'rwa', in the sweep's "
                            "overrides)")
    speeds = np.atleast_1d(np.asarray(speeds_rpm, float))
    off = fr._in_off[instance]
    n_h = len(cfg.source.harmonics)
    freqs = np.zeros((speeds.size, n_h))
    ph = np.zeros((speeds.size, n_h, fr.m), complex)
    for i, s in enumerate(speeds):
        f, a = cfg.source.lines(s * RPM)
        freqs[i] = f
        ph[i, :, off:off + 6] = cfg.scale * a
    values = steady_jitter(fr, freqs, ph, refs, metrics, duration, chunk=chunk)
    return WheelSweep(speeds, tuple(refs), tuple(metrics), values)
