"""Fast WGS-84 geodetic ↔ local NED conversions in plain ``math``.

:class:`zarco_core.geodesy.LocalFrame` goes through pymap3d, which
evaluates the transformation with numpy ufuncs on scalars at about 100 µs a
call: more than the navigation filter's whole update budget.  This module does
the same transformation (geodetic → ECEF → NED about the origin, and back with
the latitude iterated to convergence) with scalars, in a few microseconds; the
tests compare it with :class:`LocalFrame` to well below a millimetre.

Frames (as everywhere in the project): local NED, x north, y east, metres, about the frame's
geodetic origin; heights are ellipsoidal metres (the runtime uses the origin's
height for every horizontal point, as ``LocalFrame.to_ned`` does by default).
"""

from __future__ import annotations

import math

#: WGS-84 semi-major axis (m) and flattening
WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)


class FastLocalFrame:
    """Local NED tangent plane at (``lat0_deg``, ``lon0_deg``, ``h0_m``)."""

    __slots__ = ("_rot", "h0", "lat0", "lon0", "x0", "y0", "z0")

    def __init__(self, lat0_deg: float, lon0_deg: float, h0_m: float = 0.0) -> None:
        self.lat0 = lat0_deg
        self.lon0 = lon0_deg
        self.h0 = h0_m
        self.x0, self.y0, self.z0 = _ecef(lat0_deg, lon0_deg, h0_m)
        lat0, lon0 = math.radians(lat0_deg), math.radians(lon0_deg)
        self._rot = (math.sin(lat0), math.cos(lat0), math.sin(lon0), math.cos(lon0))

    def to_ned(self, lat_deg: float, lon_deg: float,
               alt_m: float | None = None) -> tuple[float, float]:
        """(north, east) metres of a geodetic point (height defaults to the origin's)."""
        x, y, z = _ecef(lat_deg, lon_deg, self.h0 if alt_m is None else alt_m)
        dx, dy, dz = x - self.x0, y - self.y0, z - self.z0
        sl, cl, so, co = self._rot
        north = -sl * co * dx - sl * so * dy + cl * dz
        east = -so * dx + co * dy
        return north, east

    def to_geodetic(self, north_m: float, east_m: float,
                    down_m: float = 0.0) -> tuple[float, float, float]:
        """(lat_deg, lon_deg, h_m) of a local point."""
        sl, cl, so, co = self._rot
        n, e, d = north_m, east_m, down_m
        x = self.x0 - sl * co * n - so * e - cl * co * d
        y = self.y0 - sl * so * n + co * e - cl * so * d
        z = self.z0 + cl * n - sl * d
        p = math.hypot(x, y)
        lon = math.atan2(y, x)
        lat = math.atan2(z, p * (1.0 - WGS84_E2))
        h = 0.0
        for _ in range(10):
            s = math.sin(lat)
            nn = WGS84_A / math.sqrt(1.0 - WGS84_E2 * s * s)
            h = p / math.cos(lat) - nn
            new = math.atan2(z, p * (1.0 - WGS84_E2 * nn / (nn + h)))
            if abs(new - lat) < 1e-14:
                lat = new
                break
            lat = new
        return math.degrees(lat), math.degrees(lon), h


def _ecef(lat_deg: float, lon_deg: float, h_m: float) -> tuple[float, float, float]:
    """Earth-centred, earth-fixed coordinates (m) of a geodetic point."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    sl, cl = math.sin(lat), math.cos(lat)
    nn = WGS84_A / math.sqrt(1.0 - WGS84_E2 * sl * sl)
    return ((nn + h_m) * cl * math.cos(lon), (nn + h_m) * cl * math.sin(lon),
            (nn * (1.0 - WGS84_E2) + h_m) * sl)
