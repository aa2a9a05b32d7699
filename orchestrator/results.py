"""Run results: the recorded table, its metadata, atomic files and a progress bar.

A run folder holds ``results.parquet`` (or ``results.csv``) with a ``time`` column and
one column per recorded ``instance.variable``, and ``run.json`` with the scenario hash,
FMU checksums, package versions, wall time, status and error.
"""

from __future__ import annotations

import functools
import json
import sys
from dataclasses import dataclass, field
from importlib import metadata as _md
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .files import atomic_write

__all__ = ["RunResult", "write_table", "read_table", "write_metadata", "package_versions"]


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


def write_table(table: dict, path, csv: bool = False) -> Path:
    """Write a column table atomically to Parquet (or CSV) and return the path.

    Parameters
    ----------
    table : dict of str to ndarray, shape (n_rows,)
    path : path-like
        Target file.
    csv : bool
        Write CSV (``%.17g``, lossless) instead of Parquet.
    """
    path = Path(path)
    cols = {k: np.asarray(v) for k, v in table.items()}
    if csv:
        def writer(tmp):
            names = list(cols)
            with open(tmp, "w", encoding="utf-8", newline="") as f:
                f.write(",".join(names) + "\n")
                if names:
                    data = np.column_stack([cols[n].astype(float) for n in names])
                    np.savetxt(f, data, delimiter=",", fmt="%.17g")
    else:
        arrow = pa.table(cols)

        def writer(tmp):
            # float columns gain nothing from dictionary encoding, which costs 2.5x
            pq.write_table(arrow, tmp, use_dictionary=False)
    atomic_write(path, writer)
    return path


def read_table(path) -> dict:
    """Read a results file (Parquet or CSV) back into a dict of numpy arrays."""
    path = Path(path)
    if path.suffix == ".csv":
        with open(path, encoding="utf-8") as f:
            names = f.readline().strip().split(",")
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        return {n: data[:, j] for j, n in enumerate(names)}

    t = pq.read_table(path)
    return {n: t.column(n).to_numpy() for n in t.column_names}


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
