"""The ``[uncertainty]`` table of a campaign file: sample counts, seed, confidence levels,
the assurance of their bounds and the uncertain inputs, each checked and refused in one
sentence before any case runs."""

from __future__ import annotations

import math

from ..analysis.uncertainty import DISTRIBUTIONS, KINDS, Distribution, Uncertain
from ..schema import keys
from .spec_base import ENGINES, CampaignError, check_table_keys

__all__ = ["parse_uncertainty"]

# the key reference's (orchestrator.schema)
_UNCERTAINTY_KEYS = keys("[uncertainty]")
_PARAMETER_KEYS = keys("[[uncertainty.parameters]]")


def parse_uncertainty(table, fmus: dict):
    """``[uncertainty]`` as a dict (None when the file has none), checked.

    Parameters
    ----------
    table : dict or None
        The file's ``[uncertainty]`` table.
    fmus : dict
        The base scenario's instances (``instances = "all"`` and the names are checked
        against them).

    Raises
    ------
    CampaignError
        One sentence naming the key or parameter that is wrong.
    """
    if table is None:
        return None
    if not isinstance(table, dict):
        raise CampaignError("[uncertainty] must be a table")
    check_table_keys(table, _UNCERTAINTY_KEYS, "[uncertainty]")
    n = table.get("samples", 200)
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise CampaignError(f"[uncertainty] samples is {n!r}; expected a whole number >= 1")
    top = table.get("max_samples")
    if top is not None and (isinstance(top, bool) or not isinstance(top, int) or top < n):
        raise CampaignError(f"[uncertainty] max_samples is {top!r}; expected a whole number "
                            f">= samples ({n}): the run extends itself from samples up to "
                            "max_samples until its values converge")
    seed = table.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise CampaignError(f"[uncertainty] seed is {seed!r}; expected a whole number >= 0")
    conf = table.get("confidence", [0.95, 0.9973])
    if not (isinstance(conf, list) and conf and all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and 0 < c < 1
            for c in conf)):
        raise CampaignError(f"[uncertainty] confidence is {conf!r}; expected a list of "
                            "levels in (0, 1), e.g. [0.95, 0.9973]")
    assurance = table.get("assurance", 0.95)
    if isinstance(assurance, bool) or not isinstance(assurance, (int, float)) or not (
            0 < assurance < 1):
        raise CampaignError(f"[uncertainty] assurance is {assurance!r}; expected the "
                            "probability in (0, 1) with which each level's upper bound lies "
                            "above its true value, e.g. 0.95 (a 95/95 statement at P_c = 0.95)")
    engine = table.get("engine", "linear")
    if engine not in ENGINES:
        raise CampaignError(f"[uncertainty] engine is {engine!r}; expected one of "
                            f"{list(ENGINES)}")
    items = table.get("parameters", [])
    if not isinstance(items, list) or not items:
        raise CampaignError("[uncertainty] needs 'parameters', a non-empty list of tables")
    out = []
    for i, p in enumerate(items):
        what = f"uncertain parameter {i + 1}"
        if not isinstance(p, dict):
            raise CampaignError(f"{what} is a {type(p).__name__}; expected a table")
        check_table_keys(p, _PARAMETER_KEYS, what)
        kind = p.get("kind")
        if kind not in KINDS:
            raise CampaignError(f"{what} has kind {kind!r}; expected one of {list(KINDS)}")
        name = str(p.get("name", kind))
        insts = p.get("instances", [])
        if kind in ("amplitude", "phase", "frequency", "gain"):
            if insts == "all":
                prefix = {"gain": "ctrl"}.get(kind, "dist")
                insts = sorted(k for k in fmus if k.startswith(prefix))
            if not isinstance(insts, list) or not insts or any(x not in fmus for x in insts):
                raise CampaignError(f"{what} ({kind}) instances is {p.get('instances')!r}; "
                                    "expected \"all\" or a list of instances of the base "
                                    f"scenario (instances: {sorted(fmus)})")
        dist = None
        if kind != "phase":
            dname = p.get("distribution")
            if dname not in DISTRIBUTIONS:
                raise CampaignError(f"{what} has distribution {dname!r}; expected one of "
                                    f"{list(DISTRIBUTIONS)}")
            args = {k: _number(p[k], f"{what} {k}", bound=k in ("low", "high"))
                    for k in ("low", "high", "mean", "std", "median", "sigma") if k in p}
            try:
                dist = Distribution(dname, **args)
            except ValueError as exc:
                raise CampaignError(f"{what}: {exc}") from None
            if dname == "uniform" and not math.isfinite(dist.high - dist.low):
                raise CampaignError(f"{what} is uniform on [{dist.low}, {dist.high}], wider "
                                    "than a float holds; give bounds of the input's own size")
            if not dist.low >= 0 and kind in ("modal_frequency", "modal_damping"):
                raise CampaignError(f"{what} ({kind}) is a factor on the modes and can reach "
                                    f"{dist.low}; give it bounds low >= 0 (negative damping "
                                    "or frequency is not a structure)")
            if not dist.low > 0 and kind == "frequency":
                raise CampaignError(f"{what} (frequency) is a factor on the sources' "
                                    f"frequencies and can reach {dist.low}; give it bounds "
                                    "low > 0 (a line needs a positive frequency)")
        band = p.get("band", [0.0, math.inf])
        if not (isinstance(band, list) and len(band) == 2
                and all(_is_number(b) and not math.isnan(b) for b in band)
                and 0 <= band[0] < band[1]):
            raise CampaignError(f"{what} band is {band!r}; expected [low, high] in Hz with "
                                "0 <= low < high, e.g. band = [0.0, 50.0]")
        per_mode = p.get("per_mode", False)
        if not isinstance(per_mode, bool):
            raise CampaignError(f"{what} per_mode is {per_mode!r}; expected true or false "
                                "(without quotes)")
        out.append(Uncertain(name, kind, dist, tuple(insts), per_mode,
                             (float(band[0]), float(band[1]))))
    names = [u.name for u in out]
    if len(set(names)) != len(names):
        raise CampaignError(f"uncertain parameters have duplicate names {names}; name them")
    if engine == "cosim":
        modal = [u.name for u in out if u.kind in ("modal_frequency", "modal_damping")]
        if modal:
            raise CampaignError(f"uncertain {modal[0]!r} moves the structure's modes, which a "
                                "co-simulation would need a structure FMU per sample for; "
                                "run it on the linear engine (engine = \"linear\")")
    return {"samples": n, "max_samples": top, "seed": seed,
            "confidence": tuple(float(c) for c in conf), "assurance": float(assurance),
            "parameters": tuple(out),
            "engine": engine}


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _number(x, what: str, bound: bool = False) -> float:
    """A distribution's number: finite (a bound may be +-inf: no bound)."""
    if not _is_number(x) or math.isnan(x) or (not bound and math.isinf(x)):
        raise CampaignError(f"{what} is {x!r}; expected a {'' if bound else 'finite '}number "
                            "(without quotes), e.g. 0.9")
    return float(x)
