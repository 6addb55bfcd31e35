"""JSON schemas and JSON encoding of the bus messages (MCAP ``jsonschema`` / ``json``).

Every bus message is a dataclass; its schema is derived once from the type
hints: numbers, integers, booleans, strings, enums (an integer enum as
``oneOf`` of titled constants, the form Foxglove reads; a string enum with its
``enum`` values), tuples and lists as arrays, dicts as objects, nested
dataclasses as objects, bytes as base64 strings.  Optional fields take the
schema of their type (JSON ``null`` stands for None, and for NaN and infinity,
which JSON cannot carry).  Field docs come from the class docstring.

The recorder hands messages to its writer process as MessagePack, a whole
batch in one call (:func:`packer`: dataclasses as maps of their fields,
enums as their values, tuples and sets as arrays, bytes as binary; a float's
8 bytes are copied, not formatted: a few tenths of a microsecond a message),
and the writer turns each into JSON (msgspec: bytes as base64, NaN and
infinity as null, non-string dict keys as strings): key for key the JSON of
the dataclass itself.  A raw device chunk is a :class:`RawChunk`, whose JSON
(with the ``utc_s`` the writer adds) is the ``zarco.RawChunk`` schema's.
"""

from __future__ import annotations

import base64
import dataclasses
import enum
import json
import types
import typing
from typing import Any

import msgspec
import orjson

#: JSON options: dict keys that are not strings become strings
OPTIONS = orjson.OPT_NON_STR_KEYS


def json_default(obj: Any) -> Any:
    """What orjson cannot encode itself: bytes as base64, sets as lists, else repr."""
    if isinstance(obj, (bytes, bytearray, memoryview)):
        return base64.b64encode(obj).decode("ascii")
    if isinstance(obj, (set, frozenset)):
        return sorted(obj, key=repr)
    return repr(obj)


def enc_hook(obj: Any) -> Any:
    """What MessagePack and JSON cannot carry as such: numpy scalars as numbers,
    sets as sorted lists, anything else as its repr (a message field is never
    dropped)."""
    if hasattr(obj, "dtype") and hasattr(obj, "item"):  # a numpy scalar or 0-d array
        return obj.item()
    if isinstance(obj, (set, frozenset)):
        return sorted(obj, key=repr)
    return repr(obj)


def packer() -> msgspec.msgpack.Encoder:
    """The encoder of the recorder's batches (runtime side)."""
    return msgspec.msgpack.Encoder(enc_hook=enc_hook)


class RawChunk(msgspec.Struct, gc=False):
    """Bytes read from (``dir`` rx) or written to (tx) a device port at runtime
    time ``t`` (see :data:`RAW_CHUNK_SCHEMA`; the writer adds ``utc_s``); a class
    per device and direction (:func:`raw_chunk_type`) says which channel a chunk
    goes to.  Made in C, untracked by the garbage collector: a tenth of a
    microsecond."""

    t: float
    data: bytes
    device: str = ""
    dir: str = ""


def raw_chunk_type(device: str, direction: str) -> type[RawChunk]:
    """The :class:`RawChunk` of one device's direction (``RawChunk(t, data)``)."""
    kind = msgspec.defstruct(f"RawChunk_{device}_{direction}",
                             [("device", str, device), ("dir", str, direction)],
                             bases=(RawChunk,))
    assert issubclass(kind, RawChunk)
    return kind


