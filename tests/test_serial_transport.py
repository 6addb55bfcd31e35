"""The GPS driver over a real serial port (a pseudo-terminal), on the real clock."""

from __future__ import annotations

import asyncio
import contextlib
import os
import tty
from pathlib import Path

from drivers.gps_parser import parse_gps
from drivers.nmea_device import NmeaDevice
from drivers.settings import Device
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.messages import DeviceHealth, GpsFix, HealthState

LOG = Path(__file__).parent / "data" / "gpsd-logs" / "nmea-rtk.log"


def test_gps_driver_reads_a_pty_and_survives_garbage() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    lines = [ln for ln in LOG.read_bytes().splitlines(keepends=True) if ln.startswith(b"$")]

    async def main() -> tuple[list[GpsFix], list[DeviceHealth], dict[str, int]]:
        bus = Bus()
        fixes = bus.subscribe(GpsFix, maxlen=10_000)
        health = bus.subscribe(DeviceHealth, maxlen=1000)
        dev = NmeaDevice("gps", Device(url=f"serial://{path}", stale_s=0.5), bus, Clock(),
                         lambda line, t: parse_gps(line, t, "gps"))
        task = asyncio.create_task(dev.run(), name="gps")
        await asyncio.sleep(0.2)
        loop = asyncio.get_running_loop()
        # noise, a truncated sentence and a bad checksum between real sentences
        junk = b"\x00\xff\x13garbage$GNGGA,1328*00\r\n$GNGGA,132819.60,4134.4*6A\r\n"
        await loop.run_in_executor(None, os.write, master, junk)
        for i in range(0, len(lines), 8):
            await loop.run_in_executor(None, os.write, master, b"".join(lines[i:i + 8]))
            await asyncio.sleep(0.005)
        await asyncio.sleep(0.3)
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        return fixes.drain(), health.drain(), dict(dev.counters)

    try:
        fixes, health, counters = asyncio.run(main())
    finally:
        os.close(master)
        os.close(slave)
    gga = sum(1 for ln in lines if b"GGA" in ln[:7])
    rmc = sum(1 for ln in lines if b"RMC" in ln[:7])
    assert len(fixes) == gga + rmc  # every real fix arrived through the serial port
    assert fixes[0].lat_deg is not None and abs(fixes[0].lat_deg - 41.5749659) < 1e-6
    assert counters["checksum"] >= 1 and counters["bytes_discarded"] > 0
    assert any(h.state is HealthState.OK for h in health)


def test_rtcm3_corrections_are_written_to_the_gps_port(tmp_path: Path) -> None:
    """Correction bytes from a file:// source reach the receiver's port, untouched,
    while the driver keeps reading NMEA from the same port."""
    master, slave = os.openpty()
    tty.setraw(slave)
    tty.setraw(master)
    path = os.ttyname(slave)
    # an RTCM3 1005 frame (station coordinates), with its CRC-24Q
    rtcm = bytes.fromhex("D300133ED7D30202980EDEEF34B4BD62AC0941986F33360B98")
    src = tmp_path / "corrections.rtcm3"
    src.write_bytes(rtcm * 20)

    async def main() -> tuple[bytes, dict[str, int]]:
        bus = Bus()
        dev = NmeaDevice("gps", Device(url=path, corrections_url=f"file://{src}",
                                       corrections_rate_bps=5000.0),
                         bus, Clock(), lambda line, t: parse_gps(line, t, "gps"))
        task = asyncio.create_task(dev.run(), name="gps")
        loop = asyncio.get_running_loop()
        got = b""
        deadline = loop.time() + 3.0
        while len(got) < len(rtcm) * 20 and loop.time() < deadline:
            await asyncio.sleep(0.05)
            with contextlib.suppress(BlockingIOError):
                got += os.read(master, 65536)
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        return got, dict(dev.counters)

    os.set_blocking(master, False)
    try:
        got, counters = asyncio.run(main())
    finally:
        os.close(master)
        os.close(slave)
    assert got == rtcm * 20
    assert counters["corrections_bytes"] == len(rtcm) * 20
