"""A campaign's ``[uncertainty]``: the budget as a distribution, on the linear engine.

Every sample draws the uncertain inputs (:func:`orchestrator.analysis.uncertainty.draw`),
closes each configuration's loop with them (modal frequencies and damping on the reduced
structure, controller gains), drives it with every event (source amplitudes and phases),
takes the campaign's metrics of each record and the RSS over the events (a sample whose
loop is unstable counts as exceeding every requirement, :mod:`.mcresults`).  Only those
numbers are kept: memory holds ``samples x configurations x events x axes x metrics``
floats and one record at a time, whatever the sample count or the record length.

Written to the campaign folder: ``uncertainty_samples.parquet`` (every sample's RSS per
configuration, instrument, axis and metric, with the records' own RSS beside it),
``uncertainty.json`` (per line: mean, std, the value at each confidence level with its
bootstrap interval, the probability of meeting the requirement, the sensitivity ranking
and the ECSS interpretation; per configuration, the unstable samples) and
``uncertainty_summary.csv`` (one row per line and confidence level).

Samples are kept as they finish, under ``uncertainty_parts/<digest>/`` (the digest of
the cases with their FMU files, the metrics and the ``[uncertainty]`` table less its
sample count): a run that is stopped keeps what it computed, and the same command
resumes it; more samples with the same seed extend it (sample ``s`` is the same draw
whatever the count, :func:`orchestrator.analysis.uncertainty.draw`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import signal
import time
from pathlib import Path

import numpy as np

from ..progress import ProgressBar
from .mcloop import engine_counts, engine_paths, sample_lin, sample_loop
from .mcparts import PARTS_DIR, PARTS_FORMAT, load_parts, save_part
from .mcresults import (DENSE_LOOP, DIVERGING, LIMIT, POLES_BY_EIGENVALUES, SAMPLES_FILE,
                        UNCERTAINTY_FILE, UNSTABLE,
                        _convergence, _lines, _report, write_results)
from .store import canonical

__all__ = ["check_uncertain_inputs", "run_uncertainty", "SAMPLES_FILE", "UNCERTAINTY_FILE"]

_BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def _layout(campaign) -> dict:
    """The lines (instrument, axis, variable), configurations and events of a campaign."""
    pairs = [(inst, axis, var) for inst, axes in campaign.instruments.items()
             for axis, var in axes.items()]
    return {"pairs": pairs, "refs": [var for _, _, var in pairs],
            "configs": list(dict.fromkeys(c.configuration for c in campaign.cases)),
            "events": list(dict.fromkeys(c.event for c in campaign.cases))}


def _setup(campaign, runner):
    """Everything a process needs to evaluate samples: compiled loops, event inputs."""
    from ..analysis.fast import FastResponse

    ctx = _layout(campaign)
    refs, configs, events = ctx["refs"], ctx["configs"], ctx["events"]
    case_of = {(c.configuration, c.event): c for c in campaign.cases if not c.sweep}
    base, inputs, models = {}, {}, {}
    for cf in configs:
        fr0 = runner.compiled(case_of[(cf, events[0])].scenario)
        structs = [n for n, b in fr0.lin.blocks.items() if b.kind == "structure"]
        base[cf] = (fr0.lin, structs, FastResponse(fr0.lin, refs))
        for name in structs:   # configurations with equal structures share its blocks
            b = fr0.lin.blocks[name]
            models[(cf, name)] = (name, _digest(b.model), b.period, b.feedthrough.tobytes())
        for ev in events:
            sc = case_of[(cf, ev)].scenario
            inputs[(cf, ev)] = (sc, runner.inputs(runner.compiled(sc), sc))
    actives = {key: np.flatnonzero(np.any(W != 0.0, axis=0)) for key, (_, W) in inputs.items()}
    return {**ctx, "base": base, "inputs": inputs, "models": models, "actives": actives}


def _digest(model) -> str:
    """A digest of a reduced model's arrays and numbers (equal models, equal digests)."""
    h = hashlib.sha256()
    for f in dataclasses.fields(model):
        v = getattr(model, f.name)
        h.update(f.name.encode())
        h.update(np.ascontiguousarray(v).tobytes() if isinstance(v, np.ndarray)
                 else repr(v).encode())
    return h.hexdigest()


