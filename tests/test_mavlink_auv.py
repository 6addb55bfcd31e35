"""The tracked AUV as a second MAVLink system: a pymavlink ground station on
loopback sees the boat and, once the tracker publishes a track, a submarine
(HEARTBEAT with the track's status, GLOBAL_POSITION_INT of the track's line
model with the depth as negative relative altitude); nothing before a track,
silence once the tracks stop, no position while lost; whatever is asked of the
AUV's system is refused as the AUV and never reaches the supervisor.

Tracks are published on the bus as the tracker would, drawn at random (line
origin, velocity, age); the expected position is computed here from the
track's line model and the origin with pymap3d's geodetic conversion."""

from __future__ import annotations

import itertools
import math
import os
import random
import time
from typing import Any

import pymap3d
import pytest
from mavlink_support import Gcs, Rig, run_rig
from pymavlink.dialects.v20 import common as mav

from zarco_core.auv_messages import AuvTrack, TrackFlags
from zarco_core.messages import Command
from zarco_runtime.settings import RuntimeConfig

OK = TrackFlags.INITIALISED | TrackFlags.LINE_VALID


def track(now: float, rng: random.Random, flags: int, lost: bool = False) -> AuvTrack:
    x0, y0 = rng.uniform(-2000.0, 2000.0), rng.uniform(-2000.0, 2000.0)
    speed = rng.uniform(0.0, 2.5)
    course = rng.uniform(-math.pi, math.pi)
    vx, vy = speed * math.cos(course), speed * math.sin(course)
    t0 = now - rng.uniform(0.0, 30.0)
    cov = tuple(float(i == j) for i in range(4) for j in range(4))
    return AuvTrack(t=now, x0_m=x0, y0_m=y0, vx_mps=vx, vy_mps=vy, psi_auv_rad=course,
                    v_auv_mps=speed, h_auv_m=0.0, cov=cov, t0=t0, t0_utc_s=time.time(),
                    fix_age_s=1.0, flags=int(flags), lost=lost, kf_x_m=x0, kf_y_m=y0,
                    kf_vx_mps=vx, kf_vy_mps=vy, kf_pos_sigma_m=1.0)


def from_auv(m: Any, sysid: int) -> bool:
    return bool(m.get_srcSystem() == sysid)


def check_position(cfg: RuntimeConfig, tr: AuvTrack, m: Any) -> None:
    o = cfg.origin
    dt = tr.t - tr.t0
    n, e = tr.x0_m + tr.vx_mps * dt, tr.y0_m + tr.vy_mps * dt
    lat, lon, _ = pymap3d.ned2geodetic(n, e, 0.0, o.lat_deg, o.lon_deg, o.alt_m)
    assert abs(m.lat - lat * 1e7) <= 1.0 and abs(m.lon - lon * 1e7) <= 1.0, (m, lat, lon)
    depth_mm = cfg.tracker.auv_depth_m * 1000.0
    assert abs(m.relative_alt + depth_mm) <= 1.0, m
    assert abs(m.alt - (o.alt_m * 1000.0 - depth_mm)) <= 1.0, m
    assert abs(m.vx - tr.vx_mps * 100.0) <= 0.5 and abs(m.vy - tr.vy_mps * 100.0) <= 0.5, m
    if math.hypot(tr.vx_mps, tr.vy_mps) >= 0.01:
        course = math.degrees(math.atan2(tr.vy_mps, tr.vx_mps)) % 360.0
        diff = (m.hdg / 100.0 - course + 180.0) % 360.0 - 180.0
        assert abs(diff) <= 0.01, (m.hdg, course)
    else:
        assert m.hdg == 65535


