"""Property test of the shore link's inputs: every command, heartbeat and RTCM
path driven with generated payloads (valid, near-valid, hostile) over a real
zenoh session on loopback, against the real runtime (``zarco sim --realtime``
in its own process, recorded).

Properties: every query gets exactly one reply, a JSON object
``{"ok": bool, "id", "mode", "reason": str}``; no component restarts and the
link counts no fault; every thruster command the runtime published (read back
from its MCAP recording) is a finite number within −100..100."""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import zenoh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shore_support import Boat, connect_when_up, free_port

from drivers.rtcm import frame
from zarco_runtime.links.shore.zenoh_config import client_config
from zarco_tools.log.reader import iter_messages, open_recording

VESSEL = "prop"
COMMANDS = ["stop", "arm", "disarm", "param", "mode", "mission", "follow", "thrust", "resume"]

# ---------------------------------------------------------------- strategies

numbers = st.one_of(
    st.floats(-150.0, 150.0),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10 ** 30), 10 ** 30),
    st.just(10 ** 400), st.just(-(10 ** 400)),
    st.sampled_from(["1e2", " 1e2 ", "false", "", "NaN", True, False, None]),
)
json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=40),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                 max_size=4),
    max_leaves=12)
points = st.lists(st.lists(numbers, min_size=2, max_size=3), max_size=5)
near_origin = st.lists(st.tuples(st.floats(41.184, 41.187), st.floats(-8.708, -8.703))
                       .map(list), min_size=2, max_size=4)


def _fields(name: str) -> st.SearchStrategy[dict[str, Any]]:
    """Arguments shaped like the command's, with values valid, near-valid or not."""
    if name == "thrust":
        return st.fixed_dictionaries({"u1": numbers, "u2": numbers})
    if name == "mode":
        return st.fixed_dictionaries(
            {"mode": st.sampled_from(["idle", "manual", "hold", "lines", "follow", "return",
                                      "sideways", "HOLD", 1])},
            optional={"lat_deg": numbers, "lon_deg": numbers})
    if name == "mission":
        return st.fixed_dictionaries(
            {"waypoints": near_origin | points},
            optional={"speed_mps": numbers, "start": st.sampled_from(
                [True, False, "false", "no", 0, 1]), "name": st.text(max_size=80),
                "start_leg": numbers})
    if name == "param":
        return st.fixed_dictionaries(
            {"name": st.sampled_from(["failsafe.link_lost_s", "failsafe.link_lost",
                                      "failsafe.clear_after_s", "mission.speed_mps",
                                      "geofence.enabled", "nope", "x" * 80]),
             "value": numbers | json_values})
    if name == "follow":
        return st.fixed_dictionaries({}, optional={"auv_plan": near_origin | points})
    return st.just({}) | st.dictionaries(st.text(max_size=8), json_values, max_size=3)


def _encode(obj: Any) -> bytes:
    # Python's json writes NaN and Infinity: not JSON, as a careless client sends
    return json.dumps(obj).encode()


hostile = st.one_of(
    st.binary(max_size=64),
    st.integers(1, 40000).map(lambda n: b"[" * n),
    st.integers(1, 5000).map(lambda n: b'{"a":' * n),
    st.just(b'{"x": "' + b"a" * 70000 + b'"}'),
    st.just(b"\xff\xfe{}"),
    json_values.map(_encode),
)


@st.composite
def command(draw: st.DrawFn) -> tuple[str, str, bytes, bytes | None]:
    name = draw(st.sampled_from(COMMANDS) | st.sampled_from(["fly", "Stop", "a_b", "x" * 40]))
    if name in COMMANDS and draw(st.booleans()):
        payload = _encode(draw(_fields(name)))
    else:
        payload = draw(hostile | st.just(b"") | st.just(b"{}"))
    att = draw(st.none() | st.just({"user": "alice", "id": "x"}).map(_encode)
               | st.fixed_dictionaries({"user": st.text(max_size=70) | numbers,
                                        "id": st.text(max_size=70) | numbers}).map(_encode)
               | hostile)
    return ("cmd", name, payload, att)


heartbeat = st.one_of(
    st.fixed_dictionaries({"t": numbers, "user": st.text(max_size=70) | numbers}).map(_encode),
    hostile,
).map(lambda b: ("hb", "", b, None))

