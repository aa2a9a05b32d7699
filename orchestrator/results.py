"""Run results: the recorded table, its metadata, atomic files and a progress bar.

A run folder holds ``results.parquet`` (or ``results.csv``) with a ``time`` column and
one column per recorded ``instance.variable``, and ``run.json`` with the scenario hash,
FMU checksums, package versions, wall time, status and error.
"""

from __future__ import annotations

import functools
import json
import re
import sys
from dataclasses import dataclass, field
from importlib import metadata as _md
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .files import atomic_write

__all__ = ["RunResult", "arrow_table", "write_table", "write_mat", "read_table", "read_columns",
           "read_units", "write_metadata", "package_versions"]


@dataclass(frozen=True)
class RunResult:
    """The outcome of one run; unpacks as ``table, metadata = result``.

    Attributes
    ----------
    table : dict of str to ndarray, shape (n_rows,)
        ``"time"`` (s) and one column per recorded ``instance.variable``.
    metadata : dict
        The content of ``run.json``.
    path : Path or None
        The output folder, if results were written.
    """

    table: dict
    metadata: dict = field(default_factory=dict)
    path: Path | None = None

    def __iter__(self):
        return iter((self.table, self.metadata))

    def __getitem__(self, key):
        return self.table[key]

    @property
    def time(self) -> np.ndarray:
        """Row times (s)."""
        return self.table["time"]

    def to_arrow(self):
        """Return the table as a ``pyarrow.Table``."""
        return pa.table({k: np.asarray(v) for k, v in self.table.items()})


def arrow_table(table: dict, units: dict | None = None) -> pa.Table:
    """A column table as a ``pyarrow.Table`` whose fields carry their units.

    Parameters
    ----------
    table : dict of str to ndarray, shape (n_rows,)
    units : dict of str to str, optional
        Unit of each column (``"rad"``, ``"s"``); a field's metadata ``unit``, and the
        schema metadata ``units`` (JSON), for pandas and MATLAB readers alike.
    """
    units = {k: u for k, u in (units or {}).items() if k in table and u}
    arrays = [column_array(v) for v in table.values()]
    fields = [pa.field(k, a.type, metadata={"unit": units[k]} if k in units else None)
              for k, a in zip(table, arrays)]
    schema = pa.schema(fields, metadata={"units": json.dumps(units)} if units else None)
    return pa.Table.from_arrays(arrays, schema=schema)


def column_array(v) -> pa.Array:
    """A column as an Arrow array: numbers from their buffer in this machine's byte
    order (without the conversion that imports pandas, 0.17 s of a short command),
    anything else converted.

    Parameters
    ----------
    v : array_like, shape (n,)

    Returns
    -------
    pyarrow.Array
    """
    v = np.asarray(v)
    if v.ndim == 1 and v.dtype.kind in "fiu":
        v = np.ascontiguousarray(v, dtype=v.dtype.newbyteorder("="))
        return pa.Array.from_buffers(pa.from_numpy_dtype(v.dtype), len(v),
                                     [None, pa.py_buffer(v)])
    return pa.array(v)


_NUMPY_OF = {pa.float64(): np.float64, pa.float32(): np.float32, pa.int64(): np.int64,
             pa.int32(): np.int32, pa.int16(): np.int16, pa.int8(): np.int8,
             pa.uint64(): np.uint64, pa.uint32(): np.uint32, pa.uint16(): np.uint16,
             pa.uint8(): np.uint8}


def rows_table(rows, schema: pa.Schema) -> pa.Table:
    """``pyarrow.Table.from_pylist(rows, schema=schema)`` built from buffers.

    Numbers, booleans and strings (a missing key or None is a null) are laid out here,
    without pyarrow's conversion of Python objects, which imports pandas (0.17 s of a
    short command); any other type is converted by pyarrow.

    Parameters
    ----------
    rows : sequence of mapping
        One mapping per row; keys outside ``schema`` are ignored.
    schema : pyarrow.Schema

    Returns
    -------
    pyarrow.Table
    """
    return pa.Table.from_arrays([_list_array([r.get(f.name) for r in rows], f.type)
                                 for f in schema], schema=schema)