def test_the_auv_is_a_second_system_with_its_track() -> None:
    """The boat's system id, and the AUV's (the default, the boat's + 1, or a
    configured one), drawn anew on every run."""
    rng = random.Random(int.from_bytes(os.urandom(4), "little"))
    boat_id = rng.randint(1, 250)
    auv_cfg = rng.choice([0, rng.choice([i for i in range(1, 256) if i != boat_id])])
    auv_id = auv_cfg or boat_id + 1
    cfg = RuntimeConfig()
    cfg.mavlink.enabled = True
    cfg.mavlink.system_id = boat_id
    cfg.mavlink.auv_system_id = auv_cfg
    cfg.origin.lat_deg = rng.uniform(-60.0, 60.0)
    cfg.origin.lon_deg = rng.uniform(-170.0, 170.0)
    cfg.origin.alt_m = rng.uniform(0.0, 20.0)
    cfg.tracker.auv_depth_m = rng.uniform(1.0, 300.0)
    gcs = Gcs()
    cfg.mavlink.url = gcs.url
    published: list[AuvTrack] = []

    def publish(rig: Rig, flags: int, lost: bool = False) -> AuvTrack:
        tr: AuvTrack = rig.publish(lambda now: track(now, rng, flags, lost))
        published.append(tr)
        return tr

    def ground_station(rig: Rig) -> None:
        # --- no track yet: the boat only
        gcs.wait(lambda m: m.get_type() == "HEARTBEAT", 10.0)
        before = gcs.collect(2.5)
        assert [m for m in before if from_auv(m, auv_id)] == []
        assert any(m.get_type() == "HEARTBEAT" and m.type == mav.MAV_TYPE_SURFACE_BOAT
                   and m.get_srcSystem() == boat_id for m in before)

        # --- a track: heartbeats and positions from the AUV's system, as the track says
        for flags, lost, state in (
                (TrackFlags.NONE, False, mav.MAV_STATE_STANDBY),       # acquiring
                (OK, False, mav.MAV_STATE_ACTIVE),                     # tracking
                (OK | TrackFlags.TURNING, False, mav.MAV_STATE_ACTIVE),
                (OK | TrackFlags.STALE, False, mav.MAV_STATE_CRITICAL),
                (OK, False, mav.MAV_STATE_ACTIVE)):
            tr = publish(rig, flags, lost)
            stamp = int(tr.t * 1000.0) & 0xFFFFFFFF
            pos = gcs.wait(lambda m, st=stamp: from_auv(m, auv_id)
                           and m.get_type() == "GLOBAL_POSITION_INT"
                           and m.time_boot_ms == st)
            check_position(rig.cfg, tr, pos)
            hb = gcs.wait(lambda m, s=state: from_auv(m, auv_id)
                          and m.get_type() == "HEARTBEAT" and m.system_status == s, 3.0)
            assert (hb.type, hb.autopilot) == (mav.MAV_TYPE_SUBMARINE,
                                               mav.MAV_AUTOPILOT_GENERIC)
            assert hb.get_srcComponent() == mav.MAV_COMP_ID_AUTOPILOT1
            assert not hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
        # several updates in a row: one position each
        trs = []
        for _ in range(5):
            trs.append(publish(rig, OK))
            time.sleep(0.15)
        got = [m for m in gcs.collect(1.0) if from_auv(m, auv_id)
               and m.get_type() == "GLOBAL_POSITION_INT"]
        stamps = {int(t.t * 1000.0) & 0xFFFFFFFF: t for t in trs}
        assert sorted(m.time_boot_ms for m in got) == sorted(stamps), (got, stamps)
        for m in got:
            check_position(rig.cfg, stamps[m.time_boot_ms], m)

        # --- what is asked of the AUV is refused as the AUV, and reaches no one
        commands_before = len(rig.seen[Command])
        for cmd, params in ((mav.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)),
                            (mav.MAV_CMD_DO_SET_MODE, (1.0, 5.0)),
                            (mav.MAV_CMD_NAV_RETURN_TO_LAUNCH, ()),
                            (mav.MAV_CMD_MISSION_START, ()),
                            (mav.MAV_CMD_REQUEST_MESSAGE,
                             (float(mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION),))):
            p = list(params) + [0.0] * (7 - len(params))
            gcs.mav.command_long_send(auv_id, 1, cmd, 0, *p)
            ack = gcs.wait(lambda m, c=cmd: m.get_type() == "COMMAND_ACK" and m.command == c)
            assert ack.get_srcSystem() == auv_id and ack.result == mav.MAV_RESULT_DENIED, ack
        gcs.mav.command_int_send(auv_id, 1, 0, mav.MAV_CMD_NAV_LOITER_UNLIM, 0, 0, 0, 0, 0, 0,
                                 0, 0, 0.0)
        ack = gcs.wait(lambda m: m.get_type() == "COMMAND_ACK"
                       and m.command == mav.MAV_CMD_NAV_LOITER_UNLIM)
        assert ack.get_srcSystem() == auv_id and ack.result == mav.MAV_RESULT_DENIED
        gcs.mav.set_mode_send(auv_id, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 5)
        ack = gcs.wait(lambda m: m.get_type() == "COMMAND_ACK"
                       and m.command == mav.MAVLINK_MSG_ID_SET_MODE)
        assert ack.get_srcSystem() == auv_id and ack.result == mav.MAV_RESULT_DENIED
        gcs.mav.mission_count_send(auv_id, 1, 2, mav.MAV_MISSION_TYPE_MISSION)
        mack = gcs.wait(lambda m: m.get_type() in ("MISSION_ACK", "MISSION_REQUEST_INT"))
        assert mack.get_type() == "MISSION_ACK" and mack.get_srcSystem() == auv_id
        assert mack.type == mav.MAV_MISSION_DENIED
        gcs.mav.mission_request_list_send(auv_id, 1, mav.MAV_MISSION_TYPE_MISSION)
        cnt = gcs.wait(lambda m: m.get_type() == "MISSION_COUNT")
        assert cnt.get_srcSystem() == auv_id and cnt.count == 0
        gcs.mav.param_request_list_send(auv_id, 1)
        gcs.mav.manual_control_send(auv_id, 1000, 0, 0, 1000, 0)
        after = gcs.collect(1.5)
        assert not [m for m in after if m.get_type() == "PARAM_VALUE"]
        assert len(rig.seen[Command]) == commands_before  # nothing reached the supervisor
        # the same command to the boat is the boat's (no supervisor here: it fails)
        gcs.mav.command_long_send(boat_id, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0,
                                  float(mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION), 0, 0, 0, 0, 0, 0)
        ack = gcs.wait(lambda m: m.get_type() == "COMMAND_ACK"
                       and m.command == mav.MAV_CMD_REQUEST_MESSAGE)
        assert ack.get_srcSystem() == boat_id and ack.result == mav.MAV_RESULT_ACCEPTED

        # --- lost: the heartbeat says so, and no position
        tr = publish(rig, OK | TrackFlags.LOST, True)
        gcs.wait(lambda m: from_auv(m, auv_id) and m.get_type() == "HEARTBEAT"
                 and m.system_status == mav.MAV_STATE_EMERGENCY, 3.0)
        publish(rig, OK | TrackFlags.LOST, True)
        lost = gcs.collect(1.5)
        assert not [m for m in lost if from_auv(m, auv_id)
                    and m.get_type() == "GLOBAL_POSITION_INT"
                    and m.time_boot_ms >= int(tr.t * 1000.0) & 0xFFFFFFFF]

        # --- the tracks stop: the AUV falls silent
        gcs.collect(3.5)
        silent = gcs.collect(2.5)
        assert [m for m in silent if from_auv(m, auv_id)] == []
        assert any(m.get_srcSystem() == boat_id for m in silent)

    try:
        rig = run_rig(cfg, ground_station, watch=(Command,))
    finally:
        gcs.close()
    # the AUV's own sequence numbers: consecutive within its stream
    seqs = [m.get_seq() for _, m in gcs.log if m.get_srcSystem() == auv_id]
    gaps = sum(1 for a, b in itertools.pairwise(seqs) if (a + 1) % 256 != b)
    assert seqs and gaps == 0, seqs
    assert rig.ep.auv.positions >= 10


