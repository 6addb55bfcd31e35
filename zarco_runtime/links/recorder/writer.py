"""The recorder's writer process: framed batches on stdin → MCAP files.

Runs as ``python …/writer.py`` beside the runtime, so that JSON encoding,
MCAP serialisation, compression and the disk never take the runtime's event
loop (or its interpreter lock).  It imports nothing of the project (the
standard library, msgspec and Foxglove's SDK; the project's geodesy only to
put an AUV on the map): it starts in a few hundredths of a second.

Input frames (``<cI`` kind and body length, then the body):

* ``J``: a JSON command: ``start`` (where and how to write, the metadata of
  every file), ``channel`` (a topic and its JSON schema; ``raw``: [device,
  "rx" or "tx"] for a device's raw bytes; ``derive``: ["vessel" or "auv",
  the channel of its map topic]; ``shore``: ["state", "auv" or "events", the
  channel of the shore view's topic derived from it]; ``watch``: the name
  under which its latest record is kept for those);
* ``D``: a batch: ``<Id`` count n and UTC offset (UTC = runtime time +
  offset), then MessagePack: [the n channel ids, the n records], each record
  the map of a message's fields (a raw chunk's: ``t``, ``data``, ``device``,
  ``dir``).  A record's time is its ``t``
  (runtime time; a record without one takes the previous record's).

Each record becomes one MCAP message on its channel, logged at its UTC time,
as JSON (msgspec; a raw chunk gains its ``utc_s``); every ``1/location_hz``
a vessel estimate (NavState) or an AUV track (AuvTrack) also gives a
``foxglove.LocationFix`` on the map topic the runtime named for it, and the
shore view's ``/shore/state`` and ``/shore/auv`` (the shore link's objects,
:mod:`zarco_runtime.links.recorder.shore_topics`); every event also gives a
``foxglove.Log`` on ``/foxglove/events``.
The MCAP files are written by Foxglove's SDK (``foxglove-sdk``: the Rust
``mcap`` writer, about a microsecond a message against four to five for the
pure-Python ``mcap`` writer; the same format, which the ``mcap`` package
reads back).

Every ``flush_s`` of wall time with messages pending, the chunk in progress is
written out (and the file ``fdatasync``-ed every ``fsync_s``): a process
killed outright leaves a file whose complete chunks every MCAP reader can
stream (it only lacks the summary at the end).  When the runtime closes the
pipe, or dies, the file is finished properly.  A file that reaches
``max_file_mb`` is finished and the next part begins; when free space falls
below ``min_free_mb`` (or a write fails) the file is finished if it can be,
recording stops and the runtime is told (one JSON line on stdout per event:
``open``, ``close``, ``disk_low``, ``error``).  SIGINT and SIGTERM are
ignored: the writer ends when its input ends, after finishing the file.
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import os
import select
import signal
import struct
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import compress
from pathlib import Path
from typing import TYPE_CHECKING, Any

import msgspec

if TYPE_CHECKING:  # imported where used: the runtime reads this module's framing only
    from foxglove.mcap import MCAPWriteOptions

#: a frame from the recorder to its writer: kind and body length, then the body
HEADER = struct.Struct("<cI")
#: a batch's head: number of records, UTC offset (UTC = runtime time + offset)
BATCH = struct.Struct("<Id")
#: most bytes of messages kept in one chunk before it is written
CHUNK_BYTES = 1 << 20

#: ``log(json, log_time_ns)``: one MCAP message on a channel of the open file
Log = Callable[[bytes, int], None]


@dataclass(slots=True)
class Channel:
    id: int
    topic: str
    schema_name: str
    schema: str
    encoding: str = "json"
    raw: tuple[str, str] | None = None
    #: a map topic derived from this one's messages: "vessel" or "auv", its channel
    derive: tuple[str, int] | None = None
    #: a shore view topic derived from this one's messages: "state", "auv" or
    #: "events", its channel
    shore: tuple[str, int] | None = None
    #: the name under which this channel's latest record is kept (for the state)
    watch: str = ""


@dataclass(slots=True)
class Options:
    dir: str = "."
    file: str = ""
    base: str = "zarco"
    max_file_mb: float = 256.0
    min_free_mb: float = 0.0
    flush_s: float = 0.25
    fsync_s: float = 1.0
    location_hz: float = 5.0
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    first_part: int = 0
    vessel: str = ""
    metadata: dict[str, str] = field(default_factory=dict)


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def emit(event: str, **kw: Any) -> None:
    """Tell the runtime (one JSON line on stdout)."""
    with contextlib.suppress(OSError, ValueError):
        sys.stdout.write(json.dumps({"ev": event, **kw}) + "\n")
        sys.stdout.flush()


@functools.cache
def software_version() -> str:
    """The package version, and the git commit when run from a work tree (once a
    process)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        v = version("zarco-runtime")
    except PackageNotFoundError:
        v = "unknown"
    root = Path(__file__).resolve().parents[3]
    if (root / ".git").exists():
        with contextlib.suppress(OSError, subprocess.SubprocessError):
            rev = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty"],
                                 capture_output=True, text=True, timeout=5.0)
            if rev.returncode == 0 and rev.stdout.strip():
                v += f"+git.{rev.stdout.strip()}"
    return v


