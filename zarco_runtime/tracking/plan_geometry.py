"""Geometry of the AUV's a-priori plan: legs, corners, and the path the AUV flies.

The plan's points, local NED (x north, y east, metres), are joined by legs;
the path coordinate ``s`` is the arc length along the legs from the first
point (m); corner k joins leg k to leg k + 1 and turns the course by
``turn_rad(k)`` (+ to starboard, in (−π, π]).  Before the first point and after
the last the path goes on straight along the first and last legs.

An AUV does not turn on the spot: it rounds a corner, starting its turn
before it and joining the next leg after it.  With a turning radius R
(``radius`` below; 0: the sharp plan) corner k is rounded by the arc tangent
to both legs, its tangent length a = R tan(|θ|/2), where that fits: a
corner turning at most ``MAX_ROUND_DEG``, a at most half of either leg.
Where it does not — a sharper turn, up to a reversal, or a leg shorter than
the arcs at its ends (the short leg of a lawnmower whose lines are closer
than the AUV's turning circle) — the AUV swings out past the next line and
its guidance brings it back: that stretch is its guidance flown
(:mod:`.plan_flown`), from where it leaves the leg before the corner to where
it is back on a leg, perhaps past several corners.  The path coordinate
stays the sharp plan's: a rounded stretch [lo, hi] maps onto the arc (or
the flown polyline) linearly in angle (in metres flown), so a progress
``s`` means the same leg and corner whatever R is (:meth:`Plan.advance`
walks metres of the rounded path).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from zarco_runtime.tracking.plan_flown import Flown, fly, switch_m

#: the most points a plan may have
MAX_POINTS = 1000
#: two consecutive points closer than this (m) are one point: refused
MIN_LEG_M = 1.0
#: a plan point further than this from the origin (m) is refused
MAX_RANGE_M = 50_000.0
#: corners turning more than this (deg) are not rounded by an arc: the AUV's
#: guidance is flown there (:mod:`.plan_flown`)
MAX_ROUND_DEG = 90.0
#: a corner after a leg longer than this plus 4 turning radii (m) is rounded
#: alone: what the AUV flew about the corner before has ended on that leg
SETTLE_LEGS_M = 100.0


@dataclass(frozen=True, slots=True)
class PlanLeg:
    """Leg ``index`` of a plan, from (n0, e0) to (n1, e1) (NED, m); ``s0_m`` the
    path coordinate of its start, (ux, uy) its unit direction."""

    index: int
    n0: float
    e0: float
    n1: float
    e1: float
    s0_m: float
    length_m: float
    ux: float
    uy: float

    @property
    def course_rad(self) -> float:
        """The leg's course, clockwise from north (rad)."""
        return math.atan2(self.uy, self.ux)

    def project(self, x: float, y: float) -> tuple[float, float]:
        """(along from its start, cross-track: > 0 to starboard of its course), m."""
        dx, dy = x - self.n0, y - self.e0
        return dx * self.ux + dy * self.uy, -dx * self.uy + dy * self.ux

    def point(self, along: float, cross: float = 0.0) -> tuple[float, float]:
        """The point ``along`` metres from its start (on its line, extended),
        ``cross`` metres to starboard."""
        return (self.n0 + along * self.ux - cross * self.uy,
                self.e0 + along * self.uy + cross * self.ux)


