"""GPS_RAW_INT carries what the receiver says: real NMEA bytes (built with
pynmea2, an independent encoder) written to a pseudo-terminal, read by the
runtime's GPS driver, turned into GPS_RAW_INT by the MAVLink endpoint and read
back by a pymavlink ground station on loopback.

A receiver sends several sentences per epoch and only GGA (or GNS) carries the
satellites, the HDOP, the altitude and the RTK quality: the RMC that follows
must not hide them.  Cases are drawn at random from the ranges a receiver
gives (0–40 satellites, HDOP 0.5–9.9, every fix quality, GGA+RMC with or
without the FAA mode, GNS), with GST errors now and then."""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import random
import time
import tty
from dataclasses import dataclass
from typing import Any

os.environ.setdefault("MAVLINK20", "1")
os.environ.setdefault("MAVLINK_DIALECT", "common")

import pynmea2
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav

from drivers.gps_parser import parse_gps
from drivers.nmea_device import NmeaDevice
from drivers.transports import SystemPorts
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.component import ComponentContext
from zarco_runtime.links.mavlink.endpoint import MavlinkEndpoint
from zarco_runtime.settings import RuntimeConfig

#: GGA quality digit → (GPS_RAW_INT fix_type, RMC FAA mode letter)
QUALITY = {
    0: (mav.GPS_FIX_TYPE_NO_FIX, "N"),
    1: (mav.GPS_FIX_TYPE_3D_FIX, "A"),
    2: (mav.GPS_FIX_TYPE_DGPS, "D"),
    4: (mav.GPS_FIX_TYPE_RTK_FIXED, "R"),
    5: (mav.GPS_FIX_TYPE_RTK_FLOAT, "F"),
}


@dataclass
class Case:
    lat: float
    lon: float
    alt_m: float
    quality: int
    sats: int
    hdop: float
    kind: str  # "gga+rmc", "gga+rmc-nomode" (NMEA 2.2 RMC), "gns"
    sigma: tuple[float, float, float] | None  # GST 1σ lat, lon, alt (m)


def dm(x: float, pos: str, neg: str, width: int) -> tuple[str, str]:
    a = abs(x)
    d = int(a)
    return f"{d:0{width}d}{(a - d) * 60.0:09.6f}", pos if x >= 0 else neg


def sentences(c: Case, utc: str) -> bytes:
    la, ns = dm(c.lat, "N", "S", 2)
    lo, ew = dm(c.lon, "E", "W", 3)
    out: list[str] = []
    mode = QUALITY[c.quality][1]
    if c.kind == "gns":
        out.append(pynmea2.GNS("GN", "GNS", (utc, la, ns, lo, ew, mode + mode, f"{c.sats:02d}",
                                            f"{c.hdop:.1f}", f"{c.alt_m:.2f}", "50.0", "1.0",
                                            "0000")).render())
    else:
        out.append(pynmea2.GGA("GP", "GGA", (utc, la, ns, lo, ew, str(c.quality),
                                            f"{c.sats:02d}", f"{c.hdop:.1f}", f"{c.alt_m:.2f}",
                                            "M", "50.0", "M", "1.0", "0000")).render())
        rmc = [utc, "A", la, ns, lo, ew, "1.50", "90.0", "251125", "", ""]
        if c.kind == "gga+rmc":
            rmc.append(mode)
        out.append(pynmea2.RMC("GP", "RMC", tuple(rmc)).render())
    if c.sigma is not None:
        s_lat, s_lon, s_alt = c.sigma
        out.append(pynmea2.GST("GP", "GST", (utc, "0.05", "0.05", "0.05", "0.0", f"{s_lat:.3f}",
                                            f"{s_lon:.3f}", f"{s_alt:.3f}")).render())
    return "".join(s + "\r\n" for s in out).encode()


