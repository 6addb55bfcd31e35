"""Assemble interrogation/reply/interrogation cycles from the buoy's event stream.

The AUV interrogates beacon i (event ``I``, beacon i), beacon i replies after
its turnaround τ_i (event ``R``, beacon i), and the AUV interrogates the next
beacon a fixed delay δ after hearing the reply.  The listener (at beacon k)
timestamps what it hears on UTC; a *cycle* j is the triple
(t^I_j, t^R_j, t^I_{j+1}) for one beacon (paper IV–V).

Rules, all on the listener's UTC times (s):

* an ``R`` from beacon i belongs to the *earliest* still-unanswered ``I`` of
  beacon i with τ_i ≤ t^R − t^I ≤ τ_i + 2 d_i / c (± ``tol``): the physical
  window (the reply cannot arrive before the turnaround, nor later than the
  longest detour d_i there and back); first arrival wins, so multipath copies
  of an ``I`` (always later) are never matched while the direct one is there;
* a matched pair *opens* a cycle; the next ``I`` (any beacon) closes it, unless
  it comes sooner than the AUV could possibly ping again
  (τ_i + δ + 2 r_min / c, r_min the AUV's depth offset from beacon i), which
  marks it a false or multipath detection (``impossible_timing``), or later than
  τ_i + δ + 2 r_max / c, or addresses beacon i again (the AUV interrogates
  another beacon after each reply), which means the closing ping was missed
  (cycle dropped ``missed_ping``);
* a second ``R`` for an already answered ``I`` is a late (multipath) arrival;
* two interrogations in a row with the reply between them missed still make a
  cycle (``t_r`` NaN: the range to the first beacon only) when a ``predictor``
  is given and their interval is within its window (below); an interrogation
  of the same beacon within ``MULTIPATH_I_S`` of the last is a late copy;
* with a ``predictor`` (the tracker's filter, once initialised) the closing
  window shrinks to P̂ ± 2(``n_sigma`` σ̂ + ``margin_m``)/c around the period
  P̂ = τ_i + δ + 2 r̂_i / c of the predicted range r̂_i (σ̂ its 1σ, m): a
  missed closing ping then shows as ``missed_ping`` instead of closing the
  cycle on the interrogation after it (a period one cycle too long).

Half cycles (:attr:`CycleAssembler.partial`, drained by the caller after each
:meth:`~CycleAssembler.push`): a missed interrogation costs two cycles — the
one it would have closed and the one it would have opened — yet each still
holds one range combination:

* *no closing ping* (an open cycle dropped ``missed_ping``, ``sequence`` or
  ``superseded``): (t^I, t^R) give r_i − r_L = c(t^R − t^I − τ_i) − d_i
  (``t_next`` NaN; nothing on the listener's own beacon, where it is 0);
* *no opening ping* (a reply outside every window, followed by the
  interrogation of its beacon's successor): (t^R, t^I_{j+1}) give
  r_i + r_L = c(t^I_{j+1} − t^R − δ) + d_i (``t_i`` NaN; the turnaround
  cancels), within ±2(``n_sigma`` σ̂ + ``margin_m``) of the predicted sum
  while tracking.

Every event that is not used is counted in :attr:`CycleAssembler.dropped` with
a reason; every cycle lost in :attr:`CycleAssembler.cycles_dropped`.  Reasons:

``garbage``          non-finite time, unknown kind, non-integer beacon
``unknown_beacon``   beacon id not in the network
``duplicate``        same kind, beacon and time (±0.5 µs) as a recent event
``out_of_order``     earlier than the last accepted event
``weak``             an SNR far below its kind's recent ones: a late multipath
                     copy or a false detection, most likely (:mod:`.weak`)
``impossible_timing`` an ``I`` too soon after an answered one to be the AUV's
``gate``             an ``R`` outside every open reply window
``late_arrival``     an ``R`` for an interrogation already answered
``no_reply``         an ``I`` never answered (expired from the buffer)

cycles: ``missed_ping`` (closing ``I`` not heard in time), ``sequence``
(closing ``I`` is not the configured successor), ``superseded`` (a new
pair opened before the previous cycle closed).

:meth:`CycleAssembler.push` never raises.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from zarco_runtime.tracking.params import Network
from zarco_runtime.tracking.weak import WeakArrivals

#: two events closer than this (s) with the same kind and beacon are duplicates
DUP_EPS_S = 0.5e-6
#: recent accepted events remembered for duplicate detection
DUP_MEMORY = 16
#: unanswered interrogations kept at most
MAX_CANDIDATES = 8
#: an interrogation of the same beacon this soon (s) after the last one is a
#: multipath copy (copies come 2–30 ms late; the AUV pings again ≥ τ + δ later)
MULTIPATH_I_S = 0.05


@dataclass(slots=True)
class Cycle:
    """One complete I/R/I cycle on the listener's UTC clock.

    ``index``/``beacon``: network index and wire id of the beacon interrogated;
    ``t_i``, ``t_r``, ``t_next``: UTC (s) of the interrogation, of the reply and
    of the AUV's next interrogation (addressed to ``next_beacon``) at the
    listener (``t_r`` NaN when the reply was not heard: the cycle then gives
    the range to the beacon only); ``t``: runtime time of the closing event.
    A half cycle (:attr:`CycleAssembler.partial`) has ``t_next`` or ``t_i`` NaN.
    """

    t: float
    index: int
    beacon: int
    t_i: float
    t_r: float
    t_next: float
    next_beacon: int


class CycleAssembler:
    """Stateful cycle assembly; feed events in arrival order with :meth:`push`."""

    __slots__ = ("_cands", "_last_utc", "_open", "_orphan", "_prev_i", "_recent", "_seq_next",
                 "accepted", "cycles", "cycles_dropped", "cycles_no_reply", "cycles_partial",
                 "dropped", "margin_m", "max_range_m", "n_sigma", "net", "partial", "predictor",
                 "r_min", "weak")

    def __init__(self, net: Network, auv_depth_m: float, max_range_m: float,
                 sequence: list[int] | None = None,
                 predictor: Callable[[int, float], tuple[float, float] | None] | None = None,
                 n_sigma: float = 4.0, margin_m: float = 15.0) -> None:
        self.net = net
        self.max_range_m = max_range_m
        #: (network index, UTC of the interrogation at the listener) → (r̂_i, σ̂) m, or None
        self.predictor = predictor
        self.n_sigma = n_sigma
        self.margin_m = margin_m
        #: smallest possible AUV range to each beacon (its depth offset), m
        self.r_min = tuple(abs(auv_depth_m - z) for z in net.depth)
        #: successor of each beacon id in the AUV's interrogation order (None: any)
        self._seq_next: dict[int, int] | None = None
        if sequence:
            self._seq_next = {b: sequence[(j + 1) % len(sequence)]
                              for j, b in enumerate(sequence)}
        self.dropped: Counter[str] = Counter()
        self.cycles_dropped: Counter[str] = Counter()
        self.cycles = 0
        #: cycles made of two interrogations whose reply was not heard (in ``cycles``)
        self.cycles_no_reply = 0
        #: half cycles made (module docstring), and those not yet taken
        self.cycles_partial = 0
        self.partial: list[Cycle] = []
        # the last reply heard outside every window: (utc, network index), or None
        self._orphan: tuple[float, int] | None = None
        # the last interrogation heard: (utc, network index, answered)
        self._prev_i: tuple[float, int, bool] | None = None
        #: events that passed the validity, duplicate and order checks
        self.accepted = 0
        # unanswered interrogations: [utc, network index]
        self._cands: deque[tuple[float, int]] = deque()
        # the open cycle: (index, t_i, t_r, physical p_lo, p_lo, p_hi) or None
        self._open: tuple[int, float, float, float, float, float] | None = None
        self._recent: deque[tuple[str, int, float]] = deque(maxlen=DUP_MEMORY)
        self._last_utc = -math.inf
        #: the arrivals' recent SNR levels (:mod:`.weak`)
        self.weak = WeakArrivals()

    def reset(self, clock: bool = False) -> None:
        """Forget every pending interrogation and open cycle (counters kept);
        with ``clock``, also the order and duplicate memory (after a time jump)."""
        self._cands.clear()
        self._open = None
        self._orphan = None
        self._prev_i = None
        if clock:
            self._recent.clear()
            self._last_utc = -math.inf

    def push(self, ev: Any) -> Cycle | None:
        """Take one :class:`~zarco_core.auv_messages.AcousticEvent`; return
        the cycle it completes, if any.  Never raises: anything unusable is
        counted in :attr:`dropped` / :attr:`cycles_dropped`."""
        try:
            return self._push(ev)
        except Exception:  # defensive: a malformed object must not stop the tracker
            self.dropped["garbage"] += 1
            return None

    def _push(self, ev: Any) -> Cycle | None:
        utc = ev.utc_epoch_s
        kind = ev.kind
        beacon = ev.beacon
        if (type(utc) not in (float, int) or not math.isfinite(utc) or kind not in ("I", "R")
                or type(beacon) is not int):
            self.dropped["garbage"] += 1
            return None
        idx = self.net.index.get(beacon)
        if idx is None:
            self.dropped["unknown_beacon"] += 1
            return None
        for k, b, u in self._recent:
            if k == kind and b == beacon and abs(u - utc) <= DUP_EPS_S:
                self.dropped["duplicate"] += 1
                return None
        if utc < self._last_utc - DUP_EPS_S:
            self.dropped["out_of_order"] += 1
            return None
        snr = getattr(ev, "snr_db", math.nan)
        if type(snr) in (float, int) and self.weak.weak(kind, idx, float(snr)):
            self.dropped["weak"] += 1
            return None
        self.accepted += 1
        self._recent.append((kind, beacon, utc))
        self._last_utc = max(self._last_utc, utc)
        self._expire(utc)
        if kind == "I":
            return self._on_interrogation(ev.t, utc, idx)
        self._on_reply(ev.t, utc, idx)
        return None

    def take_partial(self) -> list[Cycle]:
        """The half cycles made since the last call, oldest first (by reply)."""
        got, self.partial = self.partial, []
        got.sort(key=lambda cyc: cyc.t_r)
        return got

    def _half_closing(self, t: float, idx: int, t_i: float, t_r: float, nxt: int) -> None:
        """An answered interrogation of ``idx`` whose closing ping was missed."""
        if idx != self.net.listener:
            self.cycles_partial += 1
            self.partial.append(Cycle(t, idx, self.net.ids[idx], t_i, t_r, math.nan,
                                      self.net.ids[nxt]))

    def _half_opening(self, t: float, utc: float, idx: int) -> None:
        """The interrogation of ``idx`` heard at ``utc`` after a reply outside
        every window: a half cycle when it is the replying beacon's successor
        within the window of the sum of ranges."""
        orphan, self._orphan = self._orphan, None
        if orphan is None:
            return
        t_r, ridx = orphan
        net = self.net
        if ridx == idx and net.n > 1:
            return
        if self._seq_next is not None and self._seq_next.get(net.ids[ridx]) != net.ids[idx]:
            return
        c = net.c
        m = c * (utc - t_r - net.delta) + net.d[ridx]  # r_i + r_L (m)
        if not net.d[ridx] - c * net.tol <= m <= 2.0 * self.max_range_m + c * net.tol:
            return
        if self.predictor is not None:
            pi = self.predictor(ridx, t_r)
            pl = self.predictor(net.listener, utc)
            if pi is not None and pl is not None:
                half = 2.0 * (self.n_sigma * max(pi[1], pl[1]) + self.margin_m)
                if abs(m - pi[0] - pl[0]) > half:
                    return
        self.cycles_partial += 1
        self.partial.append(Cycle(t, ridx, net.ids[ridx], math.nan, t_r, utc, net.ids[idx]))

    def _expire(self, utc: float) -> None:
        """Drop unanswered interrogations whose every reply window has passed."""
        cands = self._cands
        hi = self.net.reply_hi
        while cands and utc - cands[0][0] > hi[cands[0][1]]:
            cands.popleft()
            self.dropped["no_reply"] += 1

    def _on_interrogation(self, t: float, utc: float, idx: int) -> Cycle | None:
        cycle = None
        op = self._open
        prev = self._prev_i
        # a late copy of the interrogation just heard is not the AUV's next ping
        if prev is None or prev[1] != idx or utc - prev[0] >= MULTIPATH_I_S:
            if self._orphan is not None:
                self._half_opening(t, utc, idx)
            self._prev_i = (utc, idx, False)
            if op is None and prev is not None and not prev[2]:
                cycle = self._no_reply_cycle(t, utc, idx, prev[0], prev[1])
        if op is not None:
            oidx, t_i, t_r, phys_lo, p_lo, p_hi = op
            dt = utc - t_i
            if dt < phys_lo:
                # the AUV cannot ping again this soon after an answered interrogation
                self.dropped["impossible_timing"] += 1
                return None
            if dt < p_lo:
                # possible, but not where the prediction expects the closing ping:
                # keep it as a candidate (it may start a cycle), do not close on it
                self._add_candidate(utc, idx)
                return None
            self._open = None
            net = self.net
            if dt > p_hi or (oidx == idx and net.n > 1):
                # too late, or the AUV cannot ping the same beacon twice in a row:
                # the pings between were missed
                self.cycles_dropped["missed_ping"] += 1
                self._half_closing(t, oidx, t_i, t_r, idx)
            elif (self._seq_next is not None
                  and self._seq_next.get(net.ids[oidx]) != net.ids[idx]):
                self.cycles_dropped["sequence"] += 1
                self._half_closing(t, oidx, t_i, t_r, idx)
            else:
                self.cycles += 1
                cycle = Cycle(t, oidx, net.ids[oidx], t_i, t_r, utc, net.ids[idx])
        self._add_candidate(utc, idx)
        return cycle

    def _no_reply_cycle(self, t: float, utc: float, idx: int, t_prev: float,
                        pidx: int) -> Cycle | None:
        """The AUV's interrogations of ``pidx`` (at ``t_prev``) and of ``idx`` (now)
        with the reply between them not heard: still a range to ``pidx`` when
        the interval is the one the prediction expects (only while tracking)."""
        net = self.net
        if pidx == idx and net.n > 1:  # a ping in between was missed
            return None
        pred = self.predictor(pidx, t_prev) if self.predictor is not None else None
        if pred is None:
            return None
        if (self._seq_next is not None
                and self._seq_next.get(net.ids[pidx]) != net.ids[idx]):
            return None
        c = net.c
        base = net.tau[pidx] + net.delta
        r_hat, sigma = pred
        half = 2.0 * (self.n_sigma * sigma + self.margin_m) / c + net.tol
        lo = max(base + 2.0 * self.r_min[pidx] / c - net.tol, base + 2.0 * r_hat / c - half)
        hi = min(base + 2.0 * self.max_range_m / c + net.tol, base + 2.0 * r_hat / c + half)
        if not lo <= utc - t_prev <= hi:
            return None
        self.cycles += 1
        self.cycles_no_reply += 1
        return Cycle(t, pidx, net.ids[pidx], t_prev, math.nan, utc, net.ids[idx])

    def _add_candidate(self, utc: float, idx: int) -> None:
        cands = self._cands
        if len(cands) >= MAX_CANDIDATES:
            cands.popleft()
            self.dropped["no_reply"] += 1
        cands.append((utc, idx))

    def _on_reply(self, t: float, utc: float, idx: int) -> None:
        net = self.net
        lo = net.reply_lo[idx]
        hi = net.reply_hi[idx]
        cands = self._cands
        for j, (t_i, cidx) in enumerate(cands):
            if cidx == idx and lo <= utc - t_i <= hi:
                # earliest matching interrogation: first arrival wins; everything
                # heard before it can no longer be answered in sequence
                for _ in range(j):
                    cands.popleft()
                    self.dropped["no_reply"] += 1
                cands.popleft()
                prev = self._prev_i
                if prev is not None and prev[0] == t_i and prev[1] == idx:
                    self._prev_i = (t_i, idx, True)
                # later copies of the same interrogation (multipath) must not pair
                # with a late copy of the reply
                copies = [cand for cand in cands if cand[1] == idx and cand[0] < utc]
                for cand in copies:
                    cands.remove(cand)
                    self.dropped["late_arrival"] += 1
                if self._open is not None:
                    self.cycles_dropped["superseded"] += 1
                    oidx, o_i, o_r = self._open[:3]
                    self._half_closing(t, oidx, o_i, o_r, idx)
                c = net.c
                base = net.tau[idx] + net.delta
                p_lo = phys_lo = base + 2.0 * self.r_min[idx] / c - net.tol
                p_hi = base + 2.0 * self.max_range_m / c + net.tol
                pred = self.predictor(idx, t_i) if self.predictor is not None else None
                if pred is not None:
                    r_hat, sigma = pred
                    half = 2.0 * (self.n_sigma * sigma + self.margin_m) / c + net.tol
                    lo = max(p_lo, base + 2.0 * r_hat / c - half)
                    hi = min(p_hi, base + 2.0 * r_hat / c + half)
                    if lo <= hi:
                        p_lo, p_hi = lo, hi
                self._open = (idx, t_i, utc, phys_lo, p_lo, p_hi)
                return
        op = self._open
        if op is not None and op[0] == idx and lo <= utc - op[1] <= hi:
            self.dropped["late_arrival"] += 1
        else:
            self.dropped["gate"] += 1
            # its interrogation may have been missed (the last one heard was to
            # the beacon before it): with the next one, a half cycle
            prev = self._prev_i
            seq = self._seq_next
            if prev is not None and (prev[1] != idx if seq is None
                                     else seq.get(net.ids[prev[1]]) == net.ids[idx]):
                self._orphan = (utc, idx)
