"""The typed, bounded command schema (zarco_core.commands): what decodes, what is
refused, with which field and reason, and that no payload gets anything but a
typed struct or a refusal (never another exception), cheaply."""

from __future__ import annotations

import json
import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zarco_core.commands import (
    MAX_PAYLOAD_BYTES,
    MAX_POINTS,
    SCHEMAS,
    CommandRefused,
    MissionArgs,
    ModeArgs,
    ParamArgs,
    StopArgs,
    ThrustArgs,
    decode,
    nesting_ok,
    to_json,
)
from zarco_core.modes import Mode

lat = st.floats(-90.0, 90.0, allow_nan=False)
lon = st.floats(-180.0, 180.0, allow_nan=False)
point = st.tuples(lat, lon)


def _refused(name: str, payload: Any) -> CommandRefused:
    with pytest.raises(CommandRefused) as exc:
        decode(name, payload)
    return exc.value


@given(st.floats(-100.0, 100.0), st.floats(-100.0, 100.0))
def test_thrust_within_range_decodes_as_sent_raw_and_parsed(u1: float, u2: float) -> None:
    raw = json.dumps({"u1": u1, "u2": u2})
    for payload in (raw, raw.encode(), {"u1": u1, "u2": u2}):
        a = decode("thrust", payload)
        assert isinstance(a, ThrustArgs) and (a.u1, a.u2) == (u1, u2)


@given(st.one_of(st.floats(100.0, 1e300, exclude_min=True),
                 st.floats(-1e300, -100.0, exclude_max=True)))
def test_thrust_beyond_range_is_refused_naming_the_field(u: float) -> None:
    e = _refused("thrust", {"u1": 0.0, "u2": u})
    assert e.field == "u2" and "must be" in e.reason


@pytest.mark.parametrize("bad, why", [
    ("1" + "0" * 400, "number out of range"),        # an integer beyond float range
    ("1e999", "number out of range"),
    ('" 1e2 "', "must be a number, got text"),
    ('"100"', "must be a number, got text"),
    ("true", "must be a number, got true or false"),
    ("null", "must be a number, got null"),
    ("[1]", "must be a number, got a list"),
    ("NaN", "not JSON"),
    ("Infinity", "not JSON"),
])
def test_numbers_are_finite_json_numbers(bad: str, why: str) -> None:
    e = _refused("thrust", f'{{"u1": {bad}, "u2": 0}}')
    assert why in str(e)
    if "JSON" not in why:
        assert e.field == "u1"


@pytest.mark.parametrize("v", [math.nan, math.inf, -math.inf, 10 ** 401, True, "1", None])
def test_parsed_numbers_must_be_finite_numbers_too(v: Any) -> None:
    e = _refused("thrust", {"u1": v, "u2": 0.0})
    assert e.field == "u1"


@pytest.mark.parametrize("v", ['"false"', '"no"', "0", "1", "null", '"true"'])
def test_booleans_are_booleans(v: str) -> None:
    e = _refused("mission", f'{{"waypoints": [[1, 2], [1.1, 2]], "start": {v}}}')
    assert e.field == "start"


def test_mission_name_is_bounded_and_printable() -> None:
    wps = [[41.0, -8.0], [41.001, -8.0]]
    assert isinstance(decode("mission", {"waypoints": wps, "name": "x" * 64}), MissionArgs)
    assert _refused("mission", {"waypoints": wps, "name": "x" * 65}).field == "name"
    e = _refused("mission", {"waypoints": wps, "name": "survey\x1b[2J"})
    assert e.field == "name" and "printable" in e.reason
    assert _refused("mission", {"waypoints": wps, "name": "a" * 60_000}).field == "name"


@given(st.lists(point, min_size=2, max_size=40), st.booleans(),
       st.floats(0.05, 3.0))
def test_mission_round_trips(wps: list[tuple[float, float]], start: bool, speed: float) -> None:
    payload = {"waypoints": [list(w) for w in wps], "speed_mps": speed, "start": start,
               "start_leg": len(wps) - 2, "leg_speeds_mps": [speed] * (len(wps) - 1)}
    a = decode("mission", json.dumps(payload))
    assert isinstance(a, MissionArgs)
    assert a.waypoints == wps and a.start is start and a.speed_mps == speed
    assert decode("mission", to_json(a)) == a  # what the recording keeps decodes again


@given(st.integers(0, 3), lat.filter(lambda x: abs(x) > 0), st.sampled_from([0, 1]))
def test_a_waypoint_out_of_range_is_named_by_its_index(i: int, off: float, k: int) -> None:
    wps = [[41.0, -8.0]] * 4
    bad = list(wps[i])
    bad[k] = (91.0 if k == 0 else 181.0) * math.copysign(1.0, off)
    wps = [*wps[:i], bad, *wps[i + 1:]]
    e = _refused("mission", {"waypoints": wps})
    assert e.field == f"waypoints[{i}][{k}]"


def test_lists_are_bounded() -> None:
    wps = [[41.0, -8.0 + 1e-4 * i] for i in range(MAX_POINTS + 1)]
    e = _refused("mission", {"waypoints": wps})
    assert e.field == "waypoints" and str(MAX_POINTS) in e.reason
    assert isinstance(decode("mission", {"waypoints": wps[:MAX_POINTS]}), MissionArgs)
    assert _refused("follow", {"auv_plan": wps}).field == "auv_plan"
    e = _refused("mission", {"waypoints": wps[:3], "leg_speeds_mps": [1.0]})
    assert e.field == "leg_speeds_mps"
    e = _refused("mission", {"waypoints": wps[:3], "start_leg": 2})
    assert e.field == "start_leg"
    assert _refused("mission", {"waypoints": wps[:1]}).field == "waypoints"


