"""The campaign folder on disk: case folders, their status and their file records.

``cases/KEY/case.json`` holds a case's definition, status, error and timings and, for a
finished case, the size and SHA-256 of each of its files (:data:`CASE_FILES`), so a
resumed campaign reruns a case whose files were truncated or replaced.
"""

from __future__ import annotations

import json
import os
import re
import shutil
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


def not_a_folder(cases_dir: Path, key: str) -> str | None:
    """One sentence when ``cases_dir/KEY`` exists but is not a folder, else None.

    Parameters
    ----------
    cases_dir, key : Path, str
        The campaign's ``cases`` folder and the case's key.
    """
    path = cases_dir / key
    if path.is_symlink() or not path.exists() or path.is_dir():
        return None
    return (f"{str(path)!r} is a file, not a case folder; move it away and run the "
            "campaign again to run this case")


def case_status(cases_dir: Path, key: str) -> dict | None:
    """The ``case.json`` of a case, None if it is missing or unreadable.

    A plain file where the case folder belongs reads as a failed case saying so.

    Parameters
    ----------
    cases_dir, key : Path, str
        The campaign's ``cases`` folder and the case's key.
    """
    blocked = not_a_folder(cases_dir, key)
    if blocked:
        return {"key": key, "status": "failed", "error": blocked, "seconds": None}
    p = cases_dir / key / STATUS_FILE
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def case_doubt(cases_dir: Path, case) -> str | None:
    """Why the folder of a case is not that case finished; None when it is.

    A finished case is a real folder (not a symbolic link) named by the case's key whose
    ``case.json`` says ``ok``, holds that key and the case's own scenario, and records
    the size and SHA-256 of every file of :data:`CASE_FILES`, each a regular file with
    those bytes.  A copied or linked folder of another case, or a truncated, replaced
    or missing file, makes the case run again.

    Parameters
    ----------
    cases_dir : Path
        The campaign's ``cases`` folder.
    case : Case
        The case, with its final key.

    Returns
    -------
    str or None
        ``""`` when the case has not finished (no folder, or it failed): it simply runs;
        one sentence when a folder claims to be the case but is not trusted; None when
        the case is finished.
    """
    folder = cases_dir / case.key
    if folder.is_symlink():
        return (f"its folder {str(folder)!r} is a symbolic link to "
                f"{os.readlink(folder)!r}, not a folder of this campaign")
    if not folder.is_dir():
        return ""
    st = case_status(cases_dir, case.key)
    if st is None:
        return f"its folder {str(folder)!r} has no readable {STATUS_FILE}"
    if st.get("status") != "ok":
        return ""
    if st.get("key") != case.key:
        return (f"its folder {case.key[:12]}... holds the {STATUS_FILE} of case "
                f"{str(st.get('key'))[:12]}... ({st.get('label')!r}), a copied folder")
    if canonical(st.get("scenario")) != canonical(case.scenario):
        return (f"the {STATUS_FILE} in its folder {case.key[:12]}... holds another "
                "scenario than this case's")
    if not isinstance(st.get("files"), dict):
        return f"the {STATUS_FILE} in its folder {case.key[:12]}... records no file hashes"
    for name in CASE_FILES:
        rec, path = st["files"].get(name), folder / name
        if path.is_symlink() or not path.is_file():
            return f"{name} in its folder {case.key[:12]}... is missing or a link"
        if not isinstance(rec, dict) or path.stat().st_size != rec.get("size") \
                or file_record(path) != rec:
            return (f"{name} in its folder {case.key[:12]}... is not the file its "
                    f"{STATUS_FILE} recorded (size or SHA-256 differ)")
    return None


def canonical(data) -> str:
    """Compact JSON of ``data`` with sorted keys: what a case key hashes."""
    return json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)


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
    folder = cases_dir / case.key
    st = case_status(cases_dir, case.key)
    if not_a_folder(cases_dir, case.key) or (
            st is not None and st.get("key") == case.key and not folder.is_symlink()):
        return     # the case's own record (or a file that is not ours to replace)
    tmp = temporary_folder(cases_dir, case.key)
    write_json(tmp / STATUS_FILE, {
        "key": case.key, "label": case.label, "event": case.event,
        "configuration": case.configuration, "sweep": case.sweep, "scenario": case.scenario,
        "status": "failed", "error": error, "seconds": None,
    })
    publish(tmp, folder)


def publish(tmp: Path, folder: Path) -> None:
    """Rename a case's finished temporary folder to its place ``folder``.

    What was there goes: an earlier attempt's folder, an untrusted copy, or a symbolic
    link (the link only, never what it points to).

    Parameters
    ----------
    tmp : Path
        From :func:`temporary_folder`, complete.
    folder : Path
        ``cases/KEY``.
    """
    if folder.is_symlink():
        folder.unlink()
    elif folder.exists():
        shutil.rmtree(folder, ignore_errors=True)
    os.replace(tmp, folder)


def slug(text: str) -> str:
    """File-name friendly form of a label."""
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_") or "x"
