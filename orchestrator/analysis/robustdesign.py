"""Robust design: controller gains and the ACS tuned for jitter, stable over the set.

:func:`robust_design` tunes what it is told to (a factor on one controller's gain, a
common factor on a family such as ``ctrl_iso1..3``, and the ACS by
:func:`~orchestrator.analysis.acsdesign.design_acs`) to lower an objective (a callable
of the loop; :class:`orchestrator.campaign.objective.CampaignObjective` gives the jitter
of a campaign's lines on the linear engine) subject to

* the nominal loop stable, everything closed;
* each tuned controller's gain margin at least ``margin_db`` both ways: the loop stays
  stable with that gain times ``g^(1/2)``, ``g``, ``g^(-1/2)`` and ``g^(-1)``,
  ``g = 10^(margin_db/20)``, the others as designed (the final design's margins are then
  measured by :func:`~orchestrator.analysis.loops.scenario_margins` and reported);
* every one of ``samples`` random points of the uncertainty set, and every damping bound
  across ``grid`` common frequency factors, stable (a fixed draw: the same points judge
  every candidate; the ones that failed a candidate are tried first).

The ACS, when tuned, is designed first on the flexible plant with the tuned controllers
opened, its bandwidth range lowered step by step until the set is stable with it; the
gains are then tuned with it in place.  The gains are searched in ``log2`` steps from
the scenario's own (a coordinate search: each factor, and all together, up and down by
``x2``, then ``x2^(1/2)``, down to ``x2^(1/8)``; a move is kept when it lowers the
objective by more than ``rtol`` of it and meets the constraints).  A start that misses
the constraints is first scaled down, all factors together, until it meets them.  So
the result is never worse than a feasible start.  Its robust stability is then checked
again on an independent draw (another seed) with
:func:`~orchestrator.analysis.robust.robust_stability`, which also searches the smallest
destabilising scale of the set.
"""

from __future__ import annotations

import fnmatch
import math
import re
import time
from dataclasses import dataclass, field

import numpy as np

from .blocks import AnalysisError
from .robust import pole_radius

__all__ = ["RobustDesign", "tune_targets", "robust_design"]

_BOUND = 6.0            # factors searched within 2^-6 .. 2^6 of the start
#: Seconds without a progress message after which a judged candidate says the count so
#: far (a search of slow candidates is never silent; a fast one is not a line each).
COUNT_EVERY = 10.0


@dataclass(frozen=True, eq=False)
class RobustDesign:
    """A robust design and its checks.

    Attributes
    ----------
    overrides : dict of str to float
        ``instance.parameter`` values that carry the design (gains, ACS parameters).
    factors : dict of str to float
        Per tuned target, its factor on the start gain (-).
    objective_start, objective : object or None
        The objective's value (its ``as_dict``) at the start and at the design.
    start_feasible : bool
        Whether the start met the constraints; ``start_reason`` says why not.
    start_reason : str
    lin : LinearScenario
        The designed loop.
    margins : list of GroupMargins
        Its loops' margins (:func:`~orchestrator.analysis.loops.scenario_margins`).
    robust : dict or None
        :func:`~orchestrator.analysis.robust.robust_stability` on the draw the design was
        judged with.
    resample : dict or None
        The same on an independent draw (seed + 1).
    acs : AcsDesign or None
    history : list of dict
        Every candidate judged: factors, objective, feasible, why not.
    searched : dict
        The objective, the constraints and the search, in words and numbers.
    seconds : float
    """

    overrides: dict
    factors: dict
    objective_start: object
    objective: object
    start_feasible: bool
    start_reason: str
    lin: object
    margins: list
    robust: dict | None
    resample: dict | None
    acs: object
    history: list = field(default_factory=list)
    searched: dict = field(default_factory=dict)
    seconds: float = 0.0

    def as_dict(self) -> dict:
        """Plain numbers for JSON."""
        def obj(v):
            return None if v is None else (v.as_dict() if hasattr(v, "as_dict") else v)
        return {"overrides": dict(self.overrides), "factors": dict(self.factors),
                "objective_start": obj(self.objective_start),
                "objective": obj(self.objective),
                "start_feasible": self.start_feasible, "start_reason": self.start_reason,
                "stable": self.lin.is_stable(),
                "margins": [g.as_dict() for g in self.margins],
                "robust": self.robust, "robust_resample": self.resample,
                "acs": None if self.acs is None else self.acs.as_dict(),
                "searched": self.searched, "history": self.history,
                "seconds": self.seconds}