def test_auv_system_id_settings() -> None:
    from zarco_runtime.links.mavlink.settings import MavlinkSettings

    s = MavlinkSettings(enabled=True, system_id=1)
    s.validate()
    assert s.auv_sysid() == 2
    s = MavlinkSettings(enabled=True, system_id=255)
    with pytest.raises(ValueError, match="auv_system_id"):
        s.validate()
    s = MavlinkSettings(enabled=True, system_id=255, auv_system_id=254)
    s.validate()
    assert s.auv_sysid() == 254
    s = MavlinkSettings(enabled=True, system_id=9, auv_system_id=9)
    with pytest.raises(ValueError, match="boat's system_id"):
        s.validate()


def test_a_ground_station_sees_the_boat_and_the_simulated_auv(tmp_path: Any) -> None:
    """``zarco sim follow_turn --realtime`` with the MAVLink endpoint, at an origin
    drawn at random: the boat and the AUV are two vehicles, the AUV where the
    simulator holds it (hovering at its first waypoint for its start delay) as
    the passive tracker finds it, 10 m deep."""
    import socket
    import subprocess
    import sys
    from pathlib import Path

    from pymavlink import mavutil

    from zarco_core.geodesy import LocalFrame
    from zarco_tools.scenario import load_scenario

    root = Path(__file__).resolve().parents[1]
    path = root / "config" / "scenarios" / "follow_turn.toml"
    rng = random.Random(int.from_bytes(os.urandom(4), "little"))
    sets = [f"world.origin_lat_deg={rng.uniform(-60.0, 60.0):.6f}",
            f"world.origin_lon_deg={rng.uniform(-170.0, 170.0):.6f}",
            "scenario.max_duration_s=90", "runtime.mavlink.enabled=true"]
    scn = load_scenario(path, sets)
    assert scn.auv is not None
    o = scn.runtime.origin
    frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    hover = scn.auv.waypoints[0]
    gcs = Gcs()
    with socket.socket() as sk:
        sk.bind(("127.0.0.1", 0))
        tcp_port = sk.getsockname()[1]
    cmd = [sys.executable, "-m", "zarco_runtime.cli", "sim", str(path), "--realtime", "-q",
           "--set", f'runtime.mavlink.url=["{gcs.url}", "tcpin:127.0.0.1:{tcp_port}"]']
    for s in sets:
        cmd += ["--set", s]
    boat = subprocess.Popen(cmd, cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    positions: list[Any] = []
    kinds: dict[int, int] = {}
    try:
        end = time.monotonic() + 60.0
        while time.monotonic() < end and len(positions) < 10:
            m = gcs.pump(0.2)
            if m is None:
                continue
            if m.get_type() == "HEARTBEAT":
                kinds[m.get_srcSystem()] = m.type
            # the AUV hovers until its start delay: positions from before it
            if m.get_srcSystem() == 2 and m.get_type() == "GLOBAL_POSITION_INT" \
                    and m.time_boot_ms < (scn.auv.start_delay_s - 5.0) * 1000.0:
                positions.append(m)
        assert kinds.get(1) == mav.MAV_TYPE_SURFACE_BOAT, kinds
        assert kinds.get(2) == mav.MAV_TYPE_SUBMARINE, kinds
        assert len(positions) >= 10, len(positions)
        for m in positions:
            n, e = frame.to_ned(m.lat / 1e7, m.lon / 1e7)
            assert math.hypot(n - hover[0], e - hover[1]) < 10.0, (n, e, hover)
            assert m.relative_alt == -round(scn.runtime.tracker.auv_depth_m * 1000.0)
        # a ground station connecting now, with the AUV tracked, hears the boat first
        # (MAVProxy and QGroundControl make the first vehicle heard their own)
        late = mavutil.mavlink_connection(f"tcp:127.0.0.1:{tcp_port}", source_system=254,
                                          source_component=190)
        try:
            first = late.recv_match(type="HEARTBEAT", blocking=True, timeout=10.0)
            assert first is not None and first.get_srcSystem() == 1, first
            kinds_late: dict[int, int] = {}
            end = time.monotonic() + 10.0
            while 2 not in kinds_late and time.monotonic() < end:
                hb = late.recv_match(type="HEARTBEAT", blocking=True, timeout=1.0)
                if hb is not None:
                    kinds_late[hb.get_srcSystem()] = hb.type
            assert kinds_late.get(2) == mav.MAV_TYPE_SUBMARINE, kinds_late
        finally:
            late.close()
        gcs.mav.command_long_send(2, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                  1, 0, 0, 0, 0, 0, 0)
        ack = gcs.wait(lambda m: m.get_type() == "COMMAND_ACK"
                       and m.command == mav.MAV_CMD_COMPONENT_ARM_DISARM)
        assert ack.get_srcSystem() == 2 and ack.result == mav.MAV_RESULT_DENIED
        # as a multi-vehicle ground station sorts them: two systems, each an
        # autopilot component (1); the AUV's system says only what it is, where it
        # is and its refusals, the boat's telemetry never carries its id
        gcs.collect(1.5)
        by_sys: dict[int, set[str]] = {}
        for _, m in gcs.log:
            by_sys.setdefault(m.get_srcSystem(), set()).add(m.get_type())
            assert m.get_srcComponent() == mav.MAV_COMP_ID_AUTOPILOT1, m
        assert set(by_sys) == {1, 2}, by_sys
        assert by_sys[2] == {"HEARTBEAT", "GLOBAL_POSITION_INT", "COMMAND_ACK"}, by_sys[2]
        assert {"SYS_STATUS", "GPS_RAW_INT", "ATTITUDE", "VFR_HUD", "STATUSTEXT"} <= by_sys[1]
    finally:
        if boat.poll() is None:
            boat.terminate()
        try:
            _, err = boat.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            boat.kill()
            _, err = boat.communicate()
        gcs.close()
    text = err.decode(errors="replace")
    assert boat.returncode == 0, text[-3000:]
    assert "Traceback" not in text, text[-3000:]
