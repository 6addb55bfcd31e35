"""Byte transports behind one interface, chosen by a URL (as pyserial does).

==========================  ============================================
``/dev/ttyUSB0``            serial port (pyserial-asyncio-fast)
``serial:///dev/ttyUSB0``   the same, explicit
``tcp://host:port``         TCP stream (radio modems are often bridges)
``loop://``                 in-memory loopback (what you write is read; tests)
==========================  ============================================

A transport reads chunks of bytes (``b""`` means the far end closed) and
writes bytes.  Drivers own their transport and reopen it on errors.

Which URLs can be opened is decided by a *port backend* (:class:`Ports`)
given to the runtime, as python-can selects an interface: the vessel uses
:class:`SystemPorts` (serial and TCP), the in-process simulator injects its
own backend for ``sim://NAME`` (``drivers.sim.ports``).  The drivers never
know which one they talk to.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections import deque
from collections.abc import Callable
from typing import Protocol
from urllib.parse import urlparse


class TransportError(OSError):
    """The device could not be opened or failed."""


class Transport(Protocol):
    url: str

    async def read(self) -> bytes:
        """Next chunk of bytes; ``b""`` when the far end closed."""
        ...

    async def write(self, data: bytes) -> None: ...

    def write_nowait(self, data: bytes) -> None:
        """Queue ``data`` for writing without waiting (small, rate-limited writes)."""
        ...

    async def close(self) -> None: ...


class MemoryPipe:
    """One-way in-memory byte channel with an asyncio wake-up."""

    def __init__(self) -> None:
        self._chunks: deque[bytes] = deque()
        self._waiter: asyncio.Future[None] | None = None
        self.closed = False
        self.bytes_written = 0
        #: if set, written bytes are handed to it at once instead of queued
        #: (a simulated device that reacts to bytes as they arrive)
        self.listener: Callable[[bytes], None] | None = None

    def write(self, data: bytes) -> None:
        if self.closed or not data:
            return
        self.bytes_written += len(data)
        if self.listener is not None:
            self.listener(data)
            return
        self._chunks.append(data)
        w = self._waiter
        if w is not None and not w.done():
            w.set_result(None)

    def close(self) -> None:
        self.closed = True
        w = self._waiter
        if w is not None and not w.done():
            w.set_result(None)

    async def read(self) -> bytes:
        while not self._chunks:
            if self.closed:
                return b""
            self._waiter = asyncio.get_running_loop().create_future()
            try:
                await self._waiter
            finally:
                self._waiter = None
        if len(self._chunks) == 1:
            return self._chunks.popleft()
        out = b"".join(self._chunks)
        self._chunks.clear()
        return out


class MemoryTransport:
    """One end of an in-memory link: reads ``rx``, writes ``tx``."""

    def __init__(self, url: str, rx: MemoryPipe, tx: MemoryPipe) -> None:
        self.url = url
        self._rx = rx
        self._tx = tx

    async def read(self) -> bytes:
        return await self._rx.read()

    async def write(self, data: bytes) -> None:
        if self._tx.closed:
            raise TransportError(f"{self.url}: closed")
        self._tx.write(data)

    def write_nowait(self, data: bytes) -> None:
        if self._tx.closed:
            raise TransportError(f"{self.url}: closed")
        self._tx.write(data)

    async def close(self) -> None:
        self._rx.close()
        self._tx.close()

    def on_receive(self, fn: Callable[[bytes], None]) -> None:
        """Deliver bytes written by the far end to ``fn`` synchronously."""
        self._rx.listener = fn


def memory_link(name: str) -> tuple[MemoryTransport, MemoryTransport]:
    """(device end, runtime end) of an in-memory serial link ``sim://name``."""
    a, b = MemoryPipe(), MemoryPipe()
    url = f"sim://{name}"
    return MemoryTransport(url, a, b), MemoryTransport(url, b, a)


