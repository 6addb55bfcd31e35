"""The shore ``map`` key: what a map of the vessel needs besides its state.

Everything in it changes rarely: the local frame's origin, home, the
geofence, the LBL beacons and the listening buoy, the lines of the mission in
force.  The link publishes it when it changes (checked with every status
snapshot, 1 Hz) and every :data:`MAP_PERIOD_S` besides, and answers a query on
the key at any time, so a map opened later need not wait.  Positions are
geodetic (WGS-84, degrees); a value the boat does not know is ``null``.

``origin``
    ``{lat_deg, lon_deg}``: the origin of the vessel's local frame (north, east
    metres about it are the frame of its missions and of the map).
``home``
    ``{lat_deg, lon_deg}`` where ``return`` goes, or ``null`` until known.
``geofence``
    ``radius_m`` about home (0: no circle) and ``polygon`` ``[[lat_deg,
    lon_deg], ...]`` (empty: none).
``beacons``
    ``[{id, lat_deg, lon_deg, depth_m}, ...]``, the LBL network as the tracker
    knows it (empty without the buoy feed); ``listener`` the index of the beacon
    the buoy listens at (``null`` without the buoy feed).
``buoy``
    ``{lat_deg, lon_deg}``: the listening buoy's own GPS position from its
    status sentences, or ``null``.
``mission``
    the mission in force (or the last lines mission, with ``active`` false):
    ``{kind, name, active, waypoints: [[lat_deg, lon_deg], ...]}`` (the lines'
    ends, in order), or ``null``.
``auv_plan``
    the AUV's plan while following with one — given, or the lawnmower the
    tracker inferred from its legs: ``[[lat_deg, lon_deg], ...]`` (empty: none).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from zarco_core.auv_messages import AuvPlan, BuoyStatus
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import VesselStatus
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.guidance.mission import Mission
from zarco_runtime.links.shore.telemetry import num

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

#: the map is sent at least this often even when nothing changed (s)
MAP_PERIOD_S = 10.0


def _ll(lat: float | None, lon: float | None, nd: int = 8) -> dict[str, Any] | None:
    if lat is None or lon is None:
        return None
    la, lo = num(lat, nd), num(lon, nd)
    return None if la is None or lo is None else {"lat_deg": la, "lon_deg": lo}


class MapInfo:
    """Builds the ``map`` object; the configuration's part is converted once, a
    mission's points once per mission."""

    def __init__(self, cfg: RuntimeConfig, frame: LocalFrame) -> None:
        self.frame = frame
        o = cfg.origin
        self.origin = {"lat_deg": o.lat_deg, "lon_deg": o.lon_deg}
        fence = cfg.geofence
        self.geofence = {"radius_m": fence.radius_m,
                         "polygon": [[float(p[0]), float(p[1])] for p in fence.polygon]}
        self.beacons: list[dict[str, Any]] = []
        self.listener: int | None = None
        if cfg.devices.buoy.enabled:
            net = cfg.tracker.network
            for b, bid in zip(net.beacons, net.ids(), strict=True):
                lat, lon, _ = frame.to_geodetic(b[0], b[1])
                self.beacons.append({"id": int(bid), "lat_deg": num(lat, 8),
                                     "lon_deg": num(lon, 8),
                                     "depth_m": b[2] if len(b) > 2 else None})
            self.listener = net.listener_beacon
        self._mission: Mission | None = None
        self._mission_points: list[list[float | None]] = []
        self._last_lines: Mission | None = None
        self._plan: AuvPlan | None = None
        self._plan_points: list[list[float | None]] = []

    def _points(self, m: Mission) -> list[list[float | None]]:
        if m is not self._mission:
            pts: list[list[float | None]] = []
            if m.legs:
                ends = [(m.legs[0].n0, m.legs[0].e0)] + [(lg.n1, lg.e1) for lg in m.legs]
                for n, e in ends:
                    lat, lon, _ = self.frame.to_geodetic(n, e)
                    pts.append([num(lat, 8), num(lon, 8)])
            self._mission, self._mission_points = m, pts
        return self._mission_points

    def _plan_ll(self, plan: AuvPlan | None) -> list[list[float | None]]:
        if plan is not self._plan:
            pts: list[list[float | None]] = []
            for n, e in plan.points if plan is not None else ():
                lat, lon, _ = self.frame.to_geodetic(n, e)
                pts.append([num(lat, 8), num(lon, 8)])
            self._plan, self._plan_points = plan, pts
        return self._plan_points

    def build(self, utc: float, status: VesselStatus | None, directive: Directive | None,
              buoy: BuoyStatus | None, plan: AuvPlan | None = None) -> dict[str, Any]:
        """The ``map`` object at UTC ``utc`` from the latest status, directive, buoy
        status and AUV plan."""
        home = (_ll(status.home_lat_deg, status.home_lon_deg) if status is not None
                else None)
        mission: dict[str, Any] | None = None
        m = directive.mission if directive is not None else None
        if m is not None and m.kind == "lines":
            self._last_lines = m
        shown = m if m is not None else self._last_lines
        if shown is not None:
            mission = {"kind": shown.kind, "name": shown.name, "active": shown is m,
                       "waypoints": self._points(shown)}
        return {"t": round(utc, 3), "origin": self.origin, "home": home,
                "geofence": self.geofence, "beacons": self.beacons, "listener": self.listener,
                "buoy": _ll(buoy.lat_deg, buoy.lon_deg, 6) if buoy is not None else None,
                "mission": mission, "auv_plan": self._plan_ll(plan)}
