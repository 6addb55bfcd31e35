"""Where ``zarco shore rtcm`` reads RTK corrections: a base station on a local
serial port, a TCP server, an NTRIP caster (pygnssutils' client), or a file.

``SOURCE`` forms: ``/dev/ttyUSB0`` or ``serial:///dev/ttyUSB0`` (at
``--baudrate``), ``tcp://HOST:PORT``, ``ntrip://HOST[:PORT]/MOUNTPOINT``
(credentials from ``ZARCO_NTRIP_USER`` / ``ZARCO_NTRIP_PASSWORD`` or the
console configuration's ``[ntrip] credentials_file``, never the command
line), ``file://PATH`` (paced at ``--rate`` bytes per second).  Each yields
chunks of bytes (an empty one after half a second without any, so that the
caller can stop); the relay keeps only whole, CRC-valid RTCM3 frames.
"""

from __future__ import annotations

import queue
import socket
import threading
import time
from collections.abc import Iterator
from urllib.parse import urlsplit


class SourceError(Exception):
    pass


def read_source(spec: str, stop: threading.Event, baudrate: int = 115200,
                rate_bps: float = 2000.0, ntrip_user: str = "",
                ntrip_password: str = "") -> Iterator[bytes]:
    """Chunks from ``spec`` until ``stop`` is set or the source ends."""
    if spec.startswith("tcp://"):
        yield from _tcp(spec, stop)
    elif spec.startswith("ntrip://"):
        yield from _ntrip(spec, stop, ntrip_user, ntrip_password)
    elif spec.startswith("file://"):
        yield from _file(spec[len("file://"):], stop, rate_bps)
    elif spec.startswith("serial://") or spec.startswith("/"):
        yield from _serial(spec.removeprefix("serial://"), stop, baudrate)
    else:
        raise SourceError(f"{spec}: expected a serial path, serial://PATH, tcp://HOST:PORT, "
                          "ntrip://HOST[:PORT]/MOUNTPOINT or file://PATH")


def _tcp(spec: str, stop: threading.Event) -> Iterator[bytes]:
    u = urlsplit(spec)
    if not u.hostname or not u.port:
        raise SourceError(f"{spec}: expected tcp://HOST:PORT")
    try:
        sock = socket.create_connection((u.hostname, u.port), timeout=5.0)
    except OSError as exc:
        raise SourceError(f"{spec}: {exc}") from None
    sock.settimeout(0.5)
    with sock:
        while not stop.is_set():
            try:
                data = sock.recv(4096)
            except TimeoutError:
                yield b""  # nothing for 0.5 s: the caller may stop
                continue
            except OSError as exc:
                raise SourceError(f"{spec}: {exc}") from None
            if not data:
                return
            yield data


def _serial(path: str, stop: threading.Event, baudrate: int) -> Iterator[bytes]:
    import serial

    try:
        port = serial.Serial(path, baudrate, timeout=0.5)
    except (OSError, serial.SerialException) as exc:
        raise SourceError(f"{path}: {exc}") from None
    with port:
        while not stop.is_set():
            try:
                data = port.read(4096)
            except (OSError, serial.SerialException) as exc:
                raise SourceError(f"{path}: {exc}") from None
            yield data  # b"" after 0.5 s without bytes: the caller may stop


def _file(path: str, stop: threading.Event, rate_bps: float) -> Iterator[bytes]:
    block = max(1, int(rate_bps / 5))
    try:
        fh = open(path, "rb")  # noqa: SIM115 (closed below)
    except OSError as exc:
        raise SourceError(f"{path}: {exc.strerror or exc}") from None
    with fh:
        while not stop.is_set() and (data := fh.read(block)):
            yield data
            stop.wait(len(data) / rate_bps)


def _ntrip(spec: str, stop: threading.Event, user: str, password: str) -> Iterator[bytes]:
    from pygnssutils import GNSSNTRIPClient

    u = urlsplit(spec)
    mount = u.path.lstrip("/")
    if not u.hostname or not mount:
        raise SourceError(f"{spec}: expected ntrip://HOST[:PORT]/MOUNTPOINT")
    if u.username or u.password:
        raise SourceError("NTRIP credentials go in ZARCO_NTRIP_USER / ZARCO_NTRIP_PASSWORD "
                          "or the console configuration, not on the command line")
    out: queue.Queue[tuple[bytes, object]] = queue.Queue()
    client = GNSSNTRIPClient(verbosity=0)
    client.run(server=u.hostname, port=u.port or 2101, mountpoint=mount,
               ntripuser=user or "anon", ntrippassword=password or "password",
               ggainterval=-1, output=out)
    try:
        while not stop.is_set():
            try:
                item = out.get(timeout=0.5)
            except queue.Empty:
                if not client.connected:
                    raise SourceError(f"{spec}: the caster closed the stream") from None
                yield b""
                continue
            raw = item[0] if isinstance(item, tuple) else item
            if isinstance(raw, (bytes, bytearray)):
                yield bytes(raw)
    finally:
        client.stop()
        time.sleep(0.1)
