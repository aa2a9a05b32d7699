"""The current user's private cache: extracted FMU and SSP archives, compiled loaders.

``extract_cached(archive, sha256, kind=...)`` unpacks an archive once per content hash
into the per-user cache folder (:func:`cache_root`) and returns the folder.  The cache
is created with mode 0700 and must belong to the current user; an entry is used only
after its files are checked against the hashes recorded when it was extracted, and a
new entry is unpacked into a temporary folder (removed on every error) and renamed
into place.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import stat
import tempfile
import time
import zipfile
import zlib
from pathlib import Path

from fmutools.archive import ArchiveError, SizeLimits, unpack

#: Name of the file, inside each cache entry, that lists the hashes of its files.
MANIFEST = ".jitterfmu-manifest.json"

# Entries checked by this process: a folder whose shared library is loaded is reused
# as is (loading it twice would run two copies of the FMU's globals).
_VERIFIED: set[Path] = set()


class CacheError(OSError):
    """The extraction cache cannot be used safely, or an archive cannot be unpacked."""


def cache_root() -> Path:
    """The current user's private extraction cache, created with mode 0700.

    ``$JITTERFMU_CACHE`` if set, else ``$XDG_CACHE_HOME/jitterfmu`` (default
    ``~/.cache/jitterfmu``); when that cannot be created, ``jitterfmu-<uid>`` in the
    system temp folder.  A folder that is not a real directory owned by the current
    user, or that others can read or write, is refused.

    Raises
    ------
    CacheError
        If the folder belongs to another user or is a symbolic link.
    """
    explicit = os.environ.get("JITTERFMU_CACHE")
    if explicit:
        candidates = [Path(explicit)]
    else:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        candidates = [Path(xdg) / "jitterfmu",
                      Path(tempfile.gettempdir()) / f"jitterfmu-{os.getuid()}"]
    for i, root in enumerate(candidates):
        try:
            root.parent.mkdir(parents=True, exist_ok=True)
            root.mkdir(mode=0o700, exist_ok=True)
        except OSError as exc:
            if i + 1 < len(candidates):
                continue
            raise CacheError(f"cannot create the extraction cache {root}: {exc.strerror}; set "
                             "JITTERFMU_CACHE to a folder of your own") from None
        _check_private(root, "extraction cache")
        return root
    raise AssertionError("unreachable")


def _check_private(folder: Path, what: str) -> None:
    """Raise CacheError unless ``folder`` is a real directory of ours; make it 0700."""
    st = os.lstat(folder)
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISDIR(st.st_mode):
        raise CacheError(f"{what} {folder} is not a directory (a symbolic link or a file); "
                         "remove it or set JITTERFMU_CACHE to a folder of your own")
    if st.st_uid != os.getuid():
        raise CacheError(f"{what} {folder} belongs to user id {st.st_uid}, not to you "
                         f"({os.getuid()}); remove it or set JITTERFMU_CACHE to a folder of "
                         "your own")
    if st.st_mode & 0o077:
        os.chmod(folder, 0o700)


def is_own(path, *, directory: bool = False, deny: int = 0o022) -> bool:
    """True if ``path`` is a real directory or regular file of the current user.

    A symbolic link, a file of another user, or one whose mode has any bit of ``deny``
    set (by default: writable by the group or by others) is not.

    Parameters
    ----------
    path : path-like
    directory : bool
        Expect a directory (else a regular file).
    deny : int
        Mode bits that must all be clear, e.g. ``0o077`` for a private folder.

    Returns
    -------
    bool
    """
    try:
        st = os.lstat(path)
    except OSError:
        return False
    kind = stat.S_ISDIR(st.st_mode) if directory else stat.S_ISREG(st.st_mode)
    return kind and st.st_uid == os.getuid() and not st.st_mode & deny


def _file_digests(path: Path) -> tuple[str, int, int]:
    """SHA-256 (hex), size and CRC-32 of one file."""
    h, crc, size = hashlib.sha256(), 0, 0
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
            crc = zlib.crc32(chunk, crc)
            size += len(chunk)
    return h.hexdigest(), size, crc


def _members(data: bytes) -> dict[str, tuple[int, int]] | None:
    """``{name: (size, CRC-32)}`` of the files of zip ``data``, None if not a zip."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            return {i.filename: (i.file_size, i.CRC) for i in zf.infolist() if not i.is_dir()}
    except zipfile.BadZipFile:
        return None


def _entry_is_intact(dest: Path, sha256: str, members: dict[str, tuple[int, int]]) -> bool:
    """True if ``dest`` is our 0700 folder holding exactly the archive's files.

    Each file must match the SHA-256 recorded when the entry was unpacked and the
    size and CRC-32 that the archive itself lists for it.
    """
    try:
        if not is_own(dest, directory=True, deny=0o077):
            return False
        manifest = json.loads((dest / MANIFEST).read_text())
        if manifest.get("archive_sha256") != sha256:
            return False
        files = manifest["files"]
        if set(files) != set(members):
            return False
        seen = set()
        for dirpath, dirnames, filenames in os.walk(dest):
            here = Path(dirpath)
            if any((here / name).is_symlink() for name in dirnames):
                return False
            for name in filenames:
                path = here / name
                rel = path.relative_to(dest).as_posix()
                if rel == MANIFEST:
                    continue
                if path.is_symlink():
                    return False
                if here.name == "__pycache__" and name.endswith(".pyc"):
                    continue  # written by Python when the FMU's bundled code is imported
                digest, size, crc = _file_digests(path)
                if rel not in files or files[rel] != digest or members[rel] != (size, crc):
                    return False
                seen.add(rel)
        return seen == set(files)
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False


