"""Frequency-domain views: closed-loop transfers, output PSDs, cumulative RMS.

The transfer from a source channel to an output is the fundamental of the periodic
steady state (:meth:`~orchestrator.analysis.fast.FastResponse.steady_state`): exact for
a single-rate loop; with mixed rates the slow instances also alias the input to other
frequencies, which the fundamental leaves out (:func:`transfer` says how much through
``aliased``).  The PSD of an output under a stationary random source is
``|sum_c H_c d_c|^2 S``, with ``d`` the source's direction over its channels (one
random signal along one axis: the channels are fully correlated), and the cumulative
RMS its running integral, as a PLATSIM or PEET user reads it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..metrics import response_psd
from .blocks import AnalysisError
from .fast import FastResponse

__all__ = ["Transfer", "transfer", "output_psd", "cumulative_rms"]


@dataclass(frozen=True)
class Transfer:
    """Closed-loop transfers; unpacks as ``H, freqs``.

    Attributes
    ----------
    H : ndarray, shape (n_out, n_in, n_f), complex
        Fundamental of each output per unit input (output unit per input unit).
    freqs : ndarray, shape (n_f,)
    inputs, outputs : tuple of str
    aliased : ndarray, shape (n_out, n_in, n_f)
        RMS of the rest of the periodic steady state relative to the fundamental
        (0 for a single-rate loop).
    """

    H: np.ndarray
    freqs: np.ndarray
    inputs: tuple
    outputs: tuple
    aliased: np.ndarray

    def __iter__(self):
        return iter((self.H, self.freqs))


def _channel(fr: FastResponse, ref: str) -> int:
    inst, _, var = ref.partition(".")
    b = fr.lin.blocks.get(inst)
    if b is None or b.kind != "source" or var not in b.outputs:
        from orchestrator.scenario import closest

        names = [f"{s}.{o}" for s in fr.lin.sources for o in fr.lin.blocks[s].outputs]
        raise AnalysisError(f"{ref} is not an output of a source instance"
                            f"{closest(ref, names)}; source outputs: {', '.join(names)}")
    return fr._in_off[inst] + b.outputs.index(var)


def transfer(fr: FastResponse, inputs, outputs, freqs_hz) -> Transfer:
    """Closed-loop transfer from source channels to recorded outputs.

    Parameters
    ----------
    fr : FastResponse
        The compiled loop (its ``refs`` must hold ``outputs``).
    inputs : sequence of str
        Source outputs ``instance.variable``.
    outputs : sequence of str
        Recorded outputs.
    freqs_hz : array_like, shape (n_f,)
        Frequencies (Hz), none at a multiple of the super-period's rate on a neutral
        pole (a free rigid body at 0 Hz).

    Returns
    -------
    Transfer
    """
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    inputs, outputs = tuple(inputs), tuple(outputs)
    base = float(fr.lin.plan.timebase.base)
    ph = np.exp(-2j * np.pi * np.outer(np.arange(fr.P), freqs) * base)   # (P, n_f)
    H = np.zeros((len(outputs), len(inputs), freqs.size), complex)
    rest = np.zeros(H.shape)
    for j, ref in enumerate(inputs):
        a = np.zeros((freqs.size, fr.m), complex)
        a[:, _channel(fr, ref)] = 1.0
        Y = fr.steady_state(freqs, a, outputs)                 # (P, n_f, n_out)
        fund = np.einsum("pf,pfo->of", ph, Y) / fr.P
        H[:, j] = fund
        # Y[p] minus the fundamental's own samples: what the slow instances aliased
        resid = Y - (fund.T[None] * np.conj(ph)[:, :, None])
        rms = np.sqrt(np.mean(np.abs(resid) ** 2, axis=0)).T  # (n_out, n_f)
        rest[:, j] = rms / np.maximum(np.abs(fund), 1e-300)
    return Transfer(H, freqs, inputs, outputs, rest)


def output_psd(tr: Transfer, psd_in, direction=None) -> np.ndarray:
    """PSD of every output under one random signal on the transfer's inputs.

    Parameters
    ----------
    tr : Transfer
        From :func:`transfer`.
    psd_in : array_like, shape (n_f,)
        One-sided PSD of the random signal at ``tr.freqs`` ((input unit)^2/Hz).
    direction : array_like, shape (n_in,), optional
        How the signal enters each input channel (e.g. a force's axis over ``Fx, Fy,
        Fz``); default: equally on every input, ``1 / sqrt(n_in)`` each.

    Returns
    -------
    ndarray, shape (n_out, n_f)
        (output unit)^2/Hz.
    """
    n_in = tr.H.shape[1]
    d = (np.full(n_in, 1 / np.sqrt(n_in)) if direction is None
         else np.asarray(direction, float))
    if d.shape != (n_in,):
        raise AnalysisError(f"direction has shape {d.shape}; expected ({n_in},), one per "
                            "input of the transfer")
    # one signal along d: the cross-spectral matrix of the inputs is d d^T S
    S = np.multiply.outer(np.asarray(psd_in, float), np.outer(d, d))    # (n_f, n_in, n_in)
    return response_psd(np.moveaxis(tr.H, -1, 0), S).T


def cumulative_rms(freqs_hz, psd) -> np.ndarray:
    """``sqrt(int_0^f PSD df)`` by the trapezoid rule along the last axis.

    Parameters
    ----------
    freqs_hz : array_like, shape (n_f,)
        Increasing frequencies (Hz).
    psd : array_like, shape (..., n_f)
        One-sided PSD (unit^2/Hz).

    Returns
    -------
    ndarray, shape (..., n_f)
        Cumulative RMS (unit), zero at the first frequency.
    """
    f = np.asarray(freqs_hz, float)
    p = np.asarray(psd, float)
    seg = 0.5 * (p[..., 1:] + p[..., :-1]) * np.diff(f)
    return np.sqrt(np.concatenate([np.zeros(p.shape[:-1] + (1,)),
                                   np.cumsum(seg, axis=-1)], axis=-1))
