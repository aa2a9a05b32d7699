"""A controller brought as a state-space file: ``.mat``, ``.npz`` or ``.csv``.

MATLAB users hold a controller as an ``ss`` object; ``[A, B, C, D, Ts] = ssdata(sys)``
gives its matrices and sample time, and ``save law.mat A B C D Ts`` writes them.  This
module reads such a file into a :class:`ctrlfmu.law.DiscreteLaw`, so that
``jitterfmu build --controller law.mat`` makes a controller FMU with no Python written.

The state-space is MATLAB's::

    discrete   (Ts > 0):   x(k+1) = A x(k) + B y(k),   u(k) = C x(k) + D y(k)
    continuous (Ts = 0):   dx/dt  = A x + B y,         u    = C x + D y

``y`` being what the controller measures and ``u`` its command.  A discrete law keeps its
matrices and ``Ts`` is the FMU's period.  A continuous law is discretised at the FMU's
period (``--period``, or ``period`` in the file) by a zero-order hold on the measurement
(``method = "zoh"``, the default: exact for a measurement held over each period) or by
the bilinear transform (``"tustin"``).  ``Ts = -1`` (MATLAB's "discrete, sample time
unspecified") is a discrete law at the period given.  The law is the non-delayed form
(``u(k)`` uses ``y(k)``; direct feedthrough where ``D != 0``) unless the file sets
``delayed = 1``: the paper's Eq. (11), the command applied one sample later.

Keys (the same in every format; MATLAB's property names are accepted beside ours):

==================  =========================================================
``A, B, C, D``      matrices, shapes (n, n), (n, n_in), (n_out, n), (n_out, n_in);
                    a static gain gives ``D`` alone
``Ts``              sample time (s): > 0 discrete, 0 continuous, -1 unspecified
``period``          FMU period (s) for a continuous law (``--period`` wins)
``method``          ``zoh`` (default) or ``tustin``, for a continuous law
``delayed``         0 (default) or 1 (Eq. 11: one-sample computation delay)
``inputs``          measurement names (or ``InputName``), one per column of D
``outputs``         command names (or ``OutputName``), one per row of D
``input_units``     units of the measurements (or ``InputUnit``; default ``1``)
``output_units``    units of the commands (or ``OutputUnit``; default ``V``)
``name``            the law's name (or ``Name``; default the file's stem)
``u_min, u_max``    command limits (default none)
==================  =========================================================

A ``.csv`` file holds one key per line, its values after it; a matrix takes one line
per row, in order (``A,0.9,0.2`` then ``A,-0.2,0.85``); lines starting with ``#`` are
comments.  A ``.npz`` file is read without pickles, a ``.mat`` file as data only
(``scipy.io.loadmat``); nothing in a file is run.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ctrlfmu.law import DiscreteLaw, LawFileError, load_law

__all__ = ["METHODS", "SUFFIXES", "read_controller", "read_state_space", "discretise"]

#: Discretisation methods of a continuous law.
METHODS = ("zoh", "tustin")
#: File suffixes a state-space is read from.
SUFFIXES = (".mat", ".npz", ".csv")

_ALIASES = {"InputName": "inputs", "OutputName": "outputs", "InputUnit": "input_units",
            "OutputUnit": "output_units", "Name": "name"}
_TEXT = ("inputs", "outputs", "input_units", "output_units", "name", "method")
_KNOWN = {"A", "B", "C", "D", "Ts", "period", "method", "delayed", "u_min", "u_max",
          *_TEXT}
_RTOL_PERIOD = 1e-9


def read_controller(path, period: float | None = None) -> DiscreteLaw:
    """Read a controller file: a law (``ctrlfmu.law.save_law``) or a state-space.

    Parameters
    ----------
    path : str or Path
        ``.npz`` written by :func:`ctrlfmu.law.save_law`, or a state-space ``.mat``,
        ``.npz`` or ``.csv`` (see the module docstring).
    period : float, optional
        FMU period (s): needed by a continuous state-space (``Ts = 0``) unless the file
        gives ``period``; must equal ``Ts`` for a discrete one.

    Returns
    -------
    DiscreteLaw
        The law the FMU runs.

    Raises
    ------
    LawFileError
        One sentence on what is wrong with the file and what to do.
    FileNotFoundError
        If the file does not exist.
    """
    path = Path(path)
    if path.suffix == ".npz" and path.is_file() and _is_saved_law(path):
        law = load_law(path)
        if period is not None and not _same_period(law.dt, period):
            raise LawFileError(f"{path} is a law at {law.dt:g} s; --period {period:g} s "
                               "differs (drop --period, or resample the law)")
        return law
    return read_state_space(path, period)


def _is_saved_law(path: Path) -> bool:
    try:
        with np.load(path, allow_pickle=False) as f:
            return "format" in getattr(f, "files", ())
    except (ValueError, OSError, EOFError):
        return False


def read_state_space(path, period: float | None = None) -> DiscreteLaw:
    """Read ``A, B, C, D, Ts`` (MATLAB's ``ssdata``) from a file into a law.

    Parameters
    ----------
    path : str or Path
        A ``.mat``, ``.npz`` or ``.csv`` file with the keys of the module docstring.
    period : float, optional
        FMU period (s); see :func:`read_controller`.

    Returns
    -------
    DiscreteLaw
        Discrete as given, or the continuous law discretised at ``period``.

    Raises
    ------
    LawFileError
        One sentence on what is wrong with the file and what to do.
    FileNotFoundError
        If the file does not exist.
    """
    path = Path(path)
    if path.suffix not in SUFFIXES:
        raise LawFileError(f"{path} is not a control law file: expected a .mat, .npz or .csv "
                           "state-space (A, B, C, D, Ts) or a law written by "
                           "ctrlfmu.law.save_law")
    if not path.exists():
        raise FileNotFoundError(f"No such file or directory: {str(path)!r}")
    if not path.is_file():
        raise LawFileError(f"{path} is not a control law file (it is a folder)")
    keys = {".mat": _read_mat, ".npz": _read_npz, ".csv": _read_csv}[path.suffix](path)
    keys = {_ALIASES.get(k, k): v for k, v in keys.items()}
    try:
        return _law(keys, period, path)
    except ValueError as exc:     # DiscreteLaw's own checks (shapes, finite values)
        if isinstance(exc, LawFileError):
            raise
        raise LawFileError(f"{path}: {exc}") from None


def _law(keys: dict, period, path: Path) -> DiscreteLaw:
    if "D" not in keys:
        raise LawFileError(f"{path} is not a control law file: it has no matrix D (a "
                           "state-space needs A, B, C, D and Ts as MATLAB's ssdata gives "
                           "them)")
    d = _matrix(keys, "D", path)
    n_out, n_in = d.shape
    a = _matrix(keys, "A", path, (0, 0))
    n = a.shape[0]
    b = _matrix(keys, "B", path, (n, n_in))
    c = _matrix(keys, "C", path, (n_out, n))
    if n == 0:           # MATLAB writes a static gain's empty B and C as 0x0
        b, c = b.reshape(0, n_in), c.reshape(n_out, 0)
    missing = [m for m in "ABC" if m not in keys and n > 0] + \
              [m for m in "A" if m not in keys and ("B" in keys or "C" in keys)]
    if missing:
        raise LawFileError(f"{path} has no matrix {missing[0]}; a state-space needs A, B, C, "
                           "D and Ts (as MATLAB's ssdata gives them)")
    ts = _scalar(keys, "Ts", path, None)
    if ts is None:
        raise LawFileError(f"{path} has no sample time Ts; give Ts > 0 for a discrete law "
                           "or Ts = 0 for a continuous one")
    file_period = _scalar(keys, "period", path, None)
    period = file_period if period is None else float(period)
    method = str(keys.get("method", "zoh")).strip().lower() or "zoh"
    if method not in METHODS:
        raise LawFileError(f"{path} asks for method {method!r}; expected one of "
                           f"{', '.join(METHODS)}")
    if ts > 0:
        if period is not None and not _same_period(ts, period):
            raise LawFileError(f"{path} is a discrete law at Ts = {ts:g} s but the period "
                               f"given is {period:g} s; drop --period, or convert the law "
                               "(d2d in MATLAB)")
        dt = ts
    elif ts == 0 or ts == -1:
        if period is None:
            what = "a continuous law (Ts = 0)" if ts == 0 else "Ts = -1 (unspecified)"
            raise LawFileError(f"{path} holds {what}; give the FMU's period with --period "
                               "SECONDS (or 'period' in the file)")
        if not (math.isfinite(period) and period > 0):
            raise LawFileError(f"the period must be a positive number of seconds, "
                               f"got {period!r}")
        dt = period
        if ts == 0:
            a, b, c, d = discretise(a, b, c, d, dt, method)
    else:
        raise LawFileError(f"{path} has Ts = {ts:g}; expected > 0 (discrete), 0 "
                           "(continuous) or -1 (discrete, unspecified)")
    kwargs = {k: _names(keys, k, path) for k in ("inputs", "outputs", "input_units",
                                                  "output_units") if k in keys}
    for k in ("u_min", "u_max"):
        if k in keys:
            kwargs[k] = np.asarray(keys[k], dtype=float).ravel()
            if kwargs[k].size == 1:
                kwargs[k] = float(kwargs[k][0])
    name = str(keys.get("name", "")).strip() or path.stem
    delayed = bool(_scalar(keys, "delayed", path, 0.0))
    form = (f"continuous, discretised at {dt:g} s by "
            + ("a zero-order hold" if method == "zoh" else "Tustin's bilinear transform")
            if ts == 0 else f"discrete at Ts = {dt:g} s")
    return DiscreteLaw(a, b, c, d, dt, delayed=delayed, name=name,
                       description=f"state-space from {path.name} ({form})", **kwargs)


def discretise(a, b, c, d, dt: float, method: str = "zoh"):
    """Discretise a continuous state-space at period ``dt``.

    Parameters
    ----------
    a, b, c, d : ndarray
        Continuous matrices, shapes (n, n), (n, n_in), (n_out, n), (n_out, n_in).
    dt : float
        Sample period (s).
    method : {"zoh", "tustin"}
        ``zoh``: the input held over each period, ``Ad = expm(A dt)``,
        ``Bd = int_0^dt expm(A s) ds B`` (one exponential of the block matrix
        ``[[A, B], [0, 0]] dt``), ``C, D`` unchanged.  ``tustin``: the bilinear transform
        ``s = 2/dt (z - 1)/(z + 1)``.

    Returns
    -------
    tuple of ndarray
        ``(Ad, Bd, Cd, Dd)``.
    """
    a, b, c, d = (np.asarray(m, dtype=float) for m in (a, b, c, d))
    n, m = b.shape
    if method == "zoh":
        from scipy.linalg import expm   # deferred: scipy takes about 1 s to load

        block = np.zeros((n + m, n + m))
        block[:n, :n], block[:n, n:] = a, b
        phi = expm(block * dt)
        return phi[:n, :n], phi[:n, n:], c.copy(), d.copy()
    if method == "tustin":
        from scipy.signal import cont2discrete

        ad, bd, cd, dd, _ = cont2discrete((a, b, c, d), dt, method="bilinear")
        return ad, bd, cd, dd
    raise ValueError(f"discretisation method {method!r}; expected one of {', '.join(METHODS)}")


def _same_period(a: float, b: float) -> bool:
    return abs(a - b) <= _RTOL_PERIOD * max(abs(a), abs(b))


# -- readers: each gives {key: value} with arrays of float or lists of str -----------------

def _read_mat(path: Path) -> dict:
    import scipy.io   # deferred: only for this format

    try:     # unsqueezed: a 2x1 D stays 2x1 (two outputs), a 1x2 one stays a row
        raw = scipy.io.loadmat(path, squeeze_me=False, chars_as_strings=True)
    except Exception:    # noqa: BLE001 - any damage reads as "not a .mat file"
        raise LawFileError(f"{path} is not a MATLAB .mat file that can be read (save it "
                           "with 'save law.mat A B C D Ts', format v7 or older)") from None
    out = {}
    for key, value in raw.items():
        if key.startswith("__"):
            continue
        if _ALIASES.get(key, key) in _TEXT:
            value = [_mat_text(v) for v in np.asarray(value, dtype=object).ravel()]
            if key in ("name", "Name", "method"):
                value = "".join(value)
        out[key] = value
    return out


def _mat_text(value) -> str:
    """One string of a MATLAB char array or of a cell of them ('' for an empty cell)."""
    arr = np.asarray(value).ravel()
    return "".join(str(v) for v in arr) if arr.size else ""


def _read_npz(path: Path) -> dict:
    try:
        with np.load(path, allow_pickle=False) as f:
            if not hasattr(f, "files"):
                raise ValueError
            return {k: f[k] for k in f.files}
    except (ValueError, OSError, EOFError):
        raise LawFileError(f"{path} is not a control law file (an .npz archive of A, B, C, "
                           "D, Ts, or one written by ctrlfmu.law.save_law)") from None


def _read_csv(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise LawFileError(f"{path} is not a text file; a .csv state-space has one key per "
                           "line (A,0.9,0.2)") from None
    rows: dict[str, list] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        cells = [c.strip() for c in line.split(",")]
        if not cells[0] or cells[0].startswith("#"):
            continue
        key = _ALIASES.get(cells[0], cells[0])
        if key not in _KNOWN:
            raise LawFileError(f"{path} line {number}: unknown key {cells[0]!r}; expected "
                               f"one of {', '.join(sorted(_KNOWN))}")
        values = [c for c in cells[1:] if c != ""]
        if key in _TEXT:
            rows[key] = values if key not in ("name", "method") else ",".join(values)
            continue
        try:
            rows.setdefault(key, []).append([float(v) for v in values])
        except ValueError:
            raise LawFileError(f"{path} line {number}: {cells[0]} has a value that is not a "
                               "number") from None
    out = {}
    for key, value in rows.items():
        if key in _TEXT:
            out[key] = value
        elif len({len(r) for r in value}) > 1:
            raise LawFileError(f"{path}: the rows of {key} have different lengths "
                               f"({', '.join(str(len(r)) for r in value)})")
        else:
            out[key] = np.array(value, dtype=float)
    return out


def _matrix(keys: dict, name: str, path: Path, empty=None) -> np.ndarray:
    if name not in keys:
        return np.zeros(empty if empty is not None else (0, 0))
    try:
        arr = np.asarray(keys[name], dtype=float)
    except (TypeError, ValueError):
        raise LawFileError(f"{path}: matrix {name} is not numeric") from None
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    elif arr.ndim == 1:     # a MATLAB row or column squeezed by the reader
        arr = _unsqueeze(arr, name, empty)
    if arr.ndim != 2:
        raise LawFileError(f"{path}: matrix {name} has {arr.ndim} dimensions; expected 2")
    if arr.size == 0 and empty is not None:
        return np.zeros(empty)
    return arr


def _unsqueeze(arr: np.ndarray, name: str, expected) -> np.ndarray:
    """A 1-D array read back from MATLAB's column or row vector, as the 2-D it was."""
    if expected and len(expected) == 2 and expected[1] == arr.size and expected[0] == 1:
        return arr.reshape(1, -1)
    if expected and len(expected) == 2 and expected[0] == arr.size:
        return arr.reshape(-1, 1)
    return arr.reshape(1, -1) if name in ("C", "D") else arr.reshape(-1, 1)


def _scalar(keys: dict, name: str, path: Path, default):
    if name not in keys:
        return default
    try:
        arr = np.asarray(keys[name], dtype=float).ravel()
    except (TypeError, ValueError):
        raise LawFileError(f"{path}: {name} is not a number") from None
    if arr.size != 1 or not math.isfinite(arr[0]):
        raise LawFileError(f"{path}: {name} must be one finite number, got {arr.size} values"
                           if arr.size != 1 else f"{path}: {name} is not finite")
    return float(arr[0])


def _names(keys: dict, name: str, path: Path) -> tuple:
    value = keys[name]
    if isinstance(value, str):
        value = [value]
    arr = np.asarray(value, dtype=object).ravel()
    out = tuple(str(v).strip() for v in arr)
    if any(not v for v in out):   # MATLAB's unnamed signals are ''
        if all(not v for v in out):
            return ()
        raise LawFileError(f"{path}: {name} has an empty entry; name every signal or none")
    return out
