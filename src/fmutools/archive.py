"""What may come out of an FMU or SSP archive: the one home for its path and size rules.

Every reader of an archive (the extraction cache, ``validate``, the FMU info the
master reads, the SSP reader, the linear analysis) applies these rules, so a hostile
archive is refused the same way by ``run``, ``validate`` and ``analyze``:

- a member name or a reference inside the archive (an SSP ``Component source``, a
  ``ParameterBinding source``) is a relative path with forward slashes that stays
  inside the archive: no ``..`` that leaves it, no absolute path, drive, backslash or
  URI scheme (:func:`member_problem`, :func:`inside`);
- an FMU's ``modelIdentifier``, which names its shared library, is a C identifier
  (FMI 2.0, section 2.2.1), so it can never name a file elsewhere
  (:func:`model_identifier_problem`);
- the uncompressed size of each member and of the whole archive is limited
  (:class:`SizeLimits`), checked from the zip directory before anything is unpacked
  and again on the bytes actually unpacked (:func:`unpack`, :func:`read_member`), so a
  lying header gains nothing.
"""

from __future__ import annotations

import hashlib
import io
import os
import re
import reprlib
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

__all__ = [
    "ArchiveError",
    "SizeLimits",
    "check_directory",
    "copy_member",
    "inside",
    "member_problem",
    "model_identifier_problem",
    "read_member",
    "short_repr",
    "unpack",
]

_C_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
_MIB = 1 << 20
#: Environment variables that raise the size limits (MiB).
MEMBER_ENV, TOTAL_ENV = "JITTERFMU_UNZIP_MEMBER_MIB", "JITTERFMU_UNZIP_TOTAL_MIB"


class ArchiveError(ValueError):
    """An archive holds a path that leaves it, or more data than the limits allow."""


@dataclass(frozen=True)
class SizeLimits:
    """Largest uncompressed sizes an archive may unpack to.

    Attributes
    ----------
    member : int
        Bytes of one member (default 1 GiB, or ``$JITTERFMU_UNZIP_MEMBER_MIB`` MiB).
    total : int
        Bytes of all members together (default 2 GiB, or ``$JITTERFMU_UNZIP_TOTAL_MIB``
        MiB).
    """

    member: int = 1024 * _MIB
    total: int = 2048 * _MIB

    @classmethod
    def from_env(cls) -> SizeLimits:
        """The defaults, raised or lowered by the two environment variables."""
        out = {}
        for field, env in (("member", MEMBER_ENV), ("total", TOTAL_ENV)):
            raw = os.environ.get(env)
            if raw:
                try:
                    mib = float(raw)
                except ValueError:
                    raise ArchiveError(f"{env} is {raw[:40]!r}; expected a size in MiB") from None
                if not mib > 0:
                    raise ArchiveError(f"{env} is {raw[:40]!r}; expected a size in MiB > 0")
                out[field] = int(mib * _MIB)
        return cls(**out)


def _mib(n: int) -> str:
    return f"{n / _MIB:.1f} MiB" if n < 1024 * _MIB else f"{n / (1024 * _MIB):.1f} GiB"


def member_problem(name: str, *, reference: bool = False) -> str | None:
    """Why ``name`` may not be a path inside an archive, or None if it may.

    A valid name is relative, uses forward slashes, and has no ``..``, ``.`` or empty
    part (a trailing ``/`` marks a folder), drive (``C:``), backslash, NUL or URI
    scheme.  ``a/../b`` is refused too: no archive of ours needs it, and a reader that
    resolves paths differently could be led outside.

    Parameters
    ----------
    name : str
        A member name, or a path the archive's own files give to another member.
    reference : bool
        ``name`` is such a path (``./resources/a.fmu``): ``.`` and empty parts, which
        stay in place, are allowed.

    Returns
    -------
    str or None
        What is wrong (``"an absolute path"``...), or None.
    """
    if not name:
        return "an empty name"
    if "\x00" in name:
        return "a NUL character"
    if "\\" in name:
        return "a backslash"
    if name.startswith("/"):
        return "an absolute path"
    if _SCHEME.match(name):
        return "a drive or URI scheme"
    parts = name.split("/")
    if parts[-1] == "":   # "a/b/" names a folder
        parts = parts[:-1]
    if ".." in parts:
        return "a '..' part"
    if not reference and ("" in parts or "." in parts):
        return "an empty or '.' part"
    return None


