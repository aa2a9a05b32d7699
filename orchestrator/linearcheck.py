"""The linear engine's verdict on a run's closed loops.

A run of a closed loop that is unstable can still end ``ok``: held at an output clamp,
or growing too slowly to diverge within the run.  Where the linear engine represents the
scenario (:func:`orchestrator.analysis.scenario.linearize`), :func:`linear_verdict` finds
its closed-loop poles; with one outside the unit circle, the run ends with status
``unstable`` and one line naming the loop: the controllers whose loop is unstable on its
own (the other controllers opened), else those whose loops are unstable together.  A scenario without feedback, or one the linear engine does not represent
(an FMU it has no model of, an algebraic loop), gets no verdict and keeps its status.

A process keeps its verdicts: the runs of a campaign that differ only in their sources'
parameters (a disturbance's preset, an event) close the same loop, so the second of them
reuses the first one's verdict instead of linearising again (the sources are the
instances the linear engine found without inputs; the FMU files are keyed by their
digests).
"""

from __future__ import annotations

import copy
import json
import math
import warnings
from pathlib import Path

import numpy as np

__all__ = ["UnstableLoopWarning", "linear_verdict"]


class UnstableLoopWarning(UserWarning):
    """A run whose closed loop the linear engine finds unstable (status ``unstable``)."""


def _has_feedback(connections) -> bool:
    """Whether the instances' connections close a cycle (a loop, delayed or not)."""
    graph = {}
    for c in connections:
        graph.setdefault(c.source, set()).add(c.target)
    state = {}

    def cyclic(node) -> bool:
        state[node] = 1
        for nxt in graph.get(node, ()):
            if state.get(nxt) == 1 or (nxt not in state and cyclic(nxt)):
                return True
        state[node] = 2
        return False
    return any(node not in state and cyclic(node) for node in list(graph))


def _fmu_dir(plan) -> Path | None:
    """The folder the run's FMUs came from (the linear engine reads their Python twins)."""
    paths = [Path(f.path) for f in plan.fmus.values()]
    return paths[0].parent if paths else None


# verdicts kept in this process: {loop key: (verdict, info)}, and the source instances of
# each layout of FMUs (known after its first linearisation)
_VERDICTS: dict = {}
_SOURCES: dict = {}
_KEEP = 64


def _layout(plan) -> str:
    return json.dumps(sorted((name, info.sha256) for name, info in plan.fmus.items()))


def _loop_key(plan, layout: str) -> str | None:
    """What the verdict of ``plan`` depends on: the scenario less its sources' parameters,
    with its FMUs' digests (``layout``); None before a run of this layout has told the
    sources."""
    from orchestrator.analysis.scenario import loop_key

    sources = _SOURCES.get(layout)
    if sources is None:
        return None
    data = plan.scenario.to_dict()
    data.pop("record", None)
    return json.dumps([loop_key(data, sources), layout])


def linear_verdict(plan) -> tuple[str, dict | None]:
    """The linear engine's verdict on the closed loops of a prepared run.

    Parameters
    ----------
    plan : orchestrator.cosim.Plan
        The run's plan (its scenario with the run's overrides, its FMUs).

    Returns
    -------
    (str, dict or None)
        ``("stable", None)``, ``("no feedback", None)``, ``("not represented: <why>",
        None)``, ``("unstable once the loop ... closes ...", None)`` for a run that ends before
        the unstable loop closes, or ``("unstable", info)`` with ``info`` holding
        ``instance`` and ``loop`` (the controller instances named), ``pole_abs`` (|z| over
        the hyperperiod ``period_s``), ``freq_hz``, ``doubling_s`` and ``message`` (one
        line).
    """
    from orchestrator.analysis.blocks import AnalysisError

    if not _has_feedback(plan.scenario.connections):
        return "no feedback", None
    try:
        layout = _layout(plan)
        key = _loop_key(plan, layout)
        if key in _VERDICTS:
            return copy.deepcopy(_VERDICTS[key])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            got = _verdict(plan, layout)
        key = key or _loop_key(plan, layout)   # a layout's first run has told its sources
        if key is not None:
            if len(_VERDICTS) >= _KEEP:
                _VERDICTS.clear()
            _VERDICTS[key] = copy.deepcopy(got)
        return got
    except Exception as exc:   # noqa: BLE001 -- no verdict must ever cost a run its rows
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        why = text if isinstance(exc, AnalysisError) else f"{type(exc).__name__}: {text}"
        return f"not represented: {why}", None


def _verdict(plan, layout: str) -> tuple[str, dict | None]:
    from orchestrator.analysis.scenario import _stable, linearize

    lin = linearize(plan.scenario, fmu_dir=_fmu_dir(plan))
    _SOURCES[layout] = tuple(lin.sources)
    ev = np.linalg.eigvals(lin.lifted())   # once: is_stable() would lift and solve again
    if _stable(ev):
        return "stable", None
    worst = complex(ev[np.argmax(np.abs(ev))])
    growth = math.log(abs(worst)) / lin.T
    freq = abs(np.angle(worst)) / (2 * math.pi * lin.T)
    active = lin.controllers(active_only=True)
    # each loop alone (the other controllers opened), then the loops together
    alone = [c for c in active
             if not lin.opened([o for o in active if o != c]).is_stable()]
    loop = alone or active
    if alone:
        what = ("the closed loop through " + alone[0] if len(alone) == 1 else
                "the closed loops through " + " and ".join(alone) + ", each on its own,")
    elif loop:
        what = "the closed loops through " + " and ".join(loop) + " together"
    if loop:
        advice = "lower its gain" if len(loop) == 1 else "lower their gains"
    else:
        what, advice = "the scenario's linear model (no controller in it)", "check the model"
    t_on = max((lin.blocks[c].t_on for c in loop), default=0.0)
    end = float(plan.timebase.base * plan.timebase.n_ticks)
    if end <= t_on:
        return (f"unstable once the loop through {' and '.join(loop)} closes at t = "
                f"{t_on:.6g} s, after the run's end at {end:.6g} s"), None
    verb = "are" if len(alone) > 1 or not alone and len(loop) > 1 else "is"
    message = (f"{what} {verb} unstable in the linear engine: a pole at {freq:.4g} Hz grows "
               f"by a factor {abs(worst):.6g} every {lin.T:.6g} s (doubling in "
               f"{math.log(2) / growth:.4g} s); the run is not the loop designed (status "
               f"unstable): {advice} or check the loop with jitterfmu analyze")
    return "unstable", {"instance": loop[0] if loop else None, "loop": list(loop), "pole_abs": abs(worst), "period_s": lin.T,
                        "freq_hz": freq, "doubling_s": math.log(2) / growth,
                        "message": message}
