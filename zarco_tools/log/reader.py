"""Reading recordings: MCAP files written by the recorder, finished or not.

A file whose writer was killed has no summary section and may end inside a
record; :func:`iter_messages` streams it with mcap's own record reader
(:class:`mcap.stream_reader.StreamReader`, the non-seeking path every MCAP
reader falls back to) and stops cleanly at the last complete record, saying
so in :attr:`Recording.truncated`.  Several files (the parts of one run) are
read one after the other.
"""

from __future__ import annotations

import dataclasses
import functools
import io
import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, TypeVar

import orjson
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from zarco_core.paths import PathError, oserror_reason, readable_file

T = TypeVar("T")


@dataclass(slots=True)
class Msg:
    """One recorded message: ``topic``, ``schema`` name, ``log_ns`` (UTC ns) and its JSON."""

    topic: str
    schema: str
    log_ns: int
    data: bytes

    def json(self) -> Any:
        return orjson.loads(self.data)


@dataclass(slots=True)
class Recording:
    """What was read: the files, their metadata, and whether each was finished."""

    paths: list[str]
    metadata: dict[str, str] = field(default_factory=dict)
    finished: dict[str, bool] = field(default_factory=dict)
    truncated: dict[str, str] = field(default_factory=dict)

    @property
    def config(self) -> dict[str, Any]:
        return dict(orjson.loads(self.metadata.get("config", "{}")))

    @property
    def boot(self) -> dict[str, Any]:
        return dict(orjson.loads(self.metadata.get("boot", "{}")))

    @property
    def t0(self) -> float:
        return float(self.metadata.get("t0", "0.0"))

    @property
    def utc_offset_s(self) -> float:
        return float(self.metadata.get("utc_offset_s", "0.0"))


#: a record's head inside a chunk: opcode, length
_HEAD = struct.Struct("<BQ")
#: a message record's fixed part: channel id, sequence, log time, publish time
_MSG = struct.Struct("<HIQQ")


class _StreamReader(StreamReader):
    """mcap's streaming reader, which passes over the index records (it parses each
    message index entry by entry: a third of the time of reading a file)."""

    def _read_record(self, opcode: int, length: int) -> Any:
        if opcode in _INDEXES:
            return None  # the reader reads past the record's body
        return super()._read_record(opcode, length)


_INDEXES = frozenset({Opcode.MESSAGE_INDEX, Opcode.CHUNK_INDEX, Opcode.ATTACHMENT_INDEX,
                      Opcode.METADATA_INDEX, Opcode.STATISTICS, Opcode.SUMMARY_OFFSET})


def _chunk_records(chunk: Chunk) -> bytes:
    """A chunk's records, decompressed (as mcap's own reader does)."""
    if chunk.compression == "zstd":
        import zstandard

        return bytes(zstandard.decompress(chunk.data, chunk.uncompressed_size))
    if chunk.compression == "lz4":
        import lz4.frame  # type: ignore[import-untyped]

        return bytes(lz4.frame.decompress(chunk.data))
    if chunk.compression:
        raise McapError(f"unsupported chunk compression {chunk.compression!r}")
    return bytes(chunk.data)


def _iter_file(path: str, rec: Recording, topics: set[str] | None) -> Iterator[Msg]:
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    #: channel id → (topic, schema name), for the channels asked for
    wanted: dict[int, tuple[str, str]] = {}

    def add_channel(ch: Channel) -> None:
        channels[ch.id] = ch
        if topics is None or ch.topic in topics:
            sc = schemas.get(ch.schema_id)
            wanted[ch.id] = (ch.topic, sc.name if sc else "")
        else:
            wanted.pop(ch.id, None)

    rec.finished[path] = False
    head, msg = _HEAD.unpack_from, _MSG.unpack_from
    with open(path, "rb") as fh:
        try:
            # chunks are taken whole and their message records parsed here, with
            # one struct call each (mcap's record reader costs ~20 µs a message)
            for r in _StreamReader(fh, skip_magic=False, emit_chunks=True).records:
                if isinstance(r, Chunk):
                    data = _chunk_records(r)
                    pos, end = 0, len(data)
                    while pos < end:
                        op, n = head(data, pos)
                        pos += 9
                        if op == 0x05:  # Message
                            ids = msg(data, pos)
                            w = wanted.get(ids[0])
                            if w is not None:
                                yield Msg(w[0], w[1], ids[2], data[pos + 22:pos + n])
                        elif op in (0x03, 0x04):  # Schema, Channel
                            sub = ReadDataStream(io.BytesIO(data[pos:pos + n]))
                            if op == 0x03:
                                sc = Schema.read(sub)
                                schemas[sc.id] = sc
                            else:
                                add_channel(Channel.read(sub))
                        pos += n
                elif isinstance(r, Message):
                    w = wanted.get(r.channel_id)
                    if w is not None:
                        yield Msg(w[0], w[1], r.log_time, r.data)
                elif isinstance(r, Channel):
                    add_channel(r)
                elif isinstance(r, Schema):
                    schemas[r.id] = r
                elif isinstance(r, Metadata) and r.name == "zarco":
                    for k, v in r.metadata.items():
                        rec.metadata.setdefault(k, v)
                elif isinstance(r, Footer):
                    rec.finished[path] = True
        except (McapError, EOFError, ValueError, OSError) as exc:
            # the writer was killed: keep every complete record before the cut
            rec.truncated[path] = f"{type(exc).__name__}: {exc}"[:200]
        except Exception as exc:  # zstd and struct errors of a torn last chunk
            rec.truncated[path] = f"{type(exc).__name__}: {exc}"[:200]


