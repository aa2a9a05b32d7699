"""The structured engine beside the dense one, for bench_linear_analyses.py.

Both engines evaluate the same Monte Carlo samples (:func:`orchestrator.campaign.
montecarlo._evaluate`: the sample's loop, its poles, its 24 records and their metrics)
in this process on one BLAS thread, interleaved sample by sample so that a busy machine
slows both alike.  The dense engine is the structured one told that its form never pays
(``orchestrator.analysis.structured._PAYS = 0``).
"""

from __future__ import annotations

import time
from contextlib import contextmanager

import numpy as np

from orchestrator.analysis import structured
from orchestrator.analysis.blocks import structure_block
from orchestrator.analysis.fast import FastResponse
from orchestrator.analysis.fastparts import _chain_flops
from orchestrator.analysis.structpoles import _Coupling, period_split, winding_count
from orchestrator.analysis.structured import StructuredResponse, respond
from orchestrator.analysis.uncertainty import draw
from orchestrator.campaign import montecarlo as mcm
from orchestrator.campaign.mcloop import engine_paths, sample_lin, sample_loop
from orchestrator.campaign.mcresults import DENSE_LOOP, DIVERGING, LIMIT, UNSTABLE


@contextmanager
def engine(ctx, name: str):
    """Run the Monte Carlo's samples on ``name`` ("structured" or "dense"); each
    engine keeps its own structured forms of the nominal loops between calls."""
    keep = structured._PAYS
    structured._PAYS = keep if name == "structured" else 0.0
    kept = ctx.setdefault("_forms", {}).setdefault(name, {})
    for cf in ctx["configs"]:
        fr = ctx["base"][cf][2]
        fr.__dict__.pop("_modal", None)
        if cf in kept:
            fr._modal, fr.structure_reason = kept[cf]
    try:
        yield
    finally:
        structured._PAYS = keep
        for cf in ctx["configs"]:
            fr = ctx["base"][cf][2]
            if "_modal" in fr.__dict__:
                kept[cf] = (fr.__dict__.pop("_modal"), fr.structure_reason)


def _draws(camp, ctx, n):
    lin0, structs, _ = ctx["base"][ctx["configs"][0]]
    return draw(camp.uncertainty["parameters"], n, camp.uncertainty["seed"],
                lin0.blocks[structs[0]].model.frequencies_hz)


def per_sample(camp, runner, ctx, n: int) -> dict:
    """Seconds a sample on one core, per engine, and the largest difference of their
    metrics (relative) and outcomes (rails, instability), over samples ``1 .. n``
    (sample 0 warms both); ``engines_as_named``: every structured sample ran on the
    structured loop and every dense one on the dense loop (their status bits)."""
    draws = _draws(camp, ctx, n + 1)
    out = {"structured": [], "dense": []}
    values = {}
    for s in range(n + 1):
        for name in ("structured", "dense"):
            with engine(ctx, name):
                t0 = time.perf_counter()
                v, st = mcm._evaluate(camp, runner, ctx, draws, [s])
                if s:
                    out[name].append(time.perf_counter() - t0)
                values.setdefault(name, []).append((v, st))
    return _compared(out, values)


def _compared(out: dict, values: dict) -> dict:
    """The medians of ``out`` (seconds per engine) and how the engines' samples
    ``values`` compare (:func:`per_sample`)."""
    diff = max(float(np.nanmax(np.abs(a[0] - b[0]) / np.maximum(np.abs(b[0]), 1e-300)))
               for a, b in zip(values["structured"], values["dense"]))
    outcome = LIMIT | UNSTABLE | DIVERGING   # the other bits say how the engine ran
    same = all(np.array_equal(a[1] & outcome, b[1] & outcome)
               for a, b in zip(values["structured"], values["dense"]))
    # that the structured side did run structured, and the dense side dense
    ran = (all(not (st & DENSE_LOOP).any() for _, st in values["structured"])
           and all((st & DENSE_LOOP).all() for _, st in values["dense"]))
    return {"structured_s": float(np.median(out["structured"])),
            "dense_s": float(np.median(out["dense"])), "samples": len(out["structured"]),
            "largest_metric_difference": diff, "statuses_equal": same,
            "engines_as_named": ran}


