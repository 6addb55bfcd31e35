"""RTCM3 from shore, relayed within a byte budget and off the control path.

zenoh hands the shore link each ``rtcm`` sample on its own thread.  There,
before a byte is copied, a sample larger than :data:`MAX_RTCM_BYTES` is
dropped, and so is a sample beyond the byte budget (a token bucket of
``rtcm_budget_bps`` bytes per second, holding one second's worth): a flood
costs the link bandwidth, never the control loop.  What fits goes to the
relay's own thread, which reassembles whole RTCM3 frames and checks their
CRC-24Q (:class:`~drivers.rtcm.Rtcm3Filter`), and only whole valid frames
are posted to the event loop (and from there to the GPS driver, which checks
them once more, cheaply: one CRC per frame).

The frame filter costs about 0.1 µs per byte of a sane stream, but a
hostile one (every other byte a plausible frame header) makes it check up
to a thousand bytes per byte received.  The relay thread therefore also
keeps a CPU budget, :data:`CPU_S_PER_S` seconds of its own CPU time per
second; data arriving once it is spent is dropped until the next second.
It feeds the filter in slices of :data:`SLICE_BYTES` so that it notices.

Counters (the link's ``health``): ``rtcm_bytes_in`` accepted,
``rtcm_budget_dropped_bytes`` over the byte budget,
``rtcm_oversize_dropped`` samples larger than the bound,
``rtcm_queue_dropped_bytes`` when the relay thread is behind,
``rtcm_cpu_dropped_bytes`` over the CPU budget, and the filter's
``relay_frames``, ``relay_bad_frames``, ``relay_dropped_bytes``.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections import Counter
from collections.abc import Callable

from drivers.rtcm import Rtcm3Filter

log = logging.getLogger("zarco.shore")

#: an ``rtcm`` sample larger than this is dropped unread (bytes): a relay sends
#: what it read, a few frames of at most 1029 bytes
MAX_RTCM_BYTES = 16384
#: chunks waiting for the relay thread
QUEUE_MAX = 64
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
    """Byte budget on zenoh's threads, frame filter on its own thread."""

    def __init__(self, budget_bps: float, post: Callable[[bytes], object]) -> None:
        self.bucket = TokenBucket(budget_bps, max(budget_bps, MAX_RTCM_BYTES))
        self.post = post
        self._lock = threading.Lock()
        self._counters: Counter[str] = Counter()
        self._filter_counters: dict[str, int] = {}  # the relay thread's
        self._filter = Rtcm3Filter(self._filter_counters)
        self._filter_seen: dict[str, int] = {}  # a copy, under the lock
        self._q: queue.Queue[bytes | None] = queue.Queue(QUEUE_MAX)
        self._thread: threading.Thread | None = None
        self._second = 0.0
        self._cpu_at_second = 0.0

    def counters(self) -> dict[str, int]:
        """A copy of the counters (any thread)."""
        with self._lock:
            out = dict(self._counters)
            out.update({f"relay_{k[len('rtcm_'):]}": v
                        for k, v in self._filter_seen.items()})
        return out

    def _count(self, key: str, n: int = 1) -> None:
        with self._lock:
            self._counters[key] += n

    def offer(self, size: int, read: Callable[[], bytes]) -> None:
        """One ``rtcm`` sample of ``size`` bytes (zenoh's thread); ``read`` copies it."""
        if size > MAX_RTCM_BYTES:
            self._count("rtcm_oversize_dropped")
            return
        if not self.bucket.take(size):
            self._count("rtcm_budget_dropped_bytes", size)
            return
        try:
            self._q.put_nowait(read())
        except queue.Full:
            self._count("rtcm_queue_dropped_bytes", size)
            return
        self._count("rtcm_bytes_in", size)

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="zarco-shore-rtcm",
                                        daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        t, self._thread = self._thread, None
        if t is None:
            return
        while True:  # make room for the end mark: what waits is dropped anyway
            try:
                self._q.put_nowait(None)
                break
            except queue.Full:
                with contextlib.suppress(queue.Empty):
                    self._q.get_nowait()
        t.join(timeout_s)

    def _over_cpu(self) -> bool:
        """Whether this second's CPU budget is spent (the relay thread)."""
        now = time.monotonic()
        cpu = time.thread_time()
        if now - self._second >= 1.0:
            self._second, self._cpu_at_second = now, cpu
        return cpu - self._cpu_at_second > CPU_S_PER_S

    def _run(self) -> None:
        while True:
            chunk = self._q.get()
            if chunk is None:
                return
            try:
                self.relay(chunk)
            except Exception as exc:  # a filter bug must not end the relay
                self._count("rtcm_faults")
                log.warning("shore: rtcm relay: %s: %s", type(exc).__name__, exc)

    def relay(self, chunk: bytes) -> None:
        """Filter ``chunk`` and post its whole valid frames (the relay thread)."""
        frames: list[bytes] = []
        for i in range(0, len(chunk), SLICE_BYTES):
            if self._over_cpu():
                self._filter.reset()
                self._count("rtcm_cpu_dropped_bytes", len(chunk) - i)
                break
            frames += self._filter.feed(chunk[i:i + SLICE_BYTES])
        with self._lock:
            self._filter_seen = dict(self._filter_counters)
        if frames:
            self.post(b"".join(frames))
