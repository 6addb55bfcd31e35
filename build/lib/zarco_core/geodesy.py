"""Geodetic ↔ local NED about a fixed origin, with pymap3d (WGS-84)."""

from __future__ import annotations

from dataclasses import dataclass

import pymap3d

from zarco_core.config import spec


@dataclass(slots=True)
class Origin:
    """Geodetic origin of the local NED frame (WGS-84)."""

    lat_deg: float = spec(41.185, "deg", "origin latitude", min=-90.0, max=90.0)
    lon_deg: float = spec(-8.705, "deg", "origin longitude", min=-180.0, max=180.0)
    alt_m: float = spec(0.0, "m", "origin height", min=-500.0, max=9000.0)


class LocalFrame:
    """Local NED tangent plane at (lat0, lon0, h0)."""

    def __init__(self, lat_deg: float, lon_deg: float, alt_m: float = 0.0) -> None:
        self.lat0 = lat_deg
        self.lon0 = lon_deg
        self.h0 = alt_m

    def to_ned(self, lat_deg: float, lon_deg: float,
               alt_m: float | None = None) -> tuple[float, float]:
        """(north, east) metres of a geodetic point (height defaults to the origin's)."""
        h = self.h0 if alt_m is None else alt_m
        n, e, _d = pymap3d.geodetic2ned(lat_deg, lon_deg, h, self.lat0, self.lon0, self.h0)
        return float(n), float(e)

    def to_geodetic(self, north_m: float, east_m: float,
                    down_m: float = 0.0) -> tuple[float, float, float]:
        """(lat, lon, height) of a local point."""
        lat, lon, h = pymap3d.ned2geodetic(north_m, east_m, down_m, self.lat0, self.lon0, self.h0)
        return float(lat), float(lon), float(h)