def _unpack(data: bytes, archive: Path, into: Path, kind: str,
            limits: SizeLimits | None = None) -> dict:
    """Unpack zip ``data`` into ``into`` within ``limits``; return ``{member: sha256}``."""
    where = f"{kind.upper()} file {str(archive)!r}"
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile:
        raise CacheError(f"{where} is not a zip archive") from None
    with zf:
        if MANIFEST in zf.namelist():
            raise CacheError(f"{where} holds a member named {MANIFEST!r}, which this cache "
                             "reserves; rename it")
        try:
            return unpack(zf, where, lambda name: into.joinpath(*name.split("/")), limits)
        except (ArchiveError, OSError) as exc:
            raise CacheError(str(exc)) from None


def extract_cached(archive, sha256: str | None = None, *, kind: str = "fmu",
                   required: str = "modelDescription.xml",
                   limits: SizeLimits | None = None) -> Path:
    """Unpack ``archive`` once per content hash into the private cache; return the folder.

    Parameters
    ----------
    archive : path-like
        FMU or SSP file (a zip archive).
    sha256 : str, optional
        Expected SHA-256 of the archive (hex); computed from the file when omitted.
        The bytes unpacked are the bytes hashed.
    kind : str
        Prefix of the cache entry and word used in messages (``"fmu"``, ``"ssp"``).
    required : str
        Member the archive must hold (e.g. ``modelDescription.xml``).
    limits : fmutools.archive.SizeLimits, optional
        Largest uncompressed sizes per member and in all (default
        :meth:`~fmutools.archive.SizeLimits.from_env`).

    Returns
    -------
    Path
        Folder ``<cache_root>/<kind>-<sha256>`` holding the archive's files.

    Raises
    ------
    CacheError
        If the cache is not private, the archive changed while it was read, is not a zip
        archive, holds an unsafe path, unpacks to more than ``limits`` or lacks
        ``required``.
    """
    archive = Path(archive)
    root = cache_root()
    if sha256 is not None:
        dest = root / f"{kind}-{sha256}"
        if dest in _VERIFIED and dest.is_dir():
            return dest
    data = archive.read_bytes()
    actual = hashlib.sha256(data).hexdigest()
    if sha256 is not None and actual != sha256:
        raise CacheError(f"{kind.upper()} file {str(archive)!r} changed while it was read "
                         f"(SHA-256 {actual[:16]}..., expected {sha256[:16]}...); run again")
    dest = root / f"{kind}-{actual}"
    if dest in _VERIFIED and dest.is_dir():
        return dest
    if os.path.lexists(dest):
        members = _members(data)
        if members is not None and _entry_is_intact(dest, actual, members):
            _VERIFIED.add(dest)
            _touch(dest / MANIFEST)
            return dest
        _discard(dest, root)
    _prune(root)
    tmp = Path(tempfile.mkdtemp(prefix=f".{kind}-partial-", dir=root))
    try:
        files = _unpack(data, archive, tmp, kind, limits)
        if required not in files:
            raise CacheError(f"{kind.upper()} file {str(archive)!r} has no {required}")
        (tmp / MANIFEST).write_text(json.dumps({"archive_sha256": actual, "files": files},
                                               indent=1))
        try:
            os.rename(tmp, dest)
        except OSError:  # another process put the same entry in place first
            if not _entry_is_intact(dest, actual, _members(data) or {}):
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    _VERIFIED.add(dest)
    return dest


#: Entries unused for this long (s) are removed when a new one is unpacked.
MAX_AGE = 30 * 86400
#: Leftovers of an interrupted unpack older than this (s) are removed.
_PARTIAL_AGE = 86400


def _touch(path: Path) -> None:
    try:
        os.utime(path)
    except OSError:
        pass


def _prune(root: Path) -> None:
    """Remove entries not used for MAX_AGE and old leftovers of killed extractions."""
    now = time.time()
    for entry in root.iterdir():
        try:
            if entry.name.startswith((".fmu-partial-", ".ssp-partial-", ".loader-partial-",
                                      ".fastloop-partial-", ".discarded-")):
                if now - entry.lstat().st_mtime > _PARTIAL_AGE:
                    shutil.rmtree(entry, ignore_errors=True)
            elif (entry.name.startswith(("fmu-", "ssp-")) and entry not in _VERIFIED
                  and now - (entry / MANIFEST).stat().st_mtime > MAX_AGE):
                _discard(entry, root)
        except OSError:
            continue


def _discard(dest: Path, root: Path) -> None:
    """Move a damaged entry aside and remove it (an open library keeps its inode)."""
    trash = Path(tempfile.mkdtemp(prefix=".discarded-", dir=root))
    try:
        os.rename(dest, trash / "entry")
    except OSError:
        pass
    shutil.rmtree(trash, ignore_errors=True)