@dataclass(frozen=True, slots=True)
class Arc:
    """Corner k rounded: over path coordinates [s_c − a, s_c + a] the arc of
    radius ``r`` about (cx, cy), from course ``psi0`` turning by ``theta``
    (rad, signed: + to starboard)."""

    s_c: float
    a: float
    r: float
    cx: float
    cy: float
    psi0: float
    theta: float

    def at(self, s: float, cross: float) -> tuple[float, float, float]:
        """(x, y, course) at path coordinate ``s`` in the arc's stretch."""
        phi = self.theta * min(1.0, max(0.0, (s - self.s_c + self.a) / (2.0 * self.a)))
        psi = self.psi0 + phi
        sg = 1.0 if self.theta > 0.0 else -1.0
        # the centre is to the turn's side: the point is r back from it, along
        # the starboard normal (−sin ψ, cos ψ) times the turn's sign
        rr = self.r - sg * cross
        return (self.cx + sg * rr * math.sin(psi), self.cy - sg * rr * math.cos(psi), psi)

    def nearest(self, x: float, y: float) -> tuple[float, float, float]:
        """(distance, s, cross) of the arc's point nearest (x, y)."""
        sg = 1.0 if self.theta > 0.0 else -1.0
        wx, wy = x - self.cx, y - self.cy
        rho = math.hypot(wx, wy)
        # the course ψ at which the arc passes the point's direction from the centre
        psi = math.atan2(sg * wx, -sg * wy) if rho > 0.0 else self.psi0
        phi = math.remainder(psi - self.psi0, math.tau) * sg
        if 0.0 <= phi <= abs(self.theta):
            s = self.s_c - self.a + 2.0 * self.a * phi / abs(self.theta)
            return abs(rho - self.r), s, sg * (self.r - rho)
        ends = []
        for s in (self.s_c - self.a, self.s_c + self.a):
            px, py, course = self.at(s, 0.0)
            cross = -(x - px) * math.sin(course) + (y - py) * math.cos(course)
            ends.append((math.hypot(x - px, y - py), s, math.copysign(1.0, cross)))
        d, s, sign = min(ends)
        return d, s, sign * d

    @property
    def stretch(self) -> float:
        """Path coordinate per metre of arc (2a / (r|θ|), ≥ 1)."""
        return 2.0 * self.a / (self.r * abs(self.theta))

    @property
    def lo(self) -> float:
        """The path coordinate where the arc starts (m)."""
        return self.s_c - self.a

    @property
    def hi(self) -> float:
        """The path coordinate where the arc ends (m)."""
        return self.s_c + self.a


#: how a corner is rounded: an arc, the AUV's guidance flown (a reversal, a
#: corner too tight for its arc), or sharp (None)
Rounding = Arc | Flown | None


class PlanError(ValueError):
    """Why some points are not a plan: the point (``index``, None for the whole
    list) and the ``reason``; :meth:`named` says it of a key."""

    def __init__(self, index: int | None, reason: str) -> None:
        super().__init__(reason if index is None else f"[{index}]: {reason}")
        self.index = index
        self.reason = reason

    def named(self, key: str) -> str:
        """``key[i]: reason`` (``key: reason`` for the whole list)."""
        return f"{key}: {self.reason}" if self.index is None else \
            f"{key}[{self.index}]: {self.reason}"


def check_points(points: list[tuple[float, float]]) -> PlanError | None:
    """Why these NED points (m) are not a plan (None when they are): 2 to
    ``MAX_POINTS`` finite points, within ``MAX_RANGE_M`` of the origin,
    consecutive ones at least ``MIN_LEG_M`` apart."""
    if len(points) > MAX_POINTS:
        return PlanError(None, f"has {len(points)} points, at most {MAX_POINTS}")
    if len(points) == 1:
        return PlanError(None, "a plan needs at least 2 points (or none)")
    for i, (n, e) in enumerate(points):
        if not (math.isfinite(n) and math.isfinite(e)):
            return PlanError(i, "not finite")
        if math.hypot(n, e) > MAX_RANGE_M:
            return PlanError(i, f"{math.hypot(n, e) / 1000.0:.0f} km from the origin (at most "
                                f"{MAX_RANGE_M / 1000.0:.0f} km)")
        if i and math.hypot(n - points[i - 1][0], e - points[i - 1][1]) < MIN_LEG_M:
            return PlanError(i, f"less than {MIN_LEG_M:g} m from point {i - 1}")
    return None


