"""Missions from the operator's ``mission`` command, checked against the vessel.

The command's schema (:class:`~zarco_core.commands.MissionArgs`) already holds
the waypoints to latitudes and longitudes, the speeds to 0.05..3 m/s and the
lists to their bounds; what depends on this vessel is checked here: the
configured speed limit, the distance from the origin, waypoints too close
together, the geofence.  :func:`mission_points` gives back the waypoints of
any mission as latitudes and longitudes (what the status and a ground
station show).
"""

from __future__ import annotations

import math

from zarco_core.commands import MissionArgs
from zarco_core.geodesy import LocalFrame
from zarco_runtime.guidance.mission import Leg, Mission, legs_from_points
from zarco_runtime.supervision.geofence import Fence

#: farthest a waypoint may be from the origin (m): beyond, the local frame's
#: flat-earth error is no longer negligible (and it is surely a typing error)
MAX_FROM_ORIGIN_M = 50_000.0
#: closest two consecutive waypoints may be (m)
MIN_LEG_M = 1.0


def lines_mission(a: MissionArgs, frame: LocalFrame, fence: Fence, max_speed_mps: float,
                  source: str) -> Mission | str:
    """The lines mission of ``a``, or why it cannot be run on this vessel."""
    vmax = max_speed_mps
    if a.speed_mps > vmax:
        return (f"speed_mps: must be ≤ {vmax:g} m/s (supervisor.max_speed_mps), got "
                f"{a.speed_mps:g}")
    speeds = list(a.leg_speeds_mps or ())
    for i, v in enumerate(speeds):
        if v > vmax:
            return (f"leg_speeds_mps[{i}]: must be ≤ {vmax:g} m/s "
                    f"(supervisor.max_speed_mps), got {v:g}")
    wps = [(lat, lon) for lat, lon in a.waypoints]
    pts = [frame.to_ned(lat, lon) for lat, lon in wps]
    for i, p in enumerate(pts):
        r = math.hypot(*p)
        if r > MAX_FROM_ORIGIN_M:
            return (f"waypoints[{i}]: {r / 1000:.0f} km from the origin "
                    f"(at most {MAX_FROM_ORIGIN_M / 1000:g} km)")
        if i and math.hypot(p[0] - pts[i - 1][0], p[1] - pts[i - 1][1]) < MIN_LEG_M:
            return f"waypoints[{i}]: less than {MIN_LEG_M:g} m from waypoint {i - 1}"
        if fence.enabled:
            out = fence.outside(*p)
            if out:
                return f"waypoints[{i}]: outside the geofence ({out})"
    legs = legs_from_points(pts, a.speed_mps)
    if speeds:
        legs = tuple(Leg(lg.index, lg.n0, lg.e0, lg.n1, lg.e1, v)
                     for lg, v in zip(legs, speeds, strict=True))
    name = a.name or f"{len(wps)} waypoints from {source}"
    return Mission("lines", legs, name, tuple(wps))


def mission_points(m: Mission | None, frame: LocalFrame) -> tuple[tuple[float, float], ...]:
    """The waypoints of a lines mission as (lat_deg, lon_deg): the ones it was
    given in, or its legs' ends converted (a mission from a file in NED)."""
    if m is None or m.kind != "lines":
        return ()
    if m.waypoints:
        return tuple((float(a), float(b)) for a, b in m.waypoints)
    if not m.legs:
        return ()
    ned = [(m.legs[0].n0, m.legs[0].e0)] + [(lg.n1, lg.e1) for lg in m.legs]
    out = []
    for n, e in ned:
        lat, lon, _ = frame.to_geodetic(n, e)
        out.append((float(lat), float(lon)))
    return tuple(out)
