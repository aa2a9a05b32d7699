"""Built blocks kept on disk between processes, keyed by everything they depend on.

Linearising a loop builds one :class:`~orchestrator.analysis.blocks.Block` per instance:
the structure's exact ZOH (one exponential of the whole model), the amplifiers' step and
sub-step rows, the controllers' lifted laws.  A process keeps them for every loop it
closes (:func:`~orchestrator.analysis.blocks._instance_block`); this module keeps the
structure, piezo and controller blocks for the next process too, so that a single
``--engine linear`` case, a campaign's workers, a sweep and ``jitterfmu analyze`` of the
same FMUs build each once on a machine.

* **Key**: the FMU file's SHA-256 (not its path), the instance's name, parameters,
  periods and start time, the calling thread's BLAS thread count (as in the process),
  and the digest of the code that builds a block (this package's ``blocks`` module, the
  FMUs' packages ``structfmu``, ``piezofmu``, ``ctrlfmu``, ``acsfmu``, ``fmutools``,
  ``fmukit``), the numpy, scipy and pythonfmu versions and the machine.  Any change to one of them is another entry.
* **Data, never code**: an entry is one ``.npz`` read with ``allow_pickle=False`` (the
  arrays and one JSON header), used only if it is a regular file of the current user
  that others cannot write, in the private cache (:func:`fmutools.fmucache.cache_root`,
  ``blocks/``), and only if the SHA-256 of its arrays equals the one its header records.
  Anything else (a truncated file, another format, a mismatch) is a miss: the block is
  built and the entry written again.  Writes go to a temporary file renamed into place.
* **What stays live**: a controller's ``rebuild`` (a loop gain's factor) builds the
  live block from its FMU on first use; a structure's ``model`` is its reduced model,
  kept in the entry; sources are never kept (their series come from their slave).

``JITTERFMU_BLOCK_CACHE=off`` turns the store off (reads and writes).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import platform
import tempfile
import threading
import zipfile
from pathlib import Path

import numpy as np

__all__ = ["STATS", "code_digest", "enabled", "entry_key", "load", "save"]

#: Kinds of block kept (the ACS builds in a millisecond; sources hold their slave).
KEPT = ("structure", "piezo", "controller")
_FORMAT, _VERSION = "jitterfmu-block", 1
#: Entries and bytes kept at most; the least recently used go first beyond either.
_MAX_ENTRIES = 512
_MAX_BYTES = 1 << 30
#: Reads and writes of this process: ``hit``, ``miss``, ``written``, ``refused``.
STATS = {"hit": 0, "miss": 0, "written": 0, "refused": 0}
_LOCK = threading.Lock()
_PACKAGES = ("structfmu", "piezofmu", "ctrlfmu", "acsfmu", "fmutools", "fmukit")


def enabled() -> bool:
    """Whether the store is on (``JITTERFMU_BLOCK_CACHE`` is not ``off``, ``0`` or
    ``false``)."""
    return os.environ.get("JITTERFMU_BLOCK_CACHE", "").strip().lower() not in (
        "off", "0", "false", "no")


@functools.cache
def code_digest() -> str:
    """SHA-256 of the code a block is built by, the numpy, scipy and pythonfmu versions
    and the machine (read once per process)."""
    import importlib.util
    from importlib.metadata import PackageNotFoundError, version

    import scipy

    h = hashlib.sha256()
    files = [Path(__file__).with_name("blocks.py")]
    for pkg in _PACKAGES:
        root = Path(importlib.util.find_spec(pkg).origin).parent   # found, not imported
        files += sorted(root.rglob("*.py"))
    for f in files:
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    try:
        fmu_version = version("pythonfmu")
    except PackageNotFoundError:
        fmu_version = ""
    h.update(json.dumps([np.__version__, scipy.__version__, fmu_version, platform.machine(),
                         platform.node(), os.environ.get("OPENBLAS_CORETYPE", "")]).encode())
    return h.hexdigest()


def _folder() -> Path | None:
    """The store's folder in the private cache, or None when it cannot be used."""
    from fmutools.fmucache import CacheError, cache_root, is_own

    try:
        root = cache_root() / "blocks"
        root.mkdir(mode=0o700, exist_ok=True)
    except (CacheError, OSError):
        return None
    return root if is_own(root, directory=True, deny=0o077) else None


