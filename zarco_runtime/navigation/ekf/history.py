"""Measurements at their time of validity: grouping, history and replay of late ones.

Each measurement is fused at its time of validity (arrival − configured
latency); thruster commands take their place in the same time line (the
prediction takes them up).  Measurements of one time of validity are collected
and fused together when the next time of validity (or a read of the state)
comes: one prediction, one history snapshot and, for the plain ones, one joint
update.

Every fused measurement is logged for ``history_s`` seconds, with a snapshot
of the filter taken before the first measurement of each time of validity.  A
measurement whose time of validity is before the filter time rolls the filter
back to the snapshot before the first logged measurement that is later than
it, fuses it, and re-fuses the later ones: the result is what in-order arrival
would have given.  Older than the history: dropped and counted
(``late_dropped``).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

from zarco_runtime.navigation.ekf.layout import Counters, FilterState, Measurement

#: (time of validity, snapshot before it or None within a group of equal times of
#: validity, the measurements fused at it)
Entry = tuple[float, FilterState | None, list[Measurement]]


class History:
    """The filter state now (:attr:`core`) and the fused measurements behind it."""

    def __init__(self, core: FilterState, apply: Callable[[FilterState, list[Measurement]],
                                                          None],
                 counters: Counters, history_s: float) -> None:
        self.core = core
        self._apply = apply
        self.counters = counters
        self.history_s = history_s
        self._hist: deque[Entry] = deque()
        #: measurements of one time of validity not yet fused
        self._pending: list[Measurement] = []

    def process(self, m: Measurement) -> None:
        """Fuse ``m`` at its time of validity, re-running later ones if it is late.

        Measurements of one time of validity are collected and fused together when
        the next time of validity (or a read of the state) comes."""
        pend = self._pending
        if pend:
            if m.tov == pend[0].tov:
                pend.append(m)
                return
            self.flush()
        c = self.core
        hist = self._hist
        if m.tov > c.t or (m.tov == c.t and not (hist and hist[-1][0] == m.tov)):
            self._pending.append(m)
            return
        # late, or of an instant already fused: re-run from before that instant
        first = hist[0][1] if hist else None
        if first is None or m.tov < first.t:
            self.counters.count("late_dropped")
            return
        popped: list[Entry] = []
        while hist and hist[-1][0] >= m.tov:
            popped.append(hist.pop())
        self.counters.count("replays")
        snap = popped[-1][1]  # the first of its time of validity: it has a snapshot
        assert snap is not None
        self.core = snap
        # m joins the measurements of its own time of validity, as if it had come in time
        group = [m]
        while popped and popped[-1][0] == m.tov:
            group += popped.pop()[2]
        counters = self.counters
        was = counters.replaying
        counters.replaying = True
        try:
            self._apply_logged(group)
            for _tov, _snap, later in reversed(popped):
                self._apply_logged(later)
        finally:
            counters.replaying = was

    def flush(self) -> None:
        """Fuse the measurements waiting for their time of validity to end."""
        if self._pending:
            group, self._pending = self._pending, []
            self._apply_logged(group)

    def _apply_logged(self, group: list[Measurement]) -> None:
        hist = self._hist
        tov = group[0].tov
        snap = None if hist and hist[-1][0] == tov else self.core.copy()
        self._apply(self.core, group)
        hist.append((tov, snap, group))
        horizon = self.core.t - self.history_s
        while len(hist) > 1 and hist[0][0] < horizon:
            hist.popleft()
            while hist and hist[0][1] is None:  # the rest of that time of validity
                hist.popleft()