def _list_array(values: list, typ) -> pa.Array:
    """One column of Python values as an Arrow array of type ``typ`` (see
    :func:`rows_table`)."""
    n = len(values)
    valid = np.array([v is not None for v in values], bool)
    mask = None if valid.all() else pa.py_buffer(np.packbits(valid, bitorder="little"))
    nulls = n - int(valid.sum())
    if typ in _NUMPY_OF:
        data = np.array([v if ok else 0 for v, ok in zip(values, valid)], _NUMPY_OF[typ])
        return pa.Array.from_buffers(typ, n, [mask, pa.py_buffer(data)], null_count=nulls)
    if typ == pa.bool_():
        bits = np.packbits(np.array([bool(v) for v in values], bool), bitorder="little")
        return pa.Array.from_buffers(typ, n, [mask, pa.py_buffer(bits)], null_count=nulls)
    if typ == pa.string() and all(isinstance(v, str) or v is None for v in values):
        parts = [v.encode("utf-8") if v is not None else b"" for v in values]
        offsets = np.zeros(n + 1, np.int32)
        np.cumsum([len(b) for b in parts], out=offsets[1:])
        return pa.Array.from_buffers(typ, n, [mask, pa.py_buffer(offsets),
                                              pa.py_buffer(b"".join(parts))], null_count=nulls)
    return pa.array(values, typ)


def write_table(table: dict, path, csv: bool = False, units: dict | None = None) -> Path:
    """Write a column table atomically to Parquet (or CSV) and return the path.

    Parameters
    ----------
    table : dict of str to ndarray, shape (n_rows,)
    path : path-like
        Target file.
    csv : bool
        Write CSV (``%.17g``, lossless) instead of Parquet.
    units : dict of str to str, optional
        Unit of each column: Parquet field and schema metadata, or the CSV header as
        ``name [unit]`` (:func:`read_table` reads both back).
    """
    path = Path(path)
    cols = {k: np.asarray(v) for k, v in table.items()}
    units = units or {}
    if csv:
        def writer(tmp):
            names = list(cols)
            header = [f"{n} [{units[n]}]" if units.get(n) else n for n in names]
            with open(tmp, "w", encoding="utf-8", newline="") as f:
                f.write(",".join(header) + "\n")
                if names:
                    data = np.column_stack([cols[n].astype(float) for n in names])
                    np.savetxt(f, data, delimiter=",", fmt="%.17g")
    else:
        arrow = arrow_table(cols, units)

        def writer(tmp):
            # float columns gain nothing from dictionary encoding, which costs 2.5x
            pq.write_table(arrow, tmp, use_dictionary=False)
    atomic_write(path, writer)
    return path


def write_mat(table: dict, path, units: dict | None = None) -> Path:
    """Write a column table atomically as a MATLAB file (``scipy.io.savemat``, v5).

    ``time`` is a top-level vector and each ``instance.variable`` a field of a struct per
    instance (``structure.los_tip_pitch``); ``units`` mirrors that layout, and
    ``columns`` lists the original names (names that are not MATLAB identifiers are
    written with ``_``).

    Parameters
    ----------
    table : dict of str to ndarray, shape (n_rows,)
    path : path-like
        Target ``.mat`` file.
    units : dict of str to str, optional
        Unit of each column.
    """
    import scipy.io   # only for this format

    units = units or {}
    data, unit_tree = {}, {}
    for name, col in table.items():
        inst, _, var = name.partition(".")
        key = [_mat_name(inst)] + ([_mat_name(var)] if var else [])
        for tree, value in ((data, np.asarray(col, float)), (unit_tree, units.get(name, ""))):
            node = tree
            for part in key[:-1]:
                node = node.setdefault(part, {})
            node[key[-1]] = value
    data["units"] = unit_tree
    data["columns"] = np.array(list(table), dtype=object)

    def writer(tmp):
        with open(tmp, "wb") as f:
            scipy.io.savemat(f, data, do_compression=True, oned_as="column")
    atomic_write(Path(path), writer)
    return Path(path)


def _mat_name(name: str) -> str:
    out = re.sub(r"\W", "_", name)
    return out if out[:1].isalpha() else f"x{out}"


