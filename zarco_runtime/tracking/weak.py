"""Weak arrivals: a detection much fainter than its kind's recent ones.

A late multipath copy (a reflection off the surface or the bottom) reaches
the listener weaker than the direct path, and a false detection is noise
that crossed the detector's threshold.  When the direct arrival is missed,
the copy alone is heard: its time is metres to tens of metres late, and the
cycle it makes gives ranges that long, which the gates do not always refuse
(a copy a few milliseconds late is a few metres off).

The listener reports each detection's SNR (dB).  Arrivals of one kind come
from one source over a distance that changes slowly: the replies of beacon j
cross the fixed distance from it to the listener, the AUV's interrogations
the distance from the AUV, which changes by a few metres a second.  Their
recent SNRs therefore scatter about a level: :class:`WeakArrivals` keeps the
last ``HISTORY`` of each (the replies of each beacon; the interrogations
together) and calls an arrival weak when it is more than ``SIGMAS`` robust
standard deviations (the median absolute deviation × 1.4826), and at least
``MIN_DEFICIT_DB``, below their median.  Every arrival enters the history,
weak or not (the median is robust to the few that are copies).  With the
scatter of a calm channel (2 dB) and copies 6 dB down, about two copies in
five are weak and one direct arrival in three hundred; where the channel
fades and the SNRs scatter more, the threshold widens with them and the test
says less (6 dB of scatter: one copy in twenty, one direct arrival in one
hundred and fifty).  The threshold is set to lose few direct arrivals: at 2σ
and 4 dB it caught two copies in three but lost one direct arrival in
seventy (4 % of the fixes), and the track error was worse in more missions
than it was better.
A weak arrival is dropped (:class:`~.cycles.CycleAssembler`, counted
``weak``): a cycle is lost where its direct arrival was weak, and a copy or a
false detection makes none.
"""

from __future__ import annotations

import math
from collections import deque
from statistics import median

#: recent SNRs kept per kind of arrival
HISTORY = 21
#: arrivals of a kind needed before any is judged
MIN_HISTORY = 8
#: an arrival is weak this many robust σ below the median …
SIGMAS = 3.0
#: … and at least this far below it (dB)
MIN_DEFICIT_DB = 5.0
#: a Gaussian's σ is this many times its median absolute deviation
MAD_TO_SIGMA = 1.4826


class WeakArrivals:
    """The recent SNR levels of the arrivals, by kind (module docstring)."""

    __slots__ = ("_hist",)

    def __init__(self) -> None:
        self._hist: dict[tuple[str, int], deque[float]] = {}

    def weak(self, kind: str, index: int, snr_db: float) -> bool:
        """Whether an arrival of ``kind`` (``I`` or ``R``) from the beacon of
        network ``index`` with SNR ``snr_db`` (dB) is weak; it enters the
        history either way.  A non-finite SNR is never weak and is not kept."""
        if not math.isfinite(snr_db):
            return False
        key = (kind, index if kind == "R" else -1)
        hist = self._hist.get(key)
        if hist is None:
            hist = self._hist[key] = deque(maxlen=HISTORY)
        weak = False
        if len(hist) >= MIN_HISTORY:
            med = median(hist)
            mad = median(abs(v - med) for v in hist)
            weak = med - snr_db > max(MIN_DEFICIT_DB, SIGMAS * MAD_TO_SIGMA * mad)
        hist.append(snr_db)
        return weak

