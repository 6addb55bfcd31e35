"""GPS_RTCM_DATA reassembly: MAVLink fragments → whole RTCM blocks for the GPS.

A GCS cuts each block of RTCM3 bytes from its base station into at most four
GPS_RTCM_DATA messages of up to 180 bytes.  ``flags`` bit 0 says the block is
fragmented, bits 1-2 give the fragment's index, bits 3-7 the block's sequence
number.  A block is whole when its four fragments are in, or all those before
the first fragment shorter than 180 bytes.  This follows ArduPilot's
reassembly (a repeated fragment of the current block is ignored; a fragment of
another block, or a second copy of an index with other bytes, drops what was
gathered) with one addition: QGroundControl sends a block of exactly 180, 360
or 540 bytes as full fragments with no empty one after them, so a gathered run
of full fragments 0..k−1 is passed on when the next block (another sequence
number) begins, or after ``flush_s`` without more fragments.  Nothing here checks the RTCM3 framing:
every corrections source goes through the GPS driver's CRC-24Q filter, which
drops whatever is not a whole, valid frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

FRAGMENT_LEN = 180
MAX_FRAGMENTS = 4


@dataclass(slots=True)
class RtcmCounters:
    messages: int = 0          # GPS_RTCM_DATA messages taken
    blocks: int = 0            # whole blocks passed on
    bytes: int = 0             # bytes passed on
    duplicates: int = 0        # repeated fragments ignored
    fragments_dropped: int = 0  # fragments of blocks that never became whole
    bad_length: int = 0        # len > 180


@dataclass(slots=True)
class _Block:
    sequence: int
    parts: dict[int, bytes] = field(default_factory=dict)
    t_last: float = 0.0

    def whole(self) -> bytes | None:
        """The block if it is complete (see the module docstring), else None."""
        data = b""
        for i in range(MAX_FRAGMENTS):
            p = self.parts.get(i)
            if p is None:
                return None
            data += p
            if len(p) < FRAGMENT_LEN:
                return data
        return data

    def full_run(self) -> bytes | None:
        """Fragments 0..k−1 all full and nothing after them: QGroundControl's
        block of an exact multiple of 180 bytes."""
        k = len(self.parts)
        if k == 0 or sorted(self.parts) != list(range(k)):
            return None
        if any(len(p) != FRAGMENT_LEN for p in self.parts.values()):
            return None
        return b"".join(self.parts[i] for i in range(k))


class RtcmReassembler:
    """Feed it GPS_RTCM_DATA (``flags``, ``data[:len]``); it returns the whole
    blocks, in order.  ``flush_s`` (s): how long a run of full fragments waits
    for more before it is passed on (``poll``)."""

    def __init__(self, flush_s: float = 0.2) -> None:
        self.flush_s = flush_s
        self.block: _Block | None = None
        self.counters = RtcmCounters()

    def _close(self, flush: bool = True) -> list[bytes]:
        """Drop the block being gathered, passing on (with ``flush``) a complete run
        of full fragments."""
        b, self.block = self.block, None
        if b is None:
            return []
        run = b.full_run() if flush else None
        if run is not None:
            return [run]
        self.counters.fragments_dropped += len(b.parts)
        return []

    def feed(self, flags: int, data: bytes, t: float) -> list[bytes]:
        c = self.counters
        c.messages += 1
        if len(data) > FRAGMENT_LEN:
            c.bad_length += 1
            return []
        out: list[bytes] = []
        if not flags & 1:  # a whole block in one message
            out += self._close()
            out.append(bytes(data))
            return self._count(out)
        frag = (flags >> 1) & 0x3
        seq = (flags >> 3) & 0x1F
        b = self.block
        if b is not None:
            seen = b.parts.get(frag)
            if b.sequence == seq and seen is not None and seen == data:
                c.duplicates += 1
                return []
            if b.sequence != seq:  # the next block: the last one ends here
                out += self._close()
                b = None
            elif seen is not None:  # the same index again, other bytes: conflict
                out += self._close(flush=False)
                b = None
        if b is None:
            b = self.block = _Block(seq)
        b.parts[frag] = bytes(data)
        b.t_last = t
        whole = b.whole()
        if whole is not None:
            self.block = None
            out.append(whole)
        return self._count(out)

    def poll(self, t: float) -> list[bytes]:
        """Pass on a run of full fragments that has waited ``flush_s``."""
        b = self.block
        if b is None or t - b.t_last < self.flush_s or b.full_run() is None:
            return []
        return self._count(self._close())

    def _count(self, blocks: list[bytes]) -> list[bytes]:
        blocks = [x for x in blocks if x]
        self.counters.blocks += len(blocks)
        self.counters.bytes += sum(len(x) for x in blocks)
        return blocks