class StreamTransport:
    """Transport over an asyncio StreamReader/StreamWriter (serial or TCP)."""

    def __init__(self, url: str, reader: asyncio.StreamReader,
                 writer: asyncio.StreamWriter) -> None:
        self.url = url
        self._reader = reader
        self._writer = writer

    async def read(self) -> bytes:
        return await self._reader.read(4096)

    async def write(self, data: bytes) -> None:
        self._writer.write(data)
        await self._writer.drain()

    def write_nowait(self, data: bytes) -> None:
        if self._writer.is_closing():
            raise TransportError(f"{self.url}: closed")
        self._writer.write(data)

    async def close(self) -> None:
        self._writer.close()
        with contextlib.suppress(OSError, RuntimeError):
            await self._writer.wait_closed()


#: URL schemes the vessel's own backend opens (a bare path is a serial port)
SYSTEM_SCHEMES = ("serial", "tcp")


def url_scheme(url: str) -> str:
    """The scheme of a device URL: ``serial`` for a bare path, else what precedes
    ``://`` (``""`` for an empty or malformed URL)."""
    if not url.strip():
        return ""
    if "://" in url:
        return url.split("://", 1)[0].lower()
    return "serial" if url.startswith("/") or url.startswith("COM") else ""


class Ports(Protocol):
    """A port backend: opens device URLs of the schemes it names."""

    schemes: tuple[str, ...]

    async def open(self, url: str, baudrate: int) -> Transport:
        """Open ``url``; raises TransportError with the reason."""
        ...


class SystemPorts:
    """The vessel's port backend: serial ports (pyserial-asyncio-fast) and TCP,
    plus ``loop://`` for tests when ``loopback`` is set.

    A serial port is opened exclusively: ``flock`` (pyserial's ``exclusive``,
    so another well-behaved program cannot open it) and the tty's
    ``TIOCEXCL`` (so no other unprivileged process can open it at all: nobody
    else can write ``$PZTHR`` to the thruster controller).
    """

    def __init__(self, loopback: bool = False) -> None:
        self.schemes: tuple[str, ...] = SYSTEM_SCHEMES + (("loop",) if loopback else ())

    async def open(self, url: str, baudrate: int) -> Transport:
        scheme = url_scheme(url)
        if scheme not in self.schemes:
            raise TransportError(f"{url or '(empty)'}: no such device scheme here "
                                 f"(this backend opens {', '.join(self.schemes)})")
        if scheme == "loop":
            pipe = MemoryPipe()
            return MemoryTransport(url, pipe, pipe)
        if scheme == "tcp":
            u = urlparse(url)
            if not u.hostname or not u.port:
                raise TransportError(f"{url}: expected tcp://HOST:PORT")
            try:
                reader, writer = await asyncio.open_connection(u.hostname, u.port)
            except OSError as exc:
                raise TransportError(f"{url}: {exc}") from exc
            return StreamTransport(url, reader, writer)
        path = url[len("serial://"):] if url.startswith("serial://") else url
        if not path:
            raise TransportError("empty device address")
        import serial_asyncio_fast  # pyserial-asyncio-fast

        try:
            reader, writer = await serial_asyncio_fast.open_serial_connection(
                url=path, baudrate=baudrate, exclusive=True
            )
        except (OSError, ValueError) as exc:  # serial.SerialException is an OSError
            if "lock" in str(exc).lower() or "busy" in str(exc).lower():
                raise TransportError(f"{path}: in use by another process ({exc})") from exc
            raise TransportError(f"{path}: {exc}") from exc
        ser = getattr(writer.transport, "serial", None)
        fd = getattr(ser, "fd", None)
        if isinstance(fd, int):
            import fcntl
            import termios

            with contextlib.suppress(OSError):  # not a tty (a plain file in a test)
                fcntl.ioctl(fd, termios.TIOCEXCL)
        return StreamTransport(url, reader, writer)


async def open_transport(url: str, baudrate: int = 115200,
                         ports: Ports | None = None) -> Transport:
    """Open the device at ``url`` with ``ports`` (default: the system's serial and
    TCP backend, and ``loop://``); raises TransportError with the reason."""
    return await (ports or SystemPorts(loopback=True)).open(url, baudrate)
