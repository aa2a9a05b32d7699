"""A disturbance source stored as data, for a disturbance FMU that carries its own.

A source is written as JSON of its dataclass fields, ``{"type": "Table", "times": [...],
"values": [[...], ...], "fill": "hold"}``, a sum as ``{"type": "Sum", "sources": [...]}``.
Loading builds the dataclass from the fields (its own checks apply) and never executes
anything from the file.  Python writes floats with ``repr``, which round-trips every double
exactly, so the loaded source is the one that was saved.

>>> from distfmu.sources import Table
>>> table = Table([0.0, 1.0], [[0, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0]], fill="hold")
>>> float(source_from_json(source_to_json(table)).wrench(0.25)[0])
0.25
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from distfmu import sources as S

__all__ = ["CUSTOM_PRESET", "SOURCE_FILE", "CustomSourceError", "source_from_json",
           "source_to_json"]

CUSTOM_PRESET = "custom"
"""Value of the ``preset`` parameter that selects the FMU's own source."""

SOURCE_FILE = "source.json"
"""Name of the source file in the FMU's ``resources/``."""

_FORMAT = "jitterfmu-disturbance-source 1"

#: Source types that can be stored: every time-driven source of distfmu.sources.
_TYPES = {cls.__name__: cls for cls in (S.Harmonic, S.Chopper, S.ScanMirror, S.Slew,
                                        S.Stepper, S.WheelImbalance, S.Table,
                                        S.BandLimitedRandom)}


class CustomSourceError(ValueError):
    """A disturbance source cannot be stored as data, or its data are invalid."""


def _fields(source) -> dict:
    if isinstance(source, S.Sum):
        return {"type": "Sum", "sources": [_fields(s) for s in source.sources]}
    if type(source) not in _TYPES.values():
        raise CustomSourceError(f"disturbance source {type(source).__name__} cannot be stored "
                                f"as data; expected one of {sorted(_TYPES)} or a Sum of them")
    if isinstance(source, S.WheelImbalance) and isinstance(source.speed, S.SpeedProfile):
        raise CustomSourceError("a wheel imbalance with a speed profile cannot be stored as "
                                "data; give it a constant speed")
    out: dict = {"type": type(source).__name__}
    for f in dataclasses.fields(source):
        value = getattr(source, f.name)
        if isinstance(value, (np.ndarray, np.generic, tuple)):
            value = np.asarray(value).tolist()
        out[f.name] = value
    return out


def source_to_json(source) -> bytes:
    """The JSON data of ``source`` (UTF-8).

    Parameters
    ----------
    source : Source
        A time-driven source of :mod:`distfmu.sources` (not ``Gated``, not a wheel with a
        speed profile) or a ``Sum`` of them.

    Returns
    -------
    bytes
        Content of :data:`SOURCE_FILE`.
    """
    return json.dumps({"format": _FORMAT, "source": _fields(source)},
                      allow_nan=False).encode("utf-8")


def _tuples(value):
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def _build(data, where: str):
    if not isinstance(data, dict) or not isinstance(data.get("type"), str):
        raise CustomSourceError(f"{where} must be an object with a string 'type'")
    kind = data["type"]
    if kind == "Sum":
        terms = data.get("sources")
        if not isinstance(terms, list) or set(data) != {"type", "sources"}:
            raise CustomSourceError(f"{where} (Sum) must have exactly a list 'sources'")
        return S.Sum(tuple(_build(t, f"{where}.sources[{i}]") for i, t in enumerate(terms)))
    if kind not in _TYPES:
        raise CustomSourceError(f"{where} has type {kind!r}; expected one of "
                                f"{sorted(_TYPES)} or 'Sum'")
    cls = _TYPES[kind]
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names - {"type"})
    if unknown:
        raise CustomSourceError(f"{where} ({kind}) has unknown field(s) {unknown}; "
                                f"expected some of {sorted(names)}")
    kwargs = {k: _tuples(v) for k, v in data.items() if k != "type"}
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:  # SourceError is a ValueError
        raise CustomSourceError(f"{where} ({kind}) is invalid: {exc}") from None


def source_from_json(content: bytes | str, name: str = SOURCE_FILE):
    """The source stored in ``content``, checked by its own dataclass.

    Parameters
    ----------
    content : bytes or str
        JSON written by :func:`source_to_json`.
    name : str
        File name used in error messages.

    Returns
    -------
    Source

    Raises
    ------
    CustomSourceError
        If the content is not such JSON or the source's parameters are invalid.
    """
    try:
        doc = json.loads(content)
    except (ValueError, UnicodeDecodeError) as exc:
        raise CustomSourceError(f"disturbance source file {name} is not valid JSON ({exc})") \
            from None
    if not isinstance(doc, dict) or doc.get("format") != _FORMAT:
        raise CustomSourceError(f"disturbance source file {name} has no 'format': "
                                f"{_FORMAT!r}; write it with distfmu.custom.source_to_json")
    return _build(doc.get("source"), f"disturbance source file {name}: source")
