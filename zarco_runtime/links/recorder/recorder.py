"""The recorder: every bus message and every raw device chunk, to MCAP.

A bus tap (:meth:`zarco_core.bus.Bus.tap`) only appends each message object to
a list, and each device driver hands its raw chunks to a hook
(:attr:`drivers.nmea_device.DeviceLink.raw`) that appends ``(channel, time,
bytes)`` to the same list, untouched: nothing is encoded in the publisher's
path.  Bus messages are immutable once published (every publisher builds a
new one), so a message can be encoded later.  Every ``flush_s`` the list is
packed with one MessagePack call (:func:`.schema.packer`: C code, no float
formatting) and goes, as one framed batch over a pipe, to the writer process
(:mod:`.writer`), which turns each record into JSON and writes MCAP with a
JSON schema per message type, flushes chunks, rotates and watches the disk.
The map topics (``foxglove.LocationFix`` of the vessel and the AUV) are made
here, at packing time, from the estimates themselves.

Nothing in the control loop's path waits for a disk: the pipe is
non-blocking, and batches a stalled writer cannot take are dropped, oldest
first, and counted.  On the virtual clock of a simulation the pipe blocks
instead (a simulation waits for its recording, losing nothing), and the
writer runs in a session of its own: where the scheduler shares the CPU
between sessions (Linux's autogroups, a desktop's default), a writer in the
simulation's session would take its time from the simulation rather than use
a free share; on the boat it stays in the runtime's session, below it
(``nice`` 5).

The tap is registered once (a bus tap cannot be removed), so the recorder
object lives as long as the runtime and the supervised component only
(re)starts its writer process: a writer that dies is a component failure, and
the restarted component starts the next part of the same run.  When free
space falls below ``min_free_mb`` or a write fails, the writer finishes the
file and stops; the recorder publishes a :class:`~zarco_core.messages.Fault`
and an ``Event`` and records nothing more in this run.  The process never
stops for lack of disk.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import datetime as dt
import fcntl
import json
import logging
import math
import os
import platform
import select
import subprocess
import sys
import time
from array import array
from collections import Counter, deque
from collections.abc import Callable, Sequence
from itertools import compress
from operator import attrgetter
from pathlib import Path
from typing import TYPE_CHECKING, Any

import orjson

from drivers.nmea_device import DeviceLink
from zarco_core.auv_messages import AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock, VirtualTimeEventLoop
from zarco_core.component import ComponentContext, Factory
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import Event, Fault, NavState
from zarco_runtime.links.recorder import writer
from zarco_runtime.links.recorder.schema import (
    LOCATION_FIX_SCHEMA,
    OPTIONS,
    RAW_CHUNK_SCHEMA,
    json_encoder,
    message_schema,
    plain,
    raw_chunk_type,
)
from zarco_runtime.links.recorder.writer import BATCH, HEADER
from zarco_runtime.supervision.supervisor import Boot, mission_to_json

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.recorder")

#: topics of the derived foxglove.LocationFix positions (map panel)
DERIVED = {NavState: "vessel", AuvTrack: "auv"}
#: in simulation, hand a batch over once it holds this many records
SIM_BATCH = 500
#: in simulation, the recorder's loop wakes this often (virtual time, s)
SIM_WAKE_S = 1.0
#: loop turns a stopping recorder waits for the others' last messages
SHUTDOWN_SPINS = 10
#: how long a stopping runtime waits for the writer to finish its file (s)
FINISH_TIMEOUT_S = 10.0

Devices = Callable[[], Sequence[DeviceLink | None]]
_TIME = attrgetter("t")


def _time_of(m: Any, now: float) -> float:
    """A record's runtime time: its ``t``, or ``now`` if it has none (or not a number)."""
    t = getattr(m, "t", None)
    return float(t) if isinstance(t, (int, float)) and not isinstance(t, bool) else now


