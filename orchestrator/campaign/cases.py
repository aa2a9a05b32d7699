"""A campaign's cases: the base scenario with one event, configuration and sweep point.

Every case is the base scenario's data with its overrides set, keyed by the SHA-256 of
its definition (that data, the instruments, the metrics and the skip).  The overrides are
applied to the scenario's data rather than to a parsed :class:`~orchestrator.scenario.Scenario`
because the key hashes that data: :meth:`Scenario.digest
<orchestrator.scenario.Scenario.digest>` hashes another form of it (exact times as strings),
so keying by it would change every key and no existing campaign folder would resume.
The runner's fingerprint of the FMUs then enters the key (:func:`keyed`).  A key, and
the case's folder ``cases/KEY``, reads ``<label>-<digest>``: the case's label made
file-name friendly (at most 48 characters) beside the first 16 hex digits of the SHA-256
(:func:`case_key`), so that a folder says which case it holds.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from .spec import CampaignError, CampaignSpec, parse_spec, read_spec
from .store import canonical, slug


@dataclass(frozen=True)
class Case:
    """One run of a campaign.

    Attributes
    ----------
    key : str
        ``<label>-<digest>`` (:func:`case_key`): the SHA-256 of the case definition and
        the runner's fingerprint, beside the label; the case's folder name.
    label : str
        Readable name, ``event | configuration | sweep``.
    event, configuration, sweep : str
        Coordinates in the campaign matrix (``sweep`` is ``"p=v, ..."`` or ``""``).
    scenario : dict
        Scenario data (the TOML layout) after the case's overrides.
    """

    key: str
    label: str
    event: str
    configuration: str
    sweep: str
    scenario: dict


@dataclass(frozen=True)
class Campaign:
    """A campaign expanded into cases.

    Attributes
    ----------
    name : str
    cases : tuple of Case
    instruments : dict of str to dict of str to str
        ``{instrument: {axis: recorded variable}}``; recorded LOS angles in rad.
    metrics : tuple of (str, float or None)
        ``(kind, window)`` pairs; window in s (the lag for ``stability``).
    requirements : tuple of dict
        Items with ``instrument``, ``value`` and optional ``axis``, ``metric``, ``window``.
    unit : str
        Reporting unit, a key of :data:`~orchestrator.campaign.ANGLE_UNITS`.
    skip : float
        Transient dropped from the start of every record (s).
    base_dir : Path
        Folder of the campaign file (relative paths are resolved against it).
    scenario_dir : Path
        Folder of the base scenario (FMU names are resolved against it).
    engine : str
        ``"cosim"`` (the co-simulation master, the default) or ``"linear"`` (the linear
        engine, :class:`~orchestrator.campaign.LinearRunner`).
    verify : int
        With the linear engine: the cases with the largest jitter to co-simulate and
        compare (:func:`~orchestrator.campaign.verify_campaign`).
    wheel_sweeps : tuple of dict
        Per ``[[wheel_sweeps]]`` entry and configuration: ``name``, ``configuration``,
        ``instance``, ``rpm``, ``points``, ``open`` and the ``scenario`` (base with the
        configuration's and the sweep's overrides).
    uncertainty : dict or None
        The ``[uncertainty]`` table checked: ``samples``, ``seed``, ``confidence`` and
        ``parameters`` (:class:`~orchestrator.analysis.uncertainty.Uncertain`).
    source : str
        Where the campaign came from (``"campaign file 'c.toml'"``), for messages.
    overrides : tuple of (str, str, tuple)
        Every ``instance.variable`` the campaign sets, with the field that sets it and
        the values it takes;
        :func:`~orchestrator.campaign.run_campaign` checks them against the FMUs before
        any case runs.
    """

    name: str
    cases: tuple
    instruments: dict
    metrics: tuple
    requirements: tuple = ()
    unit: str = "arcsec"
    skip: float = 0.0
    base_dir: Path = field(default_factory=Path.cwd)
    scenario_dir: Path = field(default_factory=Path.cwd)
    engine: str = "cosim"
    verify: int = 2
    wheel_sweeps: tuple = ()
    uncertainty: dict | None = None
    source: str = "campaign data"
    overrides: tuple = ()

    def requirement(self, instrument: str, axis: str, metric: str, window) -> float:
        """Requirement (in ``unit``) for one summary row, NaN if none applies.

        The most specific matching item wins (axis, metric and window each count).

        Parameters
        ----------
        instrument, axis, metric : str
            The row's instrument, axis and metric kind.
        window : float or None
            The row's window or lag (s); None for ``rms``.

        Returns
        -------
        float
            Requirement in ``unit``, NaN when no item applies.
        """
        best, score = math.nan, -1
        for r in self.requirements:
            if r["instrument"] != instrument:
                continue
            s = 0
            for key, value in (("axis", axis), ("metric", metric), ("window", window)):
                if key in r:
                    if key == "window":
                        if value is None or not math.isclose(float(r[key]), float(value)):
                            break
                    elif r[key] != value:
                        break
                    s += 1
            else:
                if s > score:
                    best, score = float(r["value"]), s
        return best


def expand(spec: CampaignSpec) -> Campaign:
    """Expand a checked campaign file into its cases (events × configurations × sweeps).

    Returns
    -------
    Campaign
        Cases keyed by the SHA-256 of their definition.
    """
    cases = []
    for ev, cf in itertools.product(spec.events, spec.configurations):
        for point in itertools.product(*spec.sweeps):
            overrides = {**cf.overrides, **ev.overrides, **dict(point)}
            scenario = _with_overrides(spec.scenario, overrides)
            definition = {"scenario": scenario, "instruments": spec.instruments,
                          "metrics": list(spec.metrics), "skip": spec.skip}
            digest = hashlib.sha256(canonical(definition).encode()).hexdigest()
            sweep = ", ".join(f"{p}={v}" for p, v in point)
            label = " | ".join(x for x in (ev.name, cf.name, sweep) if x)
            cases.append(Case(digest, label, ev.name, cf.name, sweep, scenario))
    keys = [c.key for c in cases]
    if len(set(keys)) != len(keys):
        dup = [c.label for c in cases if keys.count(c.key) > 1]
        raise CampaignError(f"cases {dup} have identical definitions; make their overrides differ")
    cases = [dataclasses.replace(c, key=case_key(c.label, c.key)) for c in cases]
    wheel = tuple({"name": w.name, "configuration": cf.name, "instance": w.instance,
                   "rpm": w.rpm, "points": w.points, "open": w.open,
                   "scenario": _with_overrides(spec.scenario, {**cf.overrides,
                                                               **w.overrides})}
                  for w in spec.wheel_sweeps for cf in spec.configurations)
    return Campaign(spec.name, tuple(cases), spec.instruments, spec.metrics, spec.requirements,
                    spec.unit, spec.skip, spec.base_dir, spec.scenario_dir, spec.engine,
                    spec.verify, wheel, spec.uncertainty, spec.source, spec.overrides)


def campaign_from_dict(data: Mapping, base_dir=None) -> Campaign:
    """Expand campaign data (the TOML layout) into a :class:`Campaign`.

    Parameters
    ----------
    data : mapping
        Tables ``campaign``, ``events``, ``configurations``, ``sweeps``, ``instruments``,
        ``metrics``, ``requirements``.  ``campaign.scenario`` is a path to the base scenario
        TOML or an inline table (the scenario layout).
    base_dir : path-like, optional
        Folder for relative paths (default: current folder).

    Returns
    -------
    Campaign
        Cases keyed by the SHA-256 of their definition;
        :func:`~orchestrator.campaign.run_campaign` mixes in the runner's fingerprint
        (:func:`keyed`).
    """
    return expand(parse_spec(data, base_dir))


def load_campaign(path, uncertainty=None, samples=None) -> Campaign:
    """Read a campaign TOML file (see :mod:`orchestrator.campaign` for the layout).

    Parameters
    ----------
    path : path-like
        Campaign file.
    uncertainty : path-like, optional
        A TOML file of one ``[uncertainty]`` table that replaces the campaign file's.
    samples : int, optional
        The Monte Carlo's sample count, in place of the table's.

    Returns
    -------
    Campaign
    """
    return expand(read_spec(path, uncertainty, samples))


def keyed(campaign: Campaign, runner) -> Campaign:
    """Mix the runner's fingerprint of each case (e.g. FMU checksums) into its key.

    Parameters
    ----------
    campaign : Campaign
        Cases keyed by their definition only.
    runner : callable
        Case runner; if it has ``fingerprint(scenario_dict) -> str`` that string enters
        every key, so a rebuilt FMU makes its cases run again.

    Returns
    -------
    Campaign
        Same campaign, final keys.
    """
    fp = getattr(runner, "fingerprint", None)
    if fp is None:
        return campaign
    cases = []
    for c in campaign.cases:
        extra = fp(c.scenario)
        digest = hashlib.sha256(f"{c.key}\n{extra}".encode()).hexdigest()
        cases.append(dataclasses.replace(c, key=case_key(c.label, digest)))
    return dataclasses.replace(campaign, cases=tuple(cases))


def case_key(label: str, digest: str) -> str:
    """A case's key and folder name: its label beside its digest.

    Parameters
    ----------
    label : str
        ``event | configuration | sweep``.
    digest : str
        Hex SHA-256 of the case's definition (and the runner's fingerprint).

    Returns
    -------
    str
        ``<label, file-name friendly, at most 48 characters>-<16 hex digits>``, e.g.
        ``ceres_scan_isolation_off-3fa2c1d09be47a15``.
    """
    return f"{slug(label)[:48].rstrip('_')}-{digest[:16]}"


def _with_overrides(scenario: dict, overrides: dict) -> dict:
    """A deep copy of scenario data with ``{"instance.variable": value}`` set.

    The instances were checked when the campaign file was read.
    """
    out = json.loads(json.dumps(scenario))  # deep copy, plain data
    for key, value in overrides.items():
        inst, var = key.split(".", 1)
        out["fmus"][inst].setdefault("parameters", {})[var] = value
    return out
