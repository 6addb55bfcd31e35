"""An AUV route as segments — straight lines, planned turns at a waypoint, and
continuous turns (arcs, circles, spirals) — turned into what the simulated
AUV flies (``[auv] waypoints`` and ``arcs``), the points along it, its
courses and its length.

Frames: local NED (x north, y east, metres), headings clockwise from north
(rad), turns + to starboard.  A continuous turn has the radius law of
:mod:`drivers.sim.auv`: R(θ) = R₀ + g·θ/360°, θ the angle turned so far.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

#: angle step (deg) of the points sampled along a continuous turn
ARC_STEP_DEG = 5.0


@dataclass(slots=True)
class Route:
    """A route being built from ``start`` with heading ``heading_rad``."""

    start: tuple[float, float]
    heading_rad: float
    waypoints: list[list[float]] = field(default_factory=list)
    #: [waypoint index, radius m, angle deg, growth m per 360°]
    arcs: list[list[float]] = field(default_factory=list)
    #: points along the route (m), every waypoint and every ARC_STEP_DEG of a turn
    points: list[tuple[float, float]] = field(default_factory=list)
    #: the course of every stretch flown (rad): lines, and a turn's sampled courses
    courses: list[float] = field(default_factory=list)
    #: the planned course changes (deg): turns at a waypoint and continuous turns
    turns_deg: list[float] = field(default_factory=list)
    length_m: float = 0.0
    #: where the route has got to (m)
    pos: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        self.waypoints = [[self.start[0], self.start[1]]]
        self.points = [self.start]
        self.pos = self.start

    def line(self, length_m: float) -> None:
        """Fly ``length_m`` on the current heading to a new waypoint."""
        h = self.heading_rad
        x = self.pos[0] + length_m * math.cos(h)
        y = self.pos[1] + length_m * math.sin(h)
        self.pos = (x, y)
        self.waypoints.append([x, y])
        self.points.append(self.pos)
        self.courses.append(h)
        self.length_m += length_m

    def turn(self, angle_deg: float) -> None:
        """Change course by ``angle_deg`` at the last waypoint (the next line's)."""
        self.heading_rad += math.radians(angle_deg)
        self.turns_deg.append(angle_deg)

    def arc(self, radius_m: float, angle_deg: float, growth_m: float = 0.0) -> None:
        """A continuous turn at the last waypoint: through ``angle_deg`` from
        radius ``radius_m``, growing ``growth_m`` per 360° (0: an arc of a
        circle)."""
        self.arcs.append([len(self.waypoints) - 1, radius_m, angle_deg, growth_m])
        self.turns_deg.append(angle_deg)
        total = math.radians(abs(angle_deg))
        sign = 1.0 if angle_deg > 0 else -1.0
        n = max(1, math.ceil(abs(angle_deg) / ARC_STEP_DEG))
        x, y = self.pos
        h = self.heading_rad
        g = growth_m / math.tau
        for k in range(n):
            th0, th1 = total * k / n, total * (k + 1) / n
            r_mid = radius_m + g * 0.5 * (th0 + th1)
            ds = r_mid * (th1 - th0)
            h_mid = h + sign * 0.5 * (th0 + th1)
            x += ds * math.cos(h_mid)
            y += ds * math.sin(h_mid)
            self.points.append((x, y))
            self.courses.append(h_mid)
            self.length_m += ds
        self.pos = (x, y)
        self.heading_rad = h + sign * total

    def shifted(self, dx: float, dy: float) -> None:
        """Move the whole route by (dx, dy) m."""
        self.waypoints = [[a + dx, b + dy] for a, b in self.waypoints]
        self.points = [(a + dx, b + dy) for a, b in self.points]
        self.pos = (self.pos[0] + dx, self.pos[1] + dy)

    def rounded(self, nd: int = 1) -> list[list[float]]:
        return [[round(a, nd), round(b, nd)] for a, b in self.waypoints]


def bbox_centre(points: list[tuple[float, float]]) -> tuple[float, float]:
    xs = [p[0] for p in points]
    ys = [p[1] for p in points]
    return 0.5 * (min(xs) + max(xs)), 0.5 * (min(ys) + max(ys))


def one_side(baseline: tuple[tuple[float, float], tuple[float, float]],
             points: list[tuple[float, float]], margin_m: float) -> bool:
    """Whether every point lies on one side of the line through the two
    beacons ``baseline``, ``margin_m`` clear of it (a two-beacon network cannot
    tell the sides apart)."""
    (x0, y0), (x1, y1) = baseline
    n = math.dist((x0, y0), (x1, y1))
    side = [((x - x0) * (y1 - y0) - (y - y0) * (x1 - x0)) / n for x, y in points]
    return min(side) > margin_m or max(side) < -margin_m


def carry_on(route: Route, length_m: float) -> tuple[float, float]:
    """The point ``length_m`` on along the route's last heading (the AUV keeps
    its course after the last waypoint)."""
    h = route.heading_rad
    return route.pos[0] + length_m * math.cos(h), route.pos[1] + length_m * math.sin(h)