def read_table(path):
    """Read a results file into a pandas DataFrame with its units.

    Parameters
    ----------
    path : path-like
        ``results.parquet`` (or a folder of Parquet parts, e.g. a run's kept rows),
        ``results.csv`` or ``results.mat``.

    Returns
    -------
    pandas.DataFrame
        One column per recorded ``instance.variable`` and ``time`` (s);
        ``df.attrs["units"]`` maps each column to its unit (``"rad"``, ``"s"``), as the
        FMUs declare them.

    Examples
    --------
    >>> df = read_table("out/run/results.parquet")            # doctest: +SKIP
    >>> df.attrs["units"]["structure.los_tip_roll"]            # doctest: +SKIP
    'rad'
    """
    import pandas as pd   # deferred: pandas takes about 0.5 s to load

    df = pd.DataFrame(read_columns(path))
    df.attrs["units"] = read_units(path)
    return df


def read_columns(path) -> dict:
    """Read a results file (Parquet, CSV or MATLAB) into a dict of numpy arrays.

    Parameters
    ----------
    path : path-like
        As :func:`read_table`.

    Returns
    -------
    dict of str to ndarray, shape (n_rows,)
        ``"time"`` (s) and one column per recorded ``instance.variable``.
    """
    path = Path(path)
    if path.suffix == ".mat":
        import scipy.io   # only for this format

        m = scipy.io.loadmat(path, simplify_cells=True)
        out = {}
        for name in m["columns"]:
            inst, _, var = str(name).partition(".")
            node = m[_mat_name(inst)]
            out[str(name)] = np.atleast_1d(node[_mat_name(var)] if var else node).astype(float)
        return out
    if path.suffix == ".csv":
        with open(path, encoding="utf-8") as f:
            names = [_UNIT_SUFFIX.sub("", n) for n in f.readline().strip().split(",")]
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        return {n: data[:, j] for j, n in enumerate(names)}

    t = read_parquet(path)
    return {n: t.column(n).to_numpy() for n in t.column_names}


def read_parquet(path) -> pa.Table:
    """A Parquet file as a table (``pq.ParquetFile``: ``pq.read_table`` loads
    ``pyarrow.dataset``, which imports pandas, 0.17 s of a short command); a folder of
    Parquet parts (an unfinished run's rows) as one table."""
    if Path(path).is_dir():
        return pq.read_table(path)
    with pq.ParquetFile(path) as f:
        return f.read()


def read_units(path) -> dict:
    """Units of a results file's columns, by column.

    Parameters
    ----------
    path : path-like
        A Parquet file or folder (field metadata), a CSV (``name [unit]`` header) or a
        MATLAB file (its ``units`` struct).

    Returns
    -------
    dict of str to str
        The unit of each column that has one.
    """
    path = Path(path)
    if path.suffix == ".csv":
        with open(path, encoding="utf-8") as f:
            header = f.readline().strip().split(",")
        out = {}
        for h in header:
            m = _UNIT_SUFFIX.search(h)
            if m:
                out[_UNIT_SUFFIX.sub("", h)] = m.group(1)
        return out
    if path.suffix == ".mat":
        import scipy.io   # only for this format

        m = scipy.io.loadmat(path, simplify_cells=True)
        tree, out = m.get("units", {}), {}
        for name in m["columns"]:
            inst, _, var = str(name).partition(".")
            node = tree.get(_mat_name(inst), "")
            unit = node.get(_mat_name(var), "") if var and isinstance(node, dict) else node
            if isinstance(unit, str) and unit:
                out[str(name)] = unit
        return out
    schema = pq.read_schema(path) if path.is_file() else pq.read_table(path).schema
    return {f.name: f.metadata[b"unit"].decode() for f in schema
            if f.metadata and b"unit" in f.metadata}


_UNIT_SUFFIX = re.compile(r" \[([^\]]*)\]$")


def write_metadata(meta: dict, path) -> Path:
    """Write ``run.json`` atomically.

    Parameters
    ----------
    meta : dict
        Run metadata; values JSON cannot encode are written as ``str(value)``.
    path : path-like
        The file to write.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    text = json.dumps(meta, indent=2, sort_keys=True, default=str)

    def writer(tmp):
        Path(tmp).write_text(text + "\n", encoding="utf-8")
    atomic_write(path, writer)
    return path


def package_versions() -> dict:
    """Versions of Python and the packages a run depends on."""
    return dict(_package_versions())


@functools.lru_cache(maxsize=1)
def _package_versions() -> tuple:
    out = {"python": sys.version.split()[0]}
    for name in ("jitterfmu", "numpy", "fmpy", "pythonfmu", "pyarrow", "scipy"):
        try:
            out[name] = _md.version(name)
        except _md.PackageNotFoundError:
            out[name] = None
    return tuple(out.items())