def tune_targets(lin, entries) -> tuple:
    """What ``--tune`` names: gain targets and whether the ACS is designed.

    Parameters
    ----------
    lin : LinearScenario
    entries : sequence of str
        ``acs``; a controller ``ctrl_iso1`` (or ``ctrl_iso1.gain``): a factor on its
        gain; a family ``ctrl_iso`` or a pattern ``ctrl_iso*``: one common factor on
        every controller it names.

    Returns
    -------
    targets : list of (str, list of str)
        Label and instances of each factor.
    acs : bool

    Raises
    ------
    AnalysisError
        One sentence: an entry that names nothing, a parameter other than a gain, a
        controller at gain 0 (a factor on it changes nothing), or nothing to tune.
    """
    ctrls = lin.controllers()
    targets, acs = [], False
    for raw in entries:
        e = raw.strip()
        if not e:
            continue
        if e == "acs" or e in lin.blocks and lin.blocks[e].kind == "acs":
            if not any(b.kind == "acs" for b in lin.blocks.values()):
                raise AnalysisError("--tune acs: the scenario has no ACS instance")
            acs = True
            continue
        if "." in e:
            e, var = e.split(".", 1)
            if var != "gain":
                raise AnalysisError(f"--tune {raw}: only gains are tuned (INSTANCE.gain), "
                                    "and the ACS as 'acs'")
        if e in ctrls:
            names = [e]
        else:
            names = [c for c in ctrls if fnmatch.fnmatchcase(c, e)
                     or re.sub(r"\d+$", "", c) == e]
        if not names:
            raise AnalysisError(f"--tune {raw} names no controller of the scenario; its "
                                f"controllers: {', '.join(ctrls) or 'none'}")
        for n in names:
            if not lin.blocks[n].active:
                raise AnalysisError(f"--tune {raw}: {n} has gain 0 in the scenario, so a "
                                    f"factor on it changes nothing; give it a starting gain "
                                    f"with --set {n}.gain=VALUE")
        targets.append((e, names))
    seen = [n for _, names in targets for n in names]
    if len(seen) != len(set(seen)):
        raise AnalysisError(f"--tune names a controller twice ({', '.join(entries)}); give "
                            "each once, alone or in one family")
    if not targets and not acs:
        raise AnalysisError("--tune names nothing to tune; give controllers, families or "
                            "acs")
    return targets, acs


def _start_gain(lin, name: str) -> float:
    inst = next(i for i in lin.plan.scenario.instances if i.name == name)
    if "gain" in inst.parameters:
        return float(inst.parameters["gain"])
    var = lin.plan.fmus[name].variables.get("gain")
    return float(var.start) if var is not None and var.start is not None else 1.0


