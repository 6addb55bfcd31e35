"""A ground station drives the simulated boat over MAVLink, as QGroundControl or
MAVProxy would: ``zarco sim --realtime`` with the MAVLink endpoint on, and a
pymavlink client on loopback.

The client connects (heartbeats), reads the parameters and sets one (and is
refused one out of range), uploads a 4-waypoint mission and downloads it back,
arms, starts it and watches the boat reach each waypoint (MISSION_ITEM_REACHED,
MISSION_CURRENT, the boat's own position), goes to hold, to manual with the
joystick (MANUAL_CONTROL → thrust, seen in SERVO_OUTPUT_RAW), lets the lease
run out, disarms and sends RTCM.  A second run has a signing key: unsigned,
wrongly signed and replayed commands are refused while signed ones are taken,
and losing the (signed) ground station's heartbeat triggers the ``link lost``
failsafe even while an unsigned one keeps sending.
"""

from __future__ import annotations

import json
import math
import os
import random
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("MAVLINK20", "1")
os.environ.setdefault("MAVLINK_DIALECT", "common")

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav

from zarco_core.geodesy import LocalFrame
from zarco_runtime.control.settings import Control
from zarco_runtime.links.mavlink.params import TABLE

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "config" / "scenarios" / "rectangle.toml"
BOAT = (1, 1)  # the boat's system and component ids (the defaults)
#: the scenario's origin (rectangle.toml keeps the world's default)
ORIGIN = (41.185, -8.705)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


#: how long a boat may take to start and send its first heartbeat: generous, a
#: loaded machine starts ``zarco sim --realtime`` (pymavlink and all) slowly
BOOT_TIMEOUT_S = 120.0


def start_boat(url: str, *sets: str, max_s: float = 180.0) -> subprocess.Popen[bytes]:
    """``zarco sim --realtime`` of the rectangle world, no mission of its own, the
    MAVLink endpoint on ``url``."""
    cmd = [sys.executable, "-m", "zarco_runtime.cli", "sim", str(SCENARIO), "--realtime",
           "-q", "--set", 'mission.kind="idle"', "--set", f"scenario.max_duration_s={max_s}",
           "--set", "runtime.mavlink.enabled=true", "--set", f'runtime.mavlink.url="{url}"']
    for s in sets:
        cmd += ["--set", s]
    return subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def stop_boat(p: subprocess.Popen[bytes]) -> str:
    """SIGTERM; the boat ends with exit 0.  Returns its stderr."""
    if p.poll() is None:
        p.terminate()
    try:
        _, err = p.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        p.kill()
        _, err = p.communicate()
    return err.decode(errors="replace")