_F = frame(bytes((0x3E, 0xD0)) + bytes(20))
rtcm = st.one_of(
    st.binary(max_size=2048),
    st.lists(st.sampled_from([_F, _F[:-1] + b"\x00", b"\xd3\x03\xff", bytes(30)]),
             max_size=20).map(b"".join),
    st.just(b"\xd3\x03" * 9000),
).map(lambda b: ("rtcm", "", b, None))

actions = st.lists(command() | heartbeat | rtcm, min_size=2, max_size=10)

# --------------------------------------------------------------------- boat


@pytest.fixture(scope="module")
def boat(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    tmp = tmp_path_factory.mktemp("shore-property")
    ep = f"tcp/127.0.0.1:{free_port()}"
    rec = tmp / "run.mcap"
    b = Boat([f'runtime.shore.listen=["{ep}"]', f"runtime.shore.vessel={VESSEL}",
              "runtime.shore.commands_per_s=1000"],
             log=tmp / "boat.log", extra_args=["--record", str(rec)])
    b.start()
    try:
        s = connect_when_up(lambda: zenoh.open(zenoh.Config.from_json5(
            json.dumps(client_config(ep)))), 60.0)
        health: dict[str, Any] = {}
        s.declare_subscriber(f"zarco/{VESSEL}/health",
                             lambda smp: health.update(json.loads(smp.payload.to_bytes())))
        deadline = time.monotonic() + 60.0
        while not health and time.monotonic() < deadline:
            time.sleep(0.1)
        assert health, "no health from the boat"
        yield {"session": s, "health": health, "boat": b, "record": rec}
        s.close()
    finally:
        assert b.stop() == 0


def _drive(s: Any, items: list[tuple[str, str, bytes, bytes | None]]) -> None:
    """Send ``items`` at once; every query must get exactly one well-formed reply."""
    replies: list[list[Any]] = [[] for _ in items]
    lock = threading.Lock()
    for i, (kind, name, payload, att) in enumerate(items):
        if kind == "cmd":
            def cb(r: Any, i: int = i) -> None:
                with lock:
                    replies[i].append(r)
            kw: dict[str, Any] = {"attachment": att} if att is not None else {}
            s.get(f"zarco/{VESSEL}/cmd/{name}", cb, payload=payload, timeout=10.0, **kw)
        else:
            s.put(f"zarco/{VESSEL}/{'operator' if kind == 'hb' else 'rtcm'}", payload)
    queries = [i for i, it in enumerate(items) if it[0] == "cmd"]
    deadline = time.monotonic() + 12.0
    while time.monotonic() < deadline:
        with lock:
            if all(replies[i] for i in queries):
                break
        time.sleep(0.01)
    time.sleep(0.05)  # a second reply would be here by now
    for i in queries:
        got = replies[i]
        assert len(got) == 1, (items[i][:2], items[i][2][:80], got)
        assert got[0].ok is not None, got[0].err.payload.to_bytes()
        body = json.loads(got[0].ok.payload.to_bytes())
        assert set(body) == {"ok", "id", "mode", "reason"}, body
        assert isinstance(body["ok"], bool) and isinstance(body["reason"], str), body
        if not body["ok"]:
            assert body["reason"], body


def test_every_input_one_reply_no_restart_finite_thrust(boat: dict[str, Any]) -> None:
    s = boat["session"]

    @settings(max_examples=200, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(items=actions, manual=st.booleans())
    def one_reply_each(items: list[tuple[str, str, bytes, bytes | None]], manual: bool
                       ) -> None:
        if manual:  # armed and in manual mode: the thrust paths go all the way
            for name, payload in (("arm", "{}"), ("mode", '{"mode": "manual"}')):
                assert len(list(s.get(f"zarco/{VESSEL}/cmd/{name}", payload=payload,
                                      timeout=10.0))) == 1
        _drive(s, items)

    one_reply_each()
    time.sleep(1.5)  # the next health after the last input
    h = boat["health"]
    assert {n: c["restarts"] for n, c in h["components"].items() if c["restarts"]} == {}
    assert h["link"].get("faults", 0) == 0, h["link"]
    assert h["link"].get("commands", 0) > 150, h["link"]  # the inputs did reach the link
    b: Boat = boat["boat"]
    assert b.stop() == 0
    rec = open_recording(str(boat["record"]))
    n = 0
    for m in iter_messages(rec, {"/ThrusterCommand"}):
        d = m.json()
        for k in ("u1", "u2"):
            u = d[k]
            assert isinstance(u, (int, float)) and math.isfinite(u) and -100 <= u <= 100, d
        n += 1
    assert n > 100
