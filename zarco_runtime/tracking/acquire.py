"""Acquisition: resolving the mirror ambiguity and (re)initialising the filter.

A two-circle fix has two solutions, mirror images across the baseline of its
beacon and the listener.  Before the filter runs, recent fixes decide:

* with several baselines, each recent fix on another baseline votes for the
  solution of the latest fix it has a candidate near (within
  ``init_agree_m`` + ``max_speed_mps`` × their time apart) when it is near
  only one of them; a solution needs more than twice the other's votes (the
  true position is common to both baselines, the mirrors are not);
* with a single baseline the configured prior (``prior_north_m``,
  ``prior_east_m``, or where the track was lost) picks the side, and
  ``reacquire_after`` fixes must agree with the choice;
* so it does with several baselines that cannot tell the two solutions apart:
  beacons (nearly) in a line have their mirrors across that one line, and
  every other baseline's fix is near both solutions although its allowance
  is under half their distance apart.  With at least ``reacquire_after``
  such fixes (and twice as many as voted either way) and no majority, the
  network is taken as one baseline there (the count ``mirror_prior``).

The filter then starts from every remembered fix consistent with the choice
(its two ranges linearised at the candidate nearest the choice).

Re-acquisition: when the filter refused ``reacquire_after`` fixes within
``init_window_s`` the tracker lets every recent fix vote; :meth:`Acquisition.explained`
and :meth:`Acquisition.line_through` then tell whether a straight track through
the voted solutions explains more fixes than the filter's track.

Positions NED (m), times UTC (s).
"""

from __future__ import annotations

import math
from collections import deque

from zarco_runtime.tracking.fix import CircleFix, range3, range_jacobian, range_variances
from zarco_runtime.tracking.imm import Imm
from zarco_runtime.tracking.kalman import CvKalman
from zarco_runtime.tracking.params import Network, TrackerParams

#: fixes remembered for the mirror vote at (re)initialisation
INIT_MEMORY = 16


class InitEntry:
    """A fix remembered for the initialisation vote: emission time (UTC s),
    beacon index, the two-circle fix and its two ranges (m)."""

    __slots__ = ("cf", "idx", "r_i", "r_l", "t")

    def __init__(self, t: float, idx: int, cf: CircleFix, r_i: float, r_l: float) -> None:
        self.t = t
        self.idx = idx
        self.cf = cf
        self.r_i = r_i
        self.r_l = r_l


