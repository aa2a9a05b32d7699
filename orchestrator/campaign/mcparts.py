"""The Monte Carlo's kept samples: parts written as samples finish, checked when read.

A part (``uncertainty_parts/<digest>/part-FIRST-LAST.npz``) holds the samples' indices,
metrics and status bits and the identity of the run that wrote it
(:func:`orchestrator.campaign.montecarlo._identity`: cases, FMU files, metrics, seed and
bounds).  On resume a part is data (``numpy.load`` without pickles), and one written by
another run, of other shapes, of a status no sample has, or holding a value no sample
gives (NaN, a negative metric, -1e300) is named on stderr and its samples run again.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ..files import atomic_write
from .mcresults import DENSE_LOOP, DIVERGING, LIMIT, POLES_BY_EIGENVALUES, UNSTABLE

__all__ = ["PARTS_DIR", "PARTS_FORMAT", "load_parts", "save_part"]

PARTS_DIR = "uncertainty_parts"
#: 2: each part carries the identity of its run; 3: its status says how the engine took
#: each sample (dense loop, poles by eigenvalues).
PARTS_FORMAT = 3


def load_parts(folder: Path, values, status, identity: str) -> np.ndarray:
    """Fill ``values`` and ``status`` with the samples kept in ``folder``; which ones.

    Parameters
    ----------
    folder : Path
        The run's parts folder.
    values : ndarray, shape (samples, configs, events, pairs, metrics)
        Filled in place at the kept samples.
    status : ndarray of int, shape (samples, configs)
        Filled in place at the kept samples.
    identity : str
        This run's identity; a part of another is named and ignored.

    Returns
    -------
    ndarray of bool, shape (samples,)
        Which samples were kept.
    """
    done = np.zeros(values.shape[0], bool)
    for f in sorted(folder.glob("part-*.npz")):
        try:
            with np.load(f, allow_pickle=False) as z:
                part = {k: z[k] for k in ("identity", "samples", "values", "status") if k in z}
            why = _part_problem(part, values, status, identity)
        except Exception as exc:   # unreadable: a part cut short, or not ours
            why = f"unreadable: {type(exc).__name__}"
        if why:
            print(f"jitterfmu: ignoring kept samples {str(f)!r} ({why}); they run again",
                  file=sys.stderr)
            continue
        idx, v, st = part["samples"], part["values"], part["status"]
        keep = idx < values.shape[0]      # a run of fewer samples uses the first ones
        values[idx[keep]], status[idx[keep]] = v[keep], st[keep]
        done[idx[keep]] = True
    return done


def _part_problem(part: dict, values, status, identity: str) -> str:
    """Why a kept part is not this run's samples, or ``""``."""
    if set(part) != {"identity", "samples", "values", "status"}:
        return "it does not carry the identity of the run that wrote it"
    if str(part["identity"]) != identity:
        return ("another run wrote it (another seed, bounds, cases, metrics or FMU files "
                "than this one)")
    idx, v, st = part["samples"], part["values"], part["status"]
    if not (idx.ndim == 1 and idx.dtype.kind == "i" and v.dtype == float
            and v.shape == (idx.size,) + values.shape[1:] and st.dtype.kind == "i"
            and st.shape == (idx.size,) + status.shape[1:] and (idx >= 0).all()
            and np.unique(idx).size == idx.size):
        return "its arrays do not have the shapes of this campaign's samples"
    known = (st >= 0) & (st <= LIMIT | UNSTABLE | DIVERGING | DENSE_LOOP |
                         POLES_BY_EIGENVALUES) & \
        (((st & DIVERGING) == 0) | ((st & UNSTABLE) != 0))
    if not known.all():
        return f"status {int(st[~known][0])} is not one a sample can have"
    shape = st.shape + (1,) * (v.ndim - st.ndim)
    limit = np.broadcast_to(((st & LIMIT) != 0).reshape(shape), v.shape)
    unstable = np.broadcast_to(((st & UNSTABLE) != 0).reshape(shape), v.shape)
    finite = np.isfinite(v) & (v >= 0)
    # a limit gives inf throughout; an unstable loop may give what it gives, not < 0
    ok = np.where(limit, v == np.inf, finite | (unstable & ~(v < 0)))
    if not ok.all():
        return (f"it holds the value {float(v[~ok][0])!r} where a sample of status "
                f"{int(np.broadcast_to(st.reshape(shape), v.shape)[~ok][0])} has "
                "a finite metric >= 0 (inf at a limit)")
    return ""


def save_part(folder: Path, samples, v, st, identity: str) -> None:
    """Keep finished samples (:func:`orchestrator.files.atomic_write`) with the identity
    of this run.

    Parameters
    ----------
    folder : Path
        The run's parts folder.
    samples : sequence of int
        The samples' indices.
    v, st : ndarray
        Their metrics and status bits (rows of :func:`load_parts`' arrays).
    identity : str
        This run's identity.
    """
    def write(tmp):
        with open(tmp, "wb") as fh:   # a file object: savez adds no suffix to it
            np.savez(fh, identity=np.asarray(identity), samples=np.asarray(samples, np.int64),
                     values=np.asarray(v, float), status=np.asarray(st, np.int64))

    atomic_write(folder / f"part-{samples[0]:07d}-{samples[-1]:07d}.npz", write)
