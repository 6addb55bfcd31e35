"""RTCM3 corrections: only whole frames with a valid CRC-24Q reach the GPS port.

The filter is checked against pyrtcm (the reference decoder) and the CRC
catalogue's check value; the GPS driver is run on a real pseudo-terminal
with corrections from the bus (two sources interleaved) and from a tcp://
corrections source, both mixed with a UBX reset command and random bytes.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import random
import tty
from collections import Counter

import pytest
from pyrtcm import RTCMReader
from pyrtcm.rtcmhelpers import calc_crc24q

from drivers.gps_parser import parse_gps
from drivers.nmea_device import NmeaDevice
from drivers.rtcm import Rtcm3Filter, crc24q, frame, message_type
from drivers.settings import Device
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.messages import RtcmCorrections

#: an RTCM3 1005 frame (reference station coordinates), as the standard's example
F1005 = bytes.fromhex("D300133ED7D30202980EDEEF34B4BD62AC0941986F33360B98")
#: u-blox UBX-CFG-RST (cold start, controlled software reset): must never reach a receiver
UBX_RESET = bytes.fromhex("B562060404 00FFB90200C88F".replace(" ", ""))


def msm_like(rng: random.Random, n: int) -> bytes:
    """A frame of message type 1077 with ``n`` random bytes after the type."""
    head = bytes(((1077 >> 4) & 0xFF, (1077 & 0x0F) << 4))
    return frame(head + rng.randbytes(n))


def test_crc24q_is_the_standard_crc() -> None:
    # the catalogue's check value of CRC-24/LTE-A (= Qualcomm CRC-24Q) over "123456789"
    assert crc24q(b"123456789") == 0xCDE703
    rng = random.Random(7)
    for n in (0, 1, 2, 3, 17, 255, 1029):
        data = rng.randbytes(n)
        assert crc24q(data) == calc_crc24q(data)
    assert crc24q(F1005) == 0


def test_frames_built_here_are_read_by_pyrtcm() -> None:
    rng = random.Random(3)
    f = msm_like(rng, 300)
    assert RTCMReader.parse(F1005).identity == "1005"
    assert message_type(F1005) == 1005 and message_type(f) == 1077
    assert calc_crc24q(f) == 0 and len(f) == 3 + 302 + 3


def test_filter_passes_whole_frames_split_anywhere() -> None:
    rng = random.Random(11)
    frames = [F1005, msm_like(rng, 100), msm_like(rng, 1021), frame(b"")]
    stream = b"".join(frames)
    for cut in range(1, 40):  # every chunk size from 1 byte up
        flt = Rtcm3Filter()
        got: list[bytes] = []
        for i in range(0, len(stream), cut):
            got += flt.feed(stream[i:i + cut])
        assert got == frames
        assert flt.counters == {"rtcm_frames": 4, "rtcm_bad_frames": 0, "rtcm_dropped_bytes": 0}
        assert flt.pending == 0


def test_filter_drops_everything_that_is_not_a_valid_frame() -> None:
    rng = random.Random(5)
    good = [F1005, msm_like(rng, 60), msm_like(rng, 200)]
    corrupt = bytearray(good[1])
    corrupt[20] ^= 0x04  # one bit flipped in the message
    # a fake header whose length swallows the start of the next valid frame
    swallow = bytes((0xD3, 0x00, 0x10)) + b"\x01\x02\x03"
    parts = [b"$GPGGA,garbage*00\r\n", good[0], UBX_RESET, bytes(corrupt), good[1],
             swallow, good[2], bytes((0xD3, 0xFF)), b"\xd3"]
    flt = Rtcm3Filter()
    got = flt.feed(b"".join(parts))
    assert got == [good[0], good[1], good[2]]
    c = flt.counters
    assert c["rtcm_frames"] == 3
    assert c["rtcm_bad_frames"] >= 2  # the corrupted frame and the swallowing header
    # every byte is either passed, dropped, or held back (the trailing preamble)
    assert sum(map(len, got)) + c["rtcm_dropped_bytes"] + flt.pending == len(b"".join(parts))
    assert flt.pending == 1
    flt.reset()
    assert flt.pending == 0 and c["rtcm_dropped_bytes"] == len(b"".join(parts)) - sum(
        map(len, got))


def test_a_false_header_does_not_hold_back_the_frames_after_it() -> None:
    """Noise that reads as a header announcing 359 bytes, then real frames and
    the end of the stream: the frames pass at once, not 359 bytes later."""
    rng = random.Random(8)
    frames = [F1005, msm_like(rng, 30), F1005]
    flt = Rtcm3Filter()
    got = flt.feed(b"\x00\xd3\x01garbage" + b"".join(frames))
    assert got == frames
    assert flt.counters["rtcm_bad_frames"] == 1
    assert flt.counters["rtcm_dropped_bytes"] == len(b"\x00\xd3\x01garbage")
    assert flt.pending == 0


def test_random_bytes_never_pass() -> None:
    rng = random.Random(2024)
    flt = Rtcm3Filter()
    out: list[bytes] = []
    total = 0
    for _ in range(200):
        chunk = rng.randbytes(rng.randint(1, 2000))
        total += len(chunk)
        out += flt.feed(chunk)
    assert out == []
    assert flt.counters["rtcm_frames"] == 0
    assert flt.counters["rtcm_bad_frames"] > 0  # headers that fit were tried; none passed
    assert flt.counters["rtcm_dropped_bytes"] + flt.pending == total


def test_message_larger_than_a_frame_is_refused() -> None:
    with pytest.raises(ValueError):
        frame(bytes(1024))


# ----------------------------------------------------------------- on a pty


def _pty() -> tuple[int, int, str]:
    master, slave = os.openpty()
    tty.setraw(slave)
    tty.setraw(master)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


async def _read_until(master: int, n: int, timeout_s: float) -> bytes:
    loop = asyncio.get_running_loop()
    got = b""
    deadline = loop.time() + timeout_s
    while len(got) < n and loop.time() < deadline:
        await asyncio.sleep(0.02)
        with contextlib.suppress(BlockingIOError):
            got += os.read(master, 65536)
    await asyncio.sleep(0.1)  # anything more would show up now
    with contextlib.suppress(BlockingIOError):
        got += os.read(master, 65536)
    return got


def _frames_in(data: bytes) -> list[bytes]:
    """Split what the receiver got into frames, strictly: it must be frames back to back."""
    out, i = [], 0
    while i < len(data):
        assert data[i] == 0xD3, f"byte {i} is not a frame start"
        n = 3 + (((data[i + 1] & 3) << 8) | data[i + 2]) + 3
        out.append(data[i:i + n])
        i += n
    return out


def test_gps_port_gets_only_valid_frames_from_the_bus() -> None:
    """Two sources (shore, MAVLink) interleaved, in odd chunks, with a UBX reset,
    random bytes and a corrupted frame: the pty sees exactly the valid frames."""
    rng = random.Random(9)
    shore = [msm_like(rng, rng.randint(10, 900)) for _ in range(8)]
    mav = [F1005, msm_like(rng, 40), msm_like(rng, 500)]
    bad = bytearray(msm_like(rng, 80))
    bad[-1] ^= 0xFF
    shore_stream = (UBX_RESET + shore[0] + rng.randbytes(3000) + shore[1] + bytes(bad)
                    + b"".join(shore[2:]) + UBX_RESET)
    mav_stream = b"".join(mav) + rng.randbytes(500)
    master, slave, path = _pty()

    async def main() -> tuple[bytes, Counter[str]]:
        bus = Bus()
        dev = NmeaDevice("gps", Device(url=path), bus, Clock(),
                         lambda line, t: parse_gps(line, t, "gps"), rtcm=True)
        task = asyncio.create_task(dev.run())
        while dev._reading is None:  # frames for a GPS port not open yet are dropped
            await asyncio.sleep(0.01)
        i = j = 0
        while i < len(shore_stream) or j < len(mav_stream):
            a, b = rng.randint(1, 700), rng.randint(1, 300)
            bus.publish(RtcmCorrections(0.0, "shore", shore_stream[i:i + a]))
            bus.publish(RtcmCorrections(0.0, "mavlink", mav_stream[j:j + b]))
            i, j = i + a, j + b
            await asyncio.sleep(0.001)
        want = sum(map(len, shore + mav))
        got = await _read_until(master, want, 3.0)
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        return got, dev.counters

    try:
        got, counters = asyncio.run(main())
    finally:
        os.close(master)
        os.close(slave)
    frames = _frames_in(got)
    assert [f for f in frames if f in shore] == shore  # each source's frames, in order
    assert [f for f in frames if f in mav] == mav
    assert len(frames) == len(shore) + len(mav)
    assert all(calc_crc24q(f) == 0 for f in frames)  # pyrtcm's own CRC check
    assert b"\xb5\x62" not in got
    assert counters["rtcm_frames"] == len(frames)
    assert counters["rtcm_bad_frames"] >= 1
    assert counters["rtcm_dropped_bytes"] >= 2 * len(UBX_RESET) + 3000 + 500
    assert counters["corrections_bytes"] == len(got)


def test_tcp_corrections_source_goes_through_the_same_filter() -> None:
    """devices.gps.corrections_url = tcp://...: a caster sending a UBX reset and
    noise between frames; the pty sees the frames only."""
    rng = random.Random(4)
    frames = [F1005] + [msm_like(rng, rng.randint(20, 400)) for _ in range(5)]
    stream = b"".join(f + UBX_RESET + rng.randbytes(rng.randint(0, 300)) for f in frames)
    master, slave, path = _pty()

    async def main() -> tuple[bytes, Counter[str]]:
        port_open = asyncio.Event()

        async def serve(_r: asyncio.StreamReader, w: asyncio.StreamWriter) -> None:
            await port_open.wait()  # frames for a GPS port not open yet are dropped
            for k in range(0, len(stream), 97):
                w.write(stream[k:k + 97])
                await w.drain()
                await asyncio.sleep(0.002)
            await asyncio.sleep(5)

        server = await asyncio.start_server(serve, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        bus = Bus()
        dev = NmeaDevice("gps", Device(url=path, corrections_url=f"tcp://127.0.0.1:{port}"),
                         bus, Clock(), lambda line, t: parse_gps(line, t, "gps"), rtcm=True)
        task = asyncio.create_task(dev.run())
        while dev._reading is None:
            await asyncio.sleep(0.01)
        port_open.set()
        got = await _read_until(master, sum(map(len, frames)), 3.0)
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        server.close()
        return got, dev.counters

    try:
        got, counters = asyncio.run(main())
    finally:
        os.close(master)
        os.close(slave)
    assert _frames_in(got) == frames
    assert b"\xb5\x62" not in got
    assert counters["rtcm_frames"] == len(frames)
    assert counters["rtcm_dropped_bytes"] >= len(frames) * len(UBX_RESET)
