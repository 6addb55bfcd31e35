"""What the recorder writes is the JSON its schemas describe.

Every message type of the bus, with awkward values (NaN, infinities, None,
enums, nested dataclasses, integer-keyed dicts, bytes, empty and long tuples,
numpy scalars, newlines and non-ASCII in strings), and raw device chunks of
arbitrary bytes, go through the recorder and its writer process into an MCAP
file.  Read back, each message

* validates against its channel's JSON schema (``jsonschema``; ``null`` stands
  for None, NaN and infinity, as the schemas' doc says), and
* holds the same values as an independent encoding of the published object
  (orjson), floats bit for bit;

each raw chunk gives back its bytes, its runtime time and its UTC time; the
map fixes validate against Foxglove's ``LocationFix`` schema.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import dataclasses
import enum
import json
import math
import tempfile
import types
import typing
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import orjson
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import zarco_core.auv_messages
import zarco_core.messages
from drivers.nmea_device import DeviceLink
from drivers.settings import Device
from drivers.transports import memory_link
from zarco_core.bus import Bus
from zarco_core.clock import Clock, run_virtual
from zarco_runtime.guidance.directive import Directive, ManualThrust
from zarco_runtime.links.recorder.recorder import Recorder
from zarco_runtime.links.recorder.schema import OPTIONS, json_default
from zarco_runtime.settings import RuntimeConfig
from zarco_tools.log.reader import iter_messages, open_recording
from zarco_tools.simulation import SimTruth

#: every message dataclass of the bus (and the nested ones, recorded alone too)
KINDS: list[type] = sorted(
    {c for m in (zarco_core.messages, zarco_core.auv_messages)
     for c in vars(m).values()
     if isinstance(c, type) and dataclasses.is_dataclass(c) and c.__module__ == m.__name__}
    | {Directive, ManualThrust, SimTruth}, key=lambda c: c.__name__)

UTC_OFFSET_S = 1.7e9
INT64 = st.integers(-(2 ** 63), 2 ** 63 - 1)
FLOATS = st.floats() | st.floats().map(np.float64) | st.sampled_from(
    [math.nan, math.inf, -math.inf, -0.0, 5e-324, 1.7976931348623157e308, 0.1])
TEXT = st.text(max_size=12) | st.sampled_from(["a\nb", "é✓", "\"\\", ""])
ANY = st.none() | st.booleans() | INT64 | FLOATS | TEXT


def strategy(tp: Any, name: str = "") -> st.SearchStrategy[Any]:
    """Values of type ``tp`` (a field's type hint); a field ``t`` is a runtime time."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return st.one_of([st.none() if a is type(None) else strategy(a) for a in args])
    if name == "t":
        return st.floats(0.0, 1e6)
    if tp is bool:
        return st.booleans()
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return st.sampled_from(list(tp))
    if tp is int:
        return INT64
    if tp is float:
        return FLOATS
    if tp is str:
        return TEXT
    if tp in (bytes, bytearray):
        return st.binary(max_size=40)
    if origin in (tuple, list):
        if origin is tuple and args and args[-1] is not Ellipsis:
            return st.tuples(*(strategy(a) for a in args))
        inner = strategy(args[0]) if args else ANY
        return st.lists(inner, max_size=30).map(tuple if origin is tuple else list)
    if origin is dict:
        k, v = args if args else (str, object)
        return st.dictionaries(strategy(k), strategy(v), max_size=4)
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        hints = typing.get_type_hints(tp)
        return st.builds(tp, **{f.name: strategy(hints[f.name], f.name)
                                for f in dataclasses.fields(tp) if f.init})
    return ANY


def nullable(schema: Any) -> Any:
    """``schema`` with null allowed wherever a value is (None, NaN, infinity)."""
    if not isinstance(schema, dict):
        return schema
    out = dict(schema)
    if isinstance(schema.get("properties"), dict):
        out["properties"] = {k: nullable(v) for k, v in schema["properties"].items()}
    for key in ("items", "additionalProperties"):
        if isinstance(schema.get(key), dict):
            out[key] = nullable(schema[key])
    if "type" in schema or "oneOf" in schema:
        return {"anyOf": [out, {"type": "null"}]}
    return out


def reference(msg: Any) -> Any:
    """The message as an independent encoder writes it (orjson), read back."""
    return orjson.loads(orjson.dumps(msg, default=json_default,
                                     option=OPTIONS | orjson.OPT_SERIALIZE_NUMPY))


def same(a: Any, b: Any) -> bool:
    """Equal JSON values, floats bit for bit (-0.0 is not 0.0)."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and bool(a == b)


def record(path: Path, msgs: list[Any], chunks: list[tuple[str, bytes]]) -> Recorder:
    """Publish ``msgs`` and read ``chunks`` (device, bytes) through real drivers'
    links, with the recorder and its writer process running."""
    cfg = RuntimeConfig()
    cfg.record.file = str(path)
    bus = Bus()
    clock = Clock(utc_offset_s=UTC_OFFSET_S)
    links = {d: DeviceLink(d, Device(url=f"sim://{d}"), bus, clock) for d in ("gps", "compass")}

    async def main() -> Recorder:
        rec = Recorder(cfg, bus, clock, devices=lambda: list(links.values()))
        task = asyncio.create_task(rec.run())
        ends = {d: memory_link(d) for d in links}
        await asyncio.sleep(0.1)
        for m in msgs:
            bus.publish(m)
        for dev, data in chunks:
            await asyncio.sleep(0.01)
            ends[dev][0].write_nowait(data)
            got = await links[dev].read_or_reopen(ends[dev][1])  # the driver's read
            assert got == data
        await asyncio.sleep(5.0)
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        return rec

    return run_virtual(main())


@settings(max_examples=4, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.large_base_example])
@given(st.data())
def test_recorded_json_is_what_the_schemas_describe(data: st.DataObject) -> None:
    msgs = [m for kind in KINDS for m in data.draw(st.lists(strategy(kind), min_size=1,
                                                            max_size=3), label=kind.__name__)]
    chunks = data.draw(st.lists(st.tuples(st.sampled_from(["gps", "compass"]),
                                          st.binary(min_size=1, max_size=64)), max_size=12))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "enc.mcap"
        rec = record(path, msgs, chunks)
        rf = open_recording(str(path))
        got = list(iter_messages(rf))
        assert all(rf.finished.values()) and not rf.truncated
        assert rec.counters["salvaged"] == 0
        schemas = _schemas(path)
    by_topic: dict[str, list[Any]] = {}
    for m in got:
        doc = m.json()
        jsonschema.validate(doc, nullable(schemas[m.topic]))  # the schema's shape
        by_topic.setdefault(m.topic, []).append((m.log_ns, doc))
    # every message, in order of publication, the same values as orjson's
    for kind in KINDS:
        sent = [reference(m) for m in msgs if type(m) is kind]
        recorded = [doc for _ns, doc in by_topic.get(f"/{kind.__name__}", [])]
        assert len(recorded) == len(sent), kind
        for a, b in zip(recorded, sent, strict=True):
            assert same(a, b), (kind.__name__, a, b)
        # logged at the message's own time (UTC)
        for (ns, doc), m in zip(by_topic.get(f"/{kind.__name__}", []),
                                [m for m in msgs if type(m) is kind], strict=True):
            if "t" in doc:
                assert ns == int((m.t + UTC_OFFSET_S) * 1e9)
    # raw chunks: the bytes, in order, with their runtime and UTC times
    for dev in ("gps", "compass"):
        docs = [doc for _ns, doc in by_topic.get(f"/raw/{dev}/rx", [])]
        assert [base64.b64decode(x["data"]) for x in docs] == [c for k, c in chunks if k == dev]
        for x in docs:
            assert x["device"] == dev and x["dir"] == "rx"
            assert x["utc_s"] == x["t"] + UTC_OFFSET_S
    # the map: a fix for the first vessel estimate published, when it is valid (the
    # map's rate gate starts at the first estimate recorded, valid or not)
    navs = [m for m in msgs if type(m).__name__ == "NavState"]
    if navs and navs[0].pos_valid and math.isfinite(navs[0].lat_deg) \
            and math.isfinite(navs[0].lon_deg):
        assert by_topic.get("/foxglove/vessel")


def _schemas(path: Path) -> dict[str, Any]:
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    return {ch.topic: json.loads(summary.schemas[ch.schema_id].data)
            for ch in summary.channels.values()}


def test_odd_messages_are_kept_not_lost(tmp_path: Path) -> None:
    """A value MessagePack cannot carry (an integer beyond 64 bits), a dict keyed by
    tuples, a message without a time or with one no clock has: each is recorded
    (the integer as its digits, the key as its repr, the time as the previous
    record's), and the run goes on."""

    @dataclasses.dataclass(slots=True)
    class Odd:
        t: Any
        big: int
        keyed: dict[Any, int]

    @dataclasses.dataclass(slots=True)
    class Timeless:
        v: float

    msgs = [Odd(1.0, 2 ** 70, {(1, 2): 3}), Timeless(0.5), Odd(math.nan, 1, {}),
            Odd(-1e300, 2, {}), Odd(1e300, 3, {}), Odd(None, 4, {}), Odd(2.0, 5, {(3,): 6})]
    rec = record(tmp_path / "odd.mcap", msgs, [])
    got = [(m.topic, m.log_ns, m.json())
           for m in iter_messages(open_recording(str(tmp_path / "odd.mcap")))]
    odd = [g for g in got if g[0] == "/Odd"]
    assert [g[2]["big"] for g in odd] == [str(2 ** 70), 1, 2, 3, 4, 5]
    assert odd[0][2]["keyed"] == {"(1, 2)": 3}  # the runtime's packer refused it
    assert odd[-1][2]["keyed"] == {"(3,)": 6}  # packed; the writer's JSON refused it
    t1 = int((1.0 + UTC_OFFSET_S) * 1e9)
    assert [g[1] for g in odd] == [t1] * 5 + [int((2.0 + UTC_OFFSET_S) * 1e9)]
    assert [g[2] for g in got if g[0] == "/Timeless"] == [{"v": 0.5}]
    assert rec.counters["salvaged"] == 1