@pytest.mark.parametrize("payload", [
    b"[" * 30000, b"{" * 30000, b'{"waypoints": ' + b"[" * 30000,
    b'{"name": "x", "extra": ' + b"[" * 30000 + b"]" * 30000 + b"}",
    b'{"waypoints": [[' + b"[" * 30000 + b"]" * 30000 + b", 1]]}",
])
def test_deep_nesting_is_refused_cheaply(payload: bytes) -> None:
    for name in ("mission", "mode", "param", "follow"):
        e = _refused(name, payload)
        # refused by the count on the raw bytes (a few C-speed passes), before
        # any decoding: no recursion, whatever the nesting
        assert e.field == "" and e.reason == "not JSON, or nested deeper than 8 levels"


def test_payload_size_is_bounded() -> None:
    big = b'{"name": "' + b"x" * MAX_PAYLOAD_BYTES + b'"}'
    e = _refused("mission", big)
    assert e.field == "" and "larger than" in e.reason


def test_unknown_fields_and_commands_are_refused() -> None:
    assert _refused("thrust", {"u1": 0, "u2": 0, "u3": 1}).field == "u3"
    e = _refused("warp", {})
    assert e.reason.startswith("unknown command 'warp'")
    assert "'" + "w" * 64 + "'" in str(_refused("w" * 1000, {}))  # the name shown is bounded
    assert _refused("mode", {"mode": "sideways"}).field == "mode"
    assert _refused("thrust", {"u1": 1}).field == "u2"  # missing


@pytest.mark.parametrize("key", ["\x1b[2J\x1b[31mred", "a\nb", "\u2028x", "\x00", "\x9b31m"])
def test_a_refusal_never_carries_control_characters(key: str) -> None:
    """An unknown field's name is shown in the refusal, escaped: the refusal goes
    to terminals (``zarco ctl``, ``zarco shore``) and to the event stream."""
    for payload in (json.dumps({"mode": "hold", key: 1}), {"mode": "hold", key: 1}):
        e = _refused("mode", payload)
        assert e.reason == "unknown field" and str(e).isprintable()
        assert e.field == key.encode("unicode_escape").decode("ascii")


def test_stop_is_always_a_stop() -> None:
    for payload in (None, b"", b"{}", b"not json", b"[" * 30000, {"x": 1}, "\xff"):
        assert decode("stop", payload) == StopArgs()


def test_mode_point_both_or_neither_and_only_for_hold() -> None:
    a = decode("mode", {"mode": "hold", "lat_deg": 41.0, "lon_deg": -8.0})
    assert isinstance(a, ModeArgs) and a.mode is Mode.HOLD and a.lat_deg == 41.0
    assert "both or neither" in str(_refused("mode", {"mode": "hold", "lat_deg": 41.0}))
    assert "for mode hold" in str(_refused("mode", {"mode": "lines", "lat_deg": 41.0,
                                                     "lon_deg": -8.0}))


@given(st.one_of(st.floats(-1e12, 1e12), st.booleans(),
                 st.text(st.characters(codec="utf-8", categories=["L", "N"]), max_size=64)))
def test_param_values(v: Any) -> None:
    a = decode("param", {"name": "failsafe.link_lost_s", "value": v})
    assert isinstance(a, ParamArgs) and a.value == v and type(a.value) is type(v)


@pytest.mark.parametrize("name", ["", "x", "failsafe", "Failsafe.link", "a.b c",
                                  "failsafe.link_lost_s" * 4, "../x.y"])
def test_param_names_are_dotted_keys(name: str) -> None:
    assert _refused("param", {"name": name, "value": 1.0}).field == "name"


@settings(max_examples=300)
@given(st.sampled_from(sorted(SCHEMAS)), st.one_of(
    st.binary(max_size=200),
    st.text(max_size=200),
    st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
                 lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=12), c,
                                                                    max_size=4),
                 max_leaves=20),
))
def test_any_payload_is_a_command_or_a_refusal(name: str, payload: Any) -> None:
    try:
        a = decode(name, payload)
    except CommandRefused as exc:
        assert str(exc) and str(exc).isprintable()
        return
    assert type(a) is SCHEMAS[name]


def _depth(v: Any) -> int:
    if isinstance(v, dict):
        return 1 + max(map(_depth, v.values()), default=0)
    if isinstance(v, list):
        return 1 + max(map(_depth, v), default=0)
    return 0


@settings(max_examples=300)
@given(st.recursive(st.none() | st.integers() | st.text(alphabet='[]{}"\\ ab', max_size=6),
                    lambda c: st.lists(c, max_size=3)
                    | st.dictionaries(st.text(alphabet='[]{}"\\ ab', max_size=4), c,
                                      max_size=3),
                    max_leaves=25),
       st.integers(1, 10))
def test_nesting_is_counted_as_json_nests(v: Any, limit: int) -> None:
    """The bytes-level count agrees with the parsed value's depth, brackets inside
    strings (escaped quotes included) not counted, ``{[]}`` two levels."""
    raw = json.dumps(v).encode()
    assert nesting_ok(raw, limit) == (_depth(v) <= limit)
    assert not nesting_ok(raw + b"]", 100)  # unmatched