class _Judge:
    """The constraints of one design problem, with the points of the set fixed."""

    def __init__(self, items, samples, seed, grid, margin_db, scale=1.0):
        self.items, self.samples, self.seed, self.grid = items, samples, seed, grid
        self.scale = scale
        self.g = 10 ** (margin_db / 20)
        self.points, self.hard, self.uset = None, [], None

    def _draw(self, lin):
        from .robust import uncertain_set
        from .uncertainty import draw

        if self.items is None or self.points is not None:
            return
        self.uset = uset = uncertain_set(lin, self.items)
        model = lin.blocks[uset.structure].model
        d = draw(list(uset.items), self.samples, self.seed, model.omega / (2 * math.pi))
        pts = [(f"sample {s}", {n: d.values[n][s] for n in d.values})
               for s in range(self.samples)]
        fw = [uset.bounds(it.name) for it in uset.items if it.kind == "modal_frequency"]
        lo, hi = min([b[0] for b in fw], default=1.0), max([b[1] for b in fw], default=1.0)
        for f in np.linspace(lo, hi, self.grid):
            for side in (0, 1):
                vals = {}
                for it in uset.items:
                    k = d.values[it.name].shape[1]
                    vals[it.name] = (np.full(k, f) if it.kind == "modal_frequency" else
                                     np.full(k, uset.bounds(it.name)[side])
                                     if it.kind == "modal_damping" else np.ones(k))
                pts.append((f"corner frequency x{f:.3f}, damping "
                            f"{'low' if side == 0 else 'high'}", vals))
        # each point at ``scale`` times its distance from nominal
        self.points = [(label, {n: 1.0 + self.scale * (np.asarray(v, float) - 1.0)
                                for n, v in vals.items()}) for label, vals in pts]

    def __call__(self, lin, gains=()) -> str:
        """Empty when ``lin`` meets the constraints, else why not (one phrase)."""
        from .fast import FastResponse
        from .robust import loop_at

        like = FastResponse(lin, [], strict=False)
        r = pole_radius(lin, like)
        if r >= 1.0:
            return f"unstable nominally (|z| {r:.6f})"
        for inst in gains:
            for k in (0.5, 1.0, -0.5, -1.0):
                f = self.g ** k
                if pole_radius(lin.with_gain(inst, f), like) >= 1.0:
                    return (f"{inst} unstable with its gain x{f:.3g} (gain margin below "
                            f"{20 * math.log10(self.g):g} dB)")
        if self.items is None:
            return ""
        self._draw(lin)
        order = self.hard + [i for i in range(len(self.points)) if i not in self.hard]
        for i in order:
            label, vals = self.points[i]
            if pole_radius(loop_at(lin, self.uset, vals), like) >= 1.0:
                if i not in self.hard:
                    self.hard.insert(0, i)
                return f"{label} of the uncertainty set unstable"
        return ""


