"""Missions: a lines mission is a sequence of waypoints with a speed per leg; a
follow mission follows the AUV, optionally with the AUV's a-priori plan.

Waypoints and the AUV's plan are given in the local NED frame (``frame =
"ned"``: [north, east] metres) or geodetic (``frame = "geodetic"``: [lat,
lon] degrees, converted about the configured origin).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.config import spec
from zarco_core.geodesy import LocalFrame
from zarco_runtime.tracking.plan import MAX_POINTS, check_points

#: metres per degree of latitude (and of longitude at the equator), for the
#: plausibility checks of geodetic points before the origin is known
M_PER_DEG = 111_195.0


@dataclass(slots=True)
class MissionConfig:
    """``[mission]`` table of a scenario or runtime config."""

    kind: str = spec("lines", "", "mission type: follow straight lines, follow the AUV "
                     "(its track from the buoy feed), or stay idle",
                     choices=["lines", "follow", "idle"])
    frame: str = spec("ned", "", "waypoint frame", choices=["ned", "geodetic"])
    waypoints: list[list[float]] = spec(list, "m or deg",
                                        "[[north, east], ...] or [[lat, lon], ...]")
    speed_mps: float = spec(1.0, "m/s", "speed along every leg", min=0.05, max=3.0)
    leg_speeds_mps: list[float] = spec(list, "m/s", "speed per leg (overrides speed_mps)",
                                       min=0.05, max=3.0)
    laps: int = spec(1, "", "repeat a closed mission this many times", min=1, max=10000)
    autostart: bool | None = spec(None, "", "start this mission at boot (unset: false on the "
                                  "vessel, true in a scenario)")
    auv_plan: list[list[float]] = spec(list, "m or deg", "follow: the AUV's a-priori mission, "
                                       "[[north, east], ...] or [[lat, lon], ...] in this "
                                       "frame (a prior for the tracker; empty: none)")

    def validate(self) -> None:
        if self.kind == "lines" and len(self.waypoints) < 2:
            raise ValueError("waypoints: a lines mission needs at least 2 waypoints")
        for i, wp in enumerate(self.waypoints):
            if len(wp) != 2:
                raise ValueError(f"waypoints: waypoint {i} must have 2 numbers, has {len(wp)}")
            if not all(math.isfinite(v) for v in wp):
                raise ValueError(f"waypoints: waypoint {i} is not finite")
        for i in range(1, len(self.waypoints)):
            a, b = self.waypoints[i - 1], self.waypoints[i]
            if a == b:
                raise ValueError(f"waypoints: waypoints {i - 1} and {i} coincide")
        n_legs = max(0, len(self.waypoints) - 1)
        if self.leg_speeds_mps and len(self.leg_speeds_mps) != n_legs:
            raise ValueError(
                f"leg_speeds_mps: has {len(self.leg_speeds_mps)} speeds for {n_legs} legs"
            )
        if self.laps > 1 and self.waypoints and self.waypoints[0] != self.waypoints[-1]:
            raise ValueError("laps: repeating needs a closed mission (last waypoint = first)")
        if self.auv_plan:
            why = self._check_plan()
            if why:
                raise ValueError(why)

    def _check_plan(self) -> str:
        """Why ``auv_plan`` is not a plan in this mission ("" when it is), as
        ``auv_plan[i]: reason``."""
        if self.kind != "follow":
            return f"auv_plan: only a follow mission has an AUV plan (kind = {self.kind!r})"
        if len(self.auv_plan) > MAX_POINTS:
            return f"auv_plan: has {len(self.auv_plan)} points, at most {MAX_POINTS}"
        pts: list[tuple[float, float]] = []
        for i, p in enumerate(self.auv_plan):
            if len(p) != 2:
                what = "[lat, lon]" if self.frame == "geodetic" else "[north, east]"
                return f"auv_plan[{i}]: must be {what}, has {len(p)} numbers"
            if self.frame == "geodetic":
                lat, lon = p
                if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                    return f"auv_plan[{i}]: not a latitude, longitude: {p}"
                # metres about the first point (plausibility only: the origin's
                # frame converts them when the mission is built)
                lat0, lon0 = self.auv_plan[0]
                pts.append(((lat - lat0) * M_PER_DEG,
                            math.remainder(lon - lon0, 360.0) * M_PER_DEG
                            * math.cos(math.radians(lat0))))
            else:
                pts.append((p[0], p[1]))
        why = check_points(pts)
        return why.named("auv_plan") if why is not None else ""


@dataclass(frozen=True, slots=True)
class Leg:
    """A straight line from (n0, e0) to (n1, e1) in NED metres, at ``speed_mps``."""

    index: int
    n0: float
    e0: float
    n1: float
    e1: float
    speed_mps: float

    @property
    def length_m(self) -> float:
        return math.hypot(self.n1 - self.n0, self.e1 - self.e0)

    @property
    def course_rad(self) -> float:
        """ψ_traj: direction of the line, clockwise from north."""
        return math.atan2(self.e1 - self.e0, self.n1 - self.n0)

    def project(self, x: float, y: float) -> tuple[float, float]:
        """(along-track from start, cross-track d) of point (x north, y east).

        d > 0 when the point is to starboard (right) of the direction of travel.
        """
        course = self.course_rad
        c, s = math.cos(course), math.sin(course)
        dx, dy = x - self.n0, y - self.e0
        return dx * c + dy * s, -dx * s + dy * c


def build_legs(mc: MissionConfig, frame: LocalFrame) -> list[Leg]:
    """Legs of a lines mission in the local frame."""
    pts: list[tuple[float, float]] = []
    for wp in mc.waypoints:
        if mc.frame == "geodetic":
            pts.append(frame.to_ned(wp[0], wp[1]))
        else:
            pts.append((float(wp[0]), float(wp[1])))
    legs: list[Leg] = []
    for _lap in range(mc.laps):
        for i in range(1, len(pts)):
            sp = mc.leg_speeds_mps[i - 1] if mc.leg_speeds_mps else mc.speed_mps
            (a, b), (c, d) = pts[i - 1], pts[i]
            legs.append(Leg(len(legs), a, b, c, d, sp))
    return legs


@dataclass(frozen=True, slots=True)
class Mission:
    """A mission the supervisor can run: ``kind`` ``lines`` (its ``legs``, NED) or
    ``follow`` (the AUV; no legs; ``auv_plan`` the AUV's a-priori plan, NED
    points).  ``waypoints`` keeps the geodetic points [lat_deg, lon_deg] it
    was given as (for ground stations and the state file), ``name`` where it
    came from."""

    kind: str
    legs: tuple[Leg, ...] = ()
    name: str = ""
    waypoints: tuple[tuple[float, float], ...] = ()
    #: follow: the AUV's a-priori plan, NED points (m); empty: none
    auv_plan: tuple[tuple[float, float], ...] = ()

    @property
    def speed_mps(self) -> float:
        return self.legs[0].speed_mps if self.legs else 0.0


def plan_points(mc: MissionConfig, frame: LocalFrame) -> tuple[tuple[float, float], ...]:
    """``[mission] auv_plan`` as NED points (m) about ``frame``'s origin."""
    if mc.frame == "geodetic":
        return tuple(frame.to_ned(p[0], p[1]) for p in mc.auv_plan)
    return tuple((float(p[0]), float(p[1])) for p in mc.auv_plan)


def legs_from_points(points: list[tuple[float, float]], speed_mps: float) -> tuple[Leg, ...]:
    """Legs between consecutive NED points (m), all at ``speed_mps``."""
    return tuple(Leg(i - 1, points[i - 1][0], points[i - 1][1], points[i][0], points[i][1],
                     speed_mps) for i in range(1, len(points)))
