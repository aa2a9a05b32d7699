"""Serialized FMU state as plain bytes: data only, never code.

``fmi2SerializeFMUstate`` and ``fmi2DeSerializeFMUstate`` of every project FMU go
through :func:`encode_state` and :func:`decode_state`.  The bytes hold values of a
few plain types in a fixed, versioned layout; decoding only ever builds those types
(no class lookup, no import, no pickle), and any byte string that is not exactly a
well-formed layout raises one :class:`FmuStateError`.

Layout (all integers little-endian)
-----------------------------------
========  ======================================================================
header    ``MAGIC`` (8 bytes), version ``u16``, body length ``u64``
body      one value (the state dict), exactly ``body length`` bytes
checksum  CRC-32 (``zlib.crc32``, ``u32``) of the header and the body
========  ======================================================================

The checksum is checked before the body is read, so a flipped byte anywhere is refused
with one message (CRC-32 detects every error burst of up to 32 bits).

A value is a one-byte tag followed by its payload:

=====  ==============  ==================================================
tag    type            payload
=====  ==============  ==================================================
``N``  None            nothing
``T``  True            nothing
``F``  False           nothing
``i``  int             ``u8`` length n, n bytes (signed, two's complement)
``f``  float           ``f64``
``c``  complex         two ``f64`` (real, imaginary)
``s``  str             ``u32`` length n, n bytes of UTF-8
``b``  bytes           ``u32`` length n, n bytes
``a``  numpy array     ``u8`` dtype code (:data:`DTYPES`), ``u8`` ndim, ndim
                       ``u64`` extents, the C-order elements (little-endian)
``l``  list            ``u32`` count, count values
``t``  tuple           ``u32`` count, count values
``d``  dict            ``u32`` count, count pairs (str key as in ``s``
                       without its tag, then a value)
=====  ==============  ==================================================

Numpy scalars are stored as the matching Python scalar.  Nesting is limited to
:data:`MAX_DEPTH` levels.

Example
-------
>>> import numpy as np
>>> blob = encode_state({"x": np.arange(3.0), "k": 7})
>>> blob[:8] == MAGIC
True
>>> decode_state(blob)["x"]
array([0., 1., 2.])
"""

from __future__ import annotations

import struct
import zlib
from typing import Any

import numpy as np

__all__ = ["DTYPES", "MAGIC", "MAX_DEPTH", "VERSION", "FmuStateError", "decode_state",
           "encode_state", "seal"]

#: First bytes of every serialized state.
MAGIC = b"JFMUSTAT"
#: Layout version written by :func:`encode_state`; :func:`decode_state` accepts only it
#: (version 1 had no checksum).
VERSION = 2
#: Array element types, by their one-byte code (little-endian, no objects).
DTYPES = (np.dtype("<f8"), np.dtype("<f4"), np.dtype("<i8"), np.dtype("<i4"),
          np.dtype("<i2"), np.dtype("i1"), np.dtype("<u8"), np.dtype("<u4"),
          np.dtype("<u2"), np.dtype("u1"), np.dtype("?"), np.dtype("<c16"),
          np.dtype("<c8"))
#: Deepest nesting of lists, tuples, dicts.
MAX_DEPTH = 32

_HEADER = struct.Struct("<8sHQ")
_CRC = struct.Struct("<I")
_CODE = {dt: i for i, dt in enumerate(DTYPES)}
_MAX_NDIM = 32


class FmuStateError(ValueError):
    """An FMU state cannot be serialized, or bytes are not a serialized FMU state."""


# ---------------------------------------------------------------------- encode
def encode_state(state: Any) -> bytes:
    """Return the bytes of ``state`` in the layout of this module.

    Parameters
    ----------
    state : object
        None, bool, int, float, complex, str, bytes, a numpy array of a type in
        :data:`DTYPES` (or a numpy scalar), or a list, tuple or str-keyed dict of
        these.

    Raises
    ------
    FmuStateError
        If a value (named by its path, e.g. ``attrs['x']``) has another type.
    """
    out: list[bytes] = []
    _encode(state, out, "state", 0)
    body = b"".join(out)
    return seal(_HEADER.pack(MAGIC, VERSION, len(body)) + body)


def seal(data: bytes) -> bytes:
    """``data`` (header and body) followed by its CRC-32, as the layout ends."""
    return data + _CRC.pack(zlib.crc32(data))


