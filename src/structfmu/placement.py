"""Where to put an active member: truss members ranked by modal strain energy.

The paper chose its two active members with finite element models "to determine regions
of high strain energy": a stack replacing a member that stores much of a mode's strain
energy has much authority over that mode (its modal force per volt and its modal strain
per unit of mode both scale with the member's elongation in the mode).
:func:`rank_members` computes the modes of a truss, the share of each mode's strain
energy in each member (:func:`structfmu.fem.member_strain_energy`) and ranks candidate
members by their mean share over the modes of interest.

Example
-------
>>> from structfmu.models import tower
>>> from structfmu.placement import rank_members
>>> ranking = rank_members(tower.build(12, 4, 3, n_active=0), modes=(0, 1), top=2)
>>> ranking.elements.tolist()          # two corner longerons of the first bay
[0, 8]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from structfmu.errors import ModelError
from structfmu.fem import Truss, assemble, member_strain_energy
from structfmu.reduce import eigenpairs

__all__ = ["MemberRanking", "rank_members"]


@dataclass(frozen=True)
class MemberRanking:
    """Candidate members ranked by their share of the modes' strain energy.

    Unpacks as ``elements, score = ranking``.

    Parameters
    ----------
    elements : ndarray of int, shape (n_top,)
        Element indices of the truss, best first.
    score : ndarray, shape (n_top,)
        Mean over the selected modes of each member's share of the mode's strain
        energy (-), descending.
    shares : ndarray, shape (n_top, n_sel)
        Share of each selected mode's strain energy in each ranked member (-).
    modes : ndarray of int, shape (n_sel,)
        Indices of the selected modes (0 = lowest).
    freqs_hz : ndarray, shape (n_sel,)
        Natural frequencies of the selected modes (Hz).
    nodes : ndarray of int, shape (n_top, 2)
        End nodes of each ranked member.
    """

    elements: np.ndarray
    score: np.ndarray
    shares: np.ndarray
    modes: np.ndarray
    freqs_hz: np.ndarray
    nodes: np.ndarray

    def __iter__(self):
        return iter((self.elements, self.score))

    def table(self) -> str:
        """The ranking as a text table, one member per line (shares in %)."""
        head = "  ".join(f"{f:7.2f} Hz" for f in self.freqs_hz)
        lines = [f"{'rank':>4} {'element':>7} {'nodes':>11} {'mean %':>7}   {head}"]
        for r, (e, s, sh, n) in enumerate(zip(self.elements, self.score, self.shares,
                                              self.nodes), start=1):
            per = "  ".join(f"{100 * v:10.2f}" for v in sh)
            lines.append(f"{r:>4} {int(e):>7} {f'{n[0]}-{n[1]}':>11} {100 * s:7.2f}   {per}")
        return "\n".join(lines)


def _select(freqs_hz: np.ndarray, modes, near_hz) -> np.ndarray:
    if (modes is None) == (near_hz is None):
        raise ValueError("give the modes of interest either as mode indices (modes=) or as "
                         "frequencies (near_hz=), not both")
    if modes is not None:
        idx = np.atleast_1d(np.asarray(modes))
        if idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
            raise ValueError(f"modes={modes!r}; expected mode indices (0 = lowest), e.g. "
                             "(0, 1); for frequencies use near_hz=")
        bad = idx[(idx < 0) | (idx >= len(freqs_hz))]
        if bad.size:
            raise ValueError(f"mode index {int(bad[0])} is out of range; computed modes are "
                             f"0..{len(freqs_hz) - 1} (raise n_modes)")
        return idx.astype(int)
    want = np.atleast_1d(np.asarray(near_hz, float))
    if want.size == 0 or not np.all(np.isfinite(want) & (want > 0)):
        raise ValueError(f"near_hz={near_hz!r}; expected positive frequencies (Hz)")
    return np.array([int(np.argmin(np.abs(freqs_hz - f))) for f in want])


def rank_members(truss: Truss, modes=None, *, near_hz=None, n_modes: int | None = None,
                 candidates=None, top: int | None = 10, shift: float = 0.0) -> MemberRanking:
    """Rank members by their mean share of the strain energy of chosen modes.

    Parameters
    ----------
    truss : Truss
        The model, usually the passive truss (before any member is made active).
    modes : sequence of int, optional
        Indices of the modes of interest (0 = lowest elastic or rigid mode).
    near_hz : sequence of float, optional
        Instead of ``modes``: the mode nearest each of these frequencies (Hz).
    n_modes : int, optional
        Number of modes computed; default enough for ``modes``, or 12 with ``near_hz``.
    candidates : sequence of int, optional
        Element indices that may be made active; default every element.
    top : int or None, default 10
        Number of members returned; None for every candidate.
    shift : float, default 0.0
        Eigenvalue shift ((rad/s)^2); negative for a free-free truss.

    Returns
    -------
    MemberRanking
        Members best first, with their shares and the selected modes' frequencies.

    Raises
    ------
    ValueError
        If the modes or candidates are not given as expected.
    ModelError
        If a selected mode stores no strain energy (a rigid-body mode).
    """
    n_el = len(truss.elements)
    if n_modes is None:
        n_modes = int(np.max(modes)) + 1 if modes is not None and np.size(modes) else 12
    K, M = assemble(truss)
    lam, phi, _ = eigenpairs(K, M, min(int(n_modes), K.shape[0]), shift=shift, truss=truss)
    freqs = np.sqrt(lam) / (2 * np.pi)
    sel = _select(freqs, modes, near_hz)
    if np.any(lam[sel] == 0):
        raise ModelError(f"truss {truss.name!r}: mode {int(sel[lam[sel] == 0][0])} is a "
                         "rigid-body mode and stores no strain energy; choose elastic modes")
    shares = member_strain_energy(truss, phi[:, sel])
    cand = np.arange(n_el) if candidates is None else np.unique(np.asarray(candidates, int))
    if cand.size == 0 or cand.min() < 0 or cand.max() >= n_el:
        raise ValueError(f"candidates must be element indices 0..{n_el - 1}")
    # best first; equal scores (symmetric members) in element order
    order = cand[np.lexsort((cand, -shares[cand].mean(axis=1)))]
    if top is not None:
        order = order[:int(top)]
    return MemberRanking(elements=order, score=shares[order].mean(axis=1),
                         shares=shares[order], modes=sel, freqs_hz=freqs[sel],
                         nodes=truss.elements[order])
