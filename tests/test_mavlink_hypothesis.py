"""Property test of the MAVLink endpoint: generated messages from a ground
station into a running boat (``zarco sim --realtime``, recorded), valid and
not — commands (COMMAND_LONG, COMMAND_INT, SET_MODE), parameter writes,
mission uploads, joystick, RTCM fragments; any parameter a float32 can be,
NaN and infinities included; addressed to the boat, to every system, to the
AUV's system or to another.  For every message:

* a command addressed to the boat (or to every system) gets exactly one
  COMMAND_ACK from the boat; one addressed to the AUV's system exactly one
  COMMAND_ACK DENIED from the AUV's; one addressed elsewhere none;
* a mission upload gets exactly one MISSION_ACK; a parameter write of a known
  parameter exactly one PARAM_VALUE;

and over the whole run, read back from the MCAP recording with mcap's reader:
no component failed or restarted, and every thruster command was finite and
within −100..100 (%) — also the bytes the thruster driver wrote.  The boat
ends with exit 0 and no traceback."""

from __future__ import annotations

import base64
import json
import math
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mavlink_support import Gcs
from mcap.reader import make_reader
from pymavlink.dialects.v20 import common as mav

from zarco_runtime.links.mavlink.params import TABLE

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "config" / "scenarios" / "rectangle.toml"
BOAT, COMP, AUV, OTHER = 1, 1, 2, 77
#: how long a reply may take (s; generous: the machine is shared)
REPLY_S = 5.0
#: after an example, how long an extra reply is waited for (s)
QUIET_S = 0.3

f32 = st.floats(width=32)  # NaN and ±inf included
u8, u16 = st.integers(0, 255), st.integers(0, 65535)
i16, i32 = st.integers(-32768, 32767), st.integers(-2**31, 2**31 - 1)
targets = st.sampled_from([0, BOAT, BOAT, BOAT, AUV, OTHER])
components = st.sampled_from([0, COMP, COMP, 5])
COMMANDS = [mav.MAV_CMD_COMPONENT_ARM_DISARM, mav.MAV_CMD_DO_SET_MODE,
            mav.MAV_CMD_MISSION_START, mav.MAV_CMD_NAV_RETURN_TO_LAUNCH,
            mav.MAV_CMD_NAV_LOITER_UNLIM, mav.MAV_CMD_DO_REPOSITION, mav.MAV_CMD_REQUEST_MESSAGE,
            mav.MAV_CMD_SET_MESSAGE_INTERVAL, mav.MAV_CMD_GET_MESSAGE_INTERVAL,
            mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES]
command_ids = st.one_of(st.sampled_from(COMMANDS), u16)
#: parameters that mean something to some command, and anything else
params = st.one_of(st.sampled_from([0.0, 1.0, 4.0, 5.0, 10.0, 11.0, 0.0, 33.0, 24.0, 1e6]),
                   f32)
custom_modes = st.one_of(st.sampled_from([0, 4, 5, 6, 10, 11]), st.integers(0, 2**32 - 1))
param_ids = st.one_of(st.sampled_from([name for name, _ in TABLE]),
                      st.text(st.characters(codec="ascii"), max_size=16))


@dataclass(frozen=True)
class Msg:
    kind: str
    args: tuple[Any, ...]


def commands_long() -> Any:
    return st.builds(lambda t, c, cmd, p: Msg("command_long", (t, c, cmd, *p)),
                     targets, components, command_ids, st.tuples(*[params] * 7))


def commands_int() -> Any:
    return st.builds(lambda t, c, cmd, fr, p, x, y, z: Msg("command_int",
                                                           (t, c, fr, cmd, *p, x, y, z)),
                     targets, components, command_ids, u8, st.tuples(*[params] * 4), i32, i32,
                     f32)


def set_modes() -> Any:
    return st.builds(lambda t, b, m: Msg("set_mode", (t, b, m)), targets, u8, custom_modes)


def param_sets() -> Any:
    return st.builds(lambda t, c, name, v, ty: Msg("param_set", (t, c, name, v, ty)),
                     targets, components, param_ids, params, u8)


def items() -> Any:
    frames = st.sampled_from([mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mav.MAV_FRAME_GLOBAL_INT,
                              mav.MAV_FRAME_MISSION, mav.MAV_FRAME_LOCAL_NED])
    cmds = st.one_of(st.sampled_from([mav.MAV_CMD_NAV_WAYPOINT, mav.MAV_CMD_DO_CHANGE_SPEED]),
                     u16)
    # near the simulated boat (41.185 N, 8.705 W), or anywhere an int32 reaches
    lat = st.one_of(st.integers(411_840_000, 411_860_000), i32)
    lon = st.one_of(st.integers(-87_060_000, -87_040_000), i32)
    return st.tuples(frames, cmds, st.tuples(*[params] * 4), lat, lon, f32)