def _encode(value: Any, out: list[bytes], path: str, depth: int) -> None:
    if depth > MAX_DEPTH:
        raise FmuStateError(f"FMU state value {path} is nested deeper than {MAX_DEPTH} levels")
    if value is None:
        out.append(b"N")
    elif isinstance(value, (bool, np.bool_)):
        out.append(b"T" if value else b"F")
    elif isinstance(value, (int, np.integer)):
        v = int(value)
        n = max(1, (v.bit_length() + 8) // 8)
        if n > 255:
            raise FmuStateError(f"FMU state value {path} is an integer of {n} bytes; "
                                "expected at most 255")
        out += [b"i", bytes([n]), v.to_bytes(n, "little", signed=True)]
    elif isinstance(value, (float, np.floating)):
        out += [b"f", struct.pack("<d", float(value))]
    elif isinstance(value, (complex, np.complexfloating)):
        v = complex(value)
        out += [b"c", struct.pack("<dd", v.real, v.imag)]
    elif isinstance(value, str):
        raw = value.encode("utf-8", "surrogatepass")
        out += [b"s", struct.pack("<I", len(raw)), raw]
    elif isinstance(value, (bytes, bytearray)):
        out += [b"b", struct.pack("<I", len(value)), bytes(value)]
    elif isinstance(value, np.ndarray):
        dtype = value.dtype.newbyteorder("<") if value.dtype.byteorder == ">" else value.dtype
        code = _CODE.get(dtype)
        if code is None:
            raise FmuStateError(f"FMU state value {path} is an array of {value.dtype}; expected "
                                f"one of {', '.join(str(d) for d in DTYPES)}")
        if value.ndim > _MAX_NDIM:
            raise FmuStateError(f"FMU state value {path} has {value.ndim} dimensions; "
                                f"expected at most {_MAX_NDIM}")
        data = np.ascontiguousarray(value, dtype=DTYPES[code])
        out += [b"a", bytes([code, data.ndim]), struct.pack(f"<{data.ndim}Q", *data.shape),
                data.tobytes()]
    elif isinstance(value, (list, tuple)):
        out += [b"l" if isinstance(value, list) else b"t", struct.pack("<I", len(value))]
        for i, item in enumerate(value):
            _encode(item, out, f"{path}[{i}]", depth + 1)
    elif isinstance(value, dict):
        out += [b"d", struct.pack("<I", len(value))]
        for key, item in value.items():
            if not isinstance(key, str):
                raise FmuStateError(f"FMU state value {path} has key {key!r}; expected str keys")
            raw = key.encode("utf-8", "surrogatepass")
            out += [struct.pack("<I", len(raw)), raw]
            _encode(item, out, f"{path}[{key!r}]", depth + 1)
    else:
        raise FmuStateError(f"FMU state value {path} is a {type(value).__name__}; expected "
                            "None, bool, int, float, complex, str, bytes, a numeric numpy "
                            "array, or a list, tuple or dict of these")


# ---------------------------------------------------------------------- decode
class _Reader:
    """Cursor over the body; every read checks the bytes left."""

    def __init__(self, data: memoryview) -> None:
        self.data = data
        self.pos = 0

    def take(self, n: int, what: str) -> memoryview:
        end = self.pos + n
        if n < 0 or end > len(self.data):
            raise _Bad(f"{what} needs {n} bytes at offset {self.pos} but only "
                       f"{len(self.data) - self.pos} are left")
        chunk = self.data[self.pos:end]
        self.pos = end
        return chunk

    def unpack(self, fmt: str, what: str) -> tuple:
        return struct.unpack(fmt, self.take(struct.calcsize(fmt), what))

    def count(self, what: str) -> int:
        (n,) = self.unpack("<I", what)
        if n > len(self.data) - self.pos:  # every item takes at least one byte
            raise _Bad(f"{what} claims {n} items but only {len(self.data) - self.pos} bytes "
                       "are left")
        return n

    def text(self, what: str) -> str:
        (n,) = self.unpack("<I", what)
        try:
            return bytes(self.take(n, what)).decode("utf-8", "surrogatepass")
        except UnicodeDecodeError:
            raise _Bad(f"{what} at offset {self.pos - n} is not UTF-8") from None


class _Bad(Exception):
    """Internal: why the bytes are not a state (wrapped into FmuStateError)."""


def decode_state(data: bytes | bytearray | memoryview) -> Any:
    """Rebuild the value that :func:`encode_state` wrote.

    Parameters
    ----------
    data : bytes-like
        The whole serialized state (header and body, nothing more).

    Returns
    -------
    object
        Plain values only: None, bool, int, float, complex, str, bytes, writable
        numpy arrays, lists, tuples and str-keyed dicts.

    Raises
    ------
    FmuStateError
        If ``data`` is not exactly one well-formed state of layout :data:`VERSION`.
    """
    try:
        view = memoryview(bytes(data))
    except TypeError:
        raise FmuStateError(f"serialized FMU state is a {type(data).__name__}; expected "
                            "bytes") from None
    try:
        if len(view) < _HEADER.size:
            raise _Bad(f"it has {len(view)} bytes, fewer than the {_HEADER.size}-byte header")
        magic, version, length = _HEADER.unpack(view[:_HEADER.size])
        if magic != MAGIC:
            raise _Bad(f"it starts with {bytes(magic)!r} instead of {MAGIC!r}")
        if version != VERSION:
            raise _Bad(f"its layout version is {version}; this FMU reads version {VERSION}")
        end = len(view) - _CRC.size
        if length != end - _HEADER.size:
            raise _Bad(f"its header announces {length} bytes of body and a checksum but "
                       f"{len(view) - _HEADER.size} bytes follow")
        (crc,) = _CRC.unpack(view[end:])
        if crc != zlib.crc32(view[:end]):
            raise _Bad("its checksum does not match its bytes (corrupted)")
        reader = _Reader(view[_HEADER.size:end])
        value = _decode(reader, 0)
        if reader.pos != len(reader.data):
            raise _Bad(f"{len(reader.data) - reader.pos} bytes follow the state")
    except _Bad as exc:
        raise FmuStateError(f"serialized FMU state is invalid: {exc}; expected bytes from "
                            "fmi2SerializeFMUstate of the same FMU") from None
    return value


def _decode(r: _Reader, depth: int) -> Any:
    if depth > MAX_DEPTH:
        raise _Bad(f"values are nested deeper than {MAX_DEPTH} levels")
    at = r.pos
    tag = bytes(r.take(1, "a value tag"))
    if tag == b"N":
        return None
    if tag == b"T":
        return True
    if tag == b"F":
        return False
    if tag == b"i":
        (n,) = r.unpack("<B", "an integer length")
        return int.from_bytes(r.take(n, "an integer"), "little", signed=True)
    if tag == b"f":
        return r.unpack("<d", "a float")[0]
    if tag == b"c":
        re_, im = r.unpack("<dd", "a complex")
        return complex(re_, im)
    if tag == b"s":
        return r.text("a string")
    if tag == b"b":
        (n,) = r.unpack("<I", "a bytes length")
        return bytes(r.take(n, "bytes"))
    if tag == b"a":
        code, ndim = r.unpack("<BB", "an array header")
        if code >= len(DTYPES):
            raise _Bad(f"array at offset {at} has dtype code {code}; expected 0 to "
                       f"{len(DTYPES) - 1}")
        if ndim > _MAX_NDIM:
            raise _Bad(f"array at offset {at} has {ndim} dimensions; expected at most "
                       f"{_MAX_NDIM}")
        shape = r.unpack(f"<{ndim}Q", "an array shape")
        dtype = DTYPES[code]
        n = dtype.itemsize
        for extent in shape:
            n *= extent
            if n > len(r.data):
                raise _Bad(f"array at offset {at} of shape {shape} is larger than the state")
        raw = r.take(n, "array elements")
        try:
            return np.frombuffer(raw, dtype=dtype).reshape(shape).copy()
        except ValueError as exc:
            raise _Bad(f"array at offset {at} of shape {shape}: {exc}") from None
    if tag in (b"l", b"t"):
        items = [_decode(r, depth + 1) for _ in range(r.count("a sequence length"))]
        return items if tag == b"l" else tuple(items)
    if tag == b"d":
        out = {}
        for _ in range(r.count("a dict length")):
            key = r.text("a dict key")
            if key in out:
                raise _Bad(f"dict key {key!r} appears twice")
            out[key] = _decode(r, depth + 1)
        return out
    raise _Bad(f"unknown value tag {tag!r} at offset {at}")