def free_mb(path: str) -> float:
    st = os.statvfs(path)
    return st.f_bavail * st.f_frsize / 1e6


def _options() -> MCAPWriteOptions:
    from foxglove.mcap import MCAPCompression, MCAPWriteOptions

    # zstd on the writer's own thread (no pool: the machine's cores are the
    # runtime's); message and chunk indexes, statistics and CRCs as usual.  No
    # seeking: each chunk is built in memory and written whole.  (A seeking writer
    # streams a chunk to the file behind a placeholder length and patches it when
    # the chunk ends: a kill -9 in between leaves a last record no reader can
    # skip; killed without seeking, the file ends in a cut record, which every
    # MCAP reader reads up to.)
    return MCAPWriteOptions(compression=MCAPCompression.Zstd, compression_threads=0,
                            chunk_size=CHUNK_BYTES, profile="", disable_seeking=True)


class McapFile:
    """One MCAP file: its own SDK context, with a channel per recorded topic."""

    def __init__(self, path: Path, exclusive: bool, metadata: dict[str, str]) -> None:
        import foxglove

        self.path = path
        self.ctx = foxglove.Context()
        self.w = foxglove.open_mcap(path, allow_overwrite=not exclusive, context=self.ctx,
                                    writer_options=_options())
        self.closed = False
        try:
            self.fd = os.open(path, os.O_RDONLY)  # for fdatasync and the size
            self.w.write_metadata("zarco", metadata)
        except Exception:
            self._abandon()
            raise
        #: ``logs[channel id]``: how to log on that channel (None: not yet made)
        self.logs: list[Log | None] = []
        self.messages = 0
        self.pending = 0
        # the new file's name must survive a power cut too
        with contextlib.suppress(OSError):
            fd = os.open(path.parent, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)

    def channel(self, ch: Channel) -> Log:
        """The log function of ``ch`` in this file (made when first used)."""
        while len(self.logs) <= ch.id:
            self.logs.append(None)
        log = self.logs[ch.id]
        if log is None:
            import foxglove

            meta = {"device": ch.raw[0], "dir": ch.raw[1]} if ch.raw else None
            c = foxglove.Channel(ch.topic, message_encoding=ch.encoding, context=self.ctx,
                                 schema=foxglove.Schema(name=ch.schema_name,
                                                        encoding="jsonschema",
                                                        data=ch.schema.encode()),
                                 metadata=meta)
            log = self.logs[ch.id] = c.base.log
        return log

    def flush(self, sync: bool) -> None:
        """Write the chunk in progress (a ``kill -9`` keeps it); ``sync``: to the disk."""
        try:
            self.w.flush()
        except RuntimeError as exc:  # the SDK's I/O errors
            raise OSError(str(exc)) from exc
        self.pending = 0
        if sync:
            os.fdatasync(self.fd)

    def size(self) -> int:
        return os.fstat(self.fd).st_size

    def finish(self) -> None:
        """Write the summary and close (the file is then complete)."""
        try:
            self.w.close()
            self.closed = True
            os.fdatasync(self.fd)
        except RuntimeError as exc:
            raise OSError(str(exc)) from exc
        finally:
            self._abandon()

    def _abandon(self) -> None:
        if not self.closed:
            # a writer that failed must still be closed here, not when the
            # interpreter is gone (the SDK would panic then)
            with contextlib.suppress(Exception):
                self.w.close()
            self.closed = True
        if getattr(self, "fd", -1) >= 0:
            with contextlib.suppress(OSError):
                os.close(self.fd)
            self.fd = -1


