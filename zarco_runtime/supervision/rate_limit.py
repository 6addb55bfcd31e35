"""Per-source limits: how many commands one sender may have handled, and how many
of its refusals become events.

A careless script or a hostile client can send thousands of commands a
second.  Each source (``shore:<user>``, ``mavlink:<system>``, ``local:uid…``)
has a token bucket: ``supervisor.command_burst`` commands at once, then
``supervisor.command_rate_hz`` a second; a command beyond is refused "rate
limited" without being handled (``stop`` and ``disarm`` are never limited).
Every command still gets its acknowledgement, but the operator's event
stream (shore ``event``, MAVLink STATUSTEXT, the journal) tells at most
:data:`EVENTS_PER_S` acknowledgements a second per source and then, once a
second, how many more there were.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

#: sources remembered at most; beyond, the longest idle is forgotten (a new source
#: starts with a full bucket, so forgetting one only ever lets it send its burst)
MAX_SOURCES = 256
#: acknowledgement events told per second per source
EVENTS_PER_S = 5


@dataclass(slots=True)
class _Bucket:
    tokens: float
    t: float


class TokenBuckets:
    """One token bucket per source; ``rate()`` (1/s) and ``burst()`` are read at
    every call (a parameter change applies at once)."""

    def __init__(self, rate: Callable[[], float], burst: Callable[[], int]) -> None:
        self.rate = rate
        self.burst = burst
        self._b: OrderedDict[str, _Bucket] = OrderedDict()
        self.limited = 0

    def take(self, source: str, now: float) -> bool:
        """Whether ``source`` may have one more command handled at ``now`` (s)."""
        burst = float(self.burst())
        b = self._b.get(source)
        if b is None:
            b = self._b[source] = _Bucket(burst, now)
            while len(self._b) > MAX_SOURCES:
                self._b.popitem(last=False)
        else:
            self._b.move_to_end(source)
            b.tokens = min(burst, b.tokens + max(0.0, now - b.t) * self.rate())
            b.t = now
        if b.tokens >= 1.0:
            b.tokens -= 1.0
            return True
        self.limited += 1
        return False


class EventBudget:
    """At most :data:`EVENTS_PER_S` events a second per source; the rest counted
    and told in one line when the second is over (:meth:`overflow`)."""

    def __init__(self, per_s: int = EVENTS_PER_S) -> None:
        self.per_s = per_s
        self._win: OrderedDict[str, list[float]] = OrderedDict()  # source → [t0, told, held]

    def allow(self, source: str, now: float) -> bool:
        w = self._win.get(source)
        if w is None or now - w[0] >= 1.0:
            held = w[2] if w is not None else 0.0
            w = self._win[source] = [now, 0.0, held]
            self._win.move_to_end(source)
            while len(self._win) > MAX_SOURCES:
                self._win.popitem(last=False)
        if w[1] < self.per_s:
            w[1] += 1
            return True
        w[2] += 1
        return False

    def overflow(self, now: float) -> list[tuple[str, int]]:
        """(source, events held back) for every source whose second is over."""
        out = []
        for src, w in self._win.items():
            if w[2] and now - w[0] >= 1.0:
                out.append((src, int(w[2])))
                w[2] = 0.0
        return out