def per_sample_rounds(camp, runner, ctxs, n: int, rounds: int = 3) -> list:
    """:func:`per_sample` of several contexts (the structure reduced to several mode
    counts).  The structured engine first, in ``rounds`` over the sizes: each round runs
    ``n`` samples of every size one after another, after one that warms it, as a Monte
    Carlo runs a size's samples; the first round warms the process and is not timed.  A
    load that drifts over the run then slows every size alike, and the slope does not
    follow it.  Then the dense engine, one round.  (With the dense samples between the
    structured ones, each of a size's structured samples came after a dense one whose
    arrays the process had just given back: the 500-mode sample took 1.09 s against
    0.89 s in a row, a slope of s^1.40 against s^1.29.)"""
    draws = [_draws(camp, ctx, n + 1) for ctx in ctxs]
    out = [{"structured": [], "dense": []} for _ in ctxs]
    values = [{} for _ in ctxs]
    for name, n_rounds in (("structured", max(2, rounds)), ("dense", 1)):
        for r in range(n_rounds):
            for i, ctx in enumerate(ctxs):
                with engine(ctx, name):
                    for s in range(n + 1):
                        t0 = time.perf_counter()
                        v, st = mcm._evaluate(camp, runner, ctx, draws[i], [s])
                        if s and (r or n_rounds == 1):
                            out[i][name].append(time.perf_counter() - t0)
                        if r == 0:
                            values[i].setdefault(name, []).append((v, st))
    return [_compared(o, v) for o, v in zip(out, values)]


def product_flops(f, nonzero: bool = False) -> float:
    """Flops of one product of a structured tick map (``_Form``) with one vector, as
    ``_Form.right`` and ``_Form.left`` multiply it: the coupling rows that read the pairs
    on the pair columns, every coupling row on the other columns, the pairs' input rows
    and their 2x2 blocks.  ``nonzero``: their zero entries left out (what the structure
    needs at least).  ``_Form.step_cost``, the engine's own count for choosing how to
    form ``M^L``, counts every coupling row on the pair columns."""
    _, Wp, rest = f._parts()
    parts = (Wp, rest, f.gamma)
    n = sum(np.count_nonzero(P) if nonzero else P.size for P in parts)
    return 2.0 * n + 6.0 * f.n_p


def _power_flops(f, L: int, c: float) -> float:
    """Flops of ``M^L`` the way the engine forms it (``_Form.run``, chosen by its own
    count), with ``c`` flops a structured product with one vector."""
    costs, chain = f.power_costs(L)
    way = int(np.argmin(costs))
    if structured._WAYS[way] == "squaring":   # the engine's chain, at this count
        return _chain_flops(L, chain, 2.0 * f.s ** 3, f.s * c)
    return f.power_costs(L, c)[0][way]