class Recording:
    """The files of one run: naming, rotation, flushing, the free-space floor."""

    def __init__(self, opts: Options) -> None:
        self.o = opts
        self.channels: list[Channel | None] = [None]
        self.file: McapFile | None = None
        self.part = opts.first_part
        self.stopped = ""
        self.last_flush = time.monotonic()
        self.last_sync = self.last_flush
        self.dropped = 0
        #: records logged at the previous record's time (they had no usable time)
        self.untimed = 0
        self.underived = 0
        self.last_ns = 0
        self.raw_ids: set[int] = set()
        self.derive_ids: set[int] = set()
        #: channels whose records derive or feed another topic (in record order)
        self.special_ids: set[int] = set()
        #: the latest record of each watched channel, and of the vessel estimate
        self.latest: dict[str, Any] = {}
        self.shore_topics: Any = None
        #: time of the next map fix, by the channel it is derived from
        self.next_fix: dict[int, float] = {}
        self.frame: Any = None
        self.decode = msgspec.msgpack.Decoder().decode
        enc = msgspec.json.Encoder()
        self.encode, self.encode_lines = enc.encode, enc.encode_lines

    # ------------------------------------------------------------ files

    def _path(self) -> tuple[Path, bool]:
        o = self.o
        if o.file:
            p = Path(o.file)
            if self.part == 1:
                return p, False  # the file asked for (zarco sim --record FILE)
            return p.with_name(f"{p.stem}-{self.part:03d}{p.suffix or '.mcap'}"), False
        d = Path(o.dir)
        base = f"{o.base}-{self.part:03d}"
        p = d / f"{base}.mcap"
        k = 1
        while p.exists():  # never overwrite a recording
            p = d / f"{base}.{k}.mcap"
            k += 1
        return p, True

    def _open(self) -> McapFile:
        self.part += 1
        path, exclusive = self._path()
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {"version": software_version(), **self.o.metadata, "part": str(self.part)}
        f = McapFile(path, exclusive, meta)
        emit("open", path=str(path), part=self.part)
        return f

    def _close(self) -> None:
        f, self.file = self.file, None
        if f is None:
            return
        try:
            f.finish()
            emit("close", path=str(f.path), bytes=f.path.stat().st_size, messages=f.messages)
        except OSError as exc:
            emit("error", text=f"{f.path}: cannot finish: {exc}")

    def _stop(self, why: str, event: str, **kw: Any) -> None:
        self.stopped = why
        path = str(self.file.path) if self.file else ""
        self._close()
        emit(event, text=why, path=path, **kw)

    def _floor(self) -> bool:
        """True if writing may go on (free space above the floor)."""
        if self.o.min_free_mb <= 0:
            return True
        d = Path(self.o.file).parent if self.o.file else Path(self.o.dir)
        while not d.exists() and d != d.parent:
            d = d.parent
        try:
            free = free_mb(str(d))
        except OSError:
            return True
        if free < self.o.min_free_mb:
            self._stop(f"free space {free:.0f} MB below the floor of {self.o.min_free_mb:g} MB: "
                       "recording stopped", "disk_low", free_mb=round(free, 1))
            return False
        return True

    # --------------------------------------------------------- messages

    def add_channel(self, d: dict[str, Any]) -> None:
        raw, der, sh = d.get("raw"), d.get("derive"), d.get("shore")
        ch = Channel(int(d["id"]), str(d["topic"]), str(d["schema_name"]), str(d["schema"]),
                     str(d.get("encoding", "json")), (str(raw[0]), str(raw[1])) if raw else None,
                     (str(der[0]), int(der[1])) if der else None,
                     (str(sh[0]), int(sh[1])) if sh else None, str(d.get("watch") or ""))
        while len(self.channels) <= ch.id:
            self.channels.append(None)
        self.channels[ch.id] = ch
        if ch.raw is not None:
            self.raw_ids.add(ch.id)
        if ch.derive is not None or (ch.shore is not None and ch.shore[0] != "events"):
            self.derive_ids.add(ch.id)
            self.next_fix[ch.id] = -math.inf
        if ch.derive is not None or ch.shore is not None or ch.watch:
            self.special_ids.add(ch.id)

    def batch(self, body: memoryview) -> None:
        n, offset = BATCH.unpack_from(body, 0)
        if self.stopped:
            self.dropped += n
            return
        if self.file is None:
            if not self._floor():
                self.dropped += n
                return
            try:
                self.file = self._open()
            except (OSError, RuntimeError) as exc:
                self.dropped += n
                self._stop(f"cannot open a recording file: {exc}: recording stopped", "error")
                return
        chans, records = self.decode(body[BATCH.size:])
        if len(records) != n or len(chans) != n:
            raise ValueError(f"a batch of {n} records holds {len(records)}")
        if self.raw_ids:  # a raw chunk's UTC time, as its log time's
            for i in compress(range(n), map(self.raw_ids.__contains__, chans)):
                r = records[i]
                r["utc_s"] = r["t"] + offset
        try:
            lines = self.encode_lines(records).split(b"\n")
        except (TypeError, ValueError):  # a dict key JSON cannot carry
            lines = [self._salvage(r) for r in records]
            lines.append(b"")
        lines.pop()
        f = self.file
        logs = f.logs
        if len(logs) < len(self.channels):
            logs.extend([None] * (len(self.channels) - len(logs)))
        written = 0
        good = self.last_ns
        try:
            for c, r, data in zip(chans, records, lines, strict=True):
                log = logs[c]
                if log is None:
                    ch = self.channels[c]
                    if ch is None:
                        continue
                    log = f.channel(ch)
                try:
                    ns = int((r["t"] + offset) * 1e9)
                    log(data, ns)
                    good = ns
                except (KeyError, TypeError, ValueError, OverflowError):
                    # no time (none, NaN, beyond 1970..2554 UTC): at the previous one's
                    self.untimed += 1
                    log(data, good)
                written += 1
            if self.special_ids:
                written += self._special(f, chans, records, offset)
        finally:
            self.last_ns = good
            f.messages += written
            f.pending += written

    def _salvage(self, r: Any) -> bytes:
        def plain(x: Any) -> Any:
            if isinstance(x, dict):
                return {k if isinstance(k, (str, int, float)) else repr(k): plain(v)
                        for k, v in x.items()}
            if isinstance(x, list):
                return [plain(v) for v in x]
            return x

        return self.encode(plain(r))

    def _special(self, f: McapFile, chans: list[int], records: list[Any],
                 offset: float) -> int:
        """The derived topics of a batch's records, in record order (a state takes the
        latest directive, guidance, thrust and status recorded before it)."""
        written = 0
        nxt = self.next_fix
        latest = self.latest
        channels = self.channels
        for i in compress(range(len(chans)), map(self.special_ids.__contains__, chans)):
            c, r = chans[i], records[i]
            ch = channels[c]
            if ch is None:
                continue
            if ch.watch:
                latest[ch.watch] = r
                continue
            try:
                if ch.derive is not None and ch.derive[0] == "vessel":
                    latest["nav"] = r
                if ch.shore is not None and ch.shore[0] == "events":
                    written += self._shore(f, ch.shore, r, offset)
                    continue
                if not r["t"] >= nxt[c]:  # at most location_hz
                    continue
                # (less 1 % of the period: a 20 Hz source's stamps, 0.2 s apart in
                # theory, are sometimes a hair closer)
                nxt[c] = float(r["t"]) + 0.99 / self.o.location_hz
                if ch.derive is not None:
                    written += self._derive(f, c, r, offset)
                if ch.shore is not None:
                    written += self._shore(f, ch.shore, r, offset)
            except (LookupError, ArithmeticError, ValueError, TypeError):
                self.underived += 1  # no time, or values no map can show
        return written

    def _shore(self, f: McapFile, shore: tuple[str, int], m: Any, offset: float) -> int:
        """The shore view's object of a record on its topic: 1 if one was written."""
        what, cid = shore
        ch = self.channels[cid] if cid < len(self.channels) else None
        if ch is None or not isinstance(m, dict):
            return 0
        if self.shore_topics is None:  # the shore link's own functions (imported once)
            from zarco_core.geodesy import LocalFrame
            from zarco_runtime.links.recorder import shore_topics

            self.shore_topics = shore_topics
            if self.frame is None:
                self.frame = LocalFrame(*self.o.origin)
        st = self.shore_topics
        utc = float(m["t"]) + offset
        if what == "state":
            obj = st.state(self.o.vessel, utc, m, self.latest)
        elif what == "auv":
            obj = st.auv(utc, m, self.frame, self.latest.get("nav"))
        else:
            obj = st.log(utc, m)
        try:
            f.channel(ch)(self.encode(obj), int(utc * 1e9))
        except (ValueError, OverflowError):  # a time beyond what MCAP holds
            return 0
        return 1

    def _derive(self, f: McapFile, c: int, m: Any, offset: float) -> int:
        """The map fix (``foxglove.LocationFix``) of a vessel estimate or an AUV
        track, at most ``location_hz``: 1 if one was written."""
        ch = self.channels[c]
        if ch is None or ch.derive is None or not isinstance(m, dict):
            return 0
        what, fix_id = ch.derive
        t = float(m["t"])
        if what == "vessel":
            lat, lon = m.get("lat_deg"), m.get("lon_deg")
            if not (m.get("pos_valid") and _finite(lat) and _finite(lon)):
                return 0
            cov = m.get("cov") or []
            if len(cov) == 25 and all(_finite(v) for v in (cov[0], cov[1], cov[6])):
                ee, en, nn = cov[6], cov[1], cov[0]  # (x north, y east) → East-North-Up
                pc, kind = [ee, en, 0.0, en, nn, 0.0, 0.0, 0.0, 0.0], 3
            else:
                pc, kind = [0.0] * 9, 0
            color = {"r": 0.1, "g": 0.4, "b": 1.0, "a": 1.0}
        else:
            x, y = m.get("kf_x_m"), m.get("kf_y_m")
            if m.get("lost") or not (int(m.get("flags") or 0) & 1) \
                    or not (_finite(x) and _finite(y)):
                return 0
            if self.frame is None:  # only with an AUV: the project's geodesy (pymap3d)
                from zarco_core.geodesy import LocalFrame

                self.frame = LocalFrame(*self.o.origin)
            lat, lon, _alt = self.frame.to_geodetic(x, y)
            sigma: Any = m.get("kf_pos_sigma_m")
            s2 = float(sigma) * float(sigma) if _finite(sigma) else 0.0
            pc, kind = [s2, 0.0, 0.0, 0.0, s2, 0.0, 0.0, 0.0, 0.0], 2 if s2 else 0
            color = {"r": 1.0, "g": 0.3, "b": 0.1, "a": 1.0}
        fch = self.channels[fix_id] if fix_id < len(self.channels) else None
        if fch is None:
            return 0
        try:
            utc = t + offset
            sec = int(utc)
            fix = {"timestamp": {"sec": sec, "nsec": int((utc - sec) * 1e9)},
                   "frame_id": what, "latitude": lat, "longitude": lon, "altitude": 0.0,
                   "position_covariance": pc, "position_covariance_type": kind,
                   "color": color}
            f.channel(fch)(self.encode(fix), int(utc * 1e9))
        except (ValueError, OverflowError):  # a time beyond what MCAP holds
            return 0
        return 1

    # ------------------------------------------------------------ timing

    def tick(self, force: bool = False) -> None:
        """Write the chunk in progress when it is due; rotate; watch the floor."""
        f = self.file
        if f is None:
            return
        now = time.monotonic()
        if not force and (f.pending == 0 or now - self.last_flush < self.o.flush_s):
            return
        self.last_flush = now
        sync = now - self.last_sync >= self.o.fsync_s
        if sync:
            self.last_sync = now
        try:
            f.flush(sync)
        except OSError as exc:
            self._stop(f"write failed: {exc}: recording stopped", "error")
            return
        if not self._floor():
            return
        if f.size() >= self.o.max_file_mb * 1e6:
            self._close()
            self.file = self._open()

    def close(self) -> None:
        if self.file is not None:
            self._close()


