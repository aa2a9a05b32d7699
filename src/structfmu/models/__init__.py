"""Built-in structural models, by name."""

from __future__ import annotations

import difflib


def _registry():
    # deferred: a model module computes its tables at import (eos_testbed: 0.6 s of CPU),
    # and structfmu.models is imported by tooling that needs neither
    from structfmu.models import eos_testbed, truss10

    return {"truss10": truss10, "eos_testbed": eos_testbed}


MODEL_NAMES = ("truss10", "eos_testbed")


def get_model(name: str):
    """The module of a built-in model (has ``build()`` and ``reduced()``)."""
    reg = _registry()
    if name not in reg:
        close = difflib.get_close_matches(name, list(reg), 2)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise KeyError(f"unknown model {name!r}{hint} Built-in models: {', '.join(reg)}")
    return reg[name]