def iter_messages(rec: Recording, topics: set[str] | None = None) -> Iterator[Msg]:
    """Every message of the recording's files, in file order (per file, the order
    the writer wrote them: time order of the runtime's publications)."""
    for p in rec.paths:
        yield from _iter_file(p, rec, topics)


#: the first bytes of every MCAP file
MCAP_MAGIC = b"\x89MCAP0\r\n"


def read_head(path: str) -> bytes:
    """The first bytes of a file to read (PathError if it cannot be read)."""
    try:
        with readable_file(path).open("rb") as fh:
            return fh.read(len(MCAP_MAGIC))
    except OSError as exc:
        raise PathError(path, oserror_reason(exc)) from None


def open_recording(paths: list[str] | str) -> Recording:
    """A recording of one or more files (the parts of a run, in order)."""
    ps = [paths] if isinstance(paths, str) else list(paths)
    for p in ps:
        head = read_head(p)
        if head != MCAP_MAGIC:
            raise PathError(p, "empty: not an MCAP recording" if not head else
                            "not an MCAP recording (no MCAP magic at its start)")
    rec = Recording(ps)
    # the metadata sits at the start of each file: read up to the first message
    for p in ps:
        for _m in _iter_file(p, rec, None):
            break
    rec.finished.clear()
    rec.truncated.clear()
    return rec


def by_topic(rec: Recording, topics: set[str]) -> dict[str, list[Msg]]:
    out: dict[str, list[Msg]] = {t: [] for t in topics}
    for m in iter_messages(rec, topics):
        out[m.topic].append(m)
    return out


@functools.cache
def _field_names(cls: type) -> frozenset[str]:
    return frozenset(f.name for f in dataclasses.fields(cls))


def rebuild(cls: type[T], d: dict[str, Any]) -> T:
    """A message dataclass from its recorded JSON (null numbers back to NaN)."""
    names = _field_names(cls)  # type: ignore[arg-type]
    kw = {k: (math.nan if v is None else tuple(v) if isinstance(v, list) else v)
          for k, v in d.items() if k in names}
    return cls(**kw)


def recover(src: str, dst: str) -> tuple[int, str]:
    """Copy every complete record of ``src`` (a file whose writer was killed) into
    a finished MCAP file ``dst`` with its summary and indexes; returns the number
    of messages and why ``src`` ended ("" if it was finished)."""
    from mcap.writer import CompressionType, Writer

    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    sids: dict[int, int] = {}
    cids: dict[int, int] = {}
    n = 0
    why = "not finished"
    with open(src, "rb") as fh, open(dst, "xb") as out:
        w = Writer(out, compression=CompressionType.ZSTD)
        w.start(profile="", library="zarco log fix (mcap-python)")
        try:
            for r in StreamReader(fh, skip_magic=False).records:
                if isinstance(r, Schema):
                    schemas[r.id] = r
                elif isinstance(r, Channel):
                    channels[r.id] = r
                elif isinstance(r, Metadata):
                    w.add_metadata(r.name, r.metadata)
                elif isinstance(r, Footer):
                    why = ""
                elif isinstance(r, Message) and r.channel_id in channels:
                    ch = channels[r.channel_id]
                    if ch.id not in cids:
                        sc = schemas.get(ch.schema_id)
                        if sc is not None and sc.id not in sids:
                            sids[sc.id] = w.register_schema(sc.name, sc.encoding, sc.data)
                        cids[ch.id] = w.register_channel(ch.topic, ch.message_encoding,
                                                         sids.get(ch.schema_id, 0), ch.metadata)
                    w.add_message(cids[ch.id], r.log_time, r.data, r.publish_time, r.sequence)
                    n += 1
        except Exception as exc:  # the torn end of a killed writer's file
            why = f"{type(exc).__name__}: {exc}"[:200]
        w.finish()
    return n, why