class Plan:
    """The legs of a plan given by its points (NED, m), and the path an AUV of
    turning radius R flies along them (module docstring).  Raises ValueError
    (:func:`check_points`) for points that are not a plan."""

    __slots__ = ("_arcs", "legs", "length_m", "points")

    def __init__(self, points: list[tuple[float, float]] | tuple[tuple[float, float], ...]
                 ) -> None:
        pts = [(float(n), float(e)) for n, e in points]
        why = check_points(pts)
        if why is not None:
            raise why
        if len(pts) < 2:
            raise PlanError(None, "a plan needs at least 2 points")
        self.points = tuple(pts)
        legs: list[PlanLeg] = []
        s = 0.0
        for i in range(1, len(pts)):
            (a, b), (c, d) = pts[i - 1], pts[i]
            length = math.hypot(c - a, d - b)
            legs.append(PlanLeg(i - 1, a, b, c, d, s, length, (c - a) / length,
                                (d - b) / length))
            s += length
        self.legs = tuple(legs)
        self.length_m = s
        self._arcs: dict[float, dict[int, Rounding]] = {}

    def turn_rad(self, k: int) -> float:
        """The course change at the end of leg ``k`` (rad, + to starboard); 0
        after the last leg."""
        if not 0 <= k < len(self.legs) - 1:
            return 0.0
        return math.remainder(self.legs[k + 1].course_rad - self.legs[k].course_rad, math.tau)

    def leg_at(self, s: float) -> PlanLeg:
        """The leg the path coordinate ``s`` (m) falls on (the first or last
        beyond the ends)."""
        legs = self.legs
        lo, hi = 0, len(legs) - 1
        while lo < hi:  # the last leg whose start is at or before s
            mid = (lo + hi + 1) // 2
            if legs[mid].s0_m <= s:
                lo = mid
            else:
                hi = mid - 1
        return legs[lo]

    def corner_distance(self, s: float) -> float:
        """How far (m of the plan's path coordinate) ``s`` is from the nearest
        corner; inf for a plan of one leg."""
        if len(self.legs) < 2:
            return math.inf
        leg = self.leg_at(s)
        d = math.inf
        if leg.index > 0:
            d = abs(s - leg.s0_m)
        if leg.index + 1 < len(self.legs):
            d = min(d, abs(leg.s0_m + leg.length_m - s))
        return d

    # ------------------------------------------------------------ rounding

    def corner(self, k: int, radius: float) -> Rounding:
        """How corner ``k`` is rounded for turning radius ``radius`` (m): an
        :class:`Arc` where one tangent to both legs fits, the AUV's guidance
        :class:`~.plan_flown.Flown` where none does (a turn of more than
        ``MAX_ROUND_DEG``, a leg shorter than the arcs at its ends; one stretch
        may fly several corners, each holding it), None for a sharp plan or a
        corner that does not turn.  Worked out when first asked, from the
        corner before it whose leg is long enough that nothing flown before
        it reaches it (``SETTLE_LEGS_M``), and kept: a flown stretch takes a
        few milliseconds."""
        done = self._arcs.get(radius)
        if done is None:
            if len(self._arcs) >= 64:
                self._arcs.clear()
            done = self._arcs[radius] = {}
        if k in done:
            return done[k]
        j = k
        settle = SETTLE_LEGS_M + 4.0 * radius
        while j > 0 and j - 1 not in done and self.legs[j].length_m < settle:
            j -= 1
        while k not in done:
            self._round(j, done, radius)
            while j in done:
                j += 1
        return done[k]

    def _needs_flight(self, k: int, radius: float) -> bool:
        """Whether no arc of ``radius`` (m) rounds corner ``k``."""
        th = abs(self.turn_rad(k))
        return th > math.radians(MAX_ROUND_DEG) or radius * math.tan(th / 2.0) > 0.5 * min(
            self.legs[k].length_m, self.legs[k + 1].length_m)

    def _round(self, k: int, done: dict[int, Rounding], radius: float) -> None:
        """Round corner ``k`` into ``done``, and the corners its stretch flies."""
        legs = self.legs
        th = self.turn_rad(k)
        if radius <= 0.0 or abs(th) < 1e-3:
            done[k] = None
            return
        if not self._needs_flight(k, radius):
            a = radius * math.tan(abs(th) / 2.0)
            lg = legs[k]
            x1, y1 = lg.point(lg.length_m - a)
            sg = 1.0 if th > 0.0 else -1.0
            cx, cy = x1 - sg * radius * lg.uy, y1 + sg * radius * lg.ux
            arc = Arc(legs[k + 1].s0_m, a, radius, cx, cy, lg.course_rad, th)
            nxt = k + 1
            # the next corner flown, from before this arc ends: fly both
            if not (nxt < len(legs) - 1 and abs(self.turn_rad(nxt)) >= 1e-3
                    and self._needs_flight(nxt, radius)
                    and arc.hi > legs[nxt + 1].s0_m - switch_m(radius, self.turn_rad(nxt))):
                done[k] = arc
                return
        flown, back_on = fly(self.legs, k, radius)
        for j in range(k, back_on):
            done[j] = flown

    def _rounded(self, k: int, radius: float) -> Rounding:
        """Corner ``k``'s rounding (:meth:`corner`); None beyond the corners or
        for a sharp plan."""
        if radius <= 0.0 or not 0 <= k < len(self.legs) - 1:
            return None
        return self.corner(k, radius)

    def _arc_at(self, s: float, radius: float) -> Rounding:
        """The rounded stretch that holds ``s``, if any."""
        if radius <= 0.0 or len(self.legs) < 2:
            return None
        k = self.leg_at(s).index
        for j in (k - 1, k):
            arc = self._rounded(j, radius)
            if arc is not None and arc.lo < s < arc.hi:
                return arc
        return None

    def span(self, k: int, radius: float) -> tuple[float, float]:
        """The path coordinates (m) between which corner ``k`` is rounded with
        turning radius ``radius`` (the corner's own, sharp)."""
        arc = self._rounded(k, radius)
        if arc is not None:
            return arc.lo, arc.hi
        c = self.legs[k + 1].s0_m if 0 <= k < len(self.legs) - 1 else math.inf
        return c, c

    def point_at(self, s: float, cross: float = 0.0, radius: float = 0.0
                 ) -> tuple[float, float, float]:
        """(x, y, course) at path coordinate ``s`` (m), ``cross`` metres to
        starboard, on the path of turning radius ``radius`` (m)."""
        arc = self._arc_at(s, radius)
        if arc is not None:
            return arc.at(s, cross)
        leg = self.leg_at(s)
        x, y = leg.point(s - leg.s0_m, cross)
        return x, y, leg.course_rad

    def _next_rounded(self, s: float, radius: float, step: float) -> Rounding:
        """The first rounded stretch wholly after ``s`` (``step`` > 0) or
        wholly before it (< 0), if any."""
        k = self.leg_at(s).index
        corners = range(k, len(self.legs) - 1) if step > 0 else range(k - 1, -1, -1)
        for j in corners:
            arc = self._rounded(j, radius)
            if arc is not None and (arc.lo >= s if step > 0 else arc.hi <= s):
                return arc
        return None

    def advance(self, s: float, dist: float, radius: float = 0.0) -> float:
        """The path coordinate ``dist`` metres of path (either sign) on from
        ``s``: on a rounded stretch a metre of path is ``stretch`` metres of
        the sharp plan's coordinate."""
        if radius <= 0.0 or dist == 0.0:
            return s + dist
        step = 1.0 if dist > 0.0 else -1.0
        left = abs(dist)
        for _ in range(2 * len(self.legs) + 2):
            arc = self._arc_at(s, radius)
            if arc is not None:
                room = (arc.hi - s) if step > 0 else (s - arc.lo)
                if left * arc.stretch <= room:
                    return s + step * left * arc.stretch
                left -= room / arc.stretch
                s = (arc.hi if step > 0 else arc.lo) + step * 1e-9
                continue
            # a straight stretch, up to the next rounded one
            nxt = self._next_rounded(s, radius, step)
            if step > 0:
                end = nxt.lo if nxt is not None else math.inf
                room = end - s
            else:
                end = nxt.hi if nxt is not None else -math.inf
                room = s - end
            if left <= room:
                return s + step * left
            left -= room
            s = end + step * 1e-9
        return s + step * left

    def nearest(self, x: float, y: float, s_lo: float, s_hi: float,
                radius: float = 0.0) -> tuple[float, float]:
        """(s, cross): the point of the path (of turning radius ``radius``)
        between path coordinates ``s_lo`` and ``s_hi`` (m) nearest (x, y), and
        the signed distance to it (> 0 to starboard of the path there)."""
        best = (math.inf, s_lo, 0.0)
        legs = self.legs
        k0 = self.leg_at(s_lo).index
        k1 = self.leg_at(s_hi).index
        seen: set[int] = set()
        for k in range(max(k0 - 1, 0), k1 + 1):
            leg = legs[k]
            prv = self._rounded(k - 1, radius)
            nxt = self._rounded(k, radius)
            lo = -math.inf if k == 0 else (prv.hi - leg.s0_m if prv is not None else 0.0)
            hi = (math.inf if k == len(legs) - 1
                  else (nxt.lo if nxt is not None else leg.s0_m + leg.length_m) - leg.s0_m)
            a0 = max(s_lo - leg.s0_m, lo)
            a1 = min(s_hi - leg.s0_m, hi)
            if a0 <= a1:
                along, cross = leg.project(x, y)
                a = min(max(along, a0), a1)
                px, py = leg.point(a)
                d = math.hypot(x - px, y - py)
                if d < best[0]:
                    best = (d, leg.s0_m + a, math.copysign(d, cross))
            if (nxt is not None and id(nxt) not in seen and nxt.hi >= s_lo
                    and nxt.lo <= s_hi):
                seen.add(id(nxt))
                d, s, c = (nxt.nearest(x, y, s_lo, s_hi) if isinstance(nxt, Flown)
                           else nxt.nearest(x, y))
                if d < best[0] and s_lo <= s <= s_hi:
                    best = (d, s, c)
        return best[1], best[2]


