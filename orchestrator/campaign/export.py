"""A campaign's results in the format engineers load: CSV or MATLAB beside the Parquet.

The campaign folder keeps its Parquet files (what resuming, the report and the linear
engine read).  :func:`export_results` writes the same tables again:

``csv``
    every case's time histories as ``cases/KEY/results.csv`` (``name [unit]`` headers,
    17 digits); the summary, budget and case tables are CSV already; a Monte Carlo's
    per-sample table as ``uncertainty_samples.csv``.
``mat``
    ``campaign.mat`` (MATLAB v5, ``scipy.io.savemat``): structs ``summary``, ``budget``,
    ``cases`` and, after a Monte Carlo, ``samples``, one field per column (text columns
    as cell arrays), with ``units`` giving the unit of each numeric column; and every
    case's time histories as ``cases/KEY/results.mat`` (``orchestrator.results.write_mat``:
    ``time`` and a struct per instance, with their units).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from ..files import atomic_write
from ..results import read_columns, read_units, write_mat, write_table
from .mcresults import SAMPLES_FILE
from .spec import RSS_EVENT
from .store import RESULTS_FILE

__all__ = ["FORMATS", "export_results"]

#: Formats of :func:`export_results` (``parquet``: nothing more to write).
FORMATS = ("parquet", "csv", "mat")
#: Units of the summary's numeric columns other than the jitter values.
_FIXED_UNITS = {"window": "s", "margin_ratio": "1", "share": "1", "seconds": "s"}


def export_results(out_dir, fmt: str) -> list[Path]:
    """Write a campaign folder's results in ``fmt`` beside its Parquet files.

    Parameters
    ----------
    out_dir : path-like
        A campaign folder (``summary.parquet``, ``cases/KEY/results.parquet``; after a
        Monte Carlo ``uncertainty_samples.parquet``).
    fmt : {"parquet", "csv", "mat"}
        The format wanted.

    Returns
    -------
    list of Path
        The files written (none for ``parquet``).
    """
    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r} is unknown; expected one of {', '.join(FORMATS)}")
    out = Path(out_dir)
    if fmt == "parquet":
        return []
    written = []
    for results in sorted((out / "cases").glob(f"*/{RESULTS_FILE}")):
        target = results.with_suffix(f".{fmt}")
        table, units = read_columns(results), read_units(results)
        if fmt == "csv":
            written.append(write_table(table, target, csv=True, units=units))
        else:
            written.append(write_mat(table, target, units=units))
    samples = out / SAMPLES_FILE
    if fmt == "csv" and samples.is_file():
        import pyarrow.csv as pacsv

        table = pq.read_table(samples)
        target = samples.with_suffix(".csv")
        atomic_write(target, lambda tmp: pacsv.write_csv(table, tmp))
        written.append(target)
    if fmt == "mat":
        written.append(_campaign_mat(out))
    return written


def _campaign_mat(out: Path) -> Path:
    """``campaign.mat``: the summary, budget, case and sample tables as structs."""
    import scipy.io   # only for this format

    data, units = {}, {}
    summary = out / "summary.parquet"
    if summary.is_file():
        rows = pq.read_table(summary)
        is_rss = np.array([e == RSS_EVENT for e in rows.column("event").to_pylist()])
        data["summary"] = _struct(rows, ~is_rss)
        data["budget"] = _struct(rows, is_rss)
        units["summary"] = units["budget"] = _units(rows)
    if (out / "cases.parquet").is_file():
        cases = pq.read_table(out / "cases.parquet")
        data["cases"] = _struct(cases, np.ones(cases.num_rows, bool))
        units["cases"] = {"seconds": "s"}
    if (out / SAMPLES_FILE).is_file():
        samples = pq.read_table(out / SAMPLES_FILE)
        data["samples"] = _struct(samples, np.ones(samples.num_rows, bool))
        units["samples"] = _units(samples)
    data["units"] = units
    target = out / "campaign.mat"

    def writer(tmp):
        with open(tmp, "wb") as f:
            scipy.io.savemat(f, data, do_compression=True, oned_as="column")
    atomic_write(target, writer)
    return target


def _struct(table, rows: np.ndarray) -> dict:
    """Columns of ``table`` (the ``rows`` kept) as MATLAB struct fields."""
    out = {}
    for name in table.column_names:
        values = table.column(name).to_pylist()
        kept = [v for v, keep in zip(values, rows) if keep]
        field = "pass_" if name == "pass" else name     # pass is a MATLAB keyword
        if all(isinstance(v, (int, float, bool)) or v is None for v in kept):
            out[field] = np.array([np.nan if v is None else float(v) for v in kept])
        else:
            out[field] = np.array(["" if v is None else str(v) for v in kept], dtype=object)
    return out


def _units(table) -> dict:
    """Units of the numeric columns of a summary or sample table (values in its unit)."""
    unit = table.column("unit")[0].as_py() if table.num_rows and "unit" in \
        table.column_names else ""
    out = {}
    for name in table.column_names:
        if name in _FIXED_UNITS:
            out[name] = _FIXED_UNITS[name]
        elif name in ("value", "requirement", "margin", "record_value"):
            out[name] = unit
    return out