def plain(obj: Any) -> Any:
    """``obj`` as plain JSON-able values (dataclasses as dicts, enums as values,
    integers beyond 64 bits as strings): the slow path for the rare message the
    packer refuses."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, enum.Enum):
        return plain(obj.value)
    if isinstance(obj, bool) or obj is None or isinstance(obj, (float, str, bytes)):
        return obj
    if isinstance(obj, (bytearray, memoryview)):
        return bytes(obj)
    if isinstance(obj, int):
        return int(obj) if -(2 ** 63) <= obj < 2 ** 64 else str(obj)
    if isinstance(obj, dict):
        return {k if isinstance(k, (str, int, float)) else repr(k): plain(v)
                for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    return plain(enc_hook(obj))


def _field_schema(tp: Any, seen: set[type]) -> dict[str, Any]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return _field_schema(args[0], seen) if len(args) == 1 else {}
    if tp is bool:
        return {"type": "boolean"}
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        values = list(tp)
        if all(isinstance(v.value, int) for v in values):
            return {"title": tp.__name__,
                    "oneOf": [{"title": v.name, "const": int(v.value)} for v in values]}
        return {"type": "string", "title": tp.__name__, "enum": [str(v.value) for v in values]}
    if tp is int:
        return {"type": "integer"}
    if tp is float:
        return {"type": "number"}
    if tp is str:
        return {"type": "string"}
    if tp in (bytes, bytearray):
        return {"type": "string", "contentEncoding": "base64"}
    if origin in (tuple, list, set, frozenset) or tp in (tuple, list):
        args = [a for a in typing.get_args(tp) if a is not Ellipsis]
        if args and all(a == args[0] for a in args):
            return {"type": "array", "items": _field_schema(args[0], seen)}
        return {"type": "array"}
    if origin is dict or tp is dict:
        kv = typing.get_args(tp)
        out: dict[str, Any] = {"type": "object"}
        if len(kv) == 2 and kv[1] is not object:
            out["additionalProperties"] = _field_schema(kv[1], seen)
        return out
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return dataclass_schema(tp, seen)
    return {}


def _field_docs(cls: type) -> dict[str, str]:
    """``name``: the sentence of the class docstring that mentions ``name`` first."""
    doc = " ".join((cls.__doc__ or "").split())
    out: dict[str, str] = {}
    sentences = [s.strip() for s in doc.replace("; ", ". ").split(". ") if s.strip()]
    for f in dataclasses.fields(cls):
        for s in sentences:
            if f"``{f.name}``" in s:
                out[f.name] = s.replace("``", "")
                break
    return out


def dataclass_schema(cls: type, seen: set[type] | None = None) -> dict[str, Any]:
    """The JSON schema of a dataclass (recursively; a cycle becomes an untyped object)."""
    seen = set() if seen is None else seen
    if cls in seen:
        return {"type": "object"}
    seen = seen | {cls}
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # an annotation only known to a type checker
        hints = {}
    docs = _field_docs(cls)
    props: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        s = _field_schema(hints.get(f.name, Any), seen)
        if f.name in docs:
            s = {**s, "description": docs[f.name]}
        props[f.name] = s
    first = (cls.__doc__ or "").strip().split("\n\n")[0]
    return {"title": f"zarco.{cls.__name__}", "description": " ".join(first.split()),
            "type": "object", "properties": props}


def message_schema(cls: type) -> bytes:
    """The schema document of a bus message type, as MCAP schema data."""
    return orjson.dumps(dataclass_schema(cls))


#: a raw chunk of bytes read from (rx) or written to (tx) a device
RAW_CHUNK_SCHEMA: dict[str, Any] = {
    "title": "zarco.RawChunk",
    "description": "Bytes read from (rx) or written to (tx) a device port, as the driver "
                   "saw them",
    "type": "object",
    "properties": {
        "t": {"type": "number", "description": "runtime clock time of the read or write (s, "
                                               "monotonic on the boat, virtual in simulation)"},
        "utc_s": {"type": "number", "description": "the same instant in UTC seconds since "
                                                   "1970"},
        "device": {"type": "string", "description": "device name (gps, compass, ...)"},
        "dir": {"type": "string", "enum": ["rx", "tx"], "description": "rx: read from the "
                "device; tx: written to it"},
        "data": {"type": "string", "contentEncoding": "base64", "description": "the bytes"},
    },
}

_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}

#: Foxglove's well-known schema read by its Map panel (fields as Foxglove defines them)
LOCATION_FIX_SCHEMA: dict[str, Any] = {
    "title": "foxglove.LocationFix",
    "description": "A geodetic position: the vessel's estimate or the AUV's track",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "time of the position (UTC)"},
        "frame_id": {"type": "string", "description": "what the position is of"},
        "latitude": {"type": "number", "description": "latitude (deg, WGS-84)"},
        "longitude": {"type": "number", "description": "longitude (deg, WGS-84)"},
        "altitude": {"type": "number", "description": "altitude (m)"},
        "position_covariance": {"type": "array", "items": {"type": "number"},
                                "minItems": 9, "maxItems": 9,
                                "description": "position covariance (m²), East-North-Up, "
                                               "row-major"},
        "position_covariance_type": {
            "title": "foxglove.PositionCovarianceType",
            "description": "how the covariance is known",
            "oneOf": [{"title": "UNKNOWN", "const": 0}, {"title": "APPROXIMATED", "const": 1},
                      {"title": "DIAGONAL_KNOWN", "const": 2}, {"title": "KNOWN", "const": 3}],
        },
        "color": {"type": "object", "title": "foxglove.Color",
                  "description": "colour of the marker on the map",
                  "properties": {k: {"type": "number"} for k in ("r", "g", "b", "a")}},
    },
}

#: Foxglove's well-known log message (its Log panel): the vessel's events
LOG_SCHEMA: dict[str, Any] = {
    "title": "foxglove.Log",
    "description": "An event of the vessel (mode change, failsafe, acknowledgement, fault)",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "time of the event (UTC)"},
        "level": {
            "title": "foxglove.LogLevel",
            "description": "severity: failsafes and faults are warnings, the rest information",
            "oneOf": [{"title": "UNKNOWN", "const": 0}, {"title": "DEBUG", "const": 1},
                      {"title": "INFO", "const": 2}, {"title": "WARNING", "const": 3},
                      {"title": "ERROR", "const": 4}, {"title": "FATAL", "const": 5}],
        },
        "message": {"type": "string", "description": "the event's text"},
        "name": {"type": "string", "description": "the event's kind (mode, failsafe, ack, "
                                                  "fault, ...) and source: kind/source"},
        "file": {"type": "string", "description": "unused (empty)"},
        "line": {"type": "integer", "minimum": 0, "description": "unused (0)"},
    },
}

_NUM = {"type": ["number", "null"]}

#: the shore link's ``state`` object (5 Hz live; at ``location_hz`` in a recording)
SHORE_STATE_SCHEMA: dict[str, Any] = {
    "title": "zarco.shore.state",
    "description": "The vessel's state as the shore link sends it (docs/protocols.md)",
    "type": "object",
    "properties": {
        "t": {"type": "number", "description": "UTC seconds since 1970"},
        "vessel": {"type": "string"},
        "mode": {"type": "string", "enum": ["idle", "manual", "lines", "follow", "hold",
                                            "return"]},
        "armed": {"type": "boolean"},
        "lat_deg": {**_NUM, "description": "latitude (deg, WGS-84)"},
        "lon_deg": {**_NUM, "description": "longitude (deg, WGS-84)"},
        "heading_deg": {**_NUM, "description": "true heading (deg, clockwise from north)"},
        "course_deg": {**_NUM, "description": "course over ground (deg)"},
        "speed_mps": {**_NUM, "description": "speed over ground (m/s)"},
        "fix": {"type": "string", "enum": ["none", "single", "dgps", "rtk_float",
                                           "rtk_fixed"]},
        "pos_valid": {"type": "boolean"},
        "heading_valid": {"type": "boolean"},
        "leg": {"type": ["integer", "null"], "description": "active leg, 0-based"},
        "legs": {"type": "integer"},
        "xtrack_m": {**_NUM, "description": "cross-track error (m, + to starboard)"},
        "u1": {**_NUM, "description": "port thruster command (-100..100)"},
        "u2": {**_NUM, "description": "starboard thruster command (-100..100)"},
        "failsafes": {"type": "array", "items": {"type": "string"}},
        "reason": {"type": "string"},
    },
}

#: the shore link's ``auv`` object (per track update live; at most ``location_hz`` recorded)
SHORE_AUV_SCHEMA: dict[str, Any] = {
    "title": "zarco.shore.auv",
    "description": "The AUV's estimate as the shore link sends it: the fitted line at t",
    "type": "object",
    "properties": {
        "t": {"type": "number", "description": "UTC seconds since 1970"},
        "lat_deg": {**_NUM, "description": "latitude (deg, WGS-84)"},
        "lon_deg": {**_NUM, "description": "longitude (deg, WGS-84)"},
        "course_deg": {**_NUM, "description": "the AUV's course (deg, clockwise from north)"},
        "speed_mps": {**_NUM, "description": "the AUV's speed (m/s)"},
        "status": {"type": "string", "enum": ["acquiring", "tracking", "turning", "stale",
                                              "lost"]},
        "distance_m": {**_NUM, "description": "horizontal distance from the vessel (m)"},
        "pos_cov_m2": {"type": ["array", "null"], "items": _NUM,
                       "description": "position covariance [north², north·east, east²] (m²)"},
        "sound_speed_mps": {**_NUM, "description": "the tracker's sound speed estimate (m/s)"},
        "sound_speed_sigma_mps": {**_NUM, "description": "its standard deviation (m/s)"},
    },
}

#: the topics a live shore view (``zarco shore foxglove``) and a recording share:
#: topic → (schema name, schema)
SHARED_TOPICS: dict[str, tuple[str, dict[str, Any]]] = {
    "/foxglove/vessel": ("foxglove.LocationFix", LOCATION_FIX_SCHEMA),
    "/foxglove/auv": ("foxglove.LocationFix", LOCATION_FIX_SCHEMA),
    "/foxglove/events": ("foxglove.Log", LOG_SCHEMA),
    "/shore/state": ("zarco.shore.state", SHORE_STATE_SCHEMA),
    "/shore/auv": ("zarco.shore.auv", SHORE_AUV_SCHEMA),
}


def log_level(kind: str) -> int:
    """The foxglove.Log level of an event of ``kind``."""
    return 3 if kind in ("failsafe", "fault") else 2


def foxglove_time(utc: float) -> dict[str, int]:
    """A Foxglove time (``sec``, ``nsec``) of UTC seconds."""
    sec = int(utc)
    return {"sec": sec, "nsec": int((utc - sec) * 1e9)}


def shared_schema(topic: str) -> tuple[str, bytes]:
    """(schema name, schema data) of a topic shared by recordings and live views."""
    name, schema = SHARED_TOPICS[topic]
    return name, json.dumps(schema).encode()
