"""The AUV's plan inferred from the legs it flies: a lawnmower.

Without an a-priori plan, a survey AUV still flies one: long legs of one
length L, back and forth, each pair joined by a short leg of one spacing W,
always swept the same way.  From its first legs the rest is predictable:
:class:`LawnmowerInference` returns the plan they make — the corner where
the last long leg ended, the one level with it on the new leg, then
``UTURNS_AHEAD`` U-turns — and the tracker matches the AUV to it as to a
plan it was given (:mod:`.plan`, tentatively: an AUV that flies straight on
past a predicted corner has left it at once), so the boat turns with the
AUV at the corners predicted.

The legs come from the filter's state after every accepted update (local
NED, m and m/s; filter time, s): a stretch at least ``LEG_MIN_S`` long whose
course stays within ``BREAK_DEG`` of the stretch's own is a leg, fitted by
least squares (position against time) without its first and last positions
more than ``END_DEG`` off its course (the turns' ends); it ends when the
course is off it on ``BREAK_UPDATES`` updates in a row, the next starting
once the course has settled within ``SETTLE_DEG`` over ``SETTLE_UPDATES``
updates.  Long legs last at least ``LONG_LEG_S``.

A lawnmower is looked for on a new leg between ``INFER_AFTER_S`` and
``INFER_WINDOW_S`` after it started (its first seconds may be the end of the
turn): the new leg runs back along the last long leg (within
``ANTI_TOL_DEG``), with only short legs between.  W is its offset from that
long leg (or, better, the spacing of the two long legs before it).  A
long leg's corner is not where the AUV began its turn (it begins up to a
turning radius before the waypoint, to come out on the next line) but where
the turn reached: the leg's end carried on along it as far as the AUV went
past it within ``REACH_WINDOW_S`` (the spacing leg flown square to it lies on
the corner's line; a reversal's apex is as far out).  L is the length from
the corner of the long leg before (level across) to that leg's, or from
where the AUV set off from hovering (onto that leg, or onto the legs before
it along its course: a swing of the filter's course early on the first leg
cuts it in two).  With a short leg square to the long
ones seen between (a spacing flown straight) one long leg measured is
enough; without (a bare reversal, which any route may fly once) two,
agreeing within ``LENGTH_TOL``.  A new plan is returned only when it moves
the next corners by more than ``REPUBLISH_M``; a long leg across the
survey's (longer than ``OFF_PLAN_SPACINGS`` spacings) clears it.

Pure and deterministic: no I/O, no clocks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from zarco_runtime.tracking.ls_fit import ls_velocity

#: below this speed (m/s) the AUV hovers: no leg, and the set-off point is kept
MIN_SPEED_MPS = 0.3
#: a leg lasts at least this long (s)
LEG_MIN_S = 6.0
#: a leg is fitted on its latest this many positions at most (bounded work per
#: update and memory on a long straight run: 10 minutes of fixes a second)
MAX_LEG_POINTS = 600
#: a leg ends when the course is this far (deg) off its own on this many updates in a row
BREAK_DEG = 30.0
BREAK_UPDATES = 2
#: the trailing positions of a leg whose course is this far (deg) off its own are
#: the turn's beginning, not the leg
END_DEG = 8.0
#: a leg starts once the course stayed within this (deg) over this many updates
SETTLE_DEG = 12.0
SETTLE_UPDATES = 4
#: a lawnmower's long legs last at least this (s: 40 m at 1.4 m/s, less the
#: turns' ends)
LONG_LEG_S = 20.0
#: a lawnmower's short legs are square to its long ones within this (deg)
SQUARE_TOL_DEG = 25.0
#: a lawnmower's long legs are antiparallel within this (deg)
ANTI_TOL_DEG = 10.0
#: two long legs agree within this fraction of their length (plus 5 m)
LENGTH_TOL = 0.15
#: spacing and leg lengths (m) a lawnmower has
MIN_SPACING_M = 4.0
MAX_LEG_M = 2000.0
#: a leg across the inferred survey's long legs longer than this many spacings
#: plus this (m) ends it
OFF_PLAN_SPACINGS = 1.5
OFF_PLAN_M = 10.0
#: the lawnmower is looked for on a new leg's positions of the last
#: ``INFER_AFTER_S`` from when it has lasted that long to ``INFER_WINDOW_S`` (s)
INFER_AFTER_S = 10.0
INFER_WINDOW_S = 25.0
#: U-turns predicted ahead
UTURNS_AHEAD = 4
#: a new inference moving the next corners by less than this (m) is not returned
REPUBLISH_M = 3.0
#: the AUV set off at most this long (s) before its first leg started: that
#: leg's length runs from the set-off point
SET_OFF_S = 30.0
#: a set-off point carried over to a leg from the legs before it lies within
#: this (m) of the leg's line
SET_OFF_LINE_M = 5.0
#: how far the AUV went on past a leg's end before coming back (its turn's
#: reach: where the corner it turned was) is looked for over this long (s)
#: after the leg ended, and taken at most this far (m)
REACH_WINDOW_S = 60.0
REACH_MAX_M = 20.0

Point = tuple[float, float]


@dataclass(frozen=True, slots=True)
class Leg:
    """A straight leg: its time span (s), a point on its line (m, NED: the
    mean of its positions), its unit direction, its last position on the
    line, and the set-off point when the AUV set off from hovering just before
    it (else None)."""

    t0: float
    t1: float
    x: float
    y: float
    ux: float
    uy: float
    #: the last position, on the line (m)
    end: Point
    start: Point | None = None
    #: from the first position to the last, along the line (m)
    length: float = 0.0
    #: how far past its end (m, along it) the AUV went in the turn after it: the
    #: corner it turned lies that far on (it began to turn before the corner)
    reach: float = 0.0

    @property
    def corner(self) -> Point:
        """Where the leg's line meets the next: its end carried on by its reach."""
        return (self.end[0] + self.reach * self.ux, self.end[1] + self.reach * self.uy)

    @property
    def course(self) -> float:
        return math.atan2(self.uy, self.ux)


