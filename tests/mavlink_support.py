"""An in-process MAVLink endpoint on a real event loop, and a pymavlink ground
station on loopback UDP, for the endpoint's tests.

``run_rig(cfg, gcs)`` builds the endpoint on ``cfg`` (its ``url`` pointed at
the ground station), runs the loop in this thread and ``gcs(rig)`` on another;
``rig.on_loop(fn)`` runs ``fn`` on the loop (the bus is not thread-safe) and
``rig.seen`` holds what was published on the bus.  There is no supervisor:
``run_rig`` publishes one status as a supervisor would at boot (idle,
disarmed), without which the boat sends no heartbeat, unless told not to."""

from __future__ import annotations

import asyncio
import contextlib
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

os.environ.setdefault("MAVLINK20", "1")
os.environ.setdefault("MAVLINK_DIALECT", "common")

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav

from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.component import ComponentContext
from zarco_core.messages import MissionProgress, VesselStatus
from zarco_runtime.links.mavlink.endpoint import MavlinkEndpoint
from zarco_runtime.settings import RuntimeConfig


class Gcs:
    """A pymavlink ground station listening on a free loopback UDP port; the
    endpoint sends to it (``url``) and it answers to where that came from."""

    def __init__(self, sysid: int = 255, compid: int = 190) -> None:
        self.conn = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=sysid,
                                               source_component=compid)
        m = mav.MAVLink(self.conn, srcSystem=sysid, srcComponent=compid)
        m.robust_parsing = True
        self.conn.mav = m
        self.conn.first_byte = False
        self.mav = m
        self.sysid = sysid
        self.log: list[tuple[float, Any]] = []
        self.next_hb = 0.0

    @property
    def url(self) -> str:
        """Where the endpoint sends to reach this ground station."""
        return f"udpout:127.0.0.1:{self.conn.port.getsockname()[1]}"

    def close(self) -> None:
        self.conn.close()

    def pump(self, timeout: float = 0.05) -> Any:
        """One message (or None), with a GCS heartbeat each second."""
        now = time.monotonic()
        if now >= self.next_hb and self.log:  # once the boat is heard (udpin learns it)
            self.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0,
                                    mav.MAV_STATE_ACTIVE)
            self.next_hb = now + 1.0
        m = self.conn.recv_match(blocking=True, timeout=timeout)
        if m is None or m.get_type() == "BAD_DATA":
            return None
        self.log.append((time.monotonic(), m))
        return m

    def wait(self, cond: Callable[[Any], bool], timeout: float = 5.0) -> Any:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.pump(min(0.1, max(0.0, end - time.monotonic())))
            if m is not None and cond(m):
                return m
        raise AssertionError(f"no such message within {timeout} s")

    def collect(self, seconds: float) -> list[Any]:
        out = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            m = self.pump(min(0.1, max(0.0, end - time.monotonic())))
            if m is not None:
                out.append(m)
        return out


@dataclass
class Rig:
    """The running endpoint, seen from the ground station's thread."""

    cfg: RuntimeConfig
    bus: Bus
    clock: Clock
    loop: asyncio.AbstractEventLoop
    ep: MavlinkEndpoint
    seen: dict[type, list[Any]] = field(default_factory=dict)

    def on_loop(self, fn: Callable[[], Any], timeout: float = 5.0) -> Any:
        """Run ``fn()`` on the endpoint's loop; its result."""
        return asyncio.run_coroutine_threadsafe(_call(fn), self.loop).result(timeout)

    def publish(self, make: Callable[[float], Any]) -> Any:
        """Publish ``make(clock now)`` on the bus (on the loop); the message."""
        def go() -> Any:
            msg = make(self.clock.now())
            self.bus.publish(msg)
            return msg
        return self.on_loop(go)


async def _call(fn: Callable[[], Any]) -> Any:
    return fn()


def boot_status(now: float, home: tuple[float, float] | None = None) -> VesselStatus:
    """A supervisor's status at boot: idle, disarmed, no failsafe; ``home``
    (lat, lon degrees) or not known yet."""
    lat, lon = home if home is not None else (None, None)
    return VesselStatus(now, time.time(), "idle", False, MissionProgress(), [], {}, {}, {},
                        home_lat_deg=lat, home_lon_deg=lon)


def run_rig(cfg: RuntimeConfig, gcs: Callable[[Rig], None],
            watch: tuple[type, ...] = (),
            setup: Callable[[Bus, Clock], None] | None = None,
            status: bool = True) -> Rig:
    """Run the endpoint on ``cfg`` while ``gcs(rig)`` runs on a thread; the
    messages of the types in ``watch`` published meanwhile are in ``rig.seen``.
    ``setup(bus, clock)`` runs on the loop before the endpoint is built (to add
    other parts on the bus: a stand-in supervisor, say); ``status``: publish
    :func:`boot_status` once the endpoint is built.  The endpoint must still
    run at the end (no failure, no restart)."""
    bus = Bus()
    clock = Clock()
    seen: dict[type, list[Any]] = {k: [] for k in watch}
    for k in watch:
        bus.listen(k, seen[k].append)
    out: list[Rig] = []

    async def main() -> None:
        if setup is not None:
            setup(bus, clock)
        ctx = ComponentContext("mavlink", bus, clock)
        ep = MavlinkEndpoint(cfg, bus, clock, ctx)
        if status:
            bus.publish(boot_status(clock.now()))
        rig = Rig(cfg, bus, clock, asyncio.get_running_loop(), ep, seen)
        out.append(rig)
        task = asyncio.ensure_future(ctx.run(ep.run()))
        try:
            await asyncio.to_thread(gcs, rig)
            await asyncio.sleep(0)
            assert not task.done(), task.exception()
            assert ctx.error is None, ctx.error
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
            for link in ep.links:
                assert link.join(2.0), "a link's thread did not end"

    asyncio.run(main())
    return out[0]
