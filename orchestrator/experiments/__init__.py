"""The paper's experiments, reproduced as commands (``jitterfmu reproduce NAME``).

Each experiment is a module with ``NAME``, ``DESCRIPTION`` and
``run(out_dir, quick=False, fmu_dir="fmus", **options) -> dict``; it builds the FMUs it
runs into ``fmu_dir`` (when missing or stale), writes its figures into ``out_dir``, and
:func:`run` writes ``out_dir/NAME.json``.  A module may add ``summary(result) -> str``,
the text ``jitterfmu reproduce`` prints.

The experiments' inputs (scenarios and campaigns) are package data under ``inputs/``
(:data:`SCENARIOS`, :data:`CAMPAIGNS`); the repository's ``scenarios/`` and
``campaigns/`` are links to them.  Nothing is written into the package.
"""

from __future__ import annotations

import difflib
import importlib
import inspect
import json
import math
from pathlib import Path

from ..files import write_text_atomic

#: The experiments' input files (package data).
INPUTS = Path(__file__).resolve().parent / "inputs"
SCENARIOS = INPUTS / "scenarios"
CAMPAIGNS = INPUTS / "campaigns"

EXPERIMENTS = {
    "truss-frf": "orchestrator.experiments.truss_frf",
    "truss-decay": "orchestrator.experiments.truss_decay",
    "eos-budget": "orchestrator.experiments.eos_budget",
    "swir-isolation": "orchestrator.experiments.swir_isolation",
    "testbed-isolation": "orchestrator.experiments.testbed_isolation",
    "testbed-servo": "orchestrator.experiments.testbed_servo",
    "testbed-robust": "orchestrator.experiments.testbed_margins",
}


def available() -> dict:
    """Experiments whose module is present, name -> description."""
    out = {}
    for name, mod in EXPERIMENTS.items():
        try:
            out[name] = importlib.import_module(mod).DESCRIPTION
        except ModuleNotFoundError:
            continue
    return out


def run(name: str, out_dir, quick: bool = False, fmu_dir=None, **options) -> dict:
    """Run one experiment; returns its JSON dict (also written to ``out_dir/NAME.json``).

    Parameters
    ----------
    name : str
        Experiment name (:data:`EXPERIMENTS`).
    out_dir : path-like
        Folder for the JSON and the figures.
    quick : bool
        Shorter runs (what the tests use).
    fmu_dir : path-like, optional
        Folder the experiment builds its FMUs into (default: ``fmus`` in the current
        folder).
    **options
        Options of that experiment's ``run`` (e.g. ``workers`` for ``eos-budget``); an
        option it does not take is refused in one sentence.
    """
    avail = available()
    if name not in avail:
        close = difflib.get_close_matches(name, list(avail), 2)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise KeyError(f"unknown experiment {name!r}{hint} Available: {', '.join(avail)}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    module = importlib.import_module(EXPERIMENTS[name])
    takes = inspect.signature(module.run).parameters
    for key in options:
        if key not in takes:
            raise ValueError(f"experiment {name!r} has no option {key!r}; run it without it")
    result = module.run(out_dir, quick=quick, fmu_dir="fmus" if fmu_dir is None else fmu_dir,
                        **options)
    write_json(out_dir / f"{name}.json", result)
    return result


def _clean(obj):
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "tolist"):
        return _clean(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_json(path, data) -> Path:
    """Write JSON atomically (NaN/Inf become null).

    Parameters
    ----------
    path : path-like
        The file to write.
    data : object
        JSON-serialisable data (numpy values included).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    write_text_atomic(path, json.dumps(_clean(data), indent=2) + "\n")
    return path
