"""The recorder: every bus message and every raw device chunk, to MCAP.

A bus tap (:meth:`zarco_core.bus.Bus.tap`) only appends each message object to
a list, and each device driver hands its raw chunks to a hook
(:attr:`drivers.nmea_device.DeviceLink.raw`) that appends them, untouched, to
the same list (a :class:`~.schema.RawChunk` of the device's class): nothing
is encoded in the publisher's path.  Bus messages are immutable once
published (every publisher builds a new one), so a message can be encoded
later.  Every ``flush_s`` the list is packed with one MessagePack call
(:func:`.schema.packer`: C code, no float formatting) and goes, as one framed
batch over a pipe, to the writer process (:mod:`.writer`), which turns each
record into JSON, derives the map topics (``foxglove.LocationFix`` of the
vessel and the AUV) and the shore view's (``/shore/state``, ``/shore/auv``,
``/foxglove/events``: what ``zarco shore foxglove`` shows live, so one Foxglove
layout serves both) and writes MCAP with a JSON schema per message type,
flushes chunks, rotates and watches the disk.

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
import datetime as dt
import fcntl
import json
import logging
import os
import platform
import select
import subprocess
import sys
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import orjson

from drivers.nmea_device import DeviceLink
from zarco_core.auv_messages import AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock, VirtualTimeEventLoop
from zarco_core.component import ComponentContext, Factory
from zarco_core.messages import (
    Event,
    Fault,
    GuidanceStatus,
    NavState,
    ThrusterCommand,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.links.recorder import writer
from zarco_runtime.links.recorder.schema import (
    OPTIONS,
    RAW_CHUNK_SCHEMA,
    message_schema,
    packer,
    plain,
    raw_chunk_type,
    shared_schema,
)
from zarco_runtime.links.recorder.writer import BATCH, HEADER
from zarco_runtime.supervision.supervisor import Boot, mission_to_json

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.recorder")

#: topics of the derived foxglove.LocationFix positions (map panel)
DERIVED = {NavState: "vessel", AuvTrack: "auv"}
#: the shore view's topics derived from a type's records (shore_topics.py)
SHORE = {NavState: ("state", "/shore/state"), AuvTrack: ("auv", "/shore/auv"),
         Event: ("events", "/foxglove/events")}
#: the types whose latest record the shore state needs
WATCHED = {Directive: "directive", GuidanceStatus: "guidance", ThrusterCommand: "thrust",
           VesselStatus: "status"}
#: in simulation, the recorder hands a batch over this often (virtual time, s)
SIM_PERIOD_S = 2.0
#: loop turns a stopping recorder waits for the others' last messages
SHUTDOWN_SPINS = 10
#: how long a stopping runtime waits for the writer to finish its file (s)
FINISH_TIMEOUT_S = 10.0

Devices = Callable[[], Sequence[DeviceLink | None]]


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
        self.pack = packer().encode
        self.pack_into = packer().encode_into
        self._per_record = 250.0  # bytes a record takes, packed (about)
        self.on = [True]
        self.stopped = ""
        self.paths: list[str] = []
        self.parts = 0
        self.base = ""
        self.t0: float | None = None
        self.proc: subprocess.Popen[bytes] | None = None
        self.out: deque[tuple[bytes | bytearray, int]] = deque()
        self.out_bytes = 0
        self._partial: memoryview | bytes = b""
        self._lines = b""
        self._virtual = False
        self._hooks: dict[str, Callable[[str, float, bytes], None]] = {}
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
        extra: dict[str, Any] = {}
        if kind in DERIVED:
            topic = f"/foxglove/{DERIVED[kind]}"
            fix = self._channel(topic, *shared_schema(topic))
            extra = {"derive": [DERIVED[kind], fix]}
        if kind in SHORE:
            role, topic = SHORE[kind]
            extra["shore"] = [role, self._channel(topic, *shared_schema(topic))]
        if kind in WATCHED:
            extra["watch"] = WATCHED[kind]
        try:
            schema = message_schema(kind)
        except Exception:  # not a dataclass: recorded, schema-less
            schema = b"{}"
        cid = self._channel(f"/{name}", f"zarco.{name}", schema, **extra)
        self.kinds[kind] = cid
        return cid

    def _hook(self, device: str) -> Callable[[str, float, bytes], None]:
        """The raw-bytes hook of ``device`` (one pair of channels however often the
        device's driver is rebuilt)."""
        hook = self._hooks.get(device)
        if hook is None:
            hook = self._hooks[device] = self._make_hook(device)
        return hook

    def _make_hook(self, device: str) -> Callable[[str, float, bytes], None]:
        raw = json.dumps(RAW_CHUNK_SCHEMA).encode()
        rx, tx = raw_chunk_type(device, "rx"), raw_chunk_type(device, "tx")
        self.kinds[rx] = self._channel(f"/raw/{device}/rx", "zarco.RawChunk", raw,
                                       raw=[device, "rx"])
        self.kinds[tx] = self._channel(f"/raw/{device}/tx", "zarco.RawChunk", raw,
                                       raw=[device, "tx"])
        append = self.pending.append
        on = self.on

        def hook(direction: str, t: float, data: bytes) -> None:
            if on[0]:
                append((rx if direction == "rx" else tx)(t, data))

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
                 "flush_s": rc.flush_s, "fsync_s": rc.fsync_s, "location_hz": rc.location_hz,
                 "origin": [o.lat_deg, o.lon_deg, o.alt_m], "first_part": self.parts,
                 "vessel": self.cfg.shore.vessel,
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

    def _queue(self, frame: bytes | bytearray, n: int) -> None:
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
        """Pack the pending records (one MessagePack call) and queue them for the
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
        for kind in set(types).difference(kinds):
            self._register(kind)
        chans = list(map(kinds.__getitem__, types))
        # the frame in one buffer (sized from the last ones): head, then channels and
        # records packed together
        pre = HEADER.size + BATCH.size
        frame = bytearray(pre + int(n * self._per_record * 1.25) + 64)
        try:
            self.pack_into((chans, items), frame, pre)
        except (TypeError, ValueError, OverflowError):  # a value MessagePack refuses
            self.pack_into((chans, self._salvage(items)), frame, pre)
        self._per_record = (len(frame) - pre) / n
        HEADER.pack_into(frame, 0, b"D", len(frame) - HEADER.size)
        BATCH.pack_into(frame, HEADER.size, n, offset)
        self._queue(frame, n)
        self.counters["messages"] += n

    def _salvage(self, items: list[Any]) -> list[Any]:
        out = []
        for m in items:
            try:
                self.pack(m)
                out.append(m)
            except (TypeError, ValueError, OverflowError):
                out.append(plain(m))
                self.counters["salvaged"] += 1
        return out

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
                self._partial = memoryview(frame)  # what the pipe did not take: no copy
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
        # a simulation hands a batch over every SIM_PERIOD_S of its own time: each
        # wake and each batch has a cost of its own (a turn of the loop, a write to
        # the pipe), and a batch of a few hundred messages is still small enough
        # that its messages die young (the garbage collector's young generation)
        wake = max(period, SIM_PERIOD_S) if self._virtual else period
        try:
            while True:
                await asyncio.sleep(wake)
                self._attach()
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
        proc = self.proc
        if proc is None:
            return
        self._batch()  # while the writer is known: a type first seen now gets its channel
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