class Gcs:
    """A pymavlink ground station on one thread: every wait pumps the link and
    sends a GCS heartbeat each second (unless ``heartbeats`` is off)."""

    def __init__(self, url: str, sysid: int = 255, compid: int = 190,
                 key: bytes | None = None, accept_any: bool = False) -> None:
        self.conn = mavutil.mavlink_connection(url, source_system=sysid,
                                               source_component=compid)
        m = mav.MAVLink(self.conn, srcSystem=sysid, srcComponent=compid)
        m.robust_parsing = True
        self.conn.mav = m
        self.conn.first_byte = False
        if key is not None:
            self.conn.setup_signing(key, sign_outgoing=True,
                                    allow_unsigned_callback=(lambda *a: True) if accept_any
                                    else None)
        self.mav = m
        self.sysid = sysid
        self.heartbeats = True
        self.next_hb = 0.0
        self.log: list[tuple[float, Any]] = []
        self.last: dict[str, Any] = {}
        self.texts: list[str] = []
        self.hb_sent_t = 0.0

    @property
    def port(self) -> int:
        return int(self.conn.port.getsockname()[1])

    def close(self) -> None:
        self.conn.close()

    def pump(self, timeout: float = 0.05) -> Any:
        now = time.monotonic()
        if self.heartbeats and now >= self.next_hb:
            self.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0,
                                    mav.MAV_STATE_ACTIVE)
            self.hb_sent_t = now
            self.next_hb = now + 1.0
        m = self.conn.recv_match(blocking=True, timeout=timeout)
        if m is None or m.get_type() == "BAD_DATA":
            return None
        if m.get_srcSystem() != BOAT[0]:
            return None
        self.log.append((time.monotonic(), m))
        self.last[m.get_type()] = m
        if m.get_type() == "STATUSTEXT":  # chunks of one text share an id
            if m.id and m.chunk_seq and self.texts:
                self.texts[-1] += m.text
            else:
                self.texts.append(m.text)
        return m

    def wait(self, kind: str, cond: Callable[[Any], bool] = lambda m: True,
             timeout: float = 5.0) -> Any:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.pump(min(0.1, max(0.0, end - time.monotonic())))
            if m is not None and m.get_type() == kind and cond(m):
                return m
        raise AssertionError(f"no {kind} within {timeout} s; last texts: {self.texts[-5:]}")

    def wait_text(self, cond: Callable[[str], bool], since: int = 0,
                  timeout: float = 5.0) -> str:
        """A status text (chunks joined), from the ``since``-th one on, that ``cond`` likes."""
        end = time.monotonic() + timeout
        while True:
            for t in self.texts[since:]:
                if cond(t):
                    return t
            if time.monotonic() >= end:
                raise AssertionError(f"no such status text; texts: {self.texts[since:]}")
            self.pump(0.1)

    def run_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.pump(min(0.1, max(0.0, end - time.monotonic())))

    def command(self, cmd: int, *params: float, timeout: float = 3.0) -> int:
        p = list(params) + [0.0] * (7 - len(params))
        self.mav.command_long_send(BOAT[0], BOAT[1], cmd, 0, *p)
        ack = self.wait("COMMAND_ACK", lambda a: a.command == cmd
                        and a.target_system == self.sysid, timeout)
        return int(ack.result)

    def heartbeat(self, cond: Callable[[Any], bool], timeout: float = 5.0) -> Any:
        return self.wait("HEARTBEAT", cond, timeout)

    def params(self) -> dict[str, float]:
        self.mav.param_request_list_send(BOAT[0], BOAT[1])
        got: dict[int, Any] = {}
        first = self.wait("PARAM_VALUE")
        got[first.param_index] = first
        while len(got) < first.param_count:
            m = self.wait("PARAM_VALUE")
            got[m.param_index] = m
        return {m.param_id: m.param_value for m in got.values()}

    def param_set(self, name: str, value: float) -> float:
        self.mav.param_set_send(BOAT[0], BOAT[1], name.encode(), value,
                                mav.MAV_PARAM_TYPE_REAL32)
        return float(self.wait("PARAM_VALUE", lambda m: m.param_id == name).param_value)

    def upload(self, items: list[tuple[int, int, float, float, float]]) -> int:
        """Upload (frame, command, param2, lat_deg, lon_deg) items; the MISSION_ACK type."""
        self.mav.mission_count_send(BOAT[0], BOAT[1], len(items), mav.MAV_MISSION_TYPE_MISSION)
        while True:
            m = self._wait_any(("MISSION_REQUEST_INT", "MISSION_ACK"))
            if m.get_type() == "MISSION_ACK":
                return int(m.type)
            frame, command, p2, lat, lon = items[m.seq]
            self.mav.mission_item_int_send(BOAT[0], BOAT[1], m.seq, frame, command, 0, 1,
                                           0.0, p2, 0.0, 0.0, round(lat * 1e7),
                                           round(lon * 1e7), 0.0,
                                           mav.MAV_MISSION_TYPE_MISSION)

    def _wait_any(self, kinds: tuple[str, ...], timeout: float = 5.0) -> Any:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.pump(0.1)
            if m is not None and m.get_type() in kinds:
                return m
        raise AssertionError(f"none of {kinds} within {timeout} s")

    def download(self) -> list[Any]:
        self.mav.mission_request_list_send(BOAT[0], BOAT[1], mav.MAV_MISSION_TYPE_MISSION)
        n = self.wait("MISSION_COUNT").count
        out = []
        for seq in range(n):
            self.mav.mission_request_int_send(BOAT[0], BOAT[1], seq,
                                              mav.MAV_MISSION_TYPE_MISSION)
            out.append(self.wait("MISSION_ITEM_INT", lambda m, s=seq: m.seq == s))
        self.mav.mission_ack_send(BOAT[0], BOAT[1], mav.MAV_MISSION_ACCEPTED,
                                  mav.MAV_MISSION_TYPE_MISSION)
        return out