def _fit(points: list[tuple[float, float, float]]) -> tuple[float, float, float, float] | None:
    """(mean north, mean east, unit direction) of positions (t, x, y) fitted
    against time; None without motion."""
    f = ls_velocity(points)
    if f is None:
        return None
    xb, yb, vx, vy, v, _ = f
    return xb, yb, vx / v, vy / v


def _turn(a: float, b: float) -> float:
    return math.remainder(b - a, math.tau)


class LawnmowerInference:
    """The legs the AUV flies and the lawnmower they make (module docstring)."""

    def __init__(self) -> None:
        self.legs: list[Leg] = []
        #: the plan last returned (its points), or None
        self.plan: tuple[Point, ...] | None = None
        self._cur: list[tuple[float, float, float]] = []
        self._cur_c: list[float] = []
        self._cur_course = math.nan
        self._off = 0
        self._recent: list[tuple[float, float, float, float]] = []
        self._rest: tuple[float, float, float] | None = None
        self._leg_start: Point | None = None

    def update(self, t: float, x: float, y: float, vx: float, vy: float
               ) -> tuple[Point, ...] | None:
        """The filter's state after an accepted update; a new plan (its points:
        empty to clear the one returned before) or None for no change."""
        if not all(math.isfinite(v) for v in (t, x, y, vx, vy)):
            return None
        if math.hypot(vx, vy) < MIN_SPEED_MPS:
            self._rest = (t, x, y)
            self._cur, self._cur_c, self._recent, self._off = [], [], [], 0
            return None
        c = math.atan2(vy, vx)
        self._reach(t, x, y)
        if self._cur:
            self._cur.append((t, x, y))
            self._cur_c.append(c)
            if len(self._cur) > MAX_LEG_POINTS:  # a long leg: its latest stretch
                del self._cur[0], self._cur_c[0]
            self._off = self._off + 1 if abs(_turn(self._cur_course, c)) > math.radians(
                BREAK_DEG) else 0
            if self._off >= BREAK_UPDATES:
                leg = self._end_leg(self._cur[:-BREAK_UPDATES], self._cur_c[:-BREAK_UPDATES])
                self._cur, self._cur_c, self._off = [], [], 0
                self._recent = []
                plan = self.plan
                if leg is not None and plan is not None and _off_axis(
                        leg.course, math.atan2(plan[2][1] - plan[1][1], plan[2][0] - plan[1][0])) \
                        and leg.length > OFF_PLAN_SPACINGS * math.dist(plan[0], plan[1]) \
                        + OFF_PLAN_M:
                    # a long leg across the survey's lines: the survey is over
                    self.plan = None
                    return ()
                return None
            if len(self._cur) >= 3:
                f = _fit(self._cur)
                if f is not None:
                    self._cur_course = math.atan2(f[3], f[2])
            if INFER_AFTER_S <= t - self._cur[0][0] <= INFER_WINDOW_S:
                # a leg's first seconds may still be the turn's end (an AUV
                # closing onto its line): look on its latest positions while it
                # is young, once it has lasted
                return self._infer([p for p in self._cur if p[0] >= t - INFER_AFTER_S])
            return None
        self._recent.append((t, x, y, c))
        del self._recent[:-SETTLE_UPDATES]
        if len(self._recent) < SETTLE_UPDATES or any(
                abs(_turn(c, r[3])) > math.radians(SETTLE_DEG) for r in self._recent):
            return None
        # a leg starts
        self._cur = [(r[0], r[1], r[2]) for r in self._recent]
        self._cur_c = [r[3] for r in self._recent]
        self._cur_course = c
        rest = self._rest
        self._leg_start = (rest[1], rest[2]) if rest is not None and \
            self._recent[0][0] - rest[0] <= SET_OFF_S else None
        self._rest = None
        self._recent = []
        return None

    def _reach(self, t: float, x: float, y: float) -> None:
        """Carry the reach of the legs that ended within ``REACH_WINDOW_S``
        out to the position (x, y) (m) when it lies further on along them."""
        legs = self.legs
        for i in range(len(legs) - 1, -1, -1):
            leg = legs[i]
            if t - leg.t1 > REACH_WINDOW_S:
                break
            if t <= leg.t1:
                continue
            on = (x - leg.end[0]) * leg.ux + (y - leg.end[1]) * leg.uy
            if leg.reach < on <= REACH_MAX_M:
                legs[i] = replace(leg, reach=on)

    def _end_leg(self, points: list[tuple[float, float, float]], courses: list[float]
                 ) -> Leg | None:
        """A leg ended: fitted on its ``points`` (t, north, east), less the
        trailing ones whose course (``courses``, rad) already turned more than
        ``END_DEG`` off the leg's (the turn's first seconds), and the leading
        ones as far off (the AUV still swinging onto the line)."""
        if len(points) < 3 or points[-1][0] - points[0][0] < LEG_MIN_S:
            return None
        f = _fit(points)
        if f is None:
            return None
        n = len(points)
        lc = _course_of(f)
        while n > 3 and abs(_turn(lc, courses[n - 1])) > math.radians(END_DEG):
            n -= 1
        i = 0
        while n - i > 3 and abs(_turn(lc, courses[i])) > math.radians(END_DEG):
            i += 1  # still swinging onto it from the turn before
        f = _fit(points[i:n]) or f
        xb, yb, ux, uy = f
        along = (points[n - 1][1] - xb) * ux + (points[n - 1][2] - yb) * uy
        first = (points[i][1] - xb) * ux + (points[i][2] - yb) * uy
        leg = Leg(points[i][0], points[n - 1][0], xb, yb, ux, uy,
                  (xb + along * ux, yb + along * uy), self._leg_start, along - first)
        self.legs.append(leg)
        del self.legs[:-8]
        return leg

    def _infer(self, start: list[tuple[float, float, float]]) -> tuple[Point, ...] | None:
        """On a young leg (its latest positions ``start``): the lawnmower the
        legs before make with it, if they make one and it is new (module
        docstring)."""
        got = self._pattern(start)
        if got is None:
            return None
        if self.plan is not None and len(self.plan) >= 3:
            # the same survey: a new plan only when its next corners moved
            old = self.plan
            near = [min(math.hypot(p[0] - q[0], p[1] - q[1]) for q in old) for p in got[1:4]]
            if max(near) <= REPUBLISH_M:
                return None
        self.plan = got
        return got

    def _pattern(self, start: list[tuple[float, float, float]]) -> tuple[Point, ...] | None:
        """The lawnmower's points, the new leg starting with positions
        ``start``: it runs back along the last long leg ``a`` (only short legs
        square to it, or none, in between), ``a`` ended at the corner c1 and
        the new leg lies the spacing W off it (c2 = c1 + W across); the long
        legs' length from ``a``'s (:meth:`_long_length`)."""
        f = _fit(start)
        if f is None:
            return None
        bc = _course_of(f)
        k = len(self.legs) - 1
        while k >= 0 and _off_axis(self.legs[k].course, bc) and not _long(self.legs[k]):
            k -= 1  # the spacing: a short leg, or the arcs of a U-turn
        if k < 0 or not _back(self.legs[k].course, bc) or not _long(self.legs[k]):
            return None
        a = self.legs[k]
        nx, ny = -a.uy, a.ux
        w = (f[0] - a.x) * nx + (f[1] - a.y) * ny
        sg = 1.0 if w > 0.0 else -1.0
        sx, sy, w = sg * nx, sg * ny, abs(w)
        # the spacing between two long legs flown whole, when the AUV swept
        # the same way: the new leg's first positions are still swinging out
        j = k - 1
        while j >= 0 and _off_axis(self.legs[j].course, a.course) and not _long(self.legs[j]):
            j -= 1
        if j >= 0:
            p = self.legs[j]
            w_prev = (a.x - p.x) * sx + (a.y - p.y) * sy
            if w_prev > 0.0 and abs(w_prev - w) <= LENGTH_TOL * w + 5.0:
                w = w_prev
        # a short leg square to the long ones seen between: a lawnmower's spacing;
        # without one (a reversal) a random route looks the same once, so two
        # long legs of one length must have been seen
        square = any(abs(abs(_turn(a.course, leg.course)) - math.pi / 2.0)
                     <= math.radians(SQUARE_TOL_DEG) for leg in self.legs[k + 1:])
        length = self._long_length(k, 1 if square else 2)
        if length is None or not MIN_SPACING_M <= w <= length:
            return None
        c1 = a.corner
        c2 = (c1[0] + w * sx, c1[1] + w * sy)
        pts: list[Point] = [c1, c2]
        px, py = c2
        dx, dy = -a.ux, -a.uy
        for _ in range(UTURNS_AHEAD):
            px, py = px + length * dx, py + length * dy
            pts.append((px, py))
            px, py = px + w * sx, py + w * sy
            pts.append((px, py))
            dx, dy = -dx, -dy
        pts.append((px + length * dx, py + length * dy))
        return tuple(pts)

    def _long_length(self, k: int, need: int) -> float | None:
        """The long legs' length (m): leg ``k``'s from where it began — level
        with the end of the long leg before it (the corners at one end of a
        lawnmower are in line across the legs), or the set-off point — to its
        end; the long leg before it too when that one's beginning is known,
        and the two must agree within ``LENGTH_TOL`` (+ 5 m).  None unless
        ``need`` of them were measured."""
        lens: list[float] = []
        while k >= 0 and len(lens) < 2:
            leg = self.legs[k]
            j = k - 1
            while j >= 0 and _off_axis(self.legs[j].course, leg.course) \
                    and not _long(self.legs[j]):
                j -= 1
            prev = (self.legs[j] if j >= 0 and _back(self.legs[j].course, leg.course)
                    and _long(self.legs[j]) else None)
            if prev is not None:
                pc, lc = prev.corner, leg.corner
                begin = (pc[0] - lc[0]) * leg.ux + (pc[1] - lc[1]) * leg.uy
                lens.append(-begin)
            elif (start := self._set_off(k)) is not None:
                lc = leg.corner
                begin = (start[0] - lc[0]) * leg.ux + (start[1] - lc[1]) * leg.uy
                lens.append(-begin)
                break
            else:
                break
            k = j
        if len(lens) < need or not all(MIN_SPACING_M <= v <= MAX_LEG_M for v in lens):
            return None
        if len(lens) == 2 and abs(lens[0] - lens[1]) > LENGTH_TOL * max(lens) + 5.0:
            return None
        return lens[0]

    def _set_off(self, k: int) -> Point | None:
        """Where the AUV set off from hovering onto leg ``k``: its own set-off
        point, or that of the legs before it within ``BREAK_DEG`` of its
        course (a swing of the filter's course early on a leg cuts it in two:
        the leg flown is still one)."""
        leg = first = self.legs[k]
        while leg.start is None and k > 0:
            k -= 1
            before = self.legs[k]
            if abs(_turn(before.course, leg.course)) > math.radians(BREAK_DEG):
                return None
            leg = before
        start = leg.start
        if start is None or abs((start[0] - first.x) * first.uy - (start[1] - first.y) * first.ux
                                ) > SET_OFF_LINE_M:
            return None  # not on the leg's line: a turn, not a swing of the course
        return start


def _long(leg: Leg) -> bool:
    """A long leg of a lawnmower lasts at least ``LONG_LEG_S``."""
    return leg.t1 - leg.t0 >= LONG_LEG_S


def _off_axis(c0: float, c1: float) -> bool:
    """Course ``c1`` (rad) is neither along ``c0`` nor back along it (within
    ``ANTI_TOL_DEG``)."""
    d = abs(_turn(c0, c1))
    return math.radians(ANTI_TOL_DEG) < d < math.pi - math.radians(ANTI_TOL_DEG)


def _back(c0: float, c1: float) -> bool:
    """Course ``c1`` (rad) runs back along ``c0`` (within ``ANTI_TOL_DEG``)."""
    return abs(_turn(c0, c1 + math.pi)) <= math.radians(ANTI_TOL_DEG)


def _course_of(f: tuple[float, float, float, float]) -> float:
    """The course (rad) of a fit from :func:`_fit`."""
    return math.atan2(f[3], f[2])
