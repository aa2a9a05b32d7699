"""The paper's experiments, reproduced as commands (``jitterfmu reproduce NAME``).

Each experiment is a module with ``NAME``, ``DESCRIPTION`` and
``run(out_dir, quick=False) -> dict``; it writes ``out_dir/NAME.json`` and its figures.
"""

from __future__ import annotations

import importlib
import json
import math
from pathlib import Path
from ..files import write_text_atomic

EXPERIMENTS = {
    "truss-frf": "orchestrator.experiments.truss_frf",
    "truss-decay": "orchestrator.experiments.truss_decay",
    "eos-budget": "orchestrator.experiments.eos_budget",
    "swir-isolation": "orchestrator.experiments.swir_isolation",
    "testbed-isolation": "orchestrator.experiments.testbed_isolation",
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


def run(name: str, out_dir, quick: bool = False, fmu_dir=None) -> dict:
    """Run one experiment; returns its JSON dict (also written to ``out_dir``).

    ``fmu_dir`` (optional) is the folder the experiment builds its FMUs into, for those
    whose ``run`` takes one; default: the experiment's own default.
    """
    avail = available()
    if name not in avail:
        import difflib
        close = difflib.get_close_matches(name, list(avail), 2)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise KeyError(f"unknown experiment {name!r}{hint} Available: {', '.join(avail)}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    module = importlib.import_module(EXPERIMENTS[name])
    kwargs = {}
    if fmu_dir is not None:
        import inspect
        if "fmu_dir" not in inspect.signature(module.run).parameters:
            raise ValueError(f"experiment {name!r} builds its FMUs where it always does; "
                             "run it without --fmu-dir")
        kwargs["fmu_dir"] = fmu_dir
    result = module.run(out_dir, quick=quick, **kwargs)
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
    """Write JSON atomically (NaN/Inf become null)."""
    path = Path(path)
    write_text_atomic(path, json.dumps(_clean(data), indent=2) + "\n")
    return path
