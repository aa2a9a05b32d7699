"""The Monte Carlo's loop of one sample and configuration, and how the engine takes it.

:func:`sample_lin` closes a configuration's loop with a sample's draws (the reduced
structure's modal frequencies and damping, controller gains) and :func:`sample_loop`
compiles it: the nominal loop's modal blocks patched where only the structure's modes
change (:func:`orchestrator.analysis.structured.respond`), the dense engine otherwise.
:func:`engine_paths` says, per configuration, which of the two a sample runs on and how
its poles are decided (counted from the structure, or dense eigenvalues), each with the
reason in one sentence; :func:`engine_counts` adds how many samples took each way (their
status bits); ``uncertainty.json`` keeps it and ``jitterfmu campaign`` prints it
(:func:`path_lines`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..analysis.uncertainty import LOOP_KINDS, MODAL_KINDS

__all__ = ["engine_counts", "engine_paths", "path_lines", "perturbed", "sample_lin",
           "sample_loop"]


def perturbed(model, draws, items, s):
    """The reduced model of sample ``s`` (modal frequency and damping factors).

    Parameters
    ----------
    model : ReducedModel
        The nominal reduced structure.
    draws : Draws
        The run's draws (:func:`orchestrator.analysis.uncertainty.draw`).
    items : sequence of UncertainItem
        The ``[uncertainty]`` parameters.
    s : int
        The sample.

    Returns
    -------
    ReducedModel
    """
    f_omega = np.ones(model.n_modes)
    f_zeta = np.ones(model.n_modes)
    for it in items:
        if it.kind not in MODAL_KINDS:
            continue
        idx = draws.modes[it.name]
        v = draws.values[it.name][s]
        target = f_omega if it.kind == "modal_frequency" else f_zeta
        target[idx] *= v if v.size == idx.size else v[0]
    # c = 2 zeta omega: both factors scale the damping coefficient
    return dataclasses.replace(model, omega=model.omega * f_omega,
                               modal_damping=model.modal_damping * f_omega * f_zeta)


def sample_lin(ctx, cf, items, draws, s: int, blocks: dict):
    """The linear loop of configuration ``cf`` for sample ``s``, or None.

    Parameters
    ----------
    ctx : dict
        The Monte Carlo's set-up (``montecarlo._setup``: nominal loops, structures).
    cf : str
        The configuration.
    items : sequence of UncertainItem
        The ``[uncertainty]`` parameters.
    draws : Draws
        The run's draws.
    s : int
        The sample.
    blocks : dict
        The sample's structure blocks, shared by the configurations (filled here).

    Returns
    -------
    LinearScenario or None
        None when no draw changes the loop (every sample shares the nominal one).
    """
    from ..analysis.blocks import structure_block

    if not any(it.kind in LOOP_KINDS for it in items):
        return None
    lin, structs, _ = ctx["base"][cf]
    for name in structs:
        b = lin.blocks[name]
        key = ctx["models"][(cf, name)]
        if key not in blocks:
            blocks[key] = structure_block(perturbed(b.model, draws, items, s), name,
                                          b.period, b.period * lin.base, b.feedthrough,
                                          blockwise=True)
        lin = lin.with_block(blocks[key])
    for it in items:
        if it.kind == "gain":
            for j, inst in enumerate(it.instances):
                lin = lin.with_gain(inst, float(draws.values[it.name][s, j]))
    return lin


def sample_loop(ctx, cf, lin):
    """The compiled loop of configuration ``cf`` for a sample's linear loop ``lin``.

    Parameters
    ----------
    ctx : dict
        The Monte Carlo's set-up (``montecarlo._setup``).
    cf : str
        The configuration.
    lin : LinearScenario or None
        The sample's loop (:func:`sample_lin`); None: the nominal one.

    Returns
    -------
    FastResponse
        The nominal loop itself for None; else the sample's loop, structured where the
        nominal form applies (:func:`~orchestrator.analysis.structured.respond`).
    """
    from ..analysis.structured import respond

    fr = ctx["base"][cf][2]
    # the nominal loop's modal blocks patched (the dense one where that form does not
    # apply or pay): the same records, to round-off
    return fr if lin is None else respond(lin, ctx["refs"], fr)


def _dense_why(fr0, lin, items) -> str:
    """Why a sample's loop ``lin`` runs dense (the nominal loop ``fr0``'s own reason
    where it has no structured form)."""
    from ..analysis.structured import StructureRefused, modal_loop

    loop = modal_loop(fr0)
    if loop is None:
        return fr0.structure_reason
    if any(it.kind == "gain" for it in items):
        return ("a sample changes more of the loop than its structure's modes (a "
                "controller's gain), which the structured form does not patch: the dense "
                "engine runs it")
    try:
        loop.sample(lin.blocks[loop.name], lin)
    except StructureRefused as exc:
        return str(exc)
    return "a sample changes more of the loop than its structure: the dense engine runs it"


def engine_paths(ctx, items, draws) -> dict:
    """Per configuration, how the linear engine evaluates a sample (found on sample 0).

    Parameters
    ----------
    ctx : dict
        The Monte Carlo's set-up (``montecarlo._setup``).
    items : sequence of UncertainItem
        The ``[uncertainty]`` parameters.
    draws : Draws
        The run's draws (at least one sample).

    Returns
    -------
    dict
        ``{configuration: {"loop": "nominal" | "structured" | "dense", "loop_why": str
        or None, "poles": "none" | "counted from the structure" | "eigenvalues",
        "poles_why": str or None}}``.  ``nominal``: no draw changes the loop, so every
        sample shares the configuration's nominal loop and no sample's poles are taken.
    """
    from ..analysis.structpoles import period_split
    from ..analysis.structured import StructuredResponse

    out = {}
    blocks = {}
    for cf in ctx["configs"]:
        fr0 = ctx["base"][cf][2]
        lin = sample_lin(ctx, cf, items, draws, 0, blocks)
        if lin is None:
            out[cf] = {"loop": "nominal", "loop_why": "no draw changes the loop: every "
                       "sample runs the configuration's nominal loop", "poles": "none",
                       "poles_why": None}
            continue
        fr = sample_loop(ctx, cf, lin)
        patched = isinstance(fr, StructuredResponse)
        loop, why = ("structured", None) if patched else ("dense", _dense_why(fr0, lin, items))
        split, poles_why = period_split(fr) if loop == "structured" else (None, None)
        out[cf] = {"loop": loop, "loop_why": why,
                   "poles": "counted from the structure" if split else "eigenvalues",
                   "poles_why": poles_why}
    return out


def engine_counts(paths: dict, status, configs) -> dict:
    """:func:`engine_paths` with how many samples took each way (their status bits).

    Parameters
    ----------
    paths : dict
        :func:`engine_paths`'s result.
    status : ndarray of int, shape (samples, configurations)
        The samples' status bits (:mod:`.mcresults`).
    configs : sequence of str
        The configurations, in the order of ``status``'s columns.

    Returns
    -------
    dict
        Each configuration's paths plus ``samples``, ``dense_loop`` (samples run on the
        dense loop) and ``poles_by_eigenvalues`` (samples whose poles the dense
        eigenvalues decided); none of these for a nominal loop.
    """
    from .mcresults import DENSE_LOOP, POLES_BY_EIGENVALUES

    out = {}
    for ci, cf in enumerate(configs):
        p = dict(paths[cf])
        if p["loop"] != "nominal":
            col = np.asarray(status)[:, ci]
            p.update(samples=int(col.size), dense_loop=int(np.sum(col & DENSE_LOOP > 0)),
                     poles_by_eigenvalues=int(np.sum(col & POLES_BY_EIGENVALUES > 0)))
        out[cf] = p
    return out


def path_lines(paths: dict) -> list:
    """``engine_paths`` (or ``engine_counts``) as the lines ``jitterfmu campaign``
    prints, one a configuration.

    Parameters
    ----------
    paths : dict
        :func:`engine_counts`'s result (``uncertainty.json``'s ``linear_engine``), or
        :func:`engine_paths`'s (no counts then).

    Returns
    -------
    list of str
    """
    out = []
    for cf, p in paths.items():
        if p["loop"] == "nominal":
            out.append(f"  {cf}: the nominal loop ({p['loop_why']})")
            continue
        n = p.get("samples")
        loop = ("structured loop (the nominal modal blocks patched)"
                if p["loop"] == "structured" else f"dense loop ({p['loop_why']})")
        counted = p["poles"] != "eigenvalues"
        poles = ("poles counted from the structure" if counted else
                 "poles by dense eigenvalues" + (f" ({p['poles_why']})" if p["poles_why"]
                                                 else ""))
        if n is not None:   # how many samples took the way sample 0 took
            dense, eig = p["dense_loop"], p["poles_by_eigenvalues"]
            loop += f", {n - dense if p['loop'] == 'structured' else dense} of {n} samples"
            poles += f", {n - eig if counted else eig} of {n}"
            if counted and eig:
                poles += f" ({eig} by dense eigenvalues: the count was not certain)"
        out.append(f"  {cf}: {loop}; {poles}")
    return out