def geo(n: float, e: float) -> tuple[float, float]:
    lat, lon, _ = LocalFrame(ORIGIN[0], ORIGIN[1], 0.0).to_geodetic(n, e)
    return lat, lon


def dist_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    f = LocalFrame(ORIGIN[0], ORIGIN[1], 0.0)
    pa, pb = f.to_ned(*a), f.to_ned(*b)
    return math.hypot(pa[0] - pb[0], pa[1] - pb[1])


def test_a_ground_station_drives_the_simulated_boat() -> None:
    gcs = Gcs("udpin:127.0.0.1:0")
    boat = start_boat(f"udpout:127.0.0.1:{gcs.port}")
    try:
        # --- connect: the boat is a surface boat, generic autopilot, idle, disarmed
        hb = gcs.heartbeat(lambda m: True, timeout=BOOT_TIMEOUT_S)
        assert hb.type == mav.MAV_TYPE_SURFACE_BOAT
        assert hb.autopilot == mav.MAV_AUTOPILOT_GENERIC
        assert hb.custom_mode == 4 and not hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
        assert gcs.command(mav.MAV_CMD_REQUEST_MESSAGE,
                           mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == mav.MAV_RESULT_ACCEPTED
        caps = gcs.last["AUTOPILOT_VERSION"].capabilities  # sent before its ack
        assert caps & mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
        assert caps & mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2

        # --- parameters: all of them, the configured values, a write within range and
        # one outside it (refused, value unchanged, reason in a status text)
        params = gcs.params()
        assert set(params) == {name for name, _ in TABLE}
        assert params["CTL_SPD_KP"] == Control().speed_kp
        assert gcs.param_set("CTL_SPD_KP", 55.0) == 55.0
        mark = len(gcs.texts)
        assert gcs.param_set("CTL_SPD_KP", 1e6) == 55.0
        # the supervisor's refusal, naming its parameter
        gcs.wait_text(lambda t: "control.speed_kp" in t and "refused" in t, mark)
        assert gcs.param_set("CTL_SPD_KP", Control().speed_kp) == Control().speed_kp

        # --- a position first (a mission needs one), then the mission: 4 waypoints
        gcs.wait("GPS_RAW_INT", lambda m: m.fix_type == mav.GPS_FIX_TYPE_RTK_FIXED, 15.0)
        wps = [geo(5.0, 0.0), geo(20.0, 0.0), geo(20.0, 12.0), geo(5.0, 12.0)]
        g6 = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        items = [(mav.MAV_FRAME_MISSION, mav.MAV_CMD_DO_CHANGE_SPEED, 2.0, 0.0, 0.0)]
        items += [(g6, mav.MAV_CMD_NAV_WAYPOINT, 0.0, lat, lon) for lat, lon in wps]
        assert gcs.upload(items) == mav.MAV_MISSION_ACCEPTED
        back = gcs.download()
        assert [m.command for m in back] == [it[1] for it in items]
        assert [(m.x, m.y) for m in back[1:]] == [(round(a * 1e7), round(b * 1e7))
                                                  for a, b in wps]
        assert back[0].param2 == 2.0
        # a mission that needs two speeds is refused (one speed per mission)
        slower = (mav.MAV_FRAME_MISSION, mav.MAV_CMD_DO_CHANGE_SPEED, 1.0, 0.0, 0.0)
        two = [*items[:3], slower, *items[3:]]
        assert gcs.upload(two) == mav.MAV_MISSION_UNSUPPORTED

        # --- arm, start, watch every waypoint being reached, in order
        assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_ACCEPTED
        gcs.heartbeat(lambda m: m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)
        assert gcs.command(mav.MAV_CMD_MISSION_START) == mav.MAV_RESULT_ACCEPTED
        gcs.heartbeat(lambda m: m.custom_mode == 10)
        wp_seqs = [1, 2, 3, 4]
        reached: list[int] = []
        currents: list[int] = []
        end = time.monotonic() + 70.0
        while len(reached) < 4 and time.monotonic() < end:
            m = gcs.pump(0.1)
            if m is None:
                continue
            if m.get_type() == "MISSION_CURRENT" and (not currents or currents[-1] != m.seq):
                currents.append(m.seq)
            if m.get_type() == "MISSION_ITEM_REACHED":
                reached.append(m.seq)
                pos = gcs.last["GLOBAL_POSITION_INT"]
                here = (pos.lat / 1e7, pos.lon / 1e7)
                wp = wps[wp_seqs.index(m.seq)]
                assert dist_m(here, wp) < 3.0, (m.seq, dist_m(here, wp))
        assert reached == wp_seqs, f"{reached}\n" + "\n".join(gcs.texts)
        assert [s for s in currents if s in wp_seqs] == wp_seqs
        # the end of the mission: holding at its last waypoint, mission complete
        gcs.heartbeat(lambda m: m.custom_mode == 5)
        mc = gcs.wait("MISSION_CURRENT")
        assert mc.mission_state == mav.MISSION_STATE_COMPLETE and mc.seq == 4

        # --- return, then hold where it is (DO_SET_MODE and NAV_LOITER_UNLIM)
        assert gcs.command(mav.MAV_CMD_NAV_RETURN_TO_LAUNCH) == mav.MAV_RESULT_ACCEPTED
        gcs.heartbeat(lambda m: m.custom_mode == 11)
        assert gcs.command(mav.MAV_CMD_DO_SET_MODE, 1, 5) == mav.MAV_RESULT_ACCEPTED
        gcs.heartbeat(lambda m: m.custom_mode == 5)
        assert gcs.command(mav.MAV_CMD_DO_SET_MODE, 1, 99) == mav.MAV_RESULT_DENIED

        # --- manual with the joystick: forward 50 %, turning to starboard 30 %
        gcs.run_for(0.5)
        mark = len(gcs.texts)
        gcs.mav.manual_control_send(BOAT[0], 500, 0, 0, 300, 0)
        gcs.wait_text(lambda t: "thrust" in t and "not in manual mode" in t, mark)
        assert gcs.command(mav.MAV_CMD_DO_SET_MODE, 1, 0) == mav.MAV_RESULT_ACCEPTED
        gcs.heartbeat(lambda m: m.custom_mode == 0)
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            gcs.mav.manual_control_send(BOAT[0], 500, 0, 0, 300, 0)
            gcs.pump(0.05)
        so = gcs.wait("SERVO_OUTPUT_RAW")
        assert (so.servo1_raw, so.servo2_raw) == (1820, 1580), [  # U1 = 80 %, U2 = 20 %
            (round(t, 2), m.servo1_raw, m.servo2_raw) for t, m in gcs.log[-400:]
            if m.get_type() == "SERVO_OUTPUT_RAW"]
        # the joystick stops: zero thrust once the lease (1 s) has run out
        gcs.run_for(1.5)
        so = gcs.wait("SERVO_OUTPUT_RAW")
        assert (so.servo1_raw, so.servo2_raw) == (1500, 1500)

        # --- disarm: idle, zero thrust
        assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0) == mav.MAV_RESULT_ACCEPTED
        hb = gcs.heartbeat(lambda m: m.custom_mode == 4)
        assert not hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED

        # --- RTCM from the base station: a 400-byte block in three fragments and a
        # short one; the link takes them (reassembly is tested in-process)
        block = bytes(range(256)) + bytes(144)
        for i in range(3):
            part = block[180 * i:180 * (i + 1)]
            gcs.mav.gps_rtcm_data_send(1 | (i << 1) | (7 << 3), len(part),
                                       list(part.ljust(180, b"\0")))
        gcs.mav.gps_rtcm_data_send(8 << 3, 5, list(b"\xd3\x00\x00\x00\x00".ljust(180, b"\0")))
        gcs.run_for(1.0)
        assert gcs.last["HEARTBEAT"].custom_mode == 4
    finally:
        err = stop_boat(boat)
        gcs.close()
        print("\n".join(gcs.texts))  # shown when the test fails
        print(err[-3000:])
    assert boat.returncode == 0, err[-3000:]
    assert "Traceback" not in err, err[-3000:]


