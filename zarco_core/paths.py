"""The files a command reads and writes, checked before it starts.

Every ``zarco`` command checks the paths it was given before it does any
work, so that a long run is never lost to a typo at its end: an input file
that is missing, a directory, unreadable or (for text) not UTF-8, and an
output file whose directory is missing, not a directory or not writable, are
refused with one :class:`PathError` naming what the path is for, the path
and the reason.  The command line prints it as one line and exits 2.

Missing parent directories are **not** created: an output's directory must
exist (a misspelt directory is refused rather than made).  A directory that
an option names itself (``zarco hil --run-dir DIR``) is created if absent,
its parent must exist.

Nothing here writes: the checks use ``os.access`` (the kernel's answer for
this process: permissions, read-only file systems, immutable files), so a
check leaves no trace.  :func:`write_text` writes a result file whole or not
at all (a temporary file beside it, renamed over it).
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from pathlib import Path

__all__ = ["PathError", "oserror_reason", "read_bytes", "read_text", "readable_file",
           "writable_dir", "writable_file", "write_text"]


class PathError(ValueError):
    """A path a command cannot use: ``what`` it is for (an option such as
    ``--report``, or a role such as ``scenario``; may be empty), the ``path``
    as given and the ``reason``, in words."""

    def __init__(self, path: str | os.PathLike[str], reason: str, what: str = "") -> None:
        self.path = os.fspath(path)
        self.reason = reason
        self.what = what
        super().__init__(f"{what}: {self.path}: {reason}" if what else f"{self.path}: {reason}")


#: the words for the errors a path meets (errno → reason)
_REASONS = {
    errno.ENOENT: "no such file or directory",
    errno.EISDIR: "is a directory, not a file",
    errno.ENOTDIR: "a part of the path is not a directory",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.EROFS: "read-only file system",
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "disk quota exceeded",
    errno.ENAMETOOLONG: "file name too long",
    errno.ELOOP: "too many levels of symbolic links",
    errno.EEXIST: "already exists",
}


def oserror_reason(exc: OSError) -> str:
    """The reason of an ``OSError`` in words (no errno number, no path)."""
    if exc.errno in _REASONS:
        return _REASONS[exc.errno]
    return (exc.strerror or str(exc)).lower()


def _access(path: Path, mode: int) -> bool:
    eff = os.access in os.supports_effective_ids
    return os.access(path, mode, effective_ids=eff)


def readable_file(path: str | os.PathLike[str], what: str = "") -> Path:
    """``path`` as a file this process can read: it exists, is not a directory
    and is readable.  Raises :class:`PathError`."""
    p = Path(path)
    if not os.fspath(path):
        raise PathError(path, "empty path", what)
    try:
        p.stat()
    except OSError as exc:
        raise PathError(path, oserror_reason(exc), what) from None
    if p.is_dir():
        raise PathError(path, "is a directory, not a file", what)
    if not _access(p, os.R_OK):
        raise PathError(path, "permission denied (not readable)", what)
    return p


def read_bytes(path: str | os.PathLike[str], what: str = "") -> bytes:
    """The bytes of a file; any problem is a :class:`PathError`."""
    p = readable_file(path, what)
    try:
        return p.read_bytes()
    except OSError as exc:
        raise PathError(path, oserror_reason(exc), what) from None


def read_text(path: str | os.PathLike[str], what: str = "") -> str:
    """A UTF-8 text file (a byte-order mark is skipped); a file that is not
    UTF-8 is refused naming the line and column of its first bad byte."""
    data = read_bytes(path, what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        before = data[:exc.start]
        line = before.count(b"\n") + 1
        col = exc.start - (before.rfind(b"\n") + 1) + 1
        bad = data[exc.start:exc.start + 1].hex().upper()
        raise PathError(path, f"not UTF-8 text: byte 0x{bad} at line {line}, column {col} "
                        "(save the file as UTF-8)", what) from None


def _dir_of(p: Path) -> Path:
    return p.parent if str(p.parent) else Path(".")


def _check_dir(d: Path, path: str | os.PathLike[str], what: str, role: str) -> None:
    """``d`` exists, is a directory and this process may create files in it."""
    if not d.exists():
        if d.is_symlink():
            raise PathError(path, f"{role} {d} is a broken symbolic link", what)
        raise PathError(path, f"{role} {d} does not exist (create it first)", what)
    if not d.is_dir():
        raise PathError(path, f"{role} {d} is not a directory", what)
    if not _access(d, os.W_OK | os.X_OK):
        why = "on a read-only file system" if _read_only_fs(d) else "not writable"
        raise PathError(path, f"{role} {d} is {why}", what)


def _read_only_fs(d: Path) -> bool:
    with contextlib.suppress(OSError):
        return bool(os.statvfs(d).f_flag & os.ST_RDONLY)
    return False


def writable_file(path: str | os.PathLike[str], what: str = "") -> Path:
    """``path`` as a file this process can create or replace: not a directory,
    its directory exists and is writable (an existing file is writable too).
    Nothing is created.  Raises :class:`PathError`."""
    if not os.fspath(path):
        raise PathError(path, "empty path", what)
    p = Path(path)
    if p.is_dir():
        raise PathError(path, "is a directory, not a file", what)
    _check_dir(_dir_of(p), path, what, "the directory")
    if p.exists() and not _access(p, os.W_OK):
        why = "on a read-only file system" if _read_only_fs(_dir_of(p)) else "not writable"
        raise PathError(path, f"the file exists and is {why}", what)
    return p


def writable_dir(path: str | os.PathLike[str], what: str = "", create: bool = False) -> Path:
    """``path`` as a directory this process can write into.  With ``create``, an
    absent one is created (its parent must exist; nothing above it is made).
    Raises :class:`PathError`."""
    if not os.fspath(path):
        raise PathError(path, "empty path", what)
    p = Path(path)
    if p.exists() or p.is_symlink():
        if not p.is_dir():
            raise PathError(path, "is not a directory", what)
        if not _access(p, os.W_OK | os.X_OK):
            why = "on a read-only file system" if _read_only_fs(p) else "not writable"
            raise PathError(path, f"the directory is {why}", what)
        return p
    if not create:
        raise PathError(path, "no such directory", what)
    _check_dir(_dir_of(p), path, what, "the parent directory")
    try:
        p.mkdir()
    except OSError as exc:
        raise PathError(path, f"cannot create it: {oserror_reason(exc)}", what) from None
    return p


def write_text(path: str | os.PathLike[str], text: str, what: str = "") -> Path:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all: into a temporary
    file beside it, then renamed over it (an existing file keeps its content if
    writing fails).  Raises :class:`PathError`."""
    p = writable_file(path, what)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=_dir_of(p))
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        mode = 0o666 & ~_umask()
        with contextlib.suppress(OSError):
            mode = p.stat().st_mode & 0o7777  # keep an existing file's mode
        os.chmod(tmp, mode)
        os.replace(tmp, p)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise PathError(path, f"cannot write it: {oserror_reason(exc)}", what) from None
    return p


def _umask() -> int:
    """This process's umask: from /proc (Linux) without changing it; elsewhere
    by setting and restoring it."""
    with contextlib.suppress(OSError, ValueError, StopIteration):
        with open("/proc/self/status", encoding="ascii") as fh:
            line = next(ln for ln in fh if ln.startswith("Umask:"))
        return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
