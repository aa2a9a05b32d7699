"""A campaign's jitter as one number of a loop: the objective of a design.

:class:`CampaignObjective` reads a campaign file for its events, instruments, metrics
and requirements, puts them on the scenario being designed (the campaign's own base
scenario and configurations are replaced by that scenario with its overrides), and for
any loop of that scenario (a :class:`~orchestrator.analysis.LinearScenario` with other
gains or another ACS) runs every event on the linear engine, takes the metrics and the
RSS over the events, as the campaign's budget does.  The value is

* with requirements: the largest ratio of a line's RSS to its requirement (a design
  that lowers it meets its budget by more, below 1 it meets every line);
* without: the RSS over the lines of the first metric, in the campaign's unit.

An unstable loop, or one whose record reaches a rail or limit, is worth ``inf``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..scenario import load_toml_file
from .cases import expand
from .spec import ANGLE_UNITS, parse_spec
from .spec_base import CampaignError

__all__ = ["CampaignObjective", "ObjectiveValue"]


@dataclass(frozen=True)
class ObjectiveValue:
    """The objective of one loop and the lines it comes from.

    Attributes
    ----------
    value : float
        The objective (see the module docstring); ``inf`` for an unstable loop.
    lines : tuple of dict
        Per line: ``instrument``, ``axis``, ``metric``, ``window``, ``value`` (RSS over
        the events, in ``unit``) and ``requirement`` (NaN if none).
    binding : str
        The line that sets the value (empty for a sum).
    stable : bool
    """

    value: float
    lines: tuple
    binding: str
    stable: bool

    def as_dict(self) -> dict:
        """Plain numbers for JSON."""
        return {"value": self.value, "binding": self.binding, "stable": self.stable,
                "lines": list(self.lines)}


class CampaignObjective:
    """The jitter of a campaign's lines on a loop of the scenario being designed.

    Parameters
    ----------
    campaign : path-like
        Campaign file: its ``[[events]]``, ``[[instruments]]``, ``[[metrics]]``,
        ``[[requirements]]``, ``skip``, ``stop``, ``output_interval`` and ``unit`` are
        used.
    scenario : path-like
        The scenario being designed (the campaign's events must name its instances).
    overrides : dict of str to value, optional
        The scenario's start values (``--set``).
    fmu_dir : path-like, optional
        Folder searched first for FMUs.

    Attributes
    ----------
    lin : LinearScenario
        The scenario's loop with the campaign's record settings (the loop to design
        from: its record length is the campaign's).
    campaign : Campaign
        The campaign as applied.
    """

    def __init__(self, campaign, scenario, overrides=None, fmu_dir=None):
        from ..analysis.fast import FastResponse
        from .linear import LinearRunner

        path = Path(campaign)
        data = load_toml_file(path, "campaign file", CampaignError)
        head = dict(data.get("campaign") or {})
        head["scenario"] = str(Path(scenario).resolve())
        data = {k: v for k, v in data.items()
                if k not in ("uncertainty", "sweeps", "wheel_sweeps", "configurations")}
        data["campaign"] = head
        data["configurations"] = [{"name": "design", "overrides": dict(overrides or {})}]
        try:
            spec = parse_spec(data, path.parent, f"campaign file {str(path)!r}")
        except CampaignError as exc:
            raise CampaignError(f"campaign file {str(path)!r} on scenario "
                                f"{str(scenario)!r}: {exc}") from None
        self.campaign = expand(spec)
        self.pairs = [(inst, axis, var) for inst, axes in self.campaign.instruments.items()
                      for axis, var in axes.items()]
        self.refs = [v for _, _, v in self.pairs]
        runner = LinearRunner(self.campaign.scenario_dir, fmu_dir)
        cases = self.campaign.cases
        fr0 = runner.compiled(cases[0].scenario)
        self.lin = fr0.lin
        self._like = FastResponse(self.lin, self.refs, strict=False)
        self.Ws = [runner.inputs(fr0, c.scenario) for c in cases]
        self.events = [c.event for c in cases]
        self.scale = ANGLE_UNITS[self.campaign.unit]
        from .montecarlo import first_tick

        self._first = first_tick(self.campaign, self.lin)
        self.requirements = [self.campaign.requirement(i, a, kind, w)
                             for i, a, _ in self.pairs for kind, w in self.campaign.metrics]

    def __call__(self, lin) -> ObjectiveValue:
        """The objective of ``lin`` (a loop of the scenario, same sources).

        Parameters
        ----------
        lin : LinearScenario

        Returns
        -------
        ObjectiveValue
        """
        from ..analysis.fast import FastResponse
        from ..analysis.sweep import unstable_poles
        from ..metrics import metric_values

        fr = FastResponse(lin, self.refs, strict=False, like=self._like)
        metrics = self.campaign.metrics
        lines = []
        if unstable_poles(fr):
            return ObjectiveValue(math.inf, (), "unstable loop", False)
        tb = lin.plan.timebase
        dt = tb.output_ticks * float(tb.base)
        per = np.zeros((len(self.Ws), len(self.pairs), len(metrics)))
        for e, rec in enumerate(fr.run_many(self.Ws, check=False, bound_limits=True,
                                            start=self._first)):
            if rec.reached:
                return ObjectiveValue(math.inf, (), f"event {self.events[e]!r} reaches a "
                                      "rail or limit", True)
            x = rec.values[::tb.output_ticks][-(-self._first // tb.output_ticks):]
            per[e] = metric_values(x.T, dt, metrics)
        rss = np.sqrt(np.sum(per ** 2, axis=0)) * self.scale        # (pairs, metrics)
        k = 0
        worst, binding = -math.inf, ""
        for p, (inst, axis, _) in enumerate(self.pairs):
            for m, (kind, w) in enumerate(metrics):
                req = self.requirements[k]
                k += 1
                lines.append({"instrument": inst, "axis": axis, "metric": kind,
                              "window": w, "value": float(rss[p, m]),
                              "requirement": req})
                if math.isfinite(req) and rss[p, m] / req > worst:
                    worst, binding = float(rss[p, m] / req), f"{inst} {axis} {kind}"
        if binding:
            return ObjectiveValue(worst, tuple(lines), binding, True)
        total = float(np.sqrt(np.sum(rss[:, 0] ** 2)))
        return ObjectiveValue(total, tuple(lines), "", True)

    def describe(self) -> str:
        """One sentence: what the value is."""
        has_req = any(math.isfinite(r) for r in self.requirements)
        what = ("the largest ratio of a line's RSS over the events to its requirement"
                if has_req else f"the RSS over the lines of the first metric "
                f"({self.campaign.metrics[0][0]}), in {self.campaign.unit}")
        return (f"{what}, under the {len(self.Ws)} events of {self.campaign.source} "
                f"({', '.join(self.events)}) on the linear engine")