def test_signing_refuses_unsigned_commands_and_link_loss_fails_safe(tmp_path: Path) -> None:
    key = os.urandom(32)
    (tmp_path / "mav.key").write_bytes(key)
    port = free_udp_port()
    boat = start_boat(f"udpin:127.0.0.1:{port}",
                      f'runtime.mavlink.signing_key_file="{tmp_path / "mav.key"}"',
                      'runtime.failsafe.link="mavlink"', "runtime.failsafe.link_lost_s=2.0",
                      'runtime.failsafe.link_lost="idle"')
    url = f"udpout:127.0.0.1:{port}"
    good = Gcs(url, 255, 190, key=key)
    plain = Gcs(url, 254, 190)
    wrong = Gcs(url, 253, 190, key=os.urandom(32), accept_any=True)
    try:
        hb = good.heartbeat(lambda m: True, timeout=BOOT_TIMEOUT_S)
        assert hb.get_signed()  # the boat signs what it sends
        for g in (plain, wrong):
            g.heartbeat(lambda m: True, timeout=5.0)
        arm = mav.MAV_CMD_COMPONENT_ARM_DISARM
        # unsigned, or signed with another key: refused, and nothing armed
        assert plain.command(arm, 1) == mav.MAV_RESULT_DENIED
        assert wrong.command(arm, 1) == mav.MAV_RESULT_DENIED
        assert plain.param_set("CTL_SPD_KP", 50.0) == Control().speed_kp
        plain.mav.mission_count_send(BOAT[0], BOAT[1], 2, mav.MAV_MISSION_TYPE_MISSION)
        ack = plain.wait("MISSION_ACK", lambda m: m.target_system == 254)
        assert ack.type == mav.MAV_MISSION_DENIED
        good.run_for(1.2)
        assert not good.last["HEARTBEAT"].base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
        # a signed command replayed byte for byte: refused (its timestamp is old)
        msg = good.mav.command_long_encode(BOAT[0], BOAT[1], mav.MAV_CMD_REQUEST_MESSAGE, 0,
                                           mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0,
                                           0, 0)
        buf = msg.pack(good.mav)
        good.mav.seq = (good.mav.seq + 1) % 256
        results = []
        for _ in range(2):
            good.conn.write(buf)
            results.append(good.wait("COMMAND_ACK", lambda a: a.target_system == 255).result)
        assert results == [mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_DENIED]
        # signed: taken
        assert good.command(arm, 1) == mav.MAV_RESULT_ACCEPTED
        good.wait("GPS_RAW_INT", lambda m: m.fix_type == mav.GPS_FIX_TYPE_RTK_FIXED, 15.0)
        assert good.command(mav.MAV_CMD_DO_SET_MODE, 1, 5) == mav.MAV_RESULT_ACCEPTED
        good.heartbeat(lambda m: m.custom_mode == 5)
        # the signed ground station goes silent; the unsigned one keeps sending
        # heartbeats, which do not count: link lost after 2 s → idle
        good.heartbeats = False
        t_last = good.hb_sent_t
        end = time.monotonic() + 6.0
        t_idle = None
        while time.monotonic() < end and t_idle is None:
            plain.pump(0.02)
            m = good.pump(0.02)
            if m is not None and m.get_type() == "HEARTBEAT" and m.custom_mode == 4:
                t_idle = time.monotonic()
        assert t_idle is not None, good.texts[-10:]
        assert 2.0 <= t_idle - t_last <= 4.0, t_idle - t_last
        assert any("link_lost" in t for t in good.texts), good.texts[-10:]
        assert not good.last["HEARTBEAT"].base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
        assert good.param_set("CTL_SPD_KP", 50.0) == 50.0  # signed: written
    finally:
        err = stop_boat(boat)
        for g in (good, plain, wrong):
            g.close()
    assert boat.returncode == 0, err[-3000:]
    assert "Traceback" not in err, err[-3000:]


