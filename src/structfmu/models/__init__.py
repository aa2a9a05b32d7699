"""Built-in structural models, by name."""

from __future__ import annotations


def _registry():
    from structfmu.models import truss10

    reg = {"truss10": truss10}
    try:
        from structfmu.models import eos_testbed  # noqa: F401
        reg["eos_testbed"] = eos_testbed
    except ImportError:  # pragma: no cover - model added later
        pass
    return reg


MODEL_NAMES = ("truss10", "eos_testbed")


def get_model(name: str):
    """The module of a built-in model (has ``build()`` and ``reduced()``)."""
    reg = _registry()
    if name not in reg:
        import difflib
        close = difflib.get_close_matches(name, list(reg), 2)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise KeyError(f"unknown model {name!r}{hint} Built-in models: {', '.join(reg)}")
    return reg[name]
