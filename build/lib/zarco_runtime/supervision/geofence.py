"""The geofence: a circle about home and/or a polygon, in the local NED frame."""

from __future__ import annotations

import math

from zarco_core.geodesy import LocalFrame
from zarco_runtime.supervision.settings import Geofence


def point_in_polygon(x: float, y: float, poly: list[tuple[float, float]]) -> bool:
    """Even-odd rule: is (x, y) inside the polygon (vertices in order, NED m)?"""
    inside = False
    n = len(poly)
    for i in range(n):
        x1, y1 = poly[i]
        x2, y2 = poly[(i + 1) % n]
        if (y1 > y) != (y2 > y):
            xc = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            if x < xc:
                inside = not inside
    return inside


class Fence:
    """Judges positions against the configured geofence."""

    def __init__(self, cfg: Geofence, frame: LocalFrame) -> None:
        self.radius_m = cfg.radius_m
        self.polygon = [frame.to_ned(p[0], p[1]) for p in cfg.polygon]
        self.home: tuple[float, float] | None = None

    @property
    def enabled(self) -> bool:
        return self.radius_m > 0.0 or bool(self.polygon)

    def outside(self, x: float, y: float) -> str:
        """Why (x, y) (NED, m) is outside the fence, or "" when inside."""
        if self.radius_m > 0.0 and self.home is not None:
            d = math.hypot(x - self.home[0], y - self.home[1])
            if d > self.radius_m:
                return f"{d:.0f} m from home, beyond the geofence radius {self.radius_m:g} m"
        if self.polygon and not point_in_polygon(x, y, self.polygon):
            return "outside the geofence polygon"
        return ""