def missions() -> Any:
    return st.builds(lambda t, c, its: Msg("mission", (t, c, its)), targets, components,
                     st.lists(items(), max_size=5))


def manuals() -> Any:
    return st.builds(lambda t, x, y, z, r: Msg("manual", (t, x, y, z, r)),
                     st.sampled_from([0, BOAT, AUV]), i16, i16, i16, i16)


def rtcm() -> Any:
    return st.builds(lambda fl, n, data: Msg("rtcm", (fl, n, data)), u8, u8,
                     st.binary(min_size=180, max_size=180))


def drives() -> Any:
    """What an operator does to move the boat: arm, a moving mode (manual, hold
    here or at a point near it, return), then the joystick, whatever its axes."""
    def make(mode: int, point: tuple[float, float] | None, joys: list[tuple[int, ...]]
             ) -> list[Msg]:
        arm = Msg("command_long", (BOAT, COMP, mav.MAV_CMD_COMPONENT_ARM_DISARM,
                                   1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        if point is not None:
            go = Msg("command_long", (BOAT, COMP, mav.MAV_CMD_NAV_LOITER_UNLIM, 0.0, 0.0,
                                      0.0, 0.0, point[0], point[1], 0.0))
        else:
            go = Msg("command_long", (BOAT, COMP, mav.MAV_CMD_DO_SET_MODE, 1.0, float(mode),
                                      0.0, 0.0, 0.0, 0.0, 0.0))
        return [arm, go, *[Msg("manual", (BOAT, *j)) for j in joys]]

    near = st.tuples(st.floats(41.1845, 41.1855), st.floats(-8.7055, -8.7045))
    return st.builds(make, st.sampled_from([0, 0, 5, 11]), st.one_of(st.none(), near),
                     st.lists(st.tuples(i16, i16, i16, i16), max_size=12))


def single(s: Any) -> Any:
    return s.map(lambda m: [m])


messages = st.lists(st.one_of(single(commands_long()), single(commands_int()),
                              single(set_modes()), single(param_sets()), single(missions()),
                              single(manuals()), single(rtcm()), drives()),
                    min_size=1, max_size=6).map(lambda xs: [m for x in xs for m in x])


def start_boat(url: str, record: Path) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "zarco_runtime.cli", "sim", str(SCENARIO), "--realtime",
           "-q", "--record", str(record), "--set", 'mission.kind="idle"',
           "--set", "scenario.max_duration_s=900",
           "--set", "runtime.mavlink.enabled=true", "--set", f'runtime.mavlink.url="{url}"']
    return subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def replies(gcs: Gcs, cond: Any, seconds: float) -> list[Any]:
    return [m for m in gcs.collect(seconds) if cond(m)]


def is_ack(m: Any, cmd: int) -> bool:
    return bool(m.get_type() == "COMMAND_ACK" and m.command == cmd and m.target_system == 255)


def send_and_check(gcs: Gcs, msg: Msg) -> None:
    """Send ``msg``; assert the replies it must get (and no more)."""
    g = gcs.mav
    a = msg.args
    if msg.kind in ("command_long", "command_int", "set_mode"):
        if msg.kind == "set_mode":
            target, comp, cmd = a[0], 0, mav.MAVLINK_MSG_ID_SET_MODE
            g.set_mode_send(*a)
        else:
            target, comp = a[0], a[1]
            cmd = a[2] if msg.kind == "command_long" else a[3]
            if msg.kind == "command_long":
                g.command_long_send(a[0], a[1], a[2], 0, *a[3:])
            else:
                g.command_int_send(*a[:4], 0, 0, *a[4:])
        ours = target in (0, BOAT) and comp in (0, COMP)
        if target == AUV:
            ack = gcs.wait(lambda m: is_ack(m, cmd), REPLY_S)
            assert ack.get_srcSystem() == AUV and ack.result == mav.MAV_RESULT_DENIED
        elif ours:
            ack = gcs.wait(lambda m: is_ack(m, cmd), REPLY_S)
            assert ack.get_srcSystem() == BOAT, ack
        more = replies(gcs, lambda m: is_ack(m, cmd), QUIET_S)
        assert more == [], (msg, more)
    elif msg.kind == "param_set":
        target, comp, name, value, ptype = a
        g.param_set_send(target, comp, name.encode("ascii"), value, ptype)
        known = name in {n for n, _ in TABLE}
        if known and target in (0, BOAT) and comp in (0, COMP):
            pv = gcs.wait(lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name,
                          REPLY_S)
            assert math.isfinite(pv.param_value)
        more = replies(gcs, lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name,
                       QUIET_S)
        assert more == [], (msg, more)
    elif msg.kind == "mission":
        target, comp, its = a
        g.mission_count_send(target, comp, len(its), mav.MAV_MISSION_TYPE_MISSION)
        expect = (target in (0, BOAT) and comp in (0, COMP)) or target == AUV
        if expect:
            while True:
                m = gcs.wait(lambda m: m.get_type() in ("MISSION_ACK", "MISSION_REQUEST_INT")
                             and m.target_system == 255, REPLY_S)
                if m.get_type() == "MISSION_ACK":
                    break
                fr, cmd, p, x, y, z = its[m.seq]
                g.mission_item_int_send(target, comp, m.seq, fr, cmd, 0, 1, *p, x, y, z,
                                        mav.MAV_MISSION_TYPE_MISSION)
            assert (m.get_srcSystem() == AUV) == (target == AUV)
        more = replies(gcs, lambda m: m.get_type() == "MISSION_ACK", QUIET_S)
        assert more == [], (msg, more)
    elif msg.kind == "manual":
        g.manual_control_send(*a, 0)
    elif msg.kind == "rtcm":
        fl, n, data = a
        g.gps_rtcm_data_send(fl, n, list(data))


def recorded(path: Path, topics: set[str]) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {t: [] for t in topics}
    with path.open("rb") as fh:
        for _, channel, message in make_reader(fh).iter_messages(topics=list(topics)):
            out[channel.topic].append(json.loads(message.data))
    return out


def test_generated_mavlink_gets_one_reply_each_and_never_unsafe_thrust(tmp_path: Path) -> None:
    gcs = Gcs()
    rec = tmp_path / "run.mcap"
    boat = start_boat(gcs.url, rec)
    sent = {"messages": 0}
    try:
        gcs.wait(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcSystem() == BOAT, 30.0)
        gcs.wait(lambda m: m.get_type() == "GPS_RAW_INT" and m.fix_type >= 3, 20.0)

        @settings(max_examples=int(os.environ.get("ZARCO_MAVLINK_EXAMPLES", "60")),
                  deadline=None, derandomize=False,
                  suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
        @given(messages)
        def one_batch(batch: list[Msg]) -> None:
            assert boat.poll() is None, "the boat ended"
            for msg in batch:
                send_and_check(gcs, msg)
                sent["messages"] += 1
            servo = [m for _, m in gcs.log[-200:] if m.get_type() == "SERVO_OUTPUT_RAW"]
            assert all(1100 <= m.servo1_raw <= 1900 and 1100 <= m.servo2_raw <= 1900
                       for m in servo)

        one_batch()
        # the boat still answers as it did
        gcs.mav.command_long_send(BOAT, COMP, mav.MAV_CMD_REQUEST_MESSAGE, 0,
                                  mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)
        ack = gcs.wait(lambda m: is_ack(m, mav.MAV_CMD_REQUEST_MESSAGE), REPLY_S)
        assert ack.result == mav.MAV_RESULT_ACCEPTED
    finally:
        if boat.poll() is None:
            boat.terminate()
        try:
            _, err = boat.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            boat.kill()
            _, err = boat.communicate()
        gcs.close()
    acks: dict[str, int] = {}
    for _, m in gcs.log:
        if m.get_type() == "COMMAND_ACK":
            k = f"{m.command}:{m.result}"
            acks[k] = acks.get(k, 0) + 1
    text = err.decode(errors="replace")
    assert boat.returncode == 0, text[-3000:]
    assert "Traceback" not in text, text[-3000:]
    assert sent["messages"] >= 60
    got = recorded(rec, {"/ThrusterCommand", "/ComponentState", "/raw/thrusters/tx"})
    cmds = got["/ThrusterCommand"]
    assert len(cmds) > 100  # the control loop ran
    moving = sum(1 for c in cmds if c["u1"] or c["u2"])
    print(f"{sent['messages']} messages; {len(cmds)} thruster commands, {moving} non-zero; "
          f"acks {sorted(acks.items())}")
    for c in cmds:
        for u in (c["u1"], c["u2"]):
            assert isinstance(u, (int, float)) and math.isfinite(u) and -100.0 <= u <= 100.0, c
    assert [s for s in got["/ComponentState"] if s["state"] != "running"] == []
    # what went down the thruster port: $PZTHR sentences with values within range
    wire = b"".join(base64.b64decode(c["data"]) for c in got["/raw/thrusters/tx"]
                    ).decode("ascii", "replace")
    values = [float(v) for v in re.findall(r"\$PZTHR,([-0-9.]+),([-0-9.]+)", wire) for v in v]
    assert values and all(-100.0 <= v <= 100.0 for v in values)
