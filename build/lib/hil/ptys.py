"""A simulated device's serial port: a pseudo-terminal behind a stable link path.

``PtyPort.plug()`` opens a pty pair (standard library ``os.openpty``), sets the
terminal raw (``tty.setraw``: no echo, no line editing, no CR/LF mapping) and
points the link (e.g. ``RUN/dev/gps``, the way udev gives
``/dev/serial/by-id/...``) at the slave side; the runtime opens the link as a
serial port.  The simulator keeps only the master side.  ``unplug()`` removes
the link and closes the master: the runtime's open port fails (hang-up), and
the link path is gone until the next ``plug()`` makes a new pty behind it.

Whether the runtime has the port open is visible from the master: with no
slave open, ``poll`` reports ``POLLHUP``.  Writes are non-blocking; bytes
written while nobody listens are counted and dropped, as a real device's
bytes are lost when no one is reading the cable.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import tty
from collections import Counter
from pathlib import Path


class PtyPort:
    def __init__(self, name: str, link: str | Path) -> None:
        self.name = name
        self.link = Path(link)
        self.master = -1
        self.pts = ""
        self.counters: Counter[str] = Counter()
        self._poll: select.poll | None = None

    @property
    def plugged(self) -> bool:
        return self.master >= 0

    def plug(self) -> None:
        """Create a new pty and point the link at it (atomically)."""
        if self.plugged:
            return
        master, slave = os.openpty()
        tty.setraw(slave)
        self.pts = os.ttyname(slave)
        os.close(slave)
        os.set_blocking(master, False)
        self.master = master
        self._poll = select.poll()
        self._poll.register(master, select.POLLOUT)
        self.link.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.link.with_name(f".{self.link.name}.new")
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        os.symlink(self.pts, tmp)
        os.replace(tmp, self.link)
        self.counters["plugs"] += 1

    def unplug(self) -> None:
        """Remove the link, then close the pty (the device vanishes)."""
        with contextlib.suppress(FileNotFoundError):
            self.link.unlink()
        if self.master >= 0:
            with contextlib.suppress(OSError):
                os.close(self.master)
            self.counters["unplugs"] += 1
        self.master = -1
        self._poll = None

    def attached(self) -> bool:
        """True when some process has the slave side open (the runtime)."""
        if self._poll is None:
            return False
        for _fd, ev in self._poll.poll(0):
            return not ev & select.POLLHUP
        return True

    def write(self, data: bytes) -> int:
        """Write without blocking; returns the bytes written (the rest is dropped)."""
        if not data:
            return 0
        if self.master < 0:
            self.counters["bytes_unplugged"] += len(data)
            return 0
        if not self.attached():
            self.counters["bytes_unheard"] += len(data)
            return 0
        try:
            n = os.write(self.master, data)
        except BlockingIOError:
            n = 0
        except OSError as exc:
            if exc.errno not in (errno.EIO, errno.EAGAIN):
                raise
            n = 0
        self.counters["bytes_written"] += n
        if n < len(data):
            self.counters["bytes_dropped"] += len(data) - n
        return n

    def read(self) -> bytes:
        """Whatever the runtime wrote (b"" if nothing or nobody attached)."""
        if self.master < 0:
            return b""
        try:
            data = os.read(self.master, 65536)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            if exc.errno == errno.EIO:  # no slave open
                return b""
            raise
        self.counters["bytes_read"] += len(data)
        return data

    def close(self) -> None:
        self.unplug()
