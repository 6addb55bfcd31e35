"""One runtime per device: a lock file per device, held for the process's life.

Before opening anything, ``zarco run`` takes an exclusive ``flock`` on a lock
file named after each device it drives (its configured path or URL, as
written: a ``/dev/serial/by-id`` or udev link is not resolved, since the device
behind it changes when it is replugged), in ``lock_dir``.  A second runtime on
the same configuration finds the lock taken and is refused with the holder's
pid; one reaching the same device by another name is stopped by the port's
exclusive open.  The kernel drops the locks when the process dies, however it
dies, so a stale lock never blocks a restart.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
from pathlib import Path

#: where lock files go (the first writable of these)
LOCK_DIRS = ("/run/lock", "/var/lock")


class LockedError(RuntimeError):
    """A device is already driven by another process."""

    def __init__(self, key: str, url: str, pid: str) -> None:
        self.key = key
        self.url = url
        self.pid = pid
        super().__init__(f"{key}: {url} is in use by another zarco runtime"
                         + (f" (pid {pid})" if pid else ""))


def lock_dir() -> Path:
    for d in LOCK_DIRS:
        if os.access(d, os.W_OK):
            return Path(d)
    return Path(tempfile.gettempdir())


def _name(url: str) -> str:
    ident = url[len("serial://"):] if url.startswith("serial://") else url
    if ident.startswith("/"):
        ident = os.path.abspath(ident)
    safe = "".join(c if c.isalnum() or c in "-." else "_" for c in ident.strip("/"))
    return f"zarco-{safe}.lock"


class InstanceLock:
    """Holds the lock files of a set of devices (``{config key: url}``)."""

    def __init__(self, devices: dict[str, str], directory: Path | None = None) -> None:
        self.devices = devices
        self.directory = directory or lock_dir()
        self._fds: list[int] = []

    def acquire(self) -> None:
        """Take every lock or none; raises LockedError naming the first one taken."""
        try:
            for key, url in self.devices.items():
                path = self.directory / _name(url)
                fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    pid = os.pread(fd, 32, 0).decode(errors="replace").strip()
                    os.close(fd)
                    raise LockedError(key, url, pid) from None
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                self._fds.append(fd)
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        for fd in self._fds:
            with contextlib.suppress(OSError):
                os.close(fd)
        self._fds.clear()

    def __enter__(self) -> InstanceLock:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