def structured_flops(camp, runner, ctx) -> tuple:
    """Flops of one structured sample (the products it computes, in their shapes), the
    same with the zero entries of the tick maps' coupling left out of their products
    (:func:`product_flops`), and a line per configuration naming the form's sizes."""
    draws = _draws(camp, ctx, 1)
    items = camp.uncertainty["parameters"]
    first = mcm.first_tick(camp, ctx["base"][ctx["configs"][0]][0])
    flop, rows = np.zeros(2), []   # as multiplied, without the zeros
    paths, blocks = engine_paths(ctx, items, draws), {}
    for cf in ctx["configs"]:
        fr = sample_loop(ctx, cf, sample_lin(ctx, cf, items, draws, 0, blocks))
        if not isinstance(fr, StructuredResponse):
            rows.append(f"{cf}: dense ({paths[cf]['loop_why']})")
            continue
        Ws = [ctx["inputs"][(cf, ev)][1] for ev in ctx["events"]]
        E, K = len(Ws), Ws[0].shape[0]
        acts = [ctx["actives"][(cf, ev)] for ev in ctx["events"]]
        k = np.unique(np.concatenate(acts)).size
        k_sum = sum(a.size for a in acts)
        kept = (K - first) / K
        s, n_los = fr.n_memory, len(fr._computed)
        runs = {}
        for key in fr._runs:
            runs[key] = runs.get(key, 0) + 1
        for (sig, L), per_period in runs.items():
            f = fr._forms[sig]
            t = fr._type(sig, L)
            n_u = max(1, round(per_period * K / fr.P))
            ML = t.ML
            for i, c in enumerate((product_flops(f), product_flops(f, nonzero=True))):
                flop[i] += ((L - 1) * (t.live.size + k) * c
                            + 2.0 * (L - 1) * t.live.size * s * k)
                if isinstance(ML, structured._BlockPower):
                    flop[i] += L * ML.cols.size * c
                    apply = 2.0 * s * ML.cols.size + 6.0 * ML.at.size
                elif ML is f:
                    apply = c
                else:   # the way the form took: the cheapest in its own count
                    flop[i] += _power_flops(f, L, c)
                    apply = 2.0 * s * s
                flop[i] += n_u * apply * E                           # state recursion
            flop += 2.0 * n_u * L * k_sum * s                         # input side
            flop += 2.0 * E * max(1, round(n_u * kept)) * s * L * n_los   # free responses
        split, why = period_split(fr)
        if split is None:                                            # poles: eigenvalues
            flop += 10.0 * s ** 3
            poles = f"poles by dense eigenvalues ({why})"
        else:                                                        # or the winding
            points = winding_count(split.A, split.U, split.W, split.n_p)[1]
            coupling = _Coupling(split.A, split.U, split.W, split.n_p)
            flop += points * coupling.point_flops()
            poles = (f"poles counted from the structure at {points} points "
                     f"(a {coupling.k}x{coupling.k} determinant each)")
        rows.append(f"{cf}: memory state {s} = {f.n_p} pair states + {s - f.n_p} others, "
                    f"coupling {f.W.shape[0]} rows ({f.k_in} structure inputs), a product "
                    f"{product_flops(f) / (2.0 * s * s):.0%} of a dense one "
                    f"({product_flops(f, True) / (2.0 * s * s):.0%} without its zero "
                    f"entries); {poles}")
    return flop[0] / 1e9, flop[1] / 1e9, rows


def scaling(camp, runner, ctx, modes, n: int) -> list:
    """Per-sample seconds on one core of both engines with the EOS structure reduced
    to each count of ``modes`` (all mount legs active, as the budget's), memory states,
    the bytes the structured loops keep and the structured sample's stages
    (:func:`stages`)."""
    from structfmu.models import eos_testbed as et

    truss = et.build(active_legs="all")
    built = []
    for n_modes in modes:
        t0 = time.perf_counter()
        model = et.reduced(n_modes, truss=truss)
        base = {}
        for cf in ctx["configs"]:
            lin, structs, fr0 = ctx["base"][cf]
            b = lin.blocks[structs[0]]
            lin_n = lin.with_block(structure_block(model, structs[0], b.period,
                                                   b.period * lin.base, b.feedthrough,
                                                   blockwise=True))
            base[cf] = (lin_n, structs, FastResponse(lin_n, ctx["refs"]))
        models = {(cf, name): (name, mcm._digest(model), base[cf][0].blocks[name].period,
                               base[cf][0].blocks[name].feedthrough.tobytes())
                  for cf in ctx["configs"] for name in base[cf][1]}
        ctx_n = {**{k: v for k, v in ctx.items() if k != "_forms"}, "base": base,
                 "models": models}
        built.append((n_modes, model, ctx_n, time.perf_counter() - t0))
    # the sizes in turn, in rounds (per_sample_rounds): the slope does not follow the load
    times = per_sample_rounds(camp, runner, [c for _, _, c, _ in built], n)
    out = []
    for (n_modes, model, ctx_n, build), t in zip(built, times):
        with engine(ctx_n, "structured"):   # the forms per_sample built, reused
            parts = stages(camp, runner, ctx_n, n)
        kept = 0
        for cf in ctx["configs"]:
            loop = ctx_n["_forms"]["structured"].get(cf, (None,))[0]
            kept += 0 if loop is None else sum(
                sum(np.asarray(v).nbytes for v in d.values() if isinstance(v, np.ndarray))
                for d in loop._base.values())
        out.append({"modes": n_modes, "ritz": model.n_ritz,
                    "memory_states": [ctx_n["base"][cf][2].n_memory for cf in ctx["configs"]],
                    "build_s": build, "form_bytes": kept, "stages_s": parts, **t})
    return out


