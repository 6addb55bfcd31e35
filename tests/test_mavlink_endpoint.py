"""The MAVLink endpoint in-process, on a real event loop, with a ground station
on loopback (UDP, TCP) or on a pseudo-terminal (serial): GPS_RTCM_DATA is
reassembled into RtcmCorrections(source="mavlink") on the bus, byte for byte;
a GCS heartbeat is an OperatorHeartbeat(link="mavlink"); a TCP ground station
can leave and come back; a serial link works through a pty; a forged signed
packet cannot lock the real ground station out."""

from __future__ import annotations

import asyncio
import os
import pty
import select
import socket
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

os.environ.setdefault("MAVLINK20", "1")
os.environ.setdefault("MAVLINK_DIALECT", "common")

import contextlib

from mavlink_support import Gcs, Rig, boot_status, run_rig
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav

from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.component import ComponentContext
from zarco_core.messages import OperatorHeartbeat, RtcmCorrections
from zarco_runtime.links.mavlink.endpoint import MavlinkEndpoint
from zarco_runtime.settings import RuntimeConfig


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Seen:
    """What the endpoint put on the bus."""

    rtcm: list[RtcmCorrections] = field(default_factory=list)
    heartbeats: list[OperatorHeartbeat] = field(default_factory=list)


def run_endpoint(url: str, gcs: Callable[[Seen], None], signing_key_file: str = "") -> Seen:
    """Run the endpoint on ``url`` while ``gcs(seen)`` runs on a thread."""
    cfg = RuntimeConfig()
    cfg.mavlink.enabled = True
    cfg.mavlink.url = url
    cfg.mavlink.signing_key_file = signing_key_file
    bus = Bus()
    seen = Seen()
    bus.listen(RtcmCorrections, seen.rtcm.append)
    bus.listen(OperatorHeartbeat, seen.heartbeats.append)

    async def main() -> None:
        clock = Clock()
        ctx = ComponentContext("mavlink", bus, clock)
        ep = MavlinkEndpoint(cfg, bus, clock, ctx)
        bus.publish(boot_status(clock.now()))  # as the supervisor at boot
        task = asyncio.ensure_future(ctx.run(ep.run()))
        try:
            await asyncio.to_thread(gcs, seen)
            assert not task.done(), task.exception()
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
            for link in ep.links:
                assert link.join(2.0), "a link's thread did not end"

    asyncio.run(main())
    return seen


def connect(url: str) -> Any:
    c = mavutil.mavlink_connection(url, source_system=255, source_component=190)
    c.mav = mav.MAVLink(c, srcSystem=255, srcComponent=190)
    c.mav.robust_parsing = True
    c.first_byte = False
    return c


def gcs_heartbeat(m: Any) -> None:
    m.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)


def wait_until(cond: Callable[[], bool], timeout: float, pump: Callable[[], Any]) -> None:
    end = time.monotonic() + timeout
    while not cond() and time.monotonic() < end:
        pump()