def entry_key(parts) -> str:
    """The entry name of a block from what it depends on (with the code's digest).

    Parameters
    ----------
    parts : sequence
        JSON-serialisable values naming the block (FMU digest, instance, parameters,
        periods, start time, BLAS threads).

    Returns
    -------
    str
        64 hex digits.
    """
    text = json.dumps([_FORMAT, _VERSION, code_digest(), list(parts)], default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _arrays_digest(arrays: dict) -> str:
    h = hashlib.sha256()
    for k in sorted(arrays):
        a = np.ascontiguousarray(arrays[k])
        h.update(f"{k}:{a.dtype.str}:{a.shape}".encode() + a.tobytes())
    return h.hexdigest()


def _pack(block) -> tuple[dict, dict]:
    """The arrays and the JSON header of a block."""
    arrays = {"A": block.A, "B": block.B, "C": block.C, "D": block.D,
              "feedthrough": np.asarray(block.feedthrough, bool)}
    cont = None
    if block.continuous is not None:
        cont = []
        for i, v in enumerate(block.continuous):
            if isinstance(v, np.ndarray):
                arrays[f"continuous{i}"] = v
                cont.append("array")
            else:
                cont.append(float(v))
    inner = []
    for i, (o, G, lo, hi, what) in enumerate(block.inner):
        arrays[f"inner{i}"] = G
        inner.append([o, float(lo), float(hi), what])
    model = None
    if block.kind == "structure":
        m = block.model
        for k in ("omega", "modal_damping", "B_e", "C_e", "K_oo", "D_oo", "B_o", "C_o"):
            arrays[f"model_{k}"] = getattr(m, k)
        model = {"name": m.name, "input_names": list(m.input_names),
                 "output_names": list(m.output_names), "output_kinds": list(m.output_kinds),
                 "meta": m.meta, "accel_lowpass": (m.accel_lowpass.to_json()
                                                   if m.accel_lowpass is not None else None)}
    header = {"format": _FORMAT, "version": _VERSION, "name": block.name, "kind": block.kind,
              "period": int(block.period), "inputs": list(block.inputs),
              "outputs": list(block.outputs), "active": bool(block.active),
              "t_on": float(block.t_on), "limits": [[o, float(lo), float(hi), w]
                                                     for o, lo, hi, w in block.limits],
              "unmodelled": list(block.unmodelled), "flags": list(block.flags),
              "continuous": cont, "inner": inner, "model": model,
              "arrays": _arrays_digest(arrays)}
    return arrays, header


def _unpack(arrays: dict, header: dict, rebuild) -> dict:
    """The block's fields from an entry's arrays and header (raises on anything
    malformed)."""
    from structfmu.reduced import ReducedModel
    from structfmu.sensors import SensorLowpass

    cont = header["continuous"]
    if cont is not None:
        cont = tuple(arrays[f"continuous{i}"] if v == "array" else float(v)
                     for i, v in enumerate(cont))
    inner = tuple((str(o), arrays[f"inner{i}"], float(lo), float(hi), str(w))
                  for i, (o, lo, hi, w) in enumerate(header["inner"]))
    model = None
    if header["kind"] == "structure":
        m = header["model"]
        model = ReducedModel(
            **{k: arrays[f"model_{k}"] for k in ("omega", "modal_damping", "B_e", "C_e",
                                                  "K_oo", "D_oo", "B_o", "C_o")},
            input_names=tuple(m["input_names"]), output_names=tuple(m["output_names"]),
            output_kinds=tuple(m["output_kinds"]), name=m["name"], meta=m["meta"],
            accel_lowpass=SensorLowpass(*m["accel_lowpass"]) if m["accel_lowpass"] else None)
    return dict(name=str(header["name"]), kind=str(header["kind"]),
                period=int(header["period"]), A=arrays["A"], B=arrays["B"], C=arrays["C"],
                D=arrays["D"], inputs=tuple(map(str, header["inputs"])),
                outputs=tuple(map(str, header["outputs"])),
                feedthrough=arrays["feedthrough"].astype(bool),
                rebuild=rebuild if header["kind"] == "controller" else None,
                active=bool(header["active"]), continuous=cont,
                limits=tuple((str(o), float(lo), float(hi), str(w))
                             for o, lo, hi, w in header["limits"]),
                unmodelled=tuple(map(str, header["unmodelled"])),
                flags=tuple(map(str, header["flags"])), model=model,
                t_on=float(header["t_on"]), inner=inner)


class _LiveRebuild:
    """A kept controller block's ``rebuild``: the live block is built from its FMU on
    the first call (``live()``), and its own ``rebuild`` answers."""

    def __init__(self, live):
        self._live, self._block = live, None

    def __call__(self, factor):
        if self._block is None:
            self._block = self._live()
        return self._block.rebuild(factor)


def load(key: str, live) -> dict | None:
    """The fields of the kept block of entry ``key`` (``Block(**fields)``), or None
    (off, missing, not ours, malformed).

    Parameters
    ----------
    key : str
        :func:`entry_key` of the block.
    live : callable
        ``live() -> Block``: builds the block from its FMU (a kept controller's
        ``rebuild`` calls it on first use).

    Returns
    -------
    dict or None
    """
    from fmutools.compiled import is_own_file

    if not enabled():
        return None
    folder = _folder()
    path = None if folder is None else folder / f"{key}.npz"
    if path is None or not path.exists():
        STATS["miss"] += 1
        return None
    try:
        if not is_own_file(path):
            raise ValueError("not a private file of ours")
        with np.load(path, allow_pickle=False) as f:
            header = json.loads(str(f["header"][()]))
            arrays = {k: f[k] for k in f.files if k != "header"}
        if header.get("format") != _FORMAT or header.get("version") != _VERSION \
                or header.get("arrays") != _arrays_digest(arrays):
            raise ValueError("another format, or arrays that are not the ones written")
        fields = _unpack(arrays, header, _LiveRebuild(live))
    except (OSError, ValueError, KeyError, TypeError, IndexError, zipfile.BadZipFile):
        STATS["refused"] += 1
        return None
    STATS["hit"] += 1
    try:
        os.utime(path)   # recently used: the last to go when the store is trimmed
    except OSError:
        pass
    return fields


def save(key: str, block) -> bool:
    """Keep ``block`` as entry ``key`` (kinds :data:`KEPT` only); False when not kept.

    Parameters
    ----------
    key : str
        :func:`entry_key` of the block.
    block : Block
        The block just built.

    Returns
    -------
    bool
    """
    if block.kind not in KEPT or not enabled():
        return False
    folder = _folder()
    if folder is None:
        return False
    arrays, header = _pack(block)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=".npz")
        with os.fdopen(fd, "wb") as out:
            np.savez(out, header=np.array(json.dumps(header)), **arrays)
        os.replace(tmp, folder / f"{key}.npz")
    except OSError:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        return False
    STATS["written"] += 1
    _trim(folder)
    return True


def _trim(folder: Path) -> None:
    """Remove the least recently used entries beyond :data:`_MAX_ENTRIES` entries or
    :data:`_MAX_BYTES` bytes (a read touches its entry)."""
    with _LOCK:
        entries = []
        for p in folder.glob("*.npz"):
            try:
                st = p.stat()
            except OSError:
                continue
            entries.append((st.st_mtime, st.st_size, p))
        entries.sort(key=lambda e: e[0], reverse=True)   # the newest first
        total = 0
        for i, (_, size, p) in enumerate(entries):
            total += size
            if i >= _MAX_ENTRIES or total > _MAX_BYTES:
                p.unlink(missing_ok=True)