def _evaluate(campaign, runner, ctx, draws, samples) -> tuple:
    """Metrics ``(len(samples), configs, events, pairs, metrics)`` and the status bits of
    every sample and configuration: 1 a record reached a rail or limit (its metrics are
    ``inf``: it exceeds every requirement), 2 the closed loop is unstable (its metrics
    are those of its records; the statistics count it as exceeding every requirement,
    :func:`.mcresults._counted`), 4 so unstable that it more than doubles over the
    record; and how the engine took it: 8 on the dense loop, 16 its poles decided by
    dense eigenvalues."""
    from ..analysis.structured import StructuredResponse
    from ..analysis.sweep import _pole_verdict
    from ..metrics import metric_values

    items = campaign.uncertainty["parameters"]
    lin0 = ctx["base"][ctx["configs"][0]][0]
    tb = lin0.plan.timebase
    dt = tb.output_ticks * float(tb.base)
    record_ticks = tb.n_ticks
    # the lines of sight before the first tick the metrics read are not computed; the
    # limits are checked over the whole record
    first = first_tick(campaign, lin0)
    values = np.full((len(samples), len(ctx["configs"]), len(ctx["events"]),
                      len(ctx["pairs"]), len(campaign.metrics)), np.nan)
    status = np.zeros((len(samples), len(ctx["configs"])), int)
    for row, s in enumerate(samples):
        blocks = {}   # the sample's structure blocks: the configurations share them
        for ci, cf in enumerate(ctx["configs"]):
            lin = sample_lin(ctx, cf, items, draws, s, blocks)
            fr = sample_loop(ctx, cf, lin)
            if lin is not None:   # the draws change the loop: its poles are the sample's
                status[row, ci] |= 0 if isinstance(fr, StructuredResponse) else DENSE_LOOP
                try:
                    bad, how = _pole_verdict(fr)
                except ValueError:   # a loop map past a float's range: no record to take
                    if np.isfinite(fr.period_map()).all():
                        raise
                    values[row, ci] = np.inf
                    status[row, ci] |= UNSTABLE | DIVERGING | LIMIT
                    continue
                status[row, ci] |= POLES_BY_EIGENVALUES if how == "eigenvalues" else 0
                if bad:   # reported; the record is what the co-simulation would give
                    growth = abs(bad[0]) ** (record_ticks / fr.P)
                    status[row, ci] |= UNSTABLE | (DIVERGING if growth > 2.0 else 0)
            # the events of a configuration share its loop: computed together
            Ws, scales = zip(*(_sample_input(runner, fr, *ctx["inputs"][(cf, ev)], draws,
                                             items, s) for ev in ctx["events"]))
            # the channels each event drives, found once unless the sample redrew it
            actives = [ctx["actives"][(cf, ev)] if W is ctx["inputs"][(cf, ev)][1] else None
                       for ev, W in zip(ctx["events"], Ws)]
            for ei, rec in enumerate(fr.run_many(Ws, check=False, bound_limits=True,
                                                 scales=scales, actives=actives,
                                                 start=first)):
                if rec.reached:   # a rail or limit: outside the linear model
                    values[row, ci] = np.inf
                    status[row, ci] |= LIMIT
                    break
                x = rec.values[::tb.output_ticks][-(-first // tb.output_ticks):]
                if not np.isfinite(x).all():   # overflowed: past every limit there is
                    values[row, ci] = np.inf
                    status[row, ci] |= LIMIT
                    break
                values[row, ci, ei] = metric_values(x.T, dt, campaign.metrics)
    return values, status


def first_tick(campaign, lin) -> int:
    """The first tick of a record whose line of sight the metrics read.

    Parameters
    ----------
    campaign : Campaign
        Its ``skip`` (s) is what the metrics leave out, as :func:`_evaluate` keeps the
        ticks.
    lin : LinearScenario
        A loop of the campaign (its time base).

    Returns
    -------
    int
    """
    from ..metrics import skip_start

    tb = lin.plan.timebase
    dt = tb.output_ticks * float(tb.base)
    return int(np.searchsorted(tb.times(range(tb.n_ticks + 1)),
                               skip_start(float(tb.start), campaign.skip, dt)))


_WORKER: dict = {}   # per worker process: the compiled loops of the campaign it serves


def _chunk(campaign, scenario_dir, fmu_dir, draws, samples) -> tuple:
    """One task's samples, on the worker's compiled loops (closed on its first task)."""
    from .linear import LinearRunner

    key = (str(scenario_dir), str(fmu_dir), tuple(c.key for c in campaign.cases))
    if _WORKER.get("key") != key:
        runner = LinearRunner(scenario_dir, fmu_dir=fmu_dir)
        _WORKER.clear()
        _WORKER.update(key=key, runner=runner, ctx=_setup(campaign, runner))
    return _evaluate(campaign, _WORKER["runner"], _WORKER["ctx"], draws, samples)




def _identity(campaign, runner, ctx) -> str:
    """What a kept sample depends on: every case with its FMU files, the lines, metrics,
    skip and the ``[uncertainty]`` table less its sample count and confidence levels."""
    unc = campaign.uncertainty
    fp = getattr(runner, "fingerprint", None)
    cases = [(c.key, fp(c.scenario) if fp else "") for c in campaign.cases if not c.sweep]
    data = {"format": PARTS_FORMAT, "cases": cases, "pairs": ctx["pairs"],
            "configs": ctx["configs"], "events": ctx["events"],
            "metrics": [list(m) for m in campaign.metrics], "skip": campaign.skip,
            "seed": unc["seed"], "engine": unc.get("engine", "linear"),
            "parameters": [repr(it) for it in unc["parameters"]]}
    return hashlib.sha256(canonical(data).encode()).hexdigest()


def run_uncertainty(campaign, out_dir, runner=None, progress: bool | None = None, *,
                    workers: int = 0, scheduler=None) -> Path | None:
    """Run a campaign's ``[uncertainty]`` on the linear engine; ``uncertainty.json``.

    With ``max_samples`` in the table the run extends itself: after ``samples`` it adds
    samples (the same per-sample draws a larger count gives) until every finite value
    at every confidence level has a bootstrap interval below 2 % of it, or
    ``max_samples`` are done; each round's count and widest interval are reported.

    Parameters
    ----------
    campaign : Campaign
        With ``uncertainty`` set (else nothing is done and None returned).
    out_dir : path-like
        The campaign folder.
    runner : LinearRunner, optional
        Reused for its compiled loops.
    progress : bool, optional
        Progress bar on stderr (default: when stderr is a terminal).
    workers : int
        0 or 1: in this process; N >= 2: N worker processes, each closing its own loops
        (the same draws, the same numbers).
    scheduler : str or distributed.Client, optional
        A Dask scheduler to run the samples on instead (same numbers).
    """
    from ..analysis.uncertainty import draw
    from .linear import LinearRunner

    unc = campaign.uncertainty
    if not unc:
        return None
    wall = time.perf_counter()
    runner = runner if isinstance(runner, LinearRunner) else LinearRunner(campaign.scenario_dir)
    items = unc["parameters"]
    if unc.get("engine") == "cosim":   # no linear loop: modal kinds are refused there
        ctx, freqs = _layout(campaign), None
    else:
        ctx = _setup(campaign, runner)
        lin0, structs, _ = ctx["base"][ctx["configs"][0]]
        freqs = lin0.blocks[structs[0]].model.frequencies_hz if structs else None
    cosim = unc.get("engine") == "cosim"   # its cases keep themselves (run_campaign)
    identity = None if cosim else _identity(campaign, runner, ctx)
    folder = None if cosim else Path(out_dir) / PARTS_DIR / identity[:24]
    n, top = unc["samples"], unc.get("max_samples") or unc["samples"]
    rounds = []
    check_uncertain_inputs(campaign, runner)
    # which loop and which pole test a sample takes, and why: found on sample 0 (the
    # same draw at any count) before any sample runs, so that it cannot fail after them
    paths = None if cosim else engine_paths(ctx, items, draw(items, 1, unc["seed"], freqs))
    while True:
        draws = draw(items, n, unc["seed"], freqs)
        _check_sources(campaign, runner, draws)
        values, status, resumed = _samples(campaign, out_dir, runner, ctx, draws,
                                           (folder, identity), workers, scheduler, progress,
                                           f" (round {len(rounds) + 1})" if top > n or
                                           rounds else "")
        lines, summary = _lines(campaign, ctx, draws, values, status)
        widest, need = _convergence(lines)
        rounds.append({"samples": n, "widest_interval": widest, "resumed": resumed})
        if need is None or n >= top:
            break
        n = min(top, max(n + 1, min(4 * n, need)))   # at most four times more a round
    report = _report(campaign, ctx, draws, status, lines, folder, out_dir, rounds, wall)
    if paths is not None:   # with how many samples took each way
        report["linear_engine"] = engine_counts(paths, status, ctx["configs"])
    return write_results(out_dir, campaign, ctx, values, status, summary, report)


def _samples(campaign, out_dir, runner, ctx, draws, kept, workers, scheduler, progress,
             round_label: str) -> tuple:
    """``(values, status, resumed)`` of every sample of ``draws``: the kept ones read
    back, the others evaluated (and kept as they finish).  ``kept`` is ``(folder,
    identity)`` of the parts, ``(None, None)`` for a co-simulated run."""
    folder, identity = kept
    n, m = draws.n, len(campaign.metrics)
    values = np.full((n, len(ctx["configs"]), len(ctx["events"]), len(ctx["pairs"]), m),
                     np.nan)
    status = np.zeros((n, len(ctx["configs"])), int)
    cosim = folder is None
    done = np.zeros(n, bool) if cosim else load_parts(folder, values, status, identity)
    todo = np.flatnonzero(~done)
    resumed = int(done.sum())
    bar = ProgressBar(todo.size, "uncertainty" + round_label, "sample", enabled=progress)
    parts = max(1, int(workers)) if scheduler is None else 2 * max(1, int(workers) or 2)
    # chunks of at most 25 samples: what a stop loses, and what a worker reports at once
    n_chunks = min(todo.size, max(4 * parts, math.ceil(todo.size / 25)))
    chunks = [list(c) for c in np.array_split(todo, max(n_chunks, 1)) if c.size]

    from .engine import _stop_on_signals
    from .runner import CampaignInterrupted

    try:
        if cosim:   # its cases are kept by run_campaign, which says so when stopped
            values, status = _cosimulate(campaign, out_dir, ctx, draws, workers, scheduler,
                                         runner, bar)
        else:
            try:
                with _stop_on_signals():
                    for c, (v, st) in _results(campaign, runner, ctx, draws, chunks,
                                               workers, scheduler):
                        values[c], status[c] = v, st
                        save_part(folder, c, v, st, identity)
                        done[c] = True
                        for _ in c:
                            bar.update("ok")
            except (CampaignInterrupted, KeyboardInterrupt) as exc:
                signum = getattr(exc, "signum", signal.SIGINT)
                raise CampaignInterrupted(signum, (
                    f"uncertainty of {campaign.name!r} stopped by "
                    f"{signal.Signals(signum).name}: kept {int(done.sum())} of {n} samples "
                    f"in {str(folder)!r}; run the same command again to resume")) from None
    finally:
        bar.close()
    return values, status, resumed


def _results(campaign, runner, ctx, draws, chunks, workers, scheduler):
    """``(chunk, (values, status))`` as chunks finish: in this process, or elsewhere."""
    if scheduler is None and workers <= 1:
        for c in chunks:
            yield c, _evaluate(campaign, runner, ctx, draws, c)
    elif chunks:
        yield from _parallel(chunks, campaign, runner, draws, workers, scheduler)


def _parallel(chunks, campaign, runner, draws, workers, scheduler):
    """``(chunk, result)`` as worker processes or Dask tasks finish them."""
    args = (campaign, runner._master.base_dir, runner.fmu_dir, draws)
    if scheduler is not None:
        try:
            from distributed import Client, as_completed
        except ImportError:
            raise ValueError("a Dask scheduler was given but the 'distributed' package is "
                             "not installed (install the 'cluster' extra)") from None
        own = not hasattr(scheduler, "submit")
        client = Client(scheduler) if own else scheduler
        try:
            futs = {client.submit(_chunk, *args, c, pure=False): c for c in chunks}
            for fut in as_completed(futs):
                yield futs[fut], fut.result()
        finally:
            if own:
                client.close()
        return
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures import as_completed as done

    # one BLAS thread per worker: N workers of two-threaded products on N cores run
    # three times slower than one process (measured); fresh interpreters read it
    saved = {k: os.environ.get(k) for k in _BLAS_THREADS}
    os.environ.update({k: "1" for k in _BLAS_THREADS})
    try:
        ctx = multiprocessing.get_context("spawn")
        from .engine import _die_with_parent
        # a killed run takes its workers (and so the resource tracker) with it
        pool = ProcessPoolExecutor(max_workers=int(workers), mp_context=ctx,
                                   initializer=_die_with_parent, initargs=(os.getpid(),))
        try:
            futs = {pool.submit(_chunk, *args, c): c for c in chunks}
            for fut in done(futs):
                yield futs[fut], fut.result()
        finally:   # stopped: the chunks not started are dropped, not waited for
            pool.shutdown(wait=True, cancel_futures=True)
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _cosimulate(campaign, out_dir, ctx, draws, workers, scheduler, runner, bar):
    """The samples as co-simulated cases (``[uncertainty] engine = "cosim"``).

    Every sample, configuration and event is a case of the base campaign with the draws
    as parameter overrides: a source's ``scale`` (amplitude), ``seed`` (phases) and
    ``frequency_scale``, a controller's ``gain``; they run as any campaign's cases
    (resumable, pool or Dask) under ``out_dir/uncertainty_cases``.
    """
    from .cases import Case, keyed
    from .runner import MasterRunner
    from .store import METRICS_FILE, case_status
    from .engine import run_campaign

    import pyarrow.parquet as pq

    items = campaign.uncertainty["parameters"]
    configs, events, pairs = ctx["configs"], ctx["events"], ctx["pairs"]
    case_of = {(c.configuration, c.event): c for c in campaign.cases if not c.sweep}
    cases, where = [], []
    for s in range(draws.n):
        for ci, cf in enumerate(configs):
            for ei, ev in enumerate(events):
                base = case_of[(cf, ev)]
                sc = json.loads(json.dumps(base.scenario))
                for it in items:
                    for j, inst in enumerate(it.instances):
                        p = sc["fmus"][inst].setdefault("parameters", {})
                        v = draws.values[it.name][s, j]
                        if it.kind == "amplitude":
                            p["scale"] = float(p.get("scale", 1.0)) * float(v)
                        elif it.kind == "phase":
                            p["seed"] = int(v)
                        elif it.kind == "frequency":
                            p["frequency_scale"] = (float(p.get("frequency_scale", 1.0))
                                                    * float(v))
                        else:
                            p["gain"] = float(p.get("gain", 1.0)) * float(v)
                key = hashlib.sha256(json.dumps(sc, sort_keys=True).encode()).hexdigest()
                cases.append(Case(key, f"{base.label} | sample {s}", ev, cf, f"sample={s}",
                                  sc))
                where.append((s, ci, ei))
    mc = dataclasses.replace(campaign, cases=tuple(cases), uncertainty=None,
                             wheel_sweeps=(), engine="cosim")
    master = MasterRunner(campaign.scenario_dir, fmu_dir=runner.fmu_dir)
    folder = Path(out_dir) / "uncertainty_cases"
    run_campaign(mc, folder, master, workers=workers or None, scheduler=scheduler,
                 progress=False)
    mc = keyed(mc, master)
    values = np.full((draws.n, len(configs), len(events), len(pairs),
                      len(campaign.metrics)), np.nan)
    status = np.zeros((draws.n, len(configs)), int)
    index = {(p[0], p[1]): j for j, p in enumerate(pairs)}
    metric_index = {(k, w): i for i, (k, w) in enumerate(campaign.metrics)}
    for case, (s, ci, ei) in zip(mc.cases, where):
        st = case_status(folder / "cases", case.key)
        if not st or st.get("status") != "ok":
            values[s, ci] = np.inf        # a failed co-simulation: no jitter to give
            status[s, ci] |= LIMIT
            continue
        for r in pq.read_table(folder / "cases" / case.key / METRICS_FILE).to_pylist():
            values[s, ci, ei, index[(r["instrument"], r["axis"])],
                   metric_index[(r["metric"], r["window"])]] = r["value"]
    for _ in range(draws.n):
        bar.update("ok")
    return values, status


# the FMU parameter each kind of draw sets; the linear engine applies an amplitude or a
# gain to the loop itself, so only a co-simulated sample needs those two
_SETS = {"phase": "seed", "frequency": "frequency_scale", "amplitude": "scale",
         "gain": "gain"}


def check_uncertain_inputs(campaign, runner) -> None:
    """Refuse an uncertain input whose instance has no FMU parameter for it (a phase or
    frequency draw on a source that is not a disturbance FMU would otherwise change
    nothing), in one sentence.

    :func:`run_uncertainty` checks before any sample runs; ``jitterfmu campaign`` before
    any case of the campaign runs too.

    Parameters
    ----------
    campaign : Campaign
        With ``uncertainty`` set.
    runner : LinearRunner
        Reads the FMUs' parameters (``parameter_names``).

    Raises
    ------
    CampaignError
        Naming the input, the instance, its FMU and the parameters it has.
    """
    from .spec_base import CampaignError

    cosim = campaign.uncertainty.get("engine") == "cosim"
    seen = {}
    for it in campaign.uncertainty["parameters"]:
        if it.kind not in _SETS or (it.kind in ("amplitude", "gain") and not cosim):
            continue
        for inst in it.instances:
            case = next((c for c in campaign.cases if not c.sweep
                         and inst in c.scenario["fmus"]), None)
            if case is None:
                continue
            if inst not in seen:
                seen[inst] = runner.parameter_names(case.scenario, inst)
            if _SETS[it.kind] not in seen[inst]:
                fmu = case.scenario["fmus"][inst]["fmu"]
                whose = "controllers" if it.kind == "gain" else "disturbance FMUs"
                raise CampaignError(
                    f"uncertain {it.name!r} ({it.kind}) sets {_SETS[it.kind]} of {inst}, "
                    f"whose FMU {fmu!r} has no such parameter (it has "
                    f"{', '.join(seen[inst]) or 'none'}); name instances of {whose} for "
                    "this kind")


def _check_sources(campaign, runner, draws) -> None:
    """Refuse, before any sample runs, a draw that a source cannot take: a frequency
    factor on a source that does not repeat, or one that breaks its timing (a scan's
    turnaround longer than its sweep), in one sentence.  The checks are monotone in the
    factor, so each source is tried at its smallest and largest draw."""
    from .spec_base import CampaignError

    for it in campaign.uncertainty["parameters"]:
        col = np.asarray(draws.values.get(it.name, ()), float)
        if col.size and not np.isfinite(col).all():
            s = int(np.flatnonzero(~np.isfinite(col).reshape(col.shape[0], -1).all(1))[0])
            bad = float(col[s][~np.isfinite(col[s])].flat[0])
            raise CampaignError(f"uncertain {it.name!r} draws {bad!r} for "
                                f"sample {s}, beyond what a float holds; give its "
                                "distribution bounds (low, high) or a smaller spread")
    items = [it for it in campaign.uncertainty["parameters"] if it.kind == "frequency"]
    seen = set()
    for case in (c for c in campaign.cases if not c.sweep):
        for it in items:
            for j, inst in enumerate(it.instances):
                own = case.scenario["fmus"][inst].get("parameters", {})
                col = draws.values[it.name][:, j]
                for v in sorted({float(col.min()), float(col.max())}):
                    f = float(own.get("frequency_scale", 1.0)) * v
                    key = (inst, json.dumps(own, sort_keys=True, default=str), f)
                    if key in seen:
                        continue
                    seen.add(key)
                    why = runner.source_problem(case.scenario, inst, {"frequency_scale": f})
                    if why:
                        raise CampaignError(f"uncertain {it.name!r} draws frequency_scale "
                                            f"{f:.6g} for {inst} in event {case.event!r}, "
                                            f"which it refuses: {why}")


def _source_parameters(scenario, draws, items, s) -> dict:
    """Sample ``s``'s parameters of the sources whose series it changes: a phase
    ``seed``, a ``frequency_scale`` (times the scenario's own)."""
    out = {}
    for it in items:
        if it.kind in ("phase", "frequency"):
            for j, inst in enumerate(it.instances):
                v = draws.values[it.name][s, j]
                p = out.setdefault(inst, {})
                if it.kind == "phase":
                    p["seed"] = int(v)
                else:
                    own = scenario["fmus"][inst].get("parameters", {})
                    p["frequency_scale"] = float(own.get("frequency_scale", 1.0)) * float(v)
    return out


def _sample_input(runner, fr, scenario, W, draws, items, s):
    """``(W, scale)`` of sample ``s``: ``W`` with its new phases and frequencies, and the
    amplitude factor of each source channel (``FastResponse.run_many``'s ``scales``)."""
    params = _source_parameters(scenario, draws, items, s)
    if params:
        W = runner.inputs(fr, scenario, params)
    factors = {}
    for it in items:
        if it.kind == "amplitude":
            for j, inst in enumerate(it.instances):
                factors[inst] = factors.get(inst, 1.0) * float(draws.values[it.name][s, j])
    scale = np.ones(fr.m)
    for inst, f in factors.items():
        off = fr._in_off.get(inst)
        if off is not None:
            scale[off:off + len(fr.lin.blocks[inst].outputs)] = f
    return W, scale