def inside(folder, ref: str, what: str) -> Path:
    """The file that ``ref`` (a path written in the archive) names inside ``folder``.

    Parameters
    ----------
    folder : path-like
        The unpacked archive (or the folder that stands for it).
    ref : str
        The path as the archive writes it (``resources/a.fmu``).
    what : str
        How the message names the reference, e.g. ``"x.ssp: Component 'a' source"``.

    Returns
    -------
    Path
        ``folder / ref``, which resolves (symbolic links followed) inside ``folder``.

    Raises
    ------
    ArchiveError
        If ``ref`` is refused by :func:`member_problem` or resolves outside ``folder``.
    """
    problem = member_problem(ref, reference=True)
    folder = Path(folder)
    target = folder.joinpath(*PurePosixPath(ref).parts) if problem is None else None
    if target is not None and not target.resolve().is_relative_to(folder.resolve()):
        problem = "a symbolic link out of the archive"
    if problem is not None:
        raise ArchiveError(f"{what} {short_repr(ref)} is unsafe ({problem}); expected a path "
                           "inside the archive, relative with forward slashes")
    return target


def model_identifier_problem(ident) -> str | None:
    """Why ``ident`` may not be an FMU's ``modelIdentifier``, or None if it may.

    FMI 2.0 makes it a C identifier (letters, digits, ``_``): it names the shared
    library ``binaries/<platform>/<modelIdentifier>.so`` and prefixes its functions.
    """
    if not isinstance(ident, str) or not _C_IDENTIFIER.fullmatch(ident):
        return (f"modelIdentifier {short_repr(ident)} is not a C identifier (letters, digits "
                "and _), as FMI 2.0 requires; it names the FMU's shared library, and this "
                "one would be loaded from outside the FMU")
    return None


_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 80
#: Characters of a file path echoed in a message (a real path fits; a 100 KB one is cut).
PATH_CHARS = 300
_REPR.maxlevel, _REPR.maxlist, _REPR.maxdict, _REPR.maxtuple = 3, 6, 6, 6


def short_repr(value, limit: int = 80) -> str:
    """``repr(value)`` cut to about ``limit`` characters, for echoing outside data.

    A long string keeps its two ends and says how long it was; a deep or long list or
    table keeps its first levels and items.  Never raises (a nesting too deep for
    ``repr`` is cut, not a RecursionError).

    Parameters
    ----------
    value : object
        A name, path or value read from a file or the command line.
    limit : int
        Characters of a string kept (about; 80 by default, more for a file path).

    Returns
    -------
    str
    """
    rep = _REPR
    if limit != rep.maxstring:
        rep = reprlib.Repr()
        rep.maxstring = rep.maxother = limit
        rep.maxlevel, rep.maxlist, rep.maxdict, rep.maxtuple = 3, 6, 6, 6
    text = rep.repr(value)
    if isinstance(value, (str, bytes)) and len(value) > rep.maxstring:
        text += f" ({len(value)} characters)"
    return text


def check_directory(zf: zipfile.ZipFile, where: str, limits: SizeLimits | None = None) -> None:
    """Refuse an archive whose directory lists an unsafe name or too many bytes.

    Parameters
    ----------
    zf : zipfile.ZipFile
        The open archive.
    where : str
        How messages name it (``"FMU 'a.fmu'"``).
    limits : SizeLimits, optional
        Default :meth:`SizeLimits.from_env`.

    Raises
    ------
    ArchiveError
        Naming the first bad member: its path problem, or its size and the limit.
    """
    limits = SizeLimits.from_env() if limits is None else limits
    total = 0
    for info in zf.infolist():
        problem = member_problem(info.filename)
        if problem is not None:
            raise ArchiveError(f"{where} holds the unsafe path {short_repr(info.filename)} "
                               f"({problem}); expected relative paths with forward slashes "
                               "inside the archive")
        _check_size(where, info.filename, info.file_size, limits.member, "member")
        total += info.file_size
        _check_size(where, info.filename, total, limits.total, "total")