def _read_exact(fd: int, n: int) -> bytearray | None:
    """The next ``n`` bytes of the input (read into place); None at its end."""
    buf = bytearray(n)
    view = memoryview(buf)
    got = 0
    while got < n:
        k = os.readv(fd, [view[got:]])
        if not k:
            return None
        got += k
    return buf


def serve(fd: int) -> int:
    rec: Recording | None = None
    try:
        while True:
            timeout = rec.o.flush_s / 2 if rec is not None and rec.file is not None else None
            ready, _, _ = select.select([fd], [], [], timeout)
            if not ready:
                if rec is not None:
                    rec.tick()
                continue
            hdr = _read_exact(fd, HEADER.size)
            if hdr is None:
                break
            kind, length = HEADER.unpack(hdr)
            body = _read_exact(fd, length)
            if body is None:
                break
            if kind == b"D":
                if rec is not None:
                    rec.batch(memoryview(body))
            elif kind == b"J":
                d = json.loads(body)
                op = d.get("op")
                if op == "start":
                    o = Options(**{k: v for k, v in d.items() if k != "op"})
                    o.origin = (float(o.origin[0]), float(o.origin[1]), float(o.origin[2]))
                    rec = Recording(o)
                elif op == "channel" and rec is not None:
                    rec.add_channel(d)
                elif op == "flush" and rec is not None:
                    rec.tick(force=True)
            if rec is not None:
                rec.tick()
    finally:
        if rec is not None:
            rec.close()
    return 0


def main() -> int:
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
    # a batch process: woken by the runtime's data, it waits its turn instead of
    # preempting the runtime (Linux's SCHED_BATCH; nice 5 on the boat besides)
    if hasattr(os, "sched_setscheduler"):
        with contextlib.suppress(OSError):
            os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    if len(sys.argv) > 2 and sys.argv[1] == "--nice":
        with contextlib.suppress(OSError):
            os.nice(int(sys.argv[2]))
    try:
        return serve(sys.stdin.fileno())
    except Exception as exc:  # reported, then the runtime restarts the writer
        emit("error", text=f"writer failed: {type(exc).__name__}: {exc}")
        raise


if __name__ == "__main__":
    sys.exit(main())
