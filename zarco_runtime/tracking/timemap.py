"""The map between the buoy's acoustic UTC clock and the runtime clock.

Acoustic events carry two times: ``utc_epoch_s``, the detection time on the
buoy's GPS-disciplined UTC clock (all the estimation runs on it), and ``t``,
when the runtime received the report (its own clock).  The tracker needs the
runtime − UTC offset only to stamp the track on the runtime clock (``t0``)
and to age it.

The offset is estimated as a running minimum of t − utc over the accepted
events (the least-delayed report is the closest to the true offset), allowed
to rise by ``CLOCK_LEAK`` s per second so that it follows clock drift, minus
``feed_latency_s``; or it is fixed from outside (e.g. from the GPS time) with
:meth:`TimeMap.set_fixed`.

An event whose offset differs from the estimate by more than ``clock_tol_s``
is refused, unless ``CLOCK_RESYNC_N`` such events in a row agree with each
other: then the clock jumped and the map re-synchronises on them (the
tracker forgets every pending cycle and its filter).

Pure: no clock reads.
"""

from __future__ import annotations

import enum
import math
from typing import Any

#: the runtime-minus-UTC estimate may rise by this much per second (s/s), so it
#: follows clock drift while sticking to the least-delayed events
CLOCK_LEAK = 1e-3
#: consecutive mutually consistent events that re-synchronise a jumped clock
CLOCK_RESYNC_N = 5


class ClockCheck(enum.Enum):
    """What :meth:`TimeMap.check` says of an event."""

    #: consistent with the map (or not checkable: garbage is the assembler's)
    OK = "ok"
    #: the clock jumped: the map re-synchronised on this event and the ones before
    RESYNC = "resync"
    #: refused: its offset disagrees with the map
    REFUSE = "refuse"


class TimeMap:
    """Runtime − UTC offset of the acoustic feed (module docstring)."""

    __slots__ = ("clock_tol_s", "feed_latency_s", "fixed", "offset", "offset_t", "resync")

    def __init__(self, clock_tol_s: float, feed_latency_s: float) -> None:
        self.clock_tol_s = clock_tol_s
        self.feed_latency_s = feed_latency_s
        #: runtime − UTC (s), None until the first accepted event
        self.offset: float | None = None
        #: runtime time (s) of the last change of :attr:`offset`
        self.offset_t = 0.0
        #: set from outside: the feed no longer moves it
        self.fixed = False
        self.resync: list[float] = []

    def set_fixed(self, runtime_minus_utc_s: float) -> None:
        """Fix the runtime − UTC offset (s) instead of estimating it."""
        self.offset = runtime_minus_utc_s
        self.fixed = True

    def check(self, ev: Any) -> ClockCheck:
        """Whether ``ev``'s runtime − UTC offset agrees with the map."""
        t = getattr(ev, "t", None)
        u = getattr(ev, "utc_epoch_s", None)
        if (self.offset is None or not isinstance(t, (float, int))
                or not isinstance(u, (float, int))):
            return ClockCheck.OK
        o = t - u
        if not math.isfinite(o):
            return ClockCheck.OK
        tol = self.clock_tol_s
        if abs(o - self.offset) <= tol + CLOCK_LEAK * max(t - self.offset_t, 0.0):
            self.resync.clear()
            return ClockCheck.OK
        rs = self.resync
        rs.append(o)
        if len(rs) >= CLOCK_RESYNC_N and max(rs[-CLOCK_RESYNC_N:]) - min(
                rs[-CLOCK_RESYNC_N:]) <= tol:
            self.offset = min(rs[-CLOCK_RESYNC_N:])
            self.offset_t = t
            self.fixed = False
            rs.clear()
            return ClockCheck.RESYNC
        return ClockCheck.REFUSE

    def update(self, t: float, o: float) -> None:
        """Fold in the offset ``o`` = t − utc (s) of an event accepted at runtime ``t``."""
        if self.fixed:
            return
        if self.offset is None:
            self.offset = o
        else:
            self.offset = min(self.offset + CLOCK_LEAK * max(t - self.offset_t, 0.0), o)
        self.offset_t = t

    def rt_offset(self) -> float:
        """runtime − UTC offset for a detection time (s), the feed latency removed."""
        return (self.offset or 0.0) - self.feed_latency_s
