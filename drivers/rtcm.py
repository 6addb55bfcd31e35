"""RTCM3 framing: only whole frames with a valid CRC-24Q reach a GPS receiver.

An RTCM3 frame (RTCM 10403.x, transport layer) is::

    0xD3 | 6 reserved bits (0) + 10-bit length N | N bytes of message | CRC-24Q (3 bytes)

:class:`Rtcm3Filter` takes a byte stream in chunks of any size (a serial
base station, a TCP/NTRIP caster, a file, the shore link, MAVLink
GPS_RTCM_DATA) and returns the whole frames whose CRC-24Q checks; anything
else (a UBX command, NMEA, noise, a truncated or corrupted frame) is counted
and dropped, so that nothing but valid corrections is ever written to a
receiver's port.  After a bad candidate the filter resynchronises on the
next preamble byte; a candidate whose announced length runs past the data
received so far does not hold back a whole valid frame found inside it.

The CRC-24Q (polynomial 0x1864CFB, initial value 0, no final XOR) is a
table-driven implementation: the bit-by-bit reference (``pyrtcm``'s
``calc_crc24q``) costs about 2 µs per byte, which would hold the event loop
for 2 ms on a 1 kB MSM7 frame; the table costs a tenth of that.  The tests
check one against the other.
"""

from __future__ import annotations

from collections.abc import MutableMapping

#: first byte of every RTCM3 frame
PREAMBLE = 0xD3
#: header (preamble + reserved/length) and CRC sizes (bytes)
HEADER_LEN = 3
CRC_LEN = 3
#: the largest message a frame can carry (10-bit length)
MAX_PAYLOAD = 1023
MAX_FRAME = HEADER_LEN + MAX_PAYLOAD + CRC_LEN
_POLY = 0x1864CFB


def _table() -> tuple[int, ...]:
    out = []
    for i in range(256):
        crc = i << 16
        for _ in range(8):
            crc <<= 1
            if crc & 0x1000000:
                crc ^= _POLY
        out.append(crc & 0xFFFFFF)
    return tuple(out)


_CRC_TABLE = _table()


def crc24q(data: bytes | bytearray | memoryview) -> int:
    """CRC-24Q of ``data``; 0 when ``data`` is a frame with its CRC appended."""
    crc = 0
    table = _CRC_TABLE
    for b in data:
        crc = ((crc << 8) & 0xFFFFFF) ^ table[(crc >> 16) ^ b]
    return crc


def frame(payload: bytes) -> bytes:
    """Wrap a message (at most 1023 bytes) into an RTCM3 frame with its CRC."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"an RTCM3 message holds at most {MAX_PAYLOAD} bytes, "
                         f"got {len(payload)}")
    head = bytes((PREAMBLE, len(payload) >> 8, len(payload) & 0xFF)) + payload
    return head + crc24q(head).to_bytes(3, "big")


def message_type(frame_bytes: bytes) -> int | None:
    """The 12-bit message number of a frame (None if it carries fewer than 2 bytes)."""
    if len(frame_bytes) < HEADER_LEN + 2 + CRC_LEN:
        return None
    return (frame_bytes[3] << 4) | (frame_bytes[4] >> 4)


def _valid_frame_from(buf: bytearray, start: int, n: int) -> int:
    """Index of the first whole, CRC-valid frame starting at or after ``start``
    within ``buf[:n]``; -1 if none."""
    j = buf.find(PREAMBLE, start, n)
    while j >= 0:
        if n - j >= HEADER_LEN and not buf[j + 1] & 0xFC:
            end = j + HEADER_LEN + (((buf[j + 1] & 0x03) << 8) | buf[j + 2]) + CRC_LEN
            if end <= n and crc24q(memoryview(buf)[j:end]) == 0:
                return j
        j = buf.find(PREAMBLE, j + 1, n)
    return -1


class Rtcm3Filter:
    """Reassembles RTCM3 frames from chunks of one byte stream; passes only valid ones.

    One filter per source (two sources interleaved in one filter would
    corrupt each other's frames).  Counters, added to ``counters`` if given:
    ``rtcm_frames`` frames passed, ``rtcm_bad_frames`` candidates (preamble,
    zero reserved bits, a whole length's worth of bytes) whose CRC failed,
    ``rtcm_dropped_bytes`` bytes that were not part of a passed frame.
    """

    def __init__(self, counters: MutableMapping[str, int] | None = None) -> None:
        self._buf = bytearray()
        self.counters: MutableMapping[str, int] = counters if counters is not None else {}
        for k in ("rtcm_frames", "rtcm_bad_frames", "rtcm_dropped_bytes"):
            self.counters.setdefault(k, 0)

    @property
    def pending(self) -> int:
        """Bytes held back: the start of a frame not yet complete."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget a partial frame (the source was reopened); its bytes count as dropped."""
        self.counters["rtcm_dropped_bytes"] += len(self._buf)
        self._buf.clear()

    def feed(self, data: bytes | bytearray | memoryview) -> list[bytes]:
        """Add ``data``; return the whole, valid frames completed by it, in order."""
        buf = self._buf
        buf += data
        n = len(buf)
        out: list[bytes] = []
        dropped = bad = 0
        i = 0
        while i < n:
            j = buf.find(PREAMBLE, i)
            if j < 0:
                dropped += n - i
                i = n
                break
            dropped += j - i
            i = j
            if n - i < HEADER_LEN:
                break
            if buf[i + 1] & 0xFC:  # the 6 reserved bits must be zero
                dropped += 1
                i += 1
                continue
            end = i + HEADER_LEN + (((buf[i + 1] & 0x03) << 8) | buf[i + 2]) + CRC_LEN
            if end > n:
                # wait for the rest of this candidate, unless a whole valid frame
                # already starts inside it: then it was noise that looked like a header
                k = _valid_frame_from(buf, i + 1, n)
                if k < 0:
                    break
                bad += 1
                dropped += k - i
                i = k
                continue
            candidate = bytes(buf[i:end])
            if crc24q(candidate) == 0:
                out.append(candidate)
                i = end
            else:
                bad += 1
                dropped += 1
                i += 1
        del buf[:i]
        c = self.counters
        if out:
            c["rtcm_frames"] += len(out)
        if bad:
            c["rtcm_bad_frames"] += bad
        if dropped:
            c["rtcm_dropped_bytes"] += dropped
        return out
