"""pyNastran, imported for numpy 2 and kept quiet.

pyNastran 1.4.1 binds ``numpy.in1d`` at import, which numpy 2.4 removed; the equivalent
``numpy.isin`` is lent for the import only.  Its readers log to the console; here they
log into a :class:`QuietLog` whose lines an error message can quote instead.
"""

from __future__ import annotations

import io
import os
import re
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np

from structfmu.nastran.spec import NastranError

__all__ = ["pynastran", "QuietLog", "reason", "includes_inside", "quiet_output"]


def pynastran():
    """pyNastran's BDF, OP2 and OP4 classes.

    Returns
    -------
    (type, type, type)
        ``pyNastran.bdf.bdf.BDF``, ``pyNastran.op2.op2.OP2``, ``pyNastran.op4.op4.OP4``.
    """
    lent = not hasattr(np, "in1d")
    if lent:
        np.in1d = np.isin
    try:
        # deferred: optional dependency (the nastran extra)
        from pyNastran.bdf.bdf import BDF
        from pyNastran.op2.op2 import OP2
        from pyNastran.op4.op4 import OP4
    except ImportError as exc:  # pragma: no cover - dependency missing
        raise ImportError(f"reading NASTRAN files needs pyNastran ({exc}); run "
                          "'make setup'") from None
    finally:
        if lent:
            del np.in1d
    return BDF, OP2, OP4


@contextmanager
def quiet_output():
    """While pyNastran reads, what it prints (its dumps of a file it cannot read, its
    "doubles(d) = ..." lines) goes nowhere: the import says what is wrong in one sentence.
    """
    with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):
        yield


@contextmanager
def includes_inside(path, folders=()):
    """While pyNastran reads ``path``, it opens an INCLUDE only inside allowed folders.

    The allowed folders are ``path``'s own and ``folders``; a name is judged as pyNastran
    opens it (joined to its include folder, links followed), so ``'../x'``, an absolute
    path and a link out are refused alike.  The refusal names the INCLUDE, never a line
    of the file it names.  Yields the list of the files read from an allowed folder
    other than ``path``'s (filled as they are opened).

    Parameters
    ----------
    path : path-like
        The file being read (a BDF or a DMIG punch file).
    folders : sequence of path-like
        Further folders the user allows INCLUDEs from (CLI ``--include-dir``).
    """
    pynastran()
    # deferred: optional dependency (the nastran extra)
    from pyNastran.bdf.bdf_interface import pybdf

    allowed = [Path(path).resolve().parent, *(Path(f).resolve() for f in folders)]
    original = pybdf.BDFInputPy._open_file_checks
    opened_outside = []

    def checked(self, bdf_filename, basename=False):
        name = os.path.basename(bdf_filename) if basename else bdf_filename
        target = Path(os.path.join(self.include_dir, name)).resolve()
        if not target.is_relative_to(allowed[0]):
            opened_outside.append(target)
        if not any(target.is_relative_to(a) for a in allowed):
            shown = str(bdf_filename)[:200]
            raise NastranError(f"{str(path)!r} has INCLUDE {shown!r}, a file outside the "
                               f"folder {str(allowed[0])!r}; copy it into that folder, or "
                               "allow its folder (include_dirs, CLI --include-dir)")
        return original(self, bdf_filename, basename)

    pybdf.BDFInputPy._open_file_checks = checked
    try:
        yield opened_outside
    finally:
        pybdf.BDFInputPy._open_file_checks = original


class QuietLog:
    """A pyNastran log that prints nothing and keeps its lines.

    ``log`` is the object to hand to pyNastran (``BDF(log=q.log)``); ``lines`` holds
    ``(level, message)`` in order.
    """

    def __init__(self):
        # deferred: optional dependency (the nastran extra)
        from cpylog import SimpleLogger

        self.lines: list = []
        self.log = SimpleLogger(level="debug", log_func=self._keep)

    def _keep(self, typ, filename, lineno, msg):
        self.lines.append((str(typ).lower(), str(msg).strip()))

    def worst(self) -> str:
        """The first error line, else the first warning line, else ``""``."""
        for level in ("error", "warning"):
            for typ, msg in self.lines:
                if typ == level and msg:
                    return msg.splitlines()[0]
        return ""


_KEY = re.compile(r"KeyError: ['\"](.+?)(?:\.\s+Allowed.*)?['\"]\s*$")


def reason(exc: BaseException, log: QuietLog | None = None) -> str:
    """pyNastran's own reason for ``exc``, as one short clause.

    A cross-reference error lists every missing id after a general first line
    ("There are cross-reference errors"); the first such id is the reason, with the
    number of others.  Otherwise the first non-empty line of the message, else the
    worst line pyNastran logged.

    Parameters
    ----------
    exc : BaseException
        What pyNastran raised.
    log : QuietLog, optional
        The log the reader wrote to.
    """
    # a KeyError's str() is the repr of its message: newlines as "\n" inside quotes
    text = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    dup = re.fullmatch(r"(\w+)=(\S+)", lines[0]) if lines else None
    if dup and len(lines) > 1 and lines[1].startswith("old_"):   # a repeated id
        card = next((ln.split()[0].split(",")[0].rstrip("*") for ln in lines[2:]
                     if not ln.startswith("$") and not ln.endswith("=")), "card")
        return (f"two {card} cards have the id {dup.group(2)} ({dup.group(1)}); give each "
                "its own id")
    keys = [m.group(1) for m in (_KEY.match(ln) for ln in lines) if m]
    if keys:
        more = f" (and {len(keys) - 1} more missing ids)" if len(keys) > 1 else ""
        return keys[0].rstrip(".") + more
    if lines:
        return lines[0].rstrip(".")
    extra = log.worst() if log is not None else ""
    return extra.rstrip(".") or type(exc).__name__