def draw(rng: random.Random, i: int) -> Case:
    quality = rng.choice([1, 2, 4, 5, 4, 5])
    kind = rng.choice(["gga+rmc", "gga+rmc-nomode", "gns"])
    sigma = None
    if rng.random() < 0.5:
        sigma = (rng.uniform(0.005, 3.0), rng.uniform(0.005, 3.0), rng.uniform(0.01, 5.0))
    return Case(rng.uniform(-60.0, 60.0), rng.uniform(-179.0, 179.0), rng.uniform(-20.0, 200.0),
                quality, rng.randint(4, 40), round(rng.uniform(0.5, 9.9), 1), kind, sigma)


def test_gps_raw_int_carries_satellites_hdop_and_fix_type_from_the_receiver() -> None:
    rng = random.Random(int.from_bytes(os.urandom(4), "little"))
    cases = [draw(rng, i) for i in range(8)]
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    cfg = RuntimeConfig()
    cfg.devices.gps.url = path
    cfg.mavlink.enabled = True
    cfg.mavlink.rates_hz = {"GPS_RAW_INT": 20.0}
    gcs = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=255,
                                     source_component=190)
    gcs.mav = mav.MAVLink(gcs, srcSystem=255, srcComponent=190)
    gcs.mav.robust_parsing = True
    gcs.first_byte = False
    cfg.mavlink.url = f"udpout:127.0.0.1:{gcs.port.getsockname()[1]}"
    seen: list[tuple[Case, Any]] = []

    def ground_station() -> None:
        for i, c in enumerate(cases):
            end = time.monotonic() + 10.0
            got = None
            next_write = 0.0
            while time.monotonic() < end and got is None:
                if time.monotonic() >= next_write:  # the receiver at 5 Hz
                    os.write(master, sentences(c, f"12{i:02d}00.00"))
                    next_write = time.monotonic() + 0.2
                m = gcs.recv_match(type="GPS_RAW_INT", blocking=True, timeout=0.1)
                # the case's own position, from a message built after its sentences
                if m is not None and abs(m.lat - round(c.lat * 1e7)) <= 1 \
                        and abs(m.lon - round(c.lon * 1e7)) <= 1 \
                        and m.satellites_visible == c.sats \
                        and (c.sigma is None) == (m.h_acc == 0):
                    got = m
            assert got is not None, f"case {i}: {c}: no GPS_RAW_INT with its position"
            seen.append((c, got))

    async def main() -> None:
        bus = Bus()
        clock = Clock()
        dev = NmeaDevice("gps", cfg.devices.gps, bus, clock,
                         lambda line, t: parse_gps(line, t, "gps", None), SystemPorts(),
                         rtcm=True)
        ctx = ComponentContext("mavlink", bus, clock)
        ep = MavlinkEndpoint(cfg, bus, clock, ctx)
        tasks = [asyncio.ensure_future(dev.run()), asyncio.ensure_future(ctx.run(ep.run()))]
        try:
            await asyncio.to_thread(ground_station)
            for t in tasks:
                assert not t.done(), t.exception()
        finally:
            for t in tasks:
                t.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await t
            for link in ep.links:
                assert link.join(2.0)

    try:
        asyncio.run(main())
    finally:
        gcs.close()
        os.close(master)
        os.close(slave)
    assert len(seen) == len(cases)
    for c, m in seen:
        assert m.fix_type == QUALITY[c.quality][0], (c, m)
        assert m.satellites_visible == c.sats, (c, m)
        assert m.eph == round(c.hdop * 100), (c, m)
        assert abs(m.alt - c.alt_m * 1000.0) <= 10.0, (c, m)  # the sentence's 1 cm
        if c.sigma is None:
            assert (m.h_acc, m.v_acc) == (0, 0), (c, m)
        else:
            s_lat, s_lon, s_alt = c.sigma
            assert abs(m.h_acc - math.hypot(s_lat, s_lon) * 1000.0) <= 2.0, (c, m)
            assert abs(m.v_acc - s_alt * 1000.0) <= 1.0, (c, m)
