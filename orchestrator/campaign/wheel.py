"""A campaign's ``[[wheel_sweeps]]``: steady-state jitter over a wheel's speed range.

Each sweep runs in every configuration of the campaign on the linear engine
(:func:`orchestrator.analysis.sweep.wheel_sweep`), with the campaign's instruments,
metrics, record length (``stop - skip``) and requirements.  Written to the campaign
folder:

* ``wheel_sweeps.parquet`` (and ``.csv``): one row per sweep, configuration,
  instrument, axis, metric, window and speed: ``rpm``, ``value`` (campaign unit),
  ``requirement``;
* ``wheel_sweeps_worst.csv``: per sweep, configuration, instrument, axis and metric, the
  speed of the largest value, the value, the requirement and the margin.

The report draws them (jitter versus speed with the requirement and the worst point).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow as pa

from ..results import rows_table
from .spec import ANGLE_UNITS
from .store import write_table

__all__ = ["run_wheel_sweeps", "WHEEL_FILE", "WORST_FILE"]

WHEEL_FILE = "wheel_sweeps.parquet"
WORST_FILE = "wheel_sweeps_worst.csv"

_SCHEMA = pa.schema([
    ("sweep", pa.string()), ("configuration", pa.string()), ("instrument", pa.string()),
    ("axis", pa.string()), ("metric", pa.string()), ("window", pa.float64()),
    ("rpm", pa.float64()), ("unit", pa.string()), ("value", pa.float64()),
    ("requirement", pa.float64()),
])
_WORST = pa.schema([
    ("sweep", pa.string()), ("configuration", pa.string()), ("instrument", pa.string()),
    ("axis", pa.string()), ("metric", pa.string()), ("window", pa.float64()),
    ("worst_rpm", pa.float64()), ("unit", pa.string()), ("value", pa.float64()),
    ("requirement", pa.float64()), ("margin", pa.float64()),
])


def run_wheel_sweeps(campaign, out_dir, runner=None, progress=None) -> Path | None:
    """Run every ``[[wheel_sweeps]]`` entry of a campaign; the table's path, or None.

    Parameters
    ----------
    campaign : Campaign
    out_dir : path-like
        The campaign folder.
    runner : LinearRunner, optional
        Reused for its compiled loops (default: a new one on the campaign's folder).
    progress : callable, optional
        ``progress(text)`` after each sweep and configuration.
    """
    from ..analysis._threads import map_threads
    from ..analysis.sweep import wheel_sweep
    from .linear import LinearRunner

    if not campaign.wheel_sweeps:
        return None
    runner = runner if isinstance(runner, LinearRunner) else LinearRunner(campaign.scenario_dir)
    scale = ANGLE_UNITS[campaign.unit]
    pairs = [(inst, axis, var) for inst, axes in campaign.instruments.items()
             for axis, var in axes.items()]
    refs = [var for _, _, var in pairs]
    rows, worst = [], []
    loops = [runner.response(sw["scenario"], refs, sw["open"]) for sw in campaign.wheel_sweeps]

    def one(job):
        sw, fr = job
        stop = float(sw["scenario"]["experiment"]["stop"])
        speeds = np.linspace(sw["rpm"][0], sw["rpm"][1], sw["points"])
        return speeds, wheel_sweep(fr, sw["instance"], speeds, refs, campaign.metrics,
                                   stop - campaign.skip)

    # each sweep on its own loop: side by side on the cores
    results = map_threads(one, list(zip(campaign.wheel_sweeps, loops)))
    for sw, (speeds, res) in zip(campaign.wheel_sweeps, results):
        for j, (inst, axis, var) in enumerate(pairs):
            for m, (kind, window) in enumerate(campaign.metrics):
                req = campaign.requirement(inst, axis, kind, window)
                vals = res.values[:, j, m] * scale
                rows += [{"sweep": sw["name"], "configuration": sw["configuration"],
                          "instrument": inst, "axis": axis, "metric": kind, "window": window,
                          "rpm": float(s), "unit": campaign.unit, "value": float(v),
                          "requirement": req} for s, v in zip(speeds, vals)]
                i = int(np.argmax(vals))
                worst.append({"sweep": sw["name"], "configuration": sw["configuration"],
                              "instrument": inst, "axis": axis, "metric": kind,
                              "window": window, "worst_rpm": float(speeds[i]),
                              "unit": campaign.unit, "value": float(vals[i]),
                              "requirement": req,
                              "margin": req - float(vals[i]) if not math.isnan(req)
                              else math.nan})
        if progress is not None:
            progress(f"wheel sweep {sw['name']!r} ({sw['configuration']}): "
                     f"{speeds.size} speeds")
    out = Path(out_dir)
    table = rows_table(rows, _SCHEMA)
    write_table(table, out / WHEEL_FILE)
    write_table(table, out / WHEEL_FILE.replace(".parquet", ".csv"), csv=True)
    write_table(rows_table(worst, _WORST), out / WORST_FILE, csv=True)
    return out / WHEEL_FILE