def test_rtcm_fragments_become_whole_blocks_on_the_bus() -> None:
    port = free_port(socket.SOCK_DGRAM)
    blocks = [os.urandom(n) for n in (40, 180, 400, 360, 719, 90)]

    def gcs(seen: Seen) -> None:
        c = connect(f"udpout:127.0.0.1:{port}")
        try:
            end = time.monotonic() + 5.0  # heartbeats until the boat (listening) answers
            while time.monotonic() < end:
                gcs_heartbeat(c.mav)
                if c.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2) is not None:
                    break
            else:
                raise AssertionError("no heartbeat from the boat")
            for seq, b in enumerate(blocks):  # as QGroundControl cuts them
                if len(b) < 180:
                    c.mav.gps_rtcm_data_send(seq << 3, len(b), list(b.ljust(180, b"\0")))
                    continue
                for i in range(0, len(b), 180):
                    part = b[i:i + 180]
                    c.mav.gps_rtcm_data_send(1 | ((i // 180) << 1) | (seq << 3), len(part),
                                             list(part.ljust(180, b"\0")))
            wait_until(lambda: len(seen.rtcm) >= len(blocks), 5.0,
                       lambda: c.recv_match(blocking=True, timeout=0.1))
        finally:
            c.close()

    seen = run_endpoint(f"udpin:127.0.0.1:{port}", gcs)
    assert [r.data for r in seen.rtcm] == blocks
    assert {r.source for r in seen.rtcm} == {"mavlink"}
    assert seen.heartbeats and {h.user for h in seen.heartbeats} == {"255"}
    assert {h.link for h in seen.heartbeats} == {"mavlink"}


def test_a_tcp_ground_station_can_leave_and_come_back() -> None:
    port = free_port(socket.SOCK_STREAM)

    def gcs(seen: Seen) -> None:
        for visit in range(3):
            c = connect(f"tcp:127.0.0.1:{port}")
            try:
                hb = c.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
                assert hb is not None and hb.type == mav.MAV_TYPE_SURFACE_BOAT, visit
                gcs_heartbeat(c.mav)
                wait_until(lambda v=visit: len(seen.heartbeats) > v, 3.0,
                           lambda c=c: c.recv_match(blocking=True, timeout=0.1))
            finally:
                c.close()

    seen = run_endpoint(f"tcpin:127.0.0.1:{port}", gcs)
    assert len(seen.heartbeats) == 3


def test_a_serial_ground_station_on_a_pty() -> None:
    master, slave = pty.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    path = os.ttyname(slave)

    def gcs(seen: Seen) -> None:
        parser = mav.MAVLink(None, 255, 190)

        class Port:
            def write(self, b: bytes) -> None:
                os.write(master, bytes(b))

        out = mav.MAVLink(Port(), 255, 190)
        got: list[Any] = []
        end = time.monotonic() + 5.0
        while time.monotonic() < end and not (got and seen.heartbeats):
            if select.select([master], [], [], 0.1)[0]:
                got += parser.parse_buffer(os.read(master, 4096)) or []
            if got:
                gcs_heartbeat(out)
        hbs = [m for m in got if m.get_type() == "HEARTBEAT"]
        assert hbs and hbs[0].type == mav.MAV_TYPE_SURFACE_BOAT

    try:
        seen = run_endpoint(f"{path},115200", gcs)
    finally:
        os.close(master)
        os.close(slave)
    assert seen.heartbeats and seen.heartbeats[0].link == "mavlink"


def test_a_forged_packet_cannot_make_the_signed_ground_station_look_replayed(
        tmp_path: Any) -> None:
    """With signing, a packet claiming the ground station's ids and a far-future
    timestamp, but signed with another key, is refused and changes nothing: the
    real station's next command is still taken."""
    key = os.urandom(32)
    (tmp_path / "k").write_bytes(key)
    port = free_port(socket.SOCK_DGRAM)
    results: list[int] = []

    def gcs(seen: Seen) -> None:
        c = connect(f"udpout:127.0.0.1:{port}")
        c.setup_signing(key, sign_outgoing=True)
        forger = mav.MAVLink(c, srcSystem=255, srcComponent=190)  # same ids, other key
        forger.signing.secret_key = os.urandom(32)
        forger.signing.sign_outgoing = True
        forger.signing.timestamp = c.mav.signing.timestamp + 100_000 * 86_400  # a day ahead

        def request(m: Any) -> int:
            m.command_long_send(1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0,
                                mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)
            ack = c.recv_match(type="COMMAND_ACK", blocking=True, timeout=3)
            assert ack is not None
            return int(ack.result)

        try:
            end = time.monotonic() + 5.0
            while time.monotonic() < end:
                gcs_heartbeat(c.mav)
                if c.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2) is not None:
                    break
            results.extend([request(c.mav), request(forger), request(c.mav)])
        finally:
            c.close()

    cfg_key = str(tmp_path / "k")
    run_endpoint(f"udpin:127.0.0.1:{port}", gcs, signing_key_file=cfg_key)
    assert results == [mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_DENIED, mav.MAV_RESULT_ACCEPTED]


def test_the_boat_is_heard_once_the_supervisor_speaks_and_home_reaches_who_asked() -> None:
    """No heartbeat before the supervisor's first status (a ground station that
    hears the boat can ask for home); home asked while not known yet is
    TEMPORARILY_REJECTED and then sent unasked as soon as the supervisor knows
    it, and again whenever it moves (not when it stays); GET_HOME_POSITION, the
    deprecated command ground stations still send, answers as REQUEST_MESSAGE."""
    import random

    rng = random.Random(int.from_bytes(os.urandom(4), "little"))
    cfg = RuntimeConfig()
    cfg.mavlink.enabled = True
    cfg.origin.lat_deg = rng.uniform(-60.0, 60.0)
    cfg.origin.lon_deg = rng.uniform(-170.0, 170.0)
    gcs = Gcs()
    cfg.mavlink.url = gcs.url

    def near() -> tuple[float, float]:
        return (cfg.origin.lat_deg + rng.uniform(-0.01, 0.01),
                cfg.origin.lon_deg + rng.uniform(-0.01, 0.01))

    def command(cmd: int, p1: float = 0.0) -> int:
        gcs.mav.command_long_send(1, 1, cmd, 0, p1, 0, 0, 0, 0, 0, 0)
        ack = gcs.wait(lambda m: m.get_type() == "COMMAND_ACK" and m.command == cmd)
        return int(ack.result)

    def is_home(m: Any, home: tuple[float, float]) -> bool:
        return bool(m.get_type() == "HOME_POSITION" and m.latitude == round(home[0] * 1e7)
                    and m.longitude == round(home[1] * 1e7))

    def ground_station(rig: Rig) -> None:
        # telemetry flows, but no heartbeat while the supervisor has not spoken
        gcs.wait(lambda m: m.get_type() == "SYS_STATUS", 10.0)
        assert not [m for m in gcs.collect(1.5) if m.get_type() == "HEARTBEAT"]
        rig.publish(lambda now: boot_status(now))
        hb = gcs.wait(lambda m: m.get_type() == "HEARTBEAT", 3.0)
        assert hb.system_status == mav.MAV_STATE_STANDBY and hb.custom_mode == 4
        # home not known yet: asked, refused for now
        for cmd, p1 in ((mav.MAV_CMD_REQUEST_MESSAGE, float(mav.MAVLINK_MSG_ID_HOME_POSITION)),
                        (mav.MAV_CMD_GET_HOME_POSITION, 0.0)):
            assert command(cmd, p1) == mav.MAV_RESULT_TEMPORARILY_REJECTED
        # the supervisor learns home: it comes unasked
        home = near()
        rig.publish(lambda now: boot_status(now, home))
        gcs.wait(lambda m: is_home(m, home), 3.0)
        rig.publish(lambda now: boot_status(now, home))  # the same home: not again
        assert not [m for m in gcs.collect(1.0) if m.get_type() == "HOME_POSITION"]
        moved = near()
        rig.publish(lambda now: boot_status(now, moved))
        gcs.wait(lambda m: is_home(m, moved), 3.0)
        for cmd, p1 in ((mav.MAV_CMD_REQUEST_MESSAGE, float(mav.MAVLINK_MSG_ID_HOME_POSITION)),
                        (mav.MAV_CMD_GET_HOME_POSITION, 0.0)):
            mark = len(gcs.log)
            assert command(cmd, p1) == mav.MAV_RESULT_ACCEPTED
            assert any(is_home(m, moved) for _, m in gcs.log[mark:])

    try:
        run_rig(cfg, ground_station, status=False)
    finally:
        gcs.close()
