"""The campaign folder on disk: case folders, their status and their file records.

``cases/KEY/case.json`` holds a case's definition, status, error and timings and, for a
finished case, the size and SHA-256 of each of its files (:data:`CASE_FILES`), so a
resumed campaign reruns a case whose files were truncated or replaced.
"""

from __future__ import annotations

import json
import os
import re
import uuid
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from ..files import atomic_write, sha256_file, write_json_atomic

STATUS_FILE = "case.json"
RESULTS_FILE = "results.parquet"
METRICS_FILE = "metrics.parquet"
#: Files of a finished case, recorded in its ``case.json``.
CASE_FILES = (RESULTS_FILE, METRICS_FILE)
#: Columns of a case's ``metrics.parquet`` (value in rad, window in s).
METRIC_SCHEMA = pa.schema([
    ("instrument", pa.string()), ("axis", pa.string()), ("metric", pa.string()),
    ("window", pa.float64()), ("value", pa.float64()),
])


def temporary_folder(cases_dir: Path, key: str) -> Path:
    """A new folder ``cases_dir/.tmp-KEY-RANDOM`` in which a case is written.

    Parameters
    ----------
    cases_dir, key : Path, str
        The campaign's ``cases`` folder and the case's key.

    Returns
    -------
    Path
        The folder, created.
    """
    tmp = cases_dir / f".tmp-{key}-{uuid.uuid4().hex[:8]}"
    tmp.mkdir(parents=True)
    return tmp


def write_json(path: Path, data) -> None:
    """Write ``data`` as indented, sorted JSON, atomically.

    Parameters
    ----------
    path : Path
        Target file.
    data : object
        JSON data; other objects are written as their ``str``.
    """
    write_json_atomic(path, data, indent=1, sort_keys=True, default=str)


def write_table(table: pa.Table, path: Path, csv: bool = False) -> None:
    """Write a table to Parquet (or CSV), atomically.

    Parameters
    ----------
    table : pyarrow.Table
    path : Path
        Target file.
    csv : bool
        Write CSV instead of Parquet.
    """
    atomic_write(path, (lambda tmp: pacsv.write_csv(table, tmp)) if csv
                 else (lambda tmp: pq.write_table(table, tmp)))


def file_record(path: Path) -> dict:
    """Size (bytes) and SHA-256 of a file, as ``case.json`` records them."""
    return {"size": path.stat().st_size, "sha256": sha256_file(path)}


def case_status(cases_dir: Path, key: str) -> dict | None:
    """The ``case.json`` of a case, None if it is missing or unreadable.

    Parameters
    ----------
    cases_dir, key : Path, str
        The campaign's ``cases`` folder and the case's key.
    """
    p = cases_dir / key / STATUS_FILE
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def case_verified(cases_dir: Path, key: str) -> bool:
    """A finished case whose files are the ones its ``case.json`` recorded.

    Status ``ok`` and, for every file of :data:`CASE_FILES`, the recorded size and
    SHA-256; a truncated, replaced or missing file (or a ``case.json`` without the
    record) makes the case run again.

    Parameters
    ----------
    cases_dir, key : Path, str
        The campaign's ``cases`` folder and the case's key.
    """
    st = case_status(cases_dir, key)
    if st is None or st.get("status") != "ok" or not isinstance(st.get("files"), dict):
        return False
    folder = cases_dir / key
    for name in CASE_FILES:
        rec, path = st["files"].get(name), folder / name
        if not isinstance(rec, dict) or not path.is_file():
            return False
        if path.stat().st_size != rec.get("size") or file_record(path) != rec:
            return False
    return True


def record_lost(cases_dir: Path, case, error: str) -> None:
    """Publish a failed ``case.json`` for a case whose worker died before writing one.

    Parameters
    ----------
    cases_dir : Path
        The campaign's ``cases`` folder.
    case : Case
    error : str
        One sentence: why the case was lost.
    """
    if case_status(cases_dir, case.key) is not None:
        return
    tmp = temporary_folder(cases_dir, case.key)
    write_json(tmp / STATUS_FILE, {
        "key": case.key, "label": case.label, "event": case.event,
        "configuration": case.configuration, "sweep": case.sweep, "scenario": case.scenario,
        "status": "failed", "error": error, "seconds": None,
    })
    os.replace(tmp, cases_dir / case.key)


def slug(text: str) -> str:
    """File-name friendly form of a label."""
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_") or "x"
