"""Mission items ↔ the supervisor's lines missions.

An uploaded mission is a list of MISSION_ITEM_INT (or MISSION_ITEM) items.
The boat takes:

* ``MAV_CMD_NAV_WAYPOINT`` in a global frame (``GLOBAL``, ``GLOBAL_INT``,
  ``GLOBAL_RELATIVE_ALT``, ``GLOBAL_RELATIVE_ALT_INT``): a vertex of the lines,
  in order; altitude, hold time and acceptance radius are ignored (the lines
  are followed until the end of each is crossed);
* ``MAV_CMD_DO_CHANGE_SPEED``: the speed (``param2``, m/s; −1 or 0: no
  change) of the legs after it; one speed per mission (the supervisor's lines
  missions have one), so items asking different speeds are refused.

Item 0 is the first vertex (there is no home item, as on PX4 and generic
autopilots).  Anything else is refused with MAV_MISSION_UNSUPPORTED (or
UNSUPPORTED_FRAME) and a status text naming the item.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from zarco_core.geodesy import LocalFrame
from zarco_runtime.guidance.mission import Mission
from zarco_runtime.links.mavlink.protocol import mav

GLOBAL_FRAMES = frozenset({
    mav.MAV_FRAME_GLOBAL, mav.MAV_FRAME_GLOBAL_INT, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
})
#: most items an upload may have
MAX_ITEMS = 1000


@dataclass(slots=True)
class Item:
    """One mission item, as MISSION_ITEM_INT carries it except that ``lat``/``lon``
    are degrees in a global frame (``x``/``y`` raw otherwise)."""

    seq: int
    frame: int
    command: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    autocontinue: int = 1

    @classmethod
    def from_msg(cls, m: Any, is_int: bool) -> Item:
        """From a MISSION_ITEM_INT (``is_int``) or MISSION_ITEM message."""
        def g(name: str) -> Any:
            return getattr(m, name)

        frame = int(g("frame"))
        x, y = float(g("x")), float(g("y"))
        if is_int and frame in GLOBAL_FRAMES:
            x, y = x / 1e7, y / 1e7
        return cls(int(g("seq")), frame, int(g("command")), float(g("param1")),
                   float(g("param2")), float(g("param3")), float(g("param4")), x, y,
                   float(g("z")), int(g("autocontinue")))

    def int_xy(self) -> tuple[int, int]:
        if self.frame in GLOBAL_FRAMES:
            return round(self.x * 1e7), round(self.y * 1e7)
        return round(self.x), round(self.y)


@dataclass(slots=True)
class Parsed:
    """An uploaded mission as the supervisor takes it, or why not (``result`` a
    MAV_MISSION_RESULT, ``reason`` in words)."""

    waypoints: list[tuple[float, float]]
    speed_mps: float
    wp_seqs: list[int]
    result: int = mav.MAV_MISSION_ACCEPTED
    reason: str = ""


def _refuse(result: int, reason: str) -> Parsed:
    return Parsed([], 0.0, [], result, reason)


def parse_items(items: list[Item], default_speed_mps: float) -> Parsed:
    """The lines mission in ``items`` (see the module docstring)."""
    wps: list[tuple[float, float]] = []
    seqs: list[int] = []
    leg_speeds: list[float] = []
    speed: float | None = None
    for it in items:
        if it.command == mav.MAV_CMD_NAV_WAYPOINT:
            if it.frame not in GLOBAL_FRAMES:
                return _refuse(mav.MAV_MISSION_UNSUPPORTED_FRAME,
                               f"item {it.seq}: frame {it.frame} is not a global frame "
                               "(latitude, longitude)")
            lat, lon = it.x, it.y
            if not (math.isfinite(lat) and math.isfinite(lon) and -90.0 <= lat <= 90.0
                    and -180.0 <= lon <= 180.0) or (lat == 0.0 and lon == 0.0):
                return _refuse(mav.MAV_MISSION_INVALID_PARAM5_X,
                               f"item {it.seq}: not a latitude, longitude: {lat}, {lon}")
            if wps:
                leg_speeds.append(speed if speed is not None else default_speed_mps)
            wps.append((lat, lon))
            seqs.append(it.seq)
        elif it.command == mav.MAV_CMD_DO_CHANGE_SPEED:
            s = it.param2
            if not math.isfinite(s) or s > 100.0:
                return _refuse(mav.MAV_MISSION_INVALID_PARAM2,
                               f"item {it.seq}: speed {s} m/s")
            if s > 0.0:
                speed = s
        else:
            return _refuse(mav.MAV_MISSION_UNSUPPORTED,
                           f"item {it.seq}: MAV_CMD {it.command} not supported (only "
                           "NAV_WAYPOINT and DO_CHANGE_SPEED)")
    if len(wps) < 2:
        return _refuse(mav.MAV_MISSION_INVALID,
                       f"a lines mission needs at least 2 waypoints, got {len(wps)}")
    distinct = sorted(set(leg_speeds))
    if len(distinct) > 1:
        return _refuse(mav.MAV_MISSION_UNSUPPORTED,
                       "one speed per mission; DO_CHANGE_SPEED items ask "
                       + ", ".join(f"{s:g}" for s in distinct) + " m/s")
    return Parsed(wps, distinct[0], seqs)


def items_from_mission(m: Mission, frame: LocalFrame) -> tuple[list[Item], list[int],
                                                                 tuple[tuple[float, float], ...]]:
    """A lines mission as mission items (for a GCS to download): a DO_CHANGE_SPEED
    before each leg whose speed differs from the previous one, and a NAV_WAYPOINT
    per vertex.  Returns the items, the item index of each vertex and the vertices."""
    if m.waypoints and len(m.waypoints) == len(m.legs) + 1:
        pts = [(float(a), float(b)) for a, b in m.waypoints]
    else:
        pts = []
        if m.legs:
            lg0 = m.legs[0]
            lat, lon, _ = frame.to_geodetic(lg0.n0, lg0.e0)
            pts.append((lat, lon))
            for lg in m.legs:
                lat, lon, _ = frame.to_geodetic(lg.n1, lg.e1)
                pts.append((lat, lon))
    items: list[Item] = []
    seqs: list[int] = []
    speed: float | None = None
    for i, (lat, lon) in enumerate(pts):
        seqs.append(len(items))
        items.append(Item(len(items), mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                          mav.MAV_CMD_NAV_WAYPOINT, x=lat, y=lon))
        if i < len(m.legs) and m.legs[i].speed_mps != speed:  # the speed of the next leg
            speed = m.legs[i].speed_mps
            items.append(Item(len(items), mav.MAV_FRAME_MISSION, mav.MAV_CMD_DO_CHANGE_SPEED,
                              1.0, speed, -1.0))
    return items, seqs, tuple(pts)


def items_from_points(points: tuple[tuple[float, float], ...]) -> tuple[list[Item], list[int]]:
    """Waypoints alone (the supervisor's loaded mission, whose speeds it does not
    tell) as NAV_WAYPOINT items; the items and the item index of each vertex."""
    items = [Item(i, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mav.MAV_CMD_NAV_WAYPOINT,
                  x=lat, y=lon) for i, (lat, lon) in enumerate(points)]
    return items, list(range(len(items)))
