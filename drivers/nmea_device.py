"""The I/O loop of an NMEA device: transport bytes → framer → pure parser → bus.

One task per device (DUNE's model).  The loop is thin: framing is
:class:`drivers.nmea.NmeaFramer`, parsing is a pure function
``parse(line, t) -> list[message]`` raising :class:`NmeaError`.  Every
rejected sentence is counted by reason; the device's health (ok / stale /
disconnected / faulty) and counters go on the bus as DeviceHealth.  A port
that fails or cannot be opened is retried with jittered exponential backoff
capped at 1 s; nothing a device does can end the process.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import random
import time
from collections import Counter
from collections.abc import Callable, Sequence

from drivers.buoy_parser import BuoyMessage
from drivers.compass_parser import CompassMessage
from drivers.gps_parser import GpsMessage
from drivers.nmea import NmeaError, NmeaFramer
from drivers.rtcm import Rtcm3Filter
from drivers.settings import Device
from drivers.transports import Ports, SystemPorts, Transport, TransportError
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.messages import DeviceHealth, HealthState, RtcmCorrections

#: what an NMEA input device publishes
DeviceMessage = GpsMessage | CompassMessage | BuoyMessage
#: ``parse(line, t)``: a pure parser of one framed sentence received at runtime
#: time ``t``; its messages, or ``NmeaError``
ParseFn = Callable[[str, float], Sequence[DeviceMessage]]
#: ``raw(direction, t, data)``: a chunk read from (``"rx"``) or written to (``"tx"``)
#: the device at runtime time ``t`` (set by a recorder; None: nobody records)
RawHook = Callable[[str, float, bytes], None]

#: reconnect backoff bounds (s): the jittered wait is 0.5–1 × the backoff, so
#: never more than BACKOFF_MAX_S (half of the 1 s within which a replugged device
#: must be read again, leaving room for the first sentence of a 5 Hz device)
BACKOFF_MIN_S = 0.05
BACKOFF_MAX_S = 0.5
#: health is published at least this often (s)
HEALTH_PERIOD_S = 1.0


class RateLimitedLog:
    """Logs at most one line per ``period_s`` per key, with a count of the rest."""

    def __init__(self, log: logging.Logger, period_s: float = 10.0) -> None:
        self.log = log
        self.period_s = period_s
        self._last: dict[str, float] = {}
        self._suppressed: Counter[str] = Counter()

    def warning(self, key: str, msg: str) -> None:
        now = time.monotonic()
        last = self._last.get(key)
        if last is not None and now - last < self.period_s:
            self._suppressed[key] += 1
            return
        n = self._suppressed.pop(key, 0)
        self._last[key] = now
        self.log.warning("%s%s", msg, f" (+{n} similar suppressed)" if n else "")


class DeviceLink:
    """Shared state of a device driver: counters, health, reconnect."""

    def __init__(self, name: str, cfg: Device, bus: Bus, clock: Clock,
                 ports: Ports | None = None) -> None:
        self.name = name
        self.cfg = cfg
        self.bus = bus
        self.clock = clock
        self.ports: Ports = ports or SystemPorts()
        self.counters: Counter[str] = Counter()
        self.state = HealthState.DISCONNECTED
        self.reason = "not opened yet"
        self.last_ok: float | None = None
        self.log = logging.getLogger(f"zarco.{name}")
        self.rlog = RateLimitedLog(self.log)
        self._rng = random.Random(name)  # deterministic jitter in simulation
        self._reading: Transport | None = None
        self._silent = False
        self.last_rx: float | None = None
        #: the raw-bytes hook (a recorder's), or None
        self.raw: RawHook | None = None

    def set_state(self, state: HealthState, reason: str = "") -> None:
        if state != self.state or reason != self.reason:
            self.state = state
            self.reason = reason
            if state is HealthState.OK:
                self.log.info("%s: ok", self.name)
            elif state is HealthState.STALE and self.last_ok is None:
                self.log.info("%s: %s", self.name, reason)  # opened, no data yet
            else:
                self.rlog.warning(f"state:{state.value}", f"{self.name}: {state.value}: {reason}")
            self.publish_health()

    def publish_health(self) -> None:
        self.bus.publish(DeviceHealth(self.clock.now(), self.name, self.state, self.reason,
                                      dict(self.counters), self.last_ok))

    async def read_or_reopen(self, tr: Transport) -> bytes:
        """Next chunk; a port silent for ``cfg.reopen_s`` is treated as failed.

        The silence is judged by :meth:`watch`, which closes the port (the read
        then returns b"") rather than arming a timer around every read: a
        timeout per read costs a timer-heap insert and cancel per chunk, which
        in simulation is a tenth of the run time.
        """
        self._reading = tr
        chunk = await tr.read()
        if not chunk:
            if self._silent:
                self._silent = False
                raise TransportError(f"no bytes for {self.cfg.reopen_s:g} s")
            raise TransportError("port closed")
        self.last_rx = t = self.clock.now()
        if self.raw is not None:
            self.raw("rx", t, chunk)
        return chunk

    async def _check_silence(self) -> None:
        tr, limit = self._reading, self.cfg.reopen_s
        if tr is None or limit <= 0.0 or self.last_rx is None:
            return
        if self.clock.now() - self.last_rx > limit:
            self._silent = True
            self.last_rx = None
            with contextlib.suppress(Exception):
                await tr.close()

    async def open(self) -> Transport:
        """Open the port, retrying with jittered backoff (never raises but on cancel)."""
        backoff = BACKOFF_MIN_S
        while True:
            try:
                tr = await self.ports.open(self.cfg.url, self.cfg.baudrate)
                self.last_rx = self.clock.now()  # silence is counted from the opening
                self.set_state(HealthState.STALE, "opened, waiting for data")
                return tr
            except TransportError as exc:
                self.counters["open_failures"] += 1
                self.set_state(HealthState.DISCONNECTED, str(exc))
            await asyncio.sleep(backoff * (0.5 + 0.5 * self._rng.random()))
            backoff = min(BACKOFF_MAX_S, backoff * 2.0)

    async def watch(self) -> None:
        """Mark the device stale when valid data stops; publish health periodically."""
        while True:
            await asyncio.sleep(min(HEALTH_PERIOD_S, self.cfg.stale_s,
                                    self.cfg.reopen_s or HEALTH_PERIOD_S))
            await self._check_silence()
            now = self.clock.now()
            if (self.state is HealthState.OK and self.last_ok is not None
                    and now - self.last_ok > self.cfg.stale_s):
                self.set_state(HealthState.STALE, f"no valid sentence for {self.cfg.stale_s} s")
            self.publish_health()


class NmeaDevice(DeviceLink):
    """An NMEA input device (GPS, compass/IMU): read, frame, parse, publish.

    With ``rtcm`` (the GPS receiver) it also writes RTCM3 corrections to its
    port: from its own ``corrections_url`` and from every
    :class:`~zarco_core.messages.RtcmCorrections` on the bus (the shore link,
    MAVLink).  Each source goes through its own :class:`~drivers.rtcm.Rtcm3Filter`:
    only whole frames with a valid CRC-24Q are written, each in one write, so
    nothing else (a UBX command, noise, half a frame) ever reaches the receiver.
    """

    #: RtcmCorrections waiting for the device (chunks; the oldest is dropped beyond)
    RTCM_QUEUE = 256

    def __init__(self, name: str, cfg: Device, bus: Bus, clock: Clock, parse: ParseFn,
                 ports: Ports | None = None, rtcm: bool = False) -> None:
        super().__init__(name, cfg, bus, clock, ports)
        self.parse = parse
        self.rtcm = rtcm
        self._rtcm_filters: dict[str, Rtcm3Filter] = {}

    def handle_line(self, line: str, t: float) -> None:
        """Parse one framed sentence and publish what it says (pure but for the bus)."""
        try:
            msgs = self.parse(line, t)
        except NmeaError as exc:
            self.counters[exc.reason] += 1
            self.rlog.warning(exc.reason, f"{self.name}: dropped {line[:40]!r}: {exc}")
            return
        except Exception as exc:  # a parser bug must not kill the driver
            self.counters["parser_bug"] += 1
            self.log.exception("%s: parser raised on %r: %s", self.name, line[:80], exc)
            return
        self.counters["sentences_ok"] += 1
        self.last_ok = t
        if self.state is not HealthState.OK:
            self.set_state(HealthState.OK)
        publish = self.bus.publish
        for m in msgs:
            publish(m)

    async def run(self) -> None:
        """Read forever; reopen the port when it fails or closes."""
        async with asyncio.TaskGroup() as tg:
            tg.create_task(self.watch(), name=f"{self.name}.health")
            tg.create_task(self._read_loop(), name=f"{self.name}.read")
            if self.cfg.corrections_url:
                tg.create_task(self._corrections_loop(), name=f"{self.name}.rtcm")
            if self.rtcm:
                tg.create_task(self._relay_loop(), name=f"{self.name}.rtcm_relay")

    async def _relay_loop(self) -> None:
        """Write the RTCM3 corrections published on the bus (shore link, MAVLink)."""
        sub = self.bus.subscribe(RtcmCorrections, maxlen=self.RTCM_QUEUE)
        try:
            while True:
                msg: RtcmCorrections = await sub.get()
                self._forward_corrections(msg.data, msg.source)
                for m in sub.drain():  # a chunk lost to overflow shows as a bad frame
                    self._forward_corrections(m.data, m.source)
        finally:
            sub.close()

    async def _corrections_loop(self) -> None:
        """Copy RTCM3 frames from the configured source to this port.

        The source is reopened with the same backoff as a device when it fails
        (a partial frame from before is dropped); only whole, CRC-valid frames
        pass; frames that arrive while the device port is down are counted and
        dropped (stale corrections are worse than none).
        """
        url = self.cfg.corrections_url
        backoff = BACKOFF_MIN_S
        while True:
            try:
                if url.startswith("file://"):
                    await self._corrections_from_file(url[len("file://"):])
                    return
                src = await self.ports.open(url, self.cfg.baudrate)
                backoff = BACKOFF_MIN_S
                try:
                    while True:
                        chunk = await src.read()
                        if not chunk:
                            raise TransportError("corrections source closed")
                        self._forward_corrections(chunk)
                finally:
                    self._rtcm_filter("corrections_url").reset()
                    with contextlib.suppress(Exception):
                        await src.close()
            except (TransportError, OSError) as exc:
                self.counters["corrections_source_errors"] += 1
                self.rlog.warning("rtcm", f"{self.name}: corrections source {url}: {exc}")
            await asyncio.sleep(backoff * (0.5 + 0.5 * self._rng.random()))
            backoff = min(BACKOFF_MAX_S, backoff * 2.0)

    async def _corrections_from_file(self, path: str) -> None:
        rate = self.cfg.corrections_rate_bps
        block = max(1, int(rate / 10))
        with open(path, "rb") as fh:
            while chunk := fh.read(block):
                while self._reading is None:  # a recording can wait for the port
                    await asyncio.sleep(0.05)
                self._forward_corrections(chunk)
                await asyncio.sleep(len(chunk) / rate)

    def _rtcm_filter(self, source: str) -> Rtcm3Filter:
        f = self._rtcm_filters.get(source)
        if f is None:
            f = self._rtcm_filters[source] = Rtcm3Filter(self.counters)
        return f

    def _forward_corrections(self, chunk: bytes, source: str = "corrections_url") -> None:
        """Pass the whole, valid RTCM3 frames of ``chunk`` (from ``source``) to the port."""
        frames = self._rtcm_filter(source).feed(chunk)
        if not frames:
            return
        data = frames[0] if len(frames) == 1 else b"".join(frames)
        tr = self._reading
        if tr is None:
            self.counters["corrections_dropped_bytes"] += len(data)
            return
        try:
            tr.write_nowait(data)
            self.counters["corrections_bytes"] += len(data)
            if self.raw is not None:
                self.raw("tx", self.clock.now(), data)
        except (TransportError, OSError):
            self.counters["corrections_dropped_bytes"] += len(data)

    async def _read_loop(self) -> None:
        now = self.clock.now
        while True:
            tr = await self.open()
            framer = NmeaFramer()
            base = self.counters["bytes_discarded"]  # counters span reconnections
            try:
                while True:
                    chunk = await self.read_or_reopen(tr)
                    self.counters["bytes"] += len(chunk)
                    t = now()
                    for line in framer.feed(chunk):
                        self.handle_line(line, t)
                    self.counters["bytes_discarded"] = base + framer.bytes_discarded
            except (TransportError, OSError) as exc:
                self.counters["reconnects"] += 1
                self.set_state(HealthState.DISCONNECTED, str(exc))
            finally:
                with contextlib.suppress(Exception):  # closing a dead port may fail
                    await tr.close()
