"""One MAVLink connection, served by its own thread.

pymavlink's transports (``mavutil.mavlink_connection``: UDP, TCP client and
server, serial) block on open, on a serial write and on a TCP connect, so none
of that happens on the event loop: each connection has a thread that opens it
(again and again, with backoff, until it works), reads and parses what arrives,
and writes what the loop queued.  The loop never waits for it:

* received messages reach the loop with ``loop.call_soon_threadsafe``, a batch
  per read;
* the loop queues messages to send on two bounded queues, replies (acks,
  parameters, mission items, status texts) before telemetry; when a link
  cannot keep up, the oldest telemetry is dropped (and counted), so a slow or
  stalled GCS costs the runtime nothing but the drops.

A message is sent as the boat (``system_id``, ``component_id``) unless it is
queued with another source: the endpoint also speaks for the tracked AUV, a
second system, and each source has its own sequence numbers.

Each connection has its own ``common.MAVLink`` object (sequence numbers,
signing state), used by its thread only.  With a signing key every message
sent is signed; received messages are all parsed, and ``msg._signed`` says
whether their signature was good (unsigned and badly signed ones are the
endpoint's to refuse).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import hashlib
import logging
import os
import select
import threading
import time
from collections.abc import Callable
from typing import Any

from zarco_runtime.links.mavlink.protocol import mav

log = logging.getLogger("zarco.mavlink")

#: the epoch of MAVLink 2 signing timestamps (2015-01-01 UTC), in Unix seconds
SIGNING_EPOCH_S = 1420070400
#: queue bounds: replies, telemetry
MAX_REPLIES = 4096
MAX_TELEMETRY = 256
REOPEN_MIN_S = 0.5
REOPEN_MAX_S = 5.0

#: who a message is sent as: (system id, component id)
Source = tuple[int, int]


class SignedMAVLink(mav.MAVLink):  # type: ignore[misc]
    """pymavlink's MAVLink with the signature checked before its timestamp is
    believed: pymavlink records a stream's newest timestamp before comparing
    the signature, so one forged packet with a far-future timestamp would make
    every later packet of the real sender look replayed (and be refused)."""

    def check_signature(self, msgbuf: bytearray, srcSystem: int,
                        srcComponent: int) -> bool:
        key = self.signing.secret_key
        if key is None or len(msgbuf) < 13:
            return False
        h = hashlib.sha256()
        h.update(key)
        h.update(msgbuf[:-6])
        if h.digest()[:6] != bytes(msgbuf[-6:]):
            return False
        return bool(super().check_signature(msgbuf, srcSystem, srcComponent))


def signing_timestamp(now_s: float | None = None) -> int:
    """A MAVLink 2 signing timestamp: 10 µs units since 2015-01-01 UTC."""
    t = time.time() if now_s is None else now_s
    return int(max(0.0, t - SIGNING_EPOCH_S) * 1e5)


class Link:
    """A connection to one ``url`` (a pymavlink connection string)."""

    def __init__(self, url: str, index: int, system_id: int, component_id: int,
                 key: bytes | None, loop: asyncio.AbstractEventLoop,
                 on_messages: Callable[[Link, list[Any]], None]) -> None:
        self.url = url
        self.index = index
        self.system_id = system_id
        self.component_id = component_id
        self.key = key
        self.loop = loop
        self.on_messages = on_messages
        self._replies: collections.deque[tuple[Any, Source | None]] = collections.deque()
        self._telemetry: collections.deque[tuple[Any, Source | None]] = collections.deque(
            maxlen=MAX_TELEMETRY)
        #: the next sequence number of each source other than the boat (thread side)
        self._seqs: dict[Source, int] = {}
        self._stop = threading.Event()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._woken = False
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name=f"mavlink:{url}", daemon=True)
        self.connected = False
        self.mav: Any = None
        # counters (written by the thread, read by the loop)
        self.sent = 0
        self.received = 0
        self.bytes_in = 0
        self.bytes_out = 0
        self.bad_data = 0
        self.dropped_telemetry = 0
        self.dropped_replies = 0
        self.opens = 0
        self.open_failures = 0
        self.last_error = ""
        # per-link state kept by the endpoint
        self.streams: dict[str, Any] = {}

    # ----------------------------------------------------------- loop side

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        """Ask the thread to close the connection and end (does not wait).  The
        thread closes the wake-up pipe as it ends, so nothing is queued after this."""
        if self._stopping:
            return
        self._stopping = True
        with contextlib.suppress(BlockingIOError, OSError):
            os.write(self._wake_w, b"x")
        self._stop.set()
        if not self._thread.is_alive() and self._thread.ident is None:  # never started
            self._close_pipe()

    def join(self, timeout_s: float) -> bool:
        self._thread.join(timeout_s)
        return not self._thread.is_alive()

    def send(self, msg: Any, reply: bool = True, source: Source | None = None) -> None:
        """Queue ``msg`` (a pymavlink message object, not shared with another link),
        sent as ``source`` (system, component; None: the boat)."""
        if self._stopping:
            return
        if reply:
            if len(self._replies) >= MAX_REPLIES:
                self.dropped_replies += 1
                return
            self._replies.append((msg, source))
        else:
            if len(self._telemetry) == self._telemetry.maxlen:
                self.dropped_telemetry += 1
            self._telemetry.append((msg, source))
        self._wake()

    def _wake(self) -> None:
        if not self._woken:
            self._woken = True
            with contextlib.suppress(BlockingIOError, OSError):
                os.write(self._wake_w, b"x")

    # --------------------------------------------------------- thread side

    def _open(self) -> Any:
        from pymavlink import mavutil

        conn = mavutil.mavlink_connection(self.url, source_system=self.system_id,
                                          source_component=self.component_id,
                                          autoreconnect=False, retries=0)
        m = SignedMAVLink(conn, srcSystem=self.system_id, srcComponent=self.component_id)
        m.robust_parsing = True
        if self.key is not None:
            m.signing.secret_key = self.key
            m.signing.sign_outgoing = True
            m.signing.link_id = self.index & 0xFF
            m.signing.timestamp = signing_timestamp()
            # parse everything; the endpoint refuses what is not signed with the key
            m.signing.allow_unsigned_callback = lambda _mav, _msgid: True
        conn.mav = m
        conn.first_byte = False  # never switch protocol versions under us
        return conn

    def _run(self) -> None:
        backoff = REOPEN_MIN_S
        try:
            while not self._stop.is_set():
                try:
                    conn = self._open()
                except Exception as exc:
                    self.open_failures += 1
                    self._error(f"cannot open {self.url}: {exc}")
                    self._stop.wait(backoff)
                    backoff = min(REOPEN_MAX_S, backoff * 2.0)
                    continue
                self.opens += 1
                self.mav = conn.mav
                self.connected = True
                backoff = REOPEN_MIN_S
                try:
                    self._serve(conn)
                except Exception as exc:
                    self._error(f"{self.url}: {type(exc).__name__}: {exc}")
                finally:
                    self.connected = False
                    with contextlib.suppress(Exception):
                        conn.close()
                if not self._stop.is_set():
                    self._stop.wait(backoff)
        finally:
            self._close_pipe()

    def _close_pipe(self) -> None:
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)

    def _error(self, text: str) -> None:
        if text != self.last_error:
            log.warning("mavlink: %s", text)
        self.last_error = text

    def _serve(self, conn: Any) -> None:
        m = conn.mav
        tcp_server = hasattr(conn, "listen") and hasattr(conn, "listen_addr")
        tcp_client = hasattr(conn, "destination_addr") and conn.__class__.__name__ == "mavtcp"
        while not self._stop.is_set():
            fds = [self._wake_r]
            if conn.fd is not None:
                fds.append(conn.fd)
            timeout = 0.05 if conn.fd is None else 0.5
            try:
                ready, _, _ = select.select(fds, [], [], timeout)
            except (OSError, ValueError):
                raise ConnectionError("select failed") from None
            if self._wake_r in ready:
                self._woken = False
                with contextlib.suppress(BlockingIOError, OSError):
                    os.read(self._wake_r, 4096)
            if conn.fd is None or conn.fd in ready:
                had_client = tcp_server and conn.port is not None
                data = conn.recv(4096)
                if not data:
                    if tcp_server and had_client and conn.fd in ready:  # the client left
                        with contextlib.suppress(OSError):
                            conn.port.close()
                        conn.port = None
                        conn.fd = conn.listen.fileno()
                    elif tcp_client and conn.fd in ready:
                        raise ConnectionError("connection closed by the peer")
                else:
                    self.bytes_in += len(data)
                    msgs = m.parse_buffer(bytearray(data)) or []
                    good = []
                    for msg in msgs:
                        if msg.get_type() == "BAD_DATA":
                            self.bad_data += 1
                        else:
                            good.append(msg)
                    if good:
                        self.received += len(good)
                        self.loop.call_soon_threadsafe(self.on_messages, self, good)
            self._flush(conn, m)

    def _flush(self, conn: Any, m: Any) -> None:
        if self.key is not None:  # signing time follows the clock (a GCS joining later
            # accepts a new stream only within a minute of its own time)
            m.signing.timestamp = max(m.signing.timestamp, signing_timestamp())
        for q in (self._replies, self._telemetry):
            while q:
                try:
                    msg, source = q.popleft()
                except IndexError:
                    break
                try:
                    buf = self._pack(m, msg, source)
                except Exception as exc:
                    self._error(f"cannot pack {msg.get_type()}: {exc}")
                    continue
                try:
                    conn.write(buf)
                except OSError as exc:
                    self._error(f"{self.url}: write: {exc}")
                self.sent += 1
                self.bytes_out += len(buf)

    def _pack(self, m: Any, msg: Any, source: Source | None) -> bytes:
        """``msg`` packed as ``source`` (None: the boat), with that source's
        sequence number."""
        if source is None:
            buf = bytes(msg.pack(m))
            m.seq = (m.seq + 1) % 256
            return buf
        own = (m.srcSystem, m.srcComponent, m.seq)
        m.srcSystem, m.srcComponent = source
        m.seq = self._seqs.get(source, 0)
        try:
            buf = bytes(msg.pack(m))
            self._seqs[source] = (m.seq + 1) % 256
        finally:
            m.srcSystem, m.srcComponent, m.seq = own
        return buf