class Acquisition:
    """The fixes remembered for the vote, the refused ones, and the prior."""

    __slots__ = ("buf", "depth", "mirror_prior", "net", "p", "prior", "rejected")

    def __init__(self, params: TrackerParams, net: Network) -> None:
        self.p = params
        self.net = net
        self.depth = params.auv_depth_m
        #: recent two-circle fixes (the vote's electorate)
        self.buf: deque[InitEntry] = deque(maxlen=INIT_MEMORY)
        #: fixes the filter refused within the last ``init_window_s``
        self.rejected: deque[InitEntry] = deque(maxlen=INIT_MEMORY)
        #: prior AUV position (NED m): resolves a single baseline's mirror
        self.prior = (params.prior_north_m, params.prior_east_m)
        #: mirrors the prior resolved with several baselines in a line
        self.mirror_prior = 0

    def clear(self) -> None:
        """Forget every remembered fix (after a loss or a clock jump)."""
        self.buf.clear()
        self.rejected.clear()

    def refused(self, entry: InitEntry) -> bool:
        """Remember a fix the filter refused; True (and forget them) when
        ``reacquire_after`` were refused within ``init_window_s``: time to
        ask whether the fixes, not the filter, are right."""
        rej = self.rejected
        rej.append(entry)
        while rej and rej[0].t < entry.t - self.p.init_window_s:
            rej.popleft()
        if len(rej) < self.p.reacquire_after:
            return False
        rej.clear()
        return True

    def vote(self) -> tuple[tuple[float, float], list[InitEntry]] | None:
        """Resolve the mirror of the latest remembered fix (module docstring).
        Returns (chosen position, the recent fixes) or None (undecided)."""
        buf = self.buf
        if not buf:
            return None
        p = self.p
        last = buf[-1]
        horizon = last.t - p.init_window_s
        recent = [e for e in buf if e.t >= horizon]
        chosen = (self._by_prior(recent, last) if self.net.n - 1 <= 1
                  else self._by_baselines(recent, last))
        return None if chosen is None else (chosen, recent)

    def _by_prior(self, recent: list[InitEntry], last: InitEntry
                  ) -> tuple[float, float] | None:
        """The solution of ``last`` nearer the prior, once ``reacquire_after``
        recent fixes agree with it (a cycle mis-assembled from missed pings
        gives a fix far off)."""
        p = self.p
        c1 = (last.cf.x1, last.cf.y1)
        c2 = (last.cf.x2, last.cf.y2)
        chosen = c1 if math.dist(c1, self.prior) <= math.dist(c2, self.prior) else c2
        agree = sum(1 for e in recent if min(
            math.dist((e.cf.x1, e.cf.y1), chosen), math.dist((e.cf.x2, e.cf.y2), chosen))
            <= p.init_agree_m + p.max_speed_mps * abs(last.t - e.t))
        return chosen if agree >= p.reacquire_after else None

    def _by_baselines(self, recent: list[InitEntry], last: InitEntry
                      ) -> tuple[float, float] | None:
        """The solution of ``last`` the other baselines' fixes vote for; the
        prior's when they cannot tell the two apart (module docstring)."""
        p = self.p
        c1 = (last.cf.x1, last.cf.y1)
        c2 = (last.cf.x2, last.cf.y2)
        sep = math.dist(c1, c2)
        v1 = v2 = ties = 0
        near_any = False
        for e in recent:
            if e.idx == last.idx:
                continue
            allow = p.init_agree_m + p.max_speed_mps * abs(last.t - e.t)
            e1 = (e.cf.x1, e.cf.y1)
            e2 = (e.cf.x2, e.cf.y2)
            ok1 = min(math.dist(c1, e1), math.dist(c1, e2)) <= allow
            ok2 = min(math.dist(c2, e1), math.dist(c2, e2)) <= allow
            near_any = near_any or ok1 or ok2
            if ok1 and ok2:
                if allow < 0.5 * sep:
                    # near both though it could tell them apart: the baselines
                    # agree on the mirror too (a fix long ago allows too much
                    # to tell anything)
                    ties += 1
            elif ok1:
                v1 += 1
            elif ok2:
                v2 += 1
        if v1 > 2 * v2:  # a clear majority (outliers may vote too)
            return c1
        if v2 > 2 * v1:
            return c2
        if near_any and sep <= p.init_agree_m:
            return c1  # near the baseline: both solutions agree anyway
        if ties >= p.reacquire_after and ties >= 2 * (v1 + v2):
            # the baselines are in a line here: their fixes are near both
            # solutions, the prior picks one as it does for a single baseline
            chosen = self._by_prior(recent, last)
            if chosen is not None:
                self.mirror_prior += 1
            return chosen
        return None

    def init_filter(self, kf: CvKalman | Imm, recent: list[InitEntry], last: InitEntry,
                    chosen: tuple[float, float],
                    velocity: tuple[float, float] = (0.0, 0.0)) -> None:
        """Initialise ``kf`` on the fixes of ``recent`` consistent with ``chosen``
        (``last`` taken at ``chosen`` itself), from ``velocity`` (m/s, 1σ
        ``init_vel_sigma_mps``)."""
        p = self.p
        net = self.net
        depth = self.depth
        first = True
        for e in recent:
            allow = p.init_agree_m + p.max_speed_mps * abs(last.t - e.t)
            cands = ((e.cf.x1, e.cf.y1), (e.cf.x2, e.cf.y2))
            q = min(cands, key=lambda c: math.dist(c, chosen))
            if e is not last and math.dist(q, chosen) > allow:
                continue
            if e is last:
                q = chosen
            if first:
                kf.init(e.t, q[0], q[1], velocity[0], velocity[1], p.init_pos_sigma_m ** 2,
                        p.init_vel_sigma_mps ** 2)
                first = False
                continue
            kf.predict(e.t)
            ji = range_jacobian(net, e.idx, q[0], q[1], depth)
            jl = range_jacobian(net, net.listener, q[0], q[1], depth)
            var_i, var_l = range_variances(net, e.idx, p.timing_sigma_s, p.range_sigma_m)
            kf.update([ji, jl], [e.r_i - range3(net, e.idx, q[0], q[1], depth) + ji[0] * q[0]
                                 + ji[1] * q[1],
                                 e.r_l - range3(net, net.listener, q[0], q[1], depth)
                                 + jl[0] * q[0] + jl[1] * q[1]], [var_i, var_l])

    def explained(self, entries: list[InitEntry], x: float, y: float, vx: float,
                  vy: float, t: float) -> int:
        """How many ``entries`` have a solution within ``init_agree_m`` of the
        straight track through (x, y) at UTC ``t`` with velocity (vx, vy)."""
        tol2 = self.p.init_agree_m ** 2
        n = 0
        for e in entries:
            ex = x + vx * (e.t - t)
            ey = y + vy * (e.t - t)
            cf = e.cf
            if min((cf.x1 - ex) ** 2 + (cf.y1 - ey) ** 2,
                   (cf.x2 - ex) ** 2 + (cf.y2 - ey) ** 2) <= tol2:
                n += 1
        return n

    def line_through(self, entries: list[InitEntry], last: InitEntry,
                     chosen: tuple[float, float]
                     ) -> tuple[float, float, float, float] | None:
        """Least-squares straight track (x, y, vx, vy at ``last.t``) through the
        solutions of ``entries`` consistent with ``chosen`` (None if < 2)."""
        p = self.p
        pts = []
        for e in entries:
            allow = p.init_agree_m + p.max_speed_mps * abs(last.t - e.t)
            cf = e.cf
            d1 = math.dist((cf.x1, cf.y1), chosen)
            d2 = math.dist((cf.x2, cf.y2), chosen)
            q = (cf.x1, cf.y1) if d1 <= d2 else (cf.x2, cf.y2)
            if min(d1, d2) <= allow:
                pts.append((e.t - last.t, q[0], q[1]))
        n = len(pts)
        if n < 2:
            return None
        mt = sum(t for t, _, _ in pts) / n
        mx = sum(x for _, x, _ in pts) / n
        my = sum(y for _, _, y in pts) / n
        stt = sum((t - mt) ** 2 for t, _, _ in pts)
        if stt < 1e-6:
            return None
        vx = sum((t - mt) * (x - mx) for t, x, _ in pts) / stt
        vy = sum((t - mt) * (y - my) for t, _, y in pts) / stt
        return mx - vx * mt, my - vy * mt, vx, vy