def robust_design(lin, items, tune, objective=None, *, margin_db: float = 6.0,
                  samples: int = 20, seed: int = 0, grid: int = 3, set_scale: float = 1.0,
                  acs_options=None,
                  max_evaluations: int = 80, min_step: float = 0.125, rtol: float = 1e-3,
                  progress=None) -> RobustDesign:
    """Tune gains and the ACS for the objective, robustly stable (module docstring).

    Parameters
    ----------
    lin : LinearScenario
        The scenario's loop at the start (its gains are the start).
    items : sequence of Uncertain or None
        The uncertainty set (:func:`orchestrator.campaign.spec_uncertainty.
        parse_uncertainty`); None: the nominal constraints only.
    tune : sequence of str
        What to tune (:func:`tune_targets`).
    objective : callable, optional
        ``objective(lin)`` with a ``value`` to lower (``inf`` when unstable) and an
        ``as_dict``; needed when gains are tuned.
    margin_db : float
        Gain margin each tuned controller keeps both ways (dB), at least 0.
    samples : int
        Random points of the set judging every candidate (>= 1).
    seed : int
        Their seed; the independent check uses ``seed + 1``.
    grid : int
        Common frequency factors of the damping corners (>= 2).
    set_scale : float
        Every point of the set judged at this many times its distance from nominal
        (>= 1; above 1 keeps a margin on the set, as ``margin_found`` measures it).
    acs_options : dict, optional
        Passed to :func:`~orchestrator.analysis.acsdesign.design_acs` (margins,
        bandwidth range, filters); its ``bandwidths`` are lowered when the set is not
        stable with the ACS.
    max_evaluations : int
        Most candidates judged in the gain search.
    min_step : float
        Smallest step of the search (``log2`` of a factor).
    rtol : float
        A move is kept when it lowers the objective by more than this fraction (-): a
        line the tuned loops barely reach does not drag them about.
    progress : callable, optional
        ``progress(message)`` at each stage and kept move, and with the candidates
        judged so far once :data:`COUNT_EVERY` seconds passed without a message.

    Returns
    -------
    RobustDesign

    Raises
    ------
    AnalysisError
        One sentence, before any computation for a bad request; or when no scale of
        the start meets the constraints.
    """
    from .loops import scenario_margins
    from .robust import robust_stability

    start = time.perf_counter()
    said = [time.monotonic()]

    def say(message):
        said[0] = time.monotonic()
        if progress is not None:
            progress(message)
    if not (math.isfinite(margin_db) and margin_db >= 0):
        raise AnalysisError(f"the requested gain margin {margin_db:g} dB is below 0 dB; "
                            "expected 0 dB or more (6 dB is usual)")
    if not (math.isfinite(set_scale) and set_scale >= 1.0):
        raise AnalysisError(f"the set scale {set_scale:g} is below 1; expected 1 (the set "
                            "as given) or more (a margin on it)")
    for name, v, low in (("samples", samples, 1), ("grid", grid, 2),
                         ("max_evaluations", max_evaluations, 1)):
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            raise AnalysisError(f"{name} is {v!r}; expected a whole number >= {low}")
    targets, do_acs = tune_targets(lin, tune)
    if targets and objective is None:
        raise AnalysisError("tuning gains needs an objective: give a campaign whose events "
                            "and instruments define the jitter to lower (--campaign)")
    if do_acs:   # the ACS request refused before any work
        from acsfmu.flexible import check_request

        from .acsdesign import acs_instance, acs_settings

        st, o = acs_settings(lin, acs_instance(lin)), acs_options or {}
        check_request(st["sample_time"], phase_margin=o.get("phase_margin", 30.0),
                      gain_margin_db=o.get("gain_margin_db", 6.0),
                      bandwidths=o.get("bandwidths", (0.1, 0.01)),
                      lowpass_ratios=o.get("lowpass_ratios", (4.0, 5.0, 6.25, 8.0)),
                      notch_hz=o.get("notch_hz", ()), antialias_hz=st["antialias"][0],
                      disk_margin_db=o.get("disk_margin_db", 0.0))
    if items is not None:
        from .robust import uncertain_set
        uncertain_set(lin, items)     # refused in one sentence before any work
    judge = _Judge(items, samples, seed, grid, margin_db, set_scale)
    tuned = [n for _, names in targets for n in names]
    history = []
    acs_design, base = None, lin
    if do_acs:
        acs_design, base = _robust_acs(lin, tuned, judge, acs_options or {}, say)

    def candidate(x):
        out = base
        for (label, names), xi in zip(targets, x):
            for n in names:
                out = out.with_gain(n, 2.0 ** xi)
        return out

    evals, seen = [0], {}

    def judged(x):
        key = tuple(np.round(x, 9))
        if key in seen:
            return seen[key]
        cand = candidate(x)
        val = objective(cand) if objective is not None else None
        why = judge(cand, tuned) if val is None or math.isfinite(val.value) else \
            "unstable nominally"
        evals[0] += 1
        history.append({"factors": {t[0]: float(2.0 ** xi) for t, xi in zip(targets, x)},
                        "objective": None if val is None else val.value,
                        "feasible": not why, "why": why})
        seen[key] = (val, why)
        if time.monotonic() - said[0] >= COUNT_EVERY:
            say(f"{evals[0]} of at most {max_evaluations} candidates judged (the last: "
                + (f"objective {val.value:.4g}, " if val is not None else "")
                + (why or "feasible") + ")")
        return val, why

    x = np.zeros(len(targets))
    say("judging the start")
    v0, why0 = judged(x) if targets else (None, "")
    if targets and why0:      # scale every tuned gain down together until it holds
        for k in range(1, 13):
            xs = np.full(len(targets), -0.5 * k)
            say(f"the start is not feasible ({why0}); trying the tuned gains x"
                f"{2 ** xs[0]:.3g}")
            val, why = judged(xs)
            if not why:
                x = xs
                break
        else:
            raise AnalysisError(f"no common scale of the tuned gains down to x1/64 meets the "
                                f"constraints (at the start: {why0}); lower the margin, "
                                "tune other controllers or narrow the uncertainty set")
    best_val = v0 if not why0 else val
    best = best_val.value if best_val is not None else math.inf
    step = 1.0
    while targets and step >= min_step - 1e-12 and evals[0] < max_evaluations:
        moved = False
        dirs = [np.eye(len(targets))[i] for i in range(len(targets))]
        if len(targets) > 1:
            dirs.append(np.ones(len(targets)))
        for d in dirs:
            for sign in (1.0, -1.0):
                xc = x + sign * step * d
                if np.any(np.abs(xc) > _BOUND) or evals[0] >= max_evaluations:
                    continue
                val, why = judged(xc)
                if val.value < best * (1 - rtol) and not why:
                    x, best, best_val, moved = xc, val.value, val, True
                    say(f"kept {', '.join(f'{t[0]} x{2 ** xi:.3g}' for t, xi in zip(targets, x))}"
                        f": objective {best:.4g}")
                    break
            if moved:
                break
        if not moved:
            step /= 2
    final = candidate(x)
    overrides = dict(acs_design.overrides) if acs_design is not None else {}
    for (label, names), xi in zip(targets, x):
        for n in names:
            overrides[f"{n}.gain"] = float(_start_gain(lin, n) * 2.0 ** xi)
    say("measuring the design's margins")
    margins = scenario_margins(final, known=[acs_design.margins]
                               if acs_design is not None and not targets else ())
    robust = resample = None
    if items is not None:
        say(f"robust stability of the design: {samples} samples (seed {seed}) and the "
            f"corners, then {samples} independent samples (seed {seed + 1})")
        robust = robust_stability(final, items, samples=samples, seed=seed, grid=grid)
        resample = robust_stability(final, items, samples=samples, seed=seed + 1, grid=grid,
                                    worst=3, k_max=0.0, certificate=False)
    searched = {
        "objective": getattr(objective, "describe", lambda: None)() if objective else None,
        "constraints": [
            "nominal loop stable, everything closed",
            f"each tuned controller stable with its gain x g^(1/2), x g, x g^(-1/2), "
            f"x g^(-1), g = {margin_db:g} dB, the others as designed",
            (f"every one of {samples} random points of the uncertainty set (seed {seed}) "
             f"and every damping bound across {grid} common frequency factors stable"
             + (f", each at {set_scale:g} times its distance from nominal"
                if set_scale != 1.0 else "")
             if items is not None else "no uncertainty set given: nominal only")],
        "targets": [{"label": t, "instances": names, "start_gain":
                     [_start_gain(lin, n) for n in names]} for t, names in targets],
        "acs": "designed on the flexible plant first (acsdesign.design_acs), the tuned "
               "controllers opened, its bandwidth range lowered until the set is stable"
               if do_acs else "not tuned",
        "search": f"log2 coordinate search from the start (each factor and all together, "
                  f"steps x2 down to x2^{min_step:g}), factors within 2^-{_BOUND:g}..2^"
                  f"{_BOUND:g}, a move kept when it lowers the objective by more than "
                  f"{rtol:g} of it; a start that misses the constraints scaled down first",
        "evaluations": evals[0], "max_evaluations": max_evaluations}
    return RobustDesign(overrides, {t[0]: float(2.0 ** xi) for t, xi in zip(targets, x)},
                        v0, best_val, not why0, why0, final, margins, robust, resample,
                        acs_design, history, searched, time.perf_counter() - start)