def ctl(path: Path, name: str, args: dict[str, Any]) -> dict[str, Any]:
    """One command over the boat's local control socket (as ``zarco ctl``)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sk:
        sk.settimeout(10.0)
        sk.connect(str(path))
        sk.sendall((json.dumps({"name": name, "args": args}) + "\n").encode())
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = sk.recv(65536)
            if not chunk:
                break
            buf += chunk
    out: dict[str, Any] = json.loads(buf)
    return out


def test_the_ground_station_sees_the_supervisors_vessel(tmp_path: Path) -> None:
    """Home, arming, the mission and the parameters are the supervisor's, never
    the endpoint's own: HOME_POSITION is the configured home (drawn at random
    near the boat); disarmed, a mission start or a moving mode is refused
    ("disarmed"); a parameter change goes to every ground station, the failsafe
    table's refused under way; clearing the mission while it runs is refused
    with the supervisor's reason; a mission loaded by another operator (the
    local control socket) is what the ground station downloads; a hold point
    that is not a latitude is refused (DENIED) with the field named."""
    rng = random.Random(int.from_bytes(os.urandom(4), "little"))
    home = geo(rng.uniform(-30.0, 30.0), rng.uniform(-30.0, 30.0))
    gcs = Gcs("udpin:127.0.0.1:0")
    other = Gcs("udpin:127.0.0.1:0", 250, 190)
    sock = tmp_path / "ctl.sock"
    boat = start_boat(f"udpout:127.0.0.1:{gcs.port}",
                      f"runtime.supervisor.home=[{home[0]:.7f}, {home[1]:.7f}]",
                      f'runtime.supervisor.control_socket="{sock}"',
                      f'runtime.mavlink.url=["udpout:127.0.0.1:{gcs.port}", '
                      f'"udpout:127.0.0.1:{other.port}"]')
    try:
        gcs.heartbeat(lambda m: True, timeout=20.0)
        other.heartbeat(lambda m: True, timeout=20.0)
        gcs.wait("GPS_RAW_INT", lambda m: m.fix_type == mav.GPS_FIX_TYPE_RTK_FIXED, 15.0)
        # the boat is heard once the supervisor has spoken: asked once, home is there
        assert gcs.command(mav.MAV_CMD_REQUEST_MESSAGE,
                           mav.MAVLINK_MSG_ID_HOME_POSITION) == mav.MAV_RESULT_ACCEPTED
        hp = gcs.last["HOME_POSITION"]
        assert (hp.latitude, hp.longitude) == (round(home[0] * 1e7), round(home[1] * 1e7))

        # a hold point that is no latitude: refused before the supervisor, field named
        mark = len(gcs.texts)
        assert gcs.command(mav.MAV_CMD_NAV_LOITER_UNLIM, 0, 0, 0, 0, 95.0,
                           home[1]) == mav.MAV_RESULT_DENIED
        gcs.wait_text(lambda t: "lat_deg" in t and "refused" in t, mark)

        wps = [geo(5.0, 0.0), geo(25.0, 0.0), geo(25.0, 15.0)]
        g6 = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        assert gcs.upload([(g6, mav.MAV_CMD_NAV_WAYPOINT, 0.0, lat, lon)
                           for lat, lon in wps]) == mav.MAV_MISSION_ACCEPTED
        # disarmed: nothing that moves the boat is taken
        mark = len(gcs.texts)
        for cmd, params in ((mav.MAV_CMD_MISSION_START, ()),
                            (mav.MAV_CMD_DO_SET_MODE, (1, 5)),
                            (mav.MAV_CMD_NAV_RETURN_TO_LAUNCH, ())):
            assert gcs.command(cmd, *params) == mav.MAV_RESULT_TEMPORARILY_REJECTED, cmd
        # the reason, said once (the same text is not repeated within 2 s)
        gcs.wait_text(lambda t: t.endswith("refused: disarmed"), mark)
        assert gcs.last["HEARTBEAT"].custom_mode == 4
        assert not gcs.last["HEARTBEAT"].base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED

        # a parameter set at rest: taken, and every ground station hears it
        value = float(rng.choice([5.0, 12.0, 20.0, 45.0]))
        assert gcs.param_set("FS_LINK_LOST_S", value) == value
        heard = other.wait("PARAM_VALUE", lambda m: m.param_id == "FS_LINK_LOST_S"
                           and m.param_value == value)
        assert heard.param_count == len(TABLE)

        # a geofence a hand's width about home: the boat is outside, a failsafe
        # holds, and arming is refused with the reason, forced or not (MAVProxy's
        # `arm throttle force` sends 2989, MAVLink's force is 21196)
        # (a value as typed: 0.1, not its float32 0.100000001)
        mark = len(gcs.texts)
        assert gcs.param_set("FENCE_RADIUS_M", 0.1) == pytest.approx(0.1)
        gcs.wait_text(lambda t: t.startswith("geofence.radius_m = 0.1 (was 0.0)"), mark)
        gcs.heartbeat(lambda m: m.system_status == mav.MAV_STATE_CRITICAL)
        # (the supervisor's event of a refusal is held back after 5 acknowledgements
        # to one source in a second: the ground station that asked is told anyway)
        for _ in range(6):
            assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0) == mav.MAV_RESULT_ACCEPTED
        for force in (0.0, 2989.0, 21196.0):
            mark = len(gcs.texts)
            assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1,
                               force) == mav.MAV_RESULT_TEMPORARILY_REJECTED, force
            if not force:  # (the same text is not repeated within 2 s)
                gcs.wait_text(lambda t: t.startswith("arm from mavlink:255: refused: "
                                                     "failsafe active: geofence"), mark)
            else:
                gcs.wait_text(lambda t, f=force: t == f"arm from mavlink:255: force ({f:g}) "
                              "does not bypass the arming checks", mark)
        assert not gcs.last["HEARTBEAT"].base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
        assert gcs.param_set("FENCE_RADIUS_M", 0.0) == 0.0
        gcs.heartbeat(lambda m: m.system_status == mav.MAV_STATE_STANDBY, timeout=10.0)
        assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_ACCEPTED
        gcs.heartbeat(lambda m: m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)
        assert gcs.command(mav.MAV_CMD_MISSION_START) == mav.MAV_RESULT_ACCEPTED
        gcs.heartbeat(lambda m: m.custom_mode == 10)
        # under way: the failsafe table does not change
        mark = len(gcs.texts)
        assert gcs.param_set("FS_LINK_LOST_S", value + 1.0) == value
        gcs.wait_text(lambda t: "failsafe.link_lost_s" in t and "under way" in t, mark)
        # running: the supervisor keeps its mission
        mark = len(gcs.texts)
        gcs.mav.mission_clear_all_send(BOAT[0], BOAT[1], mav.MAV_MISSION_TYPE_MISSION)
        ack = gcs.wait("MISSION_ACK", lambda m: m.target_system == 255)
        assert ack.type == mav.MAV_MISSION_ERROR
        gcs.wait_text(lambda t: "mission" in t and "running" in t, mark)
        assert len(gcs.download()) == 3
        # stopped, it can be cleared, and then there is nothing to start
        assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0) == mav.MAV_RESULT_ACCEPTED
        gcs.heartbeat(lambda m: m.custom_mode == 4)
        gcs.mav.mission_clear_all_send(BOAT[0], BOAT[1], mav.MAV_MISSION_TYPE_MISSION)
        ack = gcs.wait("MISSION_ACK", lambda m: m.target_system == 255)
        assert ack.type == mav.MAV_MISSION_ACCEPTED
        assert gcs.download() == []
        mark = len(gcs.texts)
        assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_ACCEPTED
        assert gcs.command(mav.MAV_CMD_MISSION_START) == mav.MAV_RESULT_TEMPORARILY_REJECTED
        gcs.wait_text(lambda t: "no mission loaded" in t, mark)

        # another operator loads a mission: the ground station downloads that one
        theirs = [geo(rng.uniform(-40, 40), rng.uniform(-40, 40)) for _ in range(4)]
        reply = ctl(sock, "mission", {"waypoints": [list(p) for p in theirs],
                                      "speed_mps": 1.0, "start": False})
        assert reply["ok"], reply
        end = time.monotonic() + 5.0
        back: list[Any] = []
        while time.monotonic() < end and len(back) != 4:
            gcs.run_for(0.3)
            back = gcs.download()
        assert [(m.x, m.y) for m in back] == [(round(a * 1e7), round(b * 1e7))
                                              for a, b in theirs]
    finally:
        err = stop_boat(boat)
        gcs.close()
        other.close()
        print("\n".join(gcs.texts))
    assert boat.returncode == 0, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