def geodetic_plan(raw: object, to_ned: Callable[[float, float], tuple[float, float]]
                  ) -> tuple[tuple[float, float], ...]:
    """An operator's plan ``[[lat_deg, lon_deg], ...]`` (a command's
    ``auv_plan``) as NED points (m) through ``to_ned``; an empty list is no
    plan.  Raises :class:`PlanError` naming the point and what is wrong."""
    if not isinstance(raw, (list, tuple)):
        raise PlanError(None, f"must be a list of [lat_deg, lon_deg], got {type(raw).__name__}")
    if len(raw) > MAX_POINTS:
        raise PlanError(None, f"has {len(raw)} points, at most {MAX_POINTS}")
    pts: list[tuple[float, float]] = []
    for i, p in enumerate(raw):
        if not (isinstance(p, (list, tuple)) and len(p) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in p)):
            raise PlanError(i, f"must be [lat_deg, lon_deg], got {p!r:.60}")
        lat, lon = float(p[0]), float(p[1])
        if not (math.isfinite(lat) and math.isfinite(lon) and -90.0 <= lat <= 90.0
                and -180.0 <= lon <= 180.0):
            raise PlanError(i, f"not a latitude, longitude: {p!r:.60}")
        pts.append(to_ned(lat, lon))
    why = check_points(pts)
    if why is not None:
        raise why
    return tuple(pts)