def _robust_acs(lin, tuned, judge, options, say) -> tuple:
    """The ACS designed on the flexible plant, its bandwidth range lowered until the
    uncertainty set is stable with it (the tuned controllers opened)."""
    from acsfmu.filters import AcsConfigError

    from .acsdesign import design_acs

    options = dict(options)
    hi, lo = (max(options.get("bandwidths", (0.1, 0.01))),
              min(options.get("bandwidths", (0.1, 0.01))))
    steps = options.pop("steps", 21)
    options.pop("bandwidths", None)
    ratio = (hi / lo) ** (1 / max(steps - 1, 1))
    cap, last = hi, ""
    while cap >= lo * (1 - 1e-9):
        say(f"designing the ACS on the flexible plant, crossovers {lo:.3g}-{cap:.3g} Hz")
        try:
            d = design_acs(lin, bandwidths=(cap, lo),
                           steps=max(2, round(math.log(cap / lo) / math.log(ratio)) + 1)
                           if cap > lo * (1 + 1e-9) else 1, **options)
        except AcsConfigError as exc:
            raise AnalysisError(str(exc)) from None
        view = d.lin.opened(tuned) if tuned else d.lin
        why = judge(view)
        if not why:
            return d, d.lin
        last = why
        top = max(a.choice.bandwidth for a in d.design.axes)
        cap = min(cap, top) / ratio
        say(f"the ACS at {top:.3g} Hz: {why}; lowering its crossovers")
    raise AnalysisError(f"no ACS design with crossovers down to {lo:g} Hz keeps the "
                        f"uncertainty set stable ({last}); lower the bandwidth range or "
                        "narrow the set")
