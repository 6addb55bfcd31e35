"""RTCM3 from shore, relayed within a byte budget and off the control path.

zenoh keeps the latest :data:`RING` ``rtcm`` samples in a ring channel
(older ones are overwritten there, uncounted); the relay's own thread (a
:class:`~.ring_reader.RingReader`) reads at most that many every
:data:`READ_PERIOD_S`.  Before a byte is copied, a sample larger than
:data:`MAX_RTCM_BYTES` is dropped, and so is a sample beyond the byte budget
(a token bucket of ``rtcm_budget_bps`` bytes per second, holding one
second's worth): a flood costs the link bandwidth, never the control loop.
What fits is reassembled into whole RTCM3 frames whose CRC-24Q is checked
(:class:`~drivers.rtcm.Rtcm3Filter`), and only whole valid frames are posted
to the event loop (and from there to the GPS driver, which checks them once
more, cheaply: one CRC per frame).

The frame filter costs about 0.1 µs per byte of a sane stream, but a
hostile one (every other byte a plausible frame header) makes it check up
to a thousand bytes per byte received.  The relay thread therefore also
keeps a CPU budget, :data:`CPU_S_PER_S` seconds of its own CPU time per
second; data arriving once it is spent is dropped until the next second.
It feeds the filter in slices of :data:`SLICE_BYTES` so that it notices.

Counters (the link's ``health``): ``rtcm_bytes_in`` accepted,
``rtcm_budget_dropped_bytes`` over the byte budget,
``rtcm_oversize_dropped`` samples larger than the bound,
``rtcm_cpu_dropped_bytes`` over the CPU budget, and the filter's
``relay_frames``, ``relay_bad_frames``, ``relay_dropped_bytes``.
"""

from __future__ import annotations

import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

from drivers.rtcm import Rtcm3Filter

#: an ``rtcm`` sample larger than this is dropped unread (bytes): a relay sends
#: what it read, a few frames of at most 1029 bytes
MAX_RTCM_BYTES = 16384
#: samples zenoh keeps for the relay (the latest; older ones are overwritten)
RING = 64
#: the relay reads at most RING samples every READ_PERIOD_S (s)
READ_PERIOD_S = 0.02
#: the relay thread's CPU time per second of wall time (s/s)
CPU_S_PER_S = 0.05
#: the filter is fed this many bytes at a time (the CPU budget is checked between)
SLICE_BYTES = 1024


class TokenBucket:
    """``rate`` tokens per second, at most ``burst`` saved (thread-safe)."""

    def __init__(self, rate: float, burst: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.rate = rate
        self.burst = burst
        self.clock = clock
        self.tokens = burst
        self.t = clock()
        self._lock = threading.Lock()

    def take(self, n: float) -> bool:
        """Take ``n`` tokens if there are (True), else take none (False)."""
        with self._lock:
            now = self.clock()
            self.tokens = min(self.burst, self.tokens + (now - self.t) * self.rate)
            self.t = now
            if n > self.tokens:
                return False
            self.tokens -= n
            return True


class RtcmRelay:
    """The byte budget, the frame filter and its CPU budget (see the module
    docstring); :meth:`on_sample` runs on the ring reader's thread."""

    def __init__(self, budget_bps: float, post: Callable[[bytes], object]) -> None:
        self.bucket = TokenBucket(budget_bps, max(budget_bps, MAX_RTCM_BYTES))
        self.post = post
        self._lock = threading.Lock()
        self._counters: Counter[str] = Counter()
        self._filter_counters: dict[str, int] = {}  # the reader thread's
        self._filter = Rtcm3Filter(self._filter_counters)
        self._second = 0.0
        self._cpu_at_second = 0.0

    def counters(self) -> dict[str, int]:
        """A copy of the counters (any thread)."""
        with self._lock:
            out = dict(self._counters)
        return out

    def _count(self, key: str, n: int = 1) -> None:
        with self._lock:
            self._counters[key] += n

    def on_sample(self, sample: Any) -> None:
        """One ``rtcm`` sample: bounded, within the budget, filtered, posted."""
        payload = sample.payload
        size = len(payload)
        if size > MAX_RTCM_BYTES:
            self._count("rtcm_oversize_dropped")
            return
        if not self.bucket.take(size):
            self._count("rtcm_budget_dropped_bytes", size)
            return
        self._count("rtcm_bytes_in", size)
        self.relay(payload.to_bytes())

    def _over_cpu(self) -> bool:
        """Whether this second's CPU budget is spent (the reader's thread)."""
        now = time.monotonic()
        cpu = time.thread_time()
        if now - self._second >= 1.0:
            self._second, self._cpu_at_second = now, cpu
        return cpu - self._cpu_at_second > CPU_S_PER_S

    def relay(self, chunk: bytes) -> None:
        """Filter ``chunk`` and post its whole valid frames."""
        frames: list[bytes] = []
        for i in range(0, len(chunk), SLICE_BYTES):
            if self._over_cpu():
                self._filter.reset()
                self._count("rtcm_cpu_dropped_bytes", len(chunk) - i)
                break
            frames += self._filter.feed(chunk[i:i + SLICE_BYTES])
        with self._lock:
            for k, v in self._filter_counters.items():
                self._counters[f"relay_{k[len('rtcm_'):]}"] = v
        if frames:
            self.post(b"".join(frames))