class Recorder:
    """Records the bus and the devices' raw bytes for the life of the runtime."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock, boot: Boot | None = None,
                 devices: Devices | None = None, base_dir: str = ".") -> None:
        self.cfg = cfg
        self.rc = cfg.record
        self.bus = bus
        self.clock = clock
        self.boot = boot or Boot()
        self.devices = devices or (lambda: ())
        self.base_dir = base_dir
        self.counters: Counter[str] = Counter()
        #: the records waiting for the writer: bus messages and raw chunks
        self.pending: list[Any] = []
        self.channels: list[dict[str, Any]] = []
        #: channel of each message type (and of each device's raw chunks)
        self.kinds: dict[type, int] = {}
        #: message types without a time ``t`` (recorded at the time they are packed)
        self.untimed: set[type] = set()
        #: message types the map topics are derived from: their channel, next time
        self.derived: dict[type, list[Any]] = {}
        self.frame = LocalFrame(cfg.origin.lat_deg, cfg.origin.lon_deg, cfg.origin.alt_m)
        self.encode = json_encoder().encode
        self.encode_lines = json_encoder().encode_lines
        self.on = [True]
        self.stopped = ""
        self.paths: list[str] = []
        self.parts = 0
        self.base = ""
        self.t0: float | None = None
        self.proc: subprocess.Popen[bytes] | None = None
        self.out: deque[tuple[bytes, int]] = deque()
        self.out_bytes = 0
        self._partial = b""
        self._lines = b""
        self._virtual = False
        self._last_drain = time.monotonic()
        self._hooked: set[int] = set()
        bus.tap(self._make_tap())
        self._attach()  # the devices built so far read nothing unrecorded

    # ------------------------------------------------------------- intake

    def _make_tap(self) -> Callable[[Any], None]:
        # the publisher's cost: one append, a builtin method (no Python frame);
        # the encoding is done later, off its path.  A stopped recorder's list is
        # emptied by its run loop (a tap cannot be removed).
        return self.pending.append

    def _channel(self, topic: str, schema_name: str, schema: bytes, **kw: Any) -> int:
        cid = len(self.channels) + 1
        d = {"op": "channel", "id": cid, "topic": topic, "schema_name": schema_name,
             "schema": schema.decode(), **kw}
        self.channels.append(d)
        if self.proc is not None:
            self._queue(self._json(d), 0)
        return cid

    def _register(self, kind: type) -> int:
        name = kind.__name__
        try:
            schema = message_schema(kind)
            timed = "t" in {f.name for f in dataclasses.fields(kind)}
        except Exception:  # not a dataclass: recorded, schema-less
            schema, timed = b"{}", False
        cid = self._channel(f"/{name}", f"zarco.{name}", schema)
        self.kinds[kind] = cid
        if not timed:
            self.untimed.add(kind)
        if kind in DERIVED:
            fix = self._channel(f"/foxglove/{DERIVED[kind]}", "foxglove.LocationFix",
                                json.dumps(LOCATION_FIX_SCHEMA).encode())
            self.derived[kind] = [fix, -math.inf]
        return cid

    def _hook(self, device: str) -> Callable[[str, float, bytes], None]:
        raw = json.dumps(RAW_CHUNK_SCHEMA).encode()
        rx, tx = raw_chunk_type(device, "rx"), raw_chunk_type(device, "tx")
        self.kinds[rx] = self._channel(f"/raw/{device}/rx", "zarco.RawChunk", raw,
                                       raw=[device, "rx"])
        self.kinds[tx] = self._channel(f"/raw/{device}/tx", "zarco.RawChunk", raw,
                                       raw=[device, "tx"])
        append = self.pending.append
        utc = self.clock.utc
        on = self.on

        def hook(direction: str, t: float, data: bytes) -> None:
            if on[0]:
                append((rx if direction == "rx" else tx)(t, utc(t), data))

        return hook

    def _attach(self) -> None:
        """Give every device driver (some are built late) the raw-bytes hook."""
        if not self.rc.raw:
            return
        for dev in self.devices():
            if dev is not None and dev.raw is None and not self.stopped:
                dev.raw = self._hook(dev.name)

    def _detach(self) -> None:
        for dev in self.devices():
            if dev is not None:
                dev.raw = None

    # ------------------------------------------------------------- writer

    def _json(self, d: dict[str, Any]) -> bytes:
        body = json.dumps(d).encode()
        return HEADER.pack(b"J", len(body)) + body

    def _metadata(self) -> dict[str, str]:
        b = self.boot
        boot = {"mission": mission_to_json(b.mission) if b.mission else None,
                "autostart": b.autostart}
        now = self.clock.now()
        # "version": the writer's (it asks git, off the runtime's time)
        return {"config": orjson.dumps(self.cfg, option=OPTIONS).decode(),
                "boot": json.dumps(boot), "t0": repr(self.t0),
                "utc_offset_s": repr(self.clock.utc(now) - now),
                "started_utc": self.base.removeprefix("zarco-"),
                "host": platform.node(), "argv": json.dumps(sys.argv),
                "clock": "virtual" if self._virtual else "real"}

    def _start_writer(self) -> None:
        rc = self.rc
        if self.t0 is None:
            self.t0 = self.clock.now()
            stamp = dt.datetime.fromtimestamp(self.clock.utc(self.t0), dt.UTC)
            self.base = "zarco-" + stamp.strftime("%Y%m%dT%H%M%SZ")
        # the writer by its file: it imports nothing of the project (a fast start)
        args = [sys.executable, str(Path(writer.__file__).resolve())]
        if not self._virtual:
            args += ["--nice", "5"]  # on the boat: below the runtime, in its session
        self.proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     close_fds=True, start_new_session=self._virtual)
        assert self.proc.stdin is not None and self.proc.stdout is not None
        fd = self.proc.stdin.fileno()
        with contextlib.suppress(OSError, AttributeError):
            fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, 1 << 20)
        os.set_blocking(fd, False)
        os.set_blocking(self.proc.stdout.fileno(), False)
        folder = rc.dir if os.path.isabs(rc.dir) else os.path.join(self.base_dir, rc.dir)
        o = self.cfg.origin
        start = {"op": "start", "dir": folder, "file": rc.file, "base": self.base,
                 "max_file_mb": rc.max_file_mb, "min_free_mb": rc.min_free_mb,
                 "flush_s": rc.flush_s, "fsync_s": rc.fsync_s,
                 "origin": [o.lat_deg, o.lon_deg, o.alt_m], "first_part": self.parts,
                 "metadata": self._metadata()}
        data = [f for f in self.out if f[1] > 0]  # batches a dead writer did not take
        self.out.clear()
        self.out_bytes = 0
        self._partial = b""
        self._queue(self._json(start), 0)
        for d in self.channels:
            self._queue(self._json(d), 0)
        for frame, n in data:
            self._queue(frame, n)

    def _queue(self, frame: bytes, n: int) -> None:
        self.out.append((frame, n))
        self.out_bytes += len(frame)
        cap = self.rc.queue_mb * 1e6
        if self._virtual:  # a simulation waits for its writer instead (_send)
            return
        while self.out_bytes > cap and len(self.out) > 1:
            # drop the oldest batch (never a channel definition: those carry no records)
            for i, (f, k) in enumerate(self.out):
                if k > 0:
                    del self.out[i]
                    self.out_bytes -= len(f)
                    self.counters["dropped"] += k
                    if self.counters["drop_events"] == 0:
                        self._fault("the writer falls behind: oldest messages dropped")
                    self.counters["drop_events"] += 1
                    break
            else:
                break

    def _batch(self) -> None:
        """Encode the pending records (one call: JSON lines) and queue them for the
        writer."""
        pending = self.pending
        n = len(pending)
        if not n:
            return
        items = pending.copy()
        pending.clear()
        if self.stopped:
            return
        now = self.clock.now()
        offset = self.clock.utc(now) - now
        kinds = self.kinds
        types = list(map(type, items))
        present = set(types)
        for kind in present.difference(kinds):
            self._register(kind)
        chans = array("H", map(kinds.__getitem__, types))
        try:
            if self.untimed and not self.untimed.isdisjoint(present):
                raise TypeError("some records have no time")
            times = array("d", map(_TIME, items))
        except (AttributeError, TypeError):
            times = array("d", [_time_of(m, now) for m in items])
        if self.derived and not present.isdisjoint(self.derived):
            derived = self.derived
            for i in compress(range(n), map(derived.__contains__, types)):
                m = items[i]
                if m.t >= derived[types[i]][1]:  # at most location_hz
                    fix = self._fix(m, offset)
                    if fix is not None:
                        items.append(fix[2])
                        chans.append(fix[0])
                        times.append(fix[1])
        try:
            lines = self.encode_lines(items)
        except (TypeError, ValueError, OverflowError):  # a value msgspec refuses
            lines = self._salvage(items)
        body = b"".join((BATCH.pack(len(items), offset), chans.tobytes(), times.tobytes(),
                         lines))
        self._queue(HEADER.pack(b"D", len(body)) + body, len(items))
        self.counters["messages"] += n
        self.counters["derived"] += len(items) - n

    def _salvage(self, items: list[Any]) -> bytes:
        out = []
        for m in items:
            try:
                out.append(self.encode(m))
            except (TypeError, ValueError, OverflowError):
                out.append(self.encode(plain(m)))
                self.counters["salvaged"] += 1
        return b"".join(x + b"\n" for x in out)

    def _fix(self, m: Any, offset: float) -> tuple[int, float, dict[str, Any]] | None:
        """The map fix (``foxglove.LocationFix``) of a vessel estimate or an AUV
        track, at most ``location_hz``."""
        d = self.derived[type(m)]
        t = m.t
        if isinstance(m, NavState):
            lat, lon = m.lat_deg, m.lon_deg
            if not (m.pos_valid and math.isfinite(lat) and math.isfinite(lon)):
                return None
            cov = m.cov
            if len(cov) == 25 and all(math.isfinite(c) for c in (cov[0], cov[1], cov[6])):
                ee, en, nn = cov[6], cov[1], cov[0]  # (x north, y east) → East-North-Up
                pc, kind = [ee, en, 0.0, en, nn, 0.0, 0.0, 0.0, 0.0], 3
            else:
                pc, kind = [0.0] * 9, 0
            what, color = "vessel", {"r": 0.1, "g": 0.4, "b": 1.0, "a": 1.0}
        else:
            x, y = m.kf_x_m, m.kf_y_m
            if m.lost or not (int(m.flags) & 1) or not (math.isfinite(x) and math.isfinite(y)):
                return None
            lat, lon, _alt = self.frame.to_geodetic(x, y)
            s = m.kf_pos_sigma_m
            s2 = s * s if math.isfinite(s) else 0.0
            pc, kind = [s2, 0.0, 0.0, 0.0, s2, 0.0, 0.0, 0.0, 0.0], 2 if s2 else 0
            what, color = "auv", {"r": 1.0, "g": 0.3, "b": 0.1, "a": 1.0}
        d[1] = t + 1.0 / self.rc.location_hz
        utc = t + offset
        sec = int(utc)
        return (d[0], t, {"timestamp": {"sec": sec, "nsec": int((utc - sec) * 1e9)},
                          "frame_id": what, "latitude": lat, "longitude": lon,
                          "altitude": 0.0, "position_covariance": pc,
                          "position_covariance_type": kind, "color": color})

    def _send(self) -> None:
        """Write queued frames to the writer's pipe (as much as it takes now)."""
        proc = self.proc
        if proc is None or proc.stdin is None:
            return
        fd = proc.stdin.fileno()
        while self.out or self._partial:
            if not self._partial:
                frame, _n = self.out.popleft()
                self.out_bytes -= len(frame)
                self._partial = frame
            try:
                k = os.write(fd, self._partial)
            except BlockingIOError:
                if not (self._virtual and self.out_bytes > self.rc.queue_mb * 1e6):
                    return  # the rest goes at the next turn
                select.select([], [fd], [])  # simulation: too far behind, wait
                continue
            except (BrokenPipeError, OSError) as exc:
                raise RuntimeError(f"recorder writer pipe: {exc}") from exc
            self._partial = self._partial[k:]

    def _events(self) -> None:
        proc = self.proc
        if proc is None or proc.stdout is None:
            return
        try:
            data = os.read(proc.stdout.fileno(), 65536)
        except (BlockingIOError, OSError):
            data = b""
        self._lines += data
        self._parse_lines()

    def _parse_lines(self) -> None:
        *lines, self._lines = self._lines.split(b"\n")
        for line in lines:
            with contextlib.suppress(ValueError):
                self._event(json.loads(line))

    def _event(self, ev: dict[str, Any]) -> None:
        kind = ev.get("ev")
        t = self.clock.now()
        if kind == "open":
            self.parts = int(ev.get("part", self.parts + 1))
            self.paths.append(str(ev["path"]))
            log.info("recording to %s", ev["path"])
            self.bus.publish(Event(t, "record", f"recording to {ev['path']}", "recorder"))
        elif kind == "close":
            self.bus.publish(Event(t, "record", f"recording closed: {ev['path']} "
                                   f"({ev.get('messages')} messages)", "recorder"))
        elif kind in ("disk_low", "error"):
            self._stop(str(ev.get("text", kind)))

    def _fault(self, text: str) -> None:
        t = self.clock.now()
        log.error("recorder: %s", text)
        self.bus.publish(Fault(t, "recorder", text))
        self.bus.publish(Event(t, "fault", f"recorder: {text}", "recorder"))

    def _stop(self, why: str) -> None:
        if self.stopped:
            return
        self._fault(why)
        self.stopped = why
        self.on[0] = False
        self.pending.clear()
        self._detach()

    # ---------------------------------------------------------------- run

    async def run(self) -> None:
        if self.stopped:  # out of disk: nothing more this run, but never end the process
            await self._discard()
        self._virtual = isinstance(asyncio.get_running_loop(), VirtualTimeEventLoop)
        self._start_writer()
        self._attach()
        proc = self.proc
        assert proc is not None
        period = self.rc.flush_s
        # a simulation's loop wakes less often (each wake is a turn of its loop) and
        # packs small batches (the messages of a big one outlive the young
        # generation of the garbage collector and make it work)
        wake = max(period, SIM_WAKE_S) if self._virtual else period
        try:
            while True:
                await asyncio.sleep(wake)
                self._attach()
                if self._virtual and len(self.pending) < SIM_BATCH \
                        and time.monotonic() - self._last_drain < period:
                    continue
                self._last_drain = time.monotonic()
                self._batch()
                self._send()
                self._events()
                if self.stopped:
                    await self._discard()
                if proc.poll() is not None:
                    self._events()
                    raise RuntimeError(f"recorder writer exited with code {proc.returncode}")
        finally:
            # the runtime is stopping: let the other components' last words (the
            # thruster driver's zero) happen before the file is finished
            with contextlib.suppress(asyncio.CancelledError):
                for _ in range(SHUTDOWN_SPINS):
                    await asyncio.sleep(0)
            self._finish()

    async def _discard(self) -> None:
        """Recording has stopped: forget what the tap still takes, for ever."""
        while True:
            self.pending.clear()
            await asyncio.sleep(self.rc.flush_s)

    def _finish(self) -> None:
        """Hand over what is pending and let the writer finish its file (blocking:
        the runtime is stopping, or the writer is gone)."""
        proc, self.proc = self.proc, None
        if proc is None:
            return
        self._batch()
        self.proc = proc
        with contextlib.suppress(RuntimeError, OSError):
            if proc.stdin is not None and proc.poll() is None:
                os.set_blocking(proc.stdin.fileno(), True)
                self._send()
        self.proc = None
        with contextlib.suppress(OSError):
            if proc.stdin is not None:
                proc.stdin.close()
        # the writer's last words, up to the end of its output (it has exited then)
        deadline = time.monotonic() + FINISH_TIMEOUT_S
        if proc.stdout is not None:
            fd = proc.stdout.fileno()
            while (left := deadline - time.monotonic()) > 0:
                if not select.select([fd], [], [], left)[0]:
                    continue
                try:
                    data = os.read(fd, 65536)
                except BlockingIOError:
                    continue
                except OSError:
                    break
                if not data:
                    break
                self._lines += data
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()) + 1.0)
        except subprocess.TimeoutExpired:
            log.error("recorder: the writer did not finish in %.0f s", FINISH_TIMEOUT_S)
            proc.kill()
            proc.wait()
        self._parse_lines()
        if proc.stdout is not None:
            proc.stdout.close()


class RecorderFactory:
    """The recorder as a supervised component's factory: one :class:`Recorder`,
    built with the runtime (its tap sees every message from the first; a tap
    cannot be removed), whose writer restarts with the component."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock, boot: Boot | None,
                 devices: Devices, base_dir: str = ".") -> None:
        self.recorder = Recorder(cfg, bus, clock, boot, devices, base_dir)

    def __call__(self, ctx: ComponentContext) -> Recorder:
        return self.recorder


def recorder_factory(cfg: RuntimeConfig, bus: Bus, clock: Clock, boot: Boot | None,
                     devices: Devices, base_dir: str = ".") -> Factory:
    """See :class:`RecorderFactory`."""
    return RecorderFactory(cfg, bus, clock, boot, devices, base_dir)


__all__ = ["Recorder", "RecorderFactory", "recorder_factory"]
