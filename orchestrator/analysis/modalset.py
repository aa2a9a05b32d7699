"""The uncertain modal set of a scenario, checked, and the loop at one of its points.

The part of a campaign's ``[uncertainty]`` list that moves poles (modal frequency and
damping factors, controller gains), for the robust analysis
(:mod:`.robust`) and its certificate (:mod:`.certify`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .blocks import AnalysisError, structure_block
from .uncertainty import LOOP_KINDS, UncertaintyError

__all__ = ["UncertainSet", "uncertain_set", "loop_at"]


@dataclass(frozen=True)
class UncertainSet:
    """The uncertain parameters that move poles, with their bounds.

    Attributes
    ----------
    items : tuple of Uncertain
        Modal frequency, modal damping and gain parameters.
    modes : dict of str to ndarray
        Parameter name -> indices of the modes it moves.
    structure : str
        The structure instance whose modes move.
    """

    items: tuple
    modes: dict
    structure: str

    def bounds(self, name) -> tuple:
        it = next(i for i in self.items if i.name == name)
        return float(it.distribution.low), float(it.distribution.high)


def uncertain_set(lin, items) -> UncertainSet:
    """The part of an ``[uncertainty]`` list that moves poles, checked.

    Parameters
    ----------
    lin : LinearScenario
        The nominal loop (its structure gives the modes' frequencies).
    items : sequence of Uncertain
        From :func:`orchestrator.campaign.spec_uncertainty.parse_uncertainty`.

    Returns
    -------
    UncertainSet

    Raises
    ------
    UncertaintyError
        One sentence: a set without finite bounds, a factor bound at or below zero
        (a negative damping or frequency), or no structure to perturb.
    """
    keep = [it for it in items if it.kind in LOOP_KINDS]
    if not keep:
        raise UncertaintyError("the uncertainty set has no modal frequency, modal damping "
                               "or gain parameter: nothing in it moves a pole")
    for it in keep:
        d = it.distribution
        if not (math.isfinite(d.low) and math.isfinite(d.high)):
            raise UncertaintyError(f"uncertain {it.name!r} has no finite bounds "
                                   f"[{d.low}, {d.high}]; the robust analysis needs a bounded "
                                   "set: give low and high")
        if it.kind != "gain" and not d.low > 0:
            what = "damping ratio" if it.kind == "modal_damping" else "frequency"
            raise UncertaintyError(f"uncertain {it.name!r} lets the modal {what} factor reach "
                                   f"{d.low:g}: its set includes a {what} at or below zero; "
                                   "expected low > 0")
    structs = [n for n, b in lin.blocks.items() if b.kind == "structure"]
    if len(structs) != 1:
        raise AnalysisError(f"the robust analysis needs one structure instance; the "
                            f"scenario has {len(structs)}")
    model = lin.blocks[structs[0]].model
    f = model.omega / (2 * math.pi)
    modes = {}
    for it in keep:
        if it.kind == "gain":
            for inst in it.instances:
                if inst not in lin.controllers():
                    raise UncertaintyError(f"uncertain {it.name!r} names {inst!r}, which is "
                                           "not a controller of the scenario")
            continue
        idx = np.flatnonzero((f >= it.band[0]) & (f <= it.band[1]) & (f > 0))
        if idx.size == 0:
            raise UncertaintyError(f"uncertain {it.name!r}: no mode in the band "
                                   f"{list(it.band)} Hz")
        modes[it.name] = idx
    return UncertainSet(tuple(keep), modes, structs[0])


def _factors(uset, values: dict, n_modes: int):
    """Per-mode frequency and damping factors and per-controller gains of one point."""
    fw, fz, gains = np.ones(n_modes), np.ones(n_modes), {}
    for it in uset.items:
        v = np.atleast_1d(values[it.name])
        if it.kind == "gain":
            for j, inst in enumerate(it.instances):
                gains[inst] = gains.get(inst, 1.0) * float(v[j if v.size > 1 else 0])
            continue
        idx = uset.modes[it.name]
        target = fw if it.kind == "modal_frequency" else fz
        target[idx] *= v if v.size == idx.size else v[0]
    return fw, fz, gains


def loop_at(lin, uset, values: dict):
    """The loop at one point of the set.

    Parameters
    ----------
    lin : LinearScenario
        Nominal loop.
    uset : UncertainSet
    values : dict of str to ndarray
        Parameter name -> its factor(s) (one per selected mode for a per-mode
        parameter, one per instance for a gain).

    Returns
    -------
    LinearScenario
    """
    b = lin.blocks[uset.structure]
    fw, fz, gains = _factors(uset, values, b.model.n_modes)
    model = replace(b.model, omega=b.model.omega * fw,
                    modal_damping=b.model.modal_damping * fw * fz)
    out = lin.with_block(structure_block(model, b.name, b.period, b.period * lin.base,
                                         b.feedthrough, blockwise=True))
    for inst, g in gains.items():
        out = out.with_gain(inst, g)
    return out