def _check_size(where: str, name: str, size: int, limit: int, kind: str) -> None:
    if size <= limit:
        return
    env = MEMBER_ENV if kind == "member" else TOTAL_ENV
    if kind == "member":
        head = (f"{where} member {short_repr(name)} unpacks to {_mib(size)}, above the limit "
                f"of {_mib(limit)} per member")
    else:
        head = (f"{where} unpacks to more than the limit of {_mib(limit)} per archive "
                f"(reached at member {short_repr(name)})")
    raise ArchiveError(f"{head}; if you trust the archive, raise the limit with "
                       f"{env}=<MiB>")


def copy_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, sink, where: str,
                limits: SizeLimits, budget: list | None = None) -> int:
    """Stream one member into ``sink(chunk)``, counting the bytes unpacked.

    The count, not the header, is held to the limits: a member that unpacks to more
    than ``limits.member`` (or the archive's remaining ``budget[0]`` bytes) stops there.

    Parameters
    ----------
    zf : zipfile.ZipFile
    info : zipfile.ZipInfo
    sink : callable
        Called with each chunk of bytes unpacked (e.g. a file's ``write``).
    where : str
        How messages name the archive.
    limits : SizeLimits
    budget : list of one int, optional
        Bytes the archive may still unpack; decreased by this member's size.

    Returns
    -------
    int
        Bytes unpacked.
    """
    n = 0
    with zf.open(info) as src:
        for chunk in iter(lambda: src.read(1 << 20), b""):
            n += len(chunk)
            _check_size(where, info.filename, n, limits.member, "member")
            if budget is not None:
                _check_size(where, info.filename, n, budget[0], "total")
            sink(chunk)
    if budget is not None:
        budget[0] -= n
    return n


#: What reading a damaged member raises: a bad header or CRC, a broken deflate stream, a
#: cut file, a local name that is not the UTF-8 it claims, a flag for a feature zipfile
#: has not (strong encryption, patched data).
CORRUPT = (zipfile.BadZipFile, zlib.error, RuntimeError, EOFError, UnicodeDecodeError,
           NotImplementedError)

def read_member(zf: zipfile.ZipFile, name: str, where: str,
                limits: SizeLimits | None = None) -> bytes:
    """The bytes of member ``name``, read within the member limit.

    Parameters
    ----------
    zf : zipfile.ZipFile
    name : str
        Member name.
    where : str
        How messages name the archive.
    limits : SizeLimits, optional
        Default :meth:`SizeLimits.from_env`.

    Returns
    -------
    bytes
    """
    limits = SizeLimits.from_env() if limits is None else limits
    info = zf.getinfo(name)
    _check_size(where, name, info.file_size, limits.member, "member")
    buf = io.BytesIO()
    copy_member(zf, info, buf.write, where, limits)
    return buf.getvalue()


def unpack(zf: zipfile.ZipFile, where: str, target_of,
           limits: SizeLimits | None = None) -> dict[str, str]:
    """Unpack the members of an archive within the limits; return their SHA-256.

    The directory is checked first (:func:`check_directory`), then each member is
    streamed to its file and counted (:func:`copy_member`).

    Parameters
    ----------
    zf : zipfile.ZipFile
        The open archive.
    where : str
        How messages name it.
    target_of : callable
        ``target_of(member_name)`` gives the file to write, or None to skip the member.
    limits : SizeLimits, optional
        Default :meth:`SizeLimits.from_env`.

    Returns
    -------
    dict of str to str
        ``{member: hex SHA-256}`` of the members written.

    Raises
    ------
    ArchiveError
        A path or size the rules refuse, or a member that cannot be read (corrupt).
    """
    limits = SizeLimits.from_env() if limits is None else limits
    check_directory(zf, where, limits)
    budget, digests = [limits.total], {}
    for info in zf.infolist():
        target = None if info.is_dir() else target_of(info.filename)
        if target is None:
            continue
        h = hashlib.sha256()
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with open(target, "wb") as out:
                def sink(chunk, out=out, h=h):
                    h.update(chunk)
                    out.write(chunk)
                copy_member(zf, info, sink, where, limits, budget)
        except (IsADirectoryError, NotADirectoryError, FileExistsError):
            raise ArchiveError(f"{where} holds {short_repr(info.filename)} both as a file and "
                               "as a folder; expected each path once") from None
        except CORRUPT as exc:
            raise ArchiveError(f"{where} is corrupt: member {info.filename!r} cannot be read "
                               f"({exc or exc.__class__.__name__})") from None
        digests[info.filename] = h.hexdigest()
    return digests
