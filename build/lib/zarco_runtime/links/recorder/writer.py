"""The recorder's writer process: framed batches on stdin → MCAP files.

Runs as ``python -m zarco_runtime.links.recorder.writer`` beside the runtime,
so that serialising to MCAP, compressing and writing to disk never take the
runtime's event loop (or its interpreter lock): the runtime only encodes
each message as JSON and hands batches over a pipe.

Input frames (``<cI`` kind and body length, then the body):

* ``J``: a JSON command: ``start`` (where and how to write, the metadata of
  every file), ``channel`` (a topic: its schema, and whether its messages are
  raw device bytes or feed a derived ``foxglove.LocationFix`` topic);
* ``D``: a batch: ``<Id`` count and UTC offset (UTC = runtime time + offset),
  then the channel ids (uint16), runtime times (float64) and lengths (uint32)
  of the records, then their bytes.

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

import base64
import contextlib
import json
import os
import select
import signal
import struct
import sys
import time
from array import array
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import orjson
from mcap.writer import CompressionType, Writer

from zarco_core.geodesy import LocalFrame

HEADER = struct.Struct("<cI")
BATCH = struct.Struct("<Id")
#: most bytes of messages kept in one chunk before it is written (mcap chunk_size)
CHUNK_BYTES = 1 << 20


@dataclass(slots=True)
class Channel:
    id: int
    topic: str
    schema_name: str
    schema: str
    encoding: str = "json"
    raw: tuple[str, str] | None = None
    derive: str = ""


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
    metadata: dict[str, str] = field(default_factory=dict)


def emit(event: str, **kw: Any) -> None:
    """Tell the runtime (one JSON line on stdout)."""
    with contextlib.suppress(OSError, ValueError):
        sys.stdout.write(json.dumps({"ev": event, **kw}) + "\n")
        sys.stdout.flush()


def free_mb(path: str) -> float:
    st = os.statvfs(path)
    return st.f_bavail * st.f_frsize / 1e6


class McapFile:
    """One MCAP file: schemas and channels registered when first used."""

    def __init__(self, path: Path, exclusive: bool, metadata: dict[str, str]) -> None:
        self.path = path
        self.fh: IO[bytes] = open(path, "xb" if exclusive else "wb")  # noqa: SIM115
        self.w = Writer(self.fh, chunk_size=CHUNK_BYTES, compression=CompressionType.ZSTD)
        self.w.start(profile="", library="zarco recorder (mcap-python)")
        self.w.add_metadata("zarco", metadata)
        self.schemas: dict[str, int] = {}
        self.channels: dict[int, int] = {}
        self.messages = 0
        self.pending = 0
        # the new file's name must survive a power cut too
        with contextlib.suppress(OSError):
            fd = os.open(path.parent, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)

    def channel(self, ch: Channel) -> int:
        cid = self.channels.get(ch.id)
        if cid is None:
            sid = self.schemas.get(ch.schema_name)
            if sid is None:
                sid = self.w.register_schema(ch.schema_name, "jsonschema", ch.schema.encode())
                self.schemas[ch.schema_name] = sid
            cid = self.w.register_channel(ch.topic, ch.encoding, sid)
            self.channels[ch.id] = cid
        return cid

    def add(self, ch: Channel, log_ns: int, pub_ns: int, data: bytes) -> None:
        self.w.add_message(self.channel(ch), log_ns, data, pub_ns)
        self.messages += 1
        self.pending += 1

    def flush(self, sync: bool) -> None:
        self.w.flush()  # type: ignore[no-untyped-call]
        self.pending = 0
        if sync:
            os.fdatasync(self.fh.fileno())

    def size(self) -> int:
        return self.fh.tell()

    def finish(self) -> None:
        try:
            self.w.finish()  # type: ignore[no-untyped-call]
            self.fh.flush()
            os.fdatasync(self.fh.fileno())
        finally:
            self.fh.close()


class Recording:
    """The files of one run: naming, rotation, flushing, the free-space floor."""

    def __init__(self, opts: Options) -> None:
        self.o = opts
        self.channels: dict[int, Channel] = {}
        self.file: McapFile | None = None
        self.part = opts.first_part
        self.stopped = ""
        self.last_flush = time.monotonic()
        self.last_sync = self.last_flush
        self.frame = LocalFrame(*opts.origin)
        self.next_fix: dict[str, float] = {}
        self.loc: dict[str, Channel] = {}
        self.dropped = 0

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
        meta = {**self.o.metadata, "part": str(self.part)}
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
        raw = d.get("raw")
        ch = Channel(int(d["id"]), str(d["topic"]), str(d["schema_name"]), str(d["schema"]),
                     str(d.get("encoding", "json")), (str(raw[0]), str(raw[1])) if raw else None,
                     str(d.get("derive", "")))
        self.channels[ch.id] = ch
        if ch.derive and ch.derive not in self.loc:
            schema = str(d["derive_schema"])
            self.loc[ch.derive] = Channel(-1 - len(self.loc), f"/foxglove/{ch.derive}",
                                          "foxglove.LocationFix", schema)

    def batch(self, body: memoryview) -> None:
        n, offset = BATCH.unpack_from(body, 0)
        if self.stopped:
            self.dropped += n
            return
        if self.file is None:
            if not self._floor():
                self.dropped += n
                return
            self.file = self._open()
        pos = BATCH.size
        chans = array("H")
        chans.frombytes(body[pos:pos + 2 * n])
        pos += 2 * n
        times = array("d")
        times.frombytes(body[pos:pos + 8 * n])
        pos += 8 * n
        lens = array("I")
        lens.frombytes(body[pos:pos + 4 * n])
        pos += 4 * n
        f = self.file
        channels = self.channels
        try:
            for c, t, ln in zip(chans, times, lens, strict=True):
                data = bytes(body[pos:pos + ln])
                pos += ln
                ch = channels.get(c)
                if ch is None:
                    continue
                utc = t + offset
                ns = int(utc * 1e9)
                if ch.raw is not None:
                    data = orjson.dumps({"t": t, "utc_s": utc, "device": ch.raw[0],
                                         "dir": ch.raw[1],
                                         "data": base64.b64encode(data).decode("ascii")})
                    f.add(ch, ns, ns, data)
                    continue
                f.add(ch, ns, ns, data)
                if ch.derive and t >= self.next_fix.get(ch.derive, -1e300):
                    self._derive(f, ch.derive, data, offset, ns)
        except OSError as exc:
            self._stop(f"write failed: {exc}: recording stopped", "error")

    def _derive(self, f: McapFile, what: str, data: bytes, offset: float, ns: int) -> None:
        m = orjson.loads(data)
        t = m.get("t")
        if not isinstance(t, float) or t < self.next_fix.get(what, -1e300):
            return
        if what == "vessel":
            lat, lon = m.get("lat_deg"), m.get("lon_deg")
            if not m.get("pos_valid") or lat is None or lon is None:
                return
            cov = m.get("cov") or []
            if len(cov) == 25 and all(isinstance(c, float) for c in (cov[0], cov[1], cov[6])):
                ee, en, nn = cov[6], cov[1], cov[0]
                pc, kind = [ee, en, 0.0, en, nn, 0.0, 0.0, 0.0, 0.0], 3
            else:
                pc, kind = [0.0] * 9, 0
            color = {"r": 0.1, "g": 0.4, "b": 1.0, "a": 1.0}
        else:
            x, y = m.get("kf_x_m"), m.get("kf_y_m")
            if m.get("lost") or not (int(m.get("flags") or 0) & 1) or x is None or y is None:
                return
            lat, lon, _alt = self.frame.to_geodetic(x, y)
            s = m.get("kf_pos_sigma_m")
            s2 = s * s if isinstance(s, float) else 0.0
            pc, kind = [s2, 0.0, 0.0, 0.0, s2, 0.0, 0.0, 0.0, 0.0], 2 if s2 else 0
            color = {"r": 1.0, "g": 0.3, "b": 0.1, "a": 1.0}
        self.next_fix[what] = t + 1.0 / self.o.location_hz
        utc = t + offset
        sec = int(utc)
        fix = {"timestamp": {"sec": sec, "nsec": int((utc - sec) * 1e9)}, "frame_id": what,
               "latitude": lat, "longitude": lon, "altitude": 0.0,
               "position_covariance": pc, "position_covariance_type": kind, "color": color}
        f.add(self.loc[what], ns, int(utc * 1e9), orjson.dumps(fix))

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


def _read_exact(fd: int, n: int, buf: bytearray) -> bool:
    """Read ``n`` bytes into ``buf`` (cleared first); False at end of input."""
    buf.clear()
    while len(buf) < n:
        chunk = os.read(fd, n - len(buf))
        if not chunk:
            return False
        buf += chunk
    return True


def serve(fd: int) -> int:
    rec: Recording | None = None
    hdr = bytearray()
    body = bytearray()
    while True:
        timeout = rec.o.flush_s / 2 if rec is not None and rec.file is not None else None
        ready, _, _ = select.select([fd], [], [], timeout)
        if not ready:
            if rec is not None:
                rec.tick()
            continue
        if not _read_exact(fd, HEADER.size, hdr):
            break
        kind, length = HEADER.unpack(hdr)
        if not _read_exact(fd, length, body):
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
    if rec is not None:
        rec.close()
    return 0


def main() -> int:
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
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
