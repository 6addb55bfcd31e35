"""Station keeping at a point (``hold``) and going home (``return``).

The two thrusters push only along the hull, so the boat cannot push itself
sideways: it holds a point the way it tracks a line.  A *station line*
through the point is laid along the estimated water current, bow upstream;
the line-tracking steering law keeps the boat on it (the water flowing past
the hull gives the steering its authority, as a moving boat's speed does),
and the surge law holds the along-line position with
X = F_f(|c|) − k_p u_g + k_s s + k_i ∫s dt, s the along-line distance to the
point (forward or astern).  Far from the point the boat first transits to
it along a straight leg, slowing down as it arrives.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.messages import NavState
from zarco_runtime.guidance.mission import Leg
from zarco_runtime.guidance.settings import HoldSettings

#: half-length of the station line (m): long enough never to be left
STATION_HALF_LENGTH_M = 1000.0
#: leg indices of hold legs (negative, apart from mission legs)
TRANSIT_LEG = -10
STATION_LEG0 = -100


@dataclass(frozen=True, slots=True)
class HoldState:
    """One instant of station keeping: ``phase`` ``transit`` or ``station``,
    ``leg`` to track, ``along_m`` how far the point is ahead along it (m),
    ``distance_m`` from the point; ``still``: no current to steer against (hold
    the heading of the leg rather than steer onto it)."""

    phase: str
    leg: Leg
    along_m: float
    distance_m: float
    still: bool = False


class HoldGuidance:
    """Guidance to hold ``point`` (NED metres)."""

    def __init__(self, point: tuple[float, float], cfg: HoldSettings) -> None:
        self.point = point
        self.cfg = cfg
        self.phase = ""
        self._course: float | None = None
        self._station_id = STATION_LEG0
        self._transit: Leg | None = None

    def _station_course(self, nav: NavState, x: float, y: float) -> float:
        cn, ce = nav.current_n_mps, nav.current_e_mps
        px, py = self.point
        if math.hypot(cn, ce) >= self.cfg.current_min_mps:
            upstream = math.atan2(-ce, -cn)
            if (self._course is None or abs(math.remainder(upstream - self._course, math.tau))
                    > math.radians(self.cfg.realign_deg)):
                self._course = upstream
                self._station_id -= 1
            return self._course
        # still water: nothing to steer against; keep the arrival heading and the
        # along-line position until the boat has drifted still_relay_m from the
        # point, then face the point and close in
        if self._course is None:
            self._course = nav.psi_rad
            self._station_id -= 1
        if math.hypot(px - x, py - y) > self.cfg.still_relay_m:
            bearing = math.atan2(py - y, px - x)
            if abs(math.remainder(bearing - self._course, math.tau)) > math.radians(20.0):
                self._course = bearing
                self._station_id -= 1
        return self._course

    def update(self, nav: NavState, x: float, y: float) -> HoldState:
        """Guidance for the boat at (x, y) (NED, m) with estimate ``nav``."""
        px, py = self.point
        dist = math.hypot(px - x, py - y)
        cfg = self.cfg
        if self.phase == "station" and dist > 2.5 * cfg.station_radius_m:
            self.phase = ""  # pushed far off: go back in transit
        if self.phase != "station" and dist > cfg.station_radius_m:
            if self.phase != "transit" or self._transit is None:
                course = math.atan2(py - y, px - x)
                self._transit = Leg(TRANSIT_LEG, px - 2.0 * dist * math.cos(course),
                                    py - 2.0 * dist * math.sin(course), px, py,
                                    cfg.transit_speed_mps)
            self.phase = "transit"
            leg = self._transit
            speed = max(0.1, min(cfg.transit_speed_mps, cfg.approach_gain * dist))
            leg = Leg(leg.index, leg.n0, leg.e0, leg.n1, leg.e1, speed)
            return HoldState("transit", leg, 0.0, dist)
        if self.phase != "station":
            self.phase = "station"
            self._course = None
        course = self._station_course(nav, x, y)
        c, s = math.cos(course), math.sin(course)
        h = STATION_HALF_LENGTH_M
        leg = Leg(self._station_id, px - h * c, py - h * s, px + h * c, py + h * s, 0.0)
        along = (px - x) * c + (py - y) * s
        still = math.hypot(nav.current_n_mps, nav.current_e_mps) < cfg.current_min_mps
        return HoldState("station", leg, along, dist, still)