def exponent(rows: list, key: str, less=None) -> float:
    """Slope of log(seconds) against log(memory state) over ``rows`` (least squares);
    ``less(row)`` seconds taken off each row's first (a stage left out)."""
    s = np.array([sum(r["memory_states"]) for r in rows], float)
    y = np.array([r[key] - (less(r) if less else 0.0) for r in rows], float)
    return float(np.polyfit(np.log(s), np.log(y), 1)[0])



def verdicts(camp, ctx, n: int) -> dict:
    """Per configuration, over samples ``0 .. n-1`` of the campaign's draws: how many
    stability verdicts of the structured loops equal the dense loops' eigenvalues',
    the unstable counts of each, and the seconds of each (loop and poles)."""
    from orchestrator.analysis.sweep import unstable_poles

    items = camp.uncertainty["parameters"]
    draws = _draws(camp, ctx, n)
    out = {cf: {"agree": 0, "unstable_structured": 0, "unstable_dense": 0,
                "structured_s": 0.0, "dense_s": 0.0} for cf in ctx["configs"]}
    for s in range(n):
        blocks = {}
        for cf in ctx["configs"]:
            fr0 = ctx["base"][cf][2]
            lin_s = sample_lin(ctx, cf, items, draws, s, blocks)
            t0 = time.perf_counter()
            a = bool(unstable_poles(respond(lin_s, ctx["refs"], fr0)))
            t1 = time.perf_counter()
            d = bool(unstable_poles(FastResponse(lin_s, ctx["refs"], like=fr0)))
            r = out[cf]
            r["structured_s"] += t1 - t0
            r["dense_s"] += time.perf_counter() - t1
            r["agree"] += a == d
            r["unstable_structured"] += a
            r["unstable_dense"] += d
    return out


def dgemm_rate(n: int = 400) -> float:
    """This machine's one-thread square dgemm rate (GFlop/s), best of 5."""
    from _measure import best_of

    rng = np.random.default_rng(0)
    A, B = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    return 2.0 * n ** 3 * 20 / best_of(lambda: [A @ B for _ in range(20)], 5)[0] / 1e9


def stages(camp, runner, ctx, n: int) -> dict:
    """Median seconds of each stage of a structured sample on one core, per
    configuration, over samples ``1 .. n``: the perturbed structure block, the sample's
    run types (``M^L``, the row and column Krylov products), the super-period map and
    its poles (:func:`~orchestrator.analysis.sweep.unstable_poles`: counted from the
    structure, or balancing and eigenvalues), and the 12 records (input sides, state
    recursion, free and forced responses, limit bounds)."""
    from orchestrator.analysis.sweep import unstable_poles

    items = camp.uncertainty["parameters"]
    draws = _draws(camp, ctx, n + 1)
    first = mcm.first_tick(camp, ctx["base"][ctx["configs"][0]][0])
    out = {}
    for cf in ctx["configs"]:
        times = {k: [] for k in ("structure block", "run types", "poles", "records")}
        for s in range(1, n + 1):
            t0 = time.perf_counter()
            fr = sample_loop(ctx, cf, sample_lin(ctx, cf, items, draws, s, {}))
            t1 = time.perf_counter()
            for sig, L in fr._runs:
                fr._type(sig, L)
            t2 = time.perf_counter()
            unstable_poles(fr)   # from the structure where it can, else eigenvalues
            t3 = time.perf_counter()
            Ws, scales = zip(*(mcm._sample_input(runner, fr, *ctx["inputs"][(cf, ev)],
                                                 draws, items, s) for ev in ctx["events"]))
            acts = [ctx["actives"][(cf, ev)] if W is ctx["inputs"][(cf, ev)][1] else None
                    for ev, W in zip(ctx["events"], Ws)]
            fr.run_many(Ws, check=False, bound_limits=True, scales=scales, actives=acts,
                        start=first)
            t4 = time.perf_counter()
            for k, v in zip(times, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
                times[k].append(v)
        out[cf] = {k: float(np.median(v)) for k, v in times.items()}
        out[cf]["memory_state"] = fr.n_memory
    return out
