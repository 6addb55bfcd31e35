"""The tracked AUV as a second MAVLink system, so that QGroundControl and
MAVProxy show it on their map beside the boat.

System ``[mavlink] auv_system_id`` (default the boat's + 1), component 1
(MAV_COMP_ID_AUTOPILOT1: a ground station makes a vehicle only of an
autopilot's heartbeat).  While the tracker publishes a track (it does at
least once a second once it has one), on every connection:

* HEARTBEAT right after each of the boat's (1 Hz; after, so that a ground
  station hears the boat first and makes it its active vehicle):
  MAV_TYPE_SUBMARINE, MAV_AUTOPILOT_GENERIC, ``base_mode``
  0 (the boat does not command the AUV), ``system_status`` from the track:
  ACTIVE while tracking (or turning), STANDBY while acquiring, CRITICAL when
  stale, EMERGENCY when lost;
* GLOBAL_POSITION_INT at each track update (at most every
  :data:`POSITION_MIN_S`): the line model evaluated at the update's time, as
  the shore link's ``auv`` key gives it; ``relative_alt`` minus the AUV's depth
  (``tracker.auv_depth_m``, mm), ``alt`` the origin's altitude minus the depth;
  ``vx``/``vy`` the north/east velocity (cm/s); ``hdg`` the course (cdeg,
  65535 when the AUV is not moving).  None while the track is lost or before
  it has a position.

Nothing is sent without a track, and the AUV falls silent
:data:`QUIET_S` after the last update.  Whatever a ground station asks of the
AUV's system is refused, answered as the AUV: a command (COMMAND_LONG,
COMMAND_INT, SET_MODE) with COMMAND_ACK DENIED, a mission upload or clear with
MISSION_ACK DENIED, a mission download with MISSION_COUNT 0; parameter
requests get nothing (a component without parameters ignores them) and a
joystick is ignored."""

from __future__ import annotations

import math
from typing import Any

from zarco_core.auv_messages import AuvTrack, TrackFlags
from zarco_runtime.links.mavlink.builders import r_int
from zarco_runtime.links.mavlink.core import Core
from zarco_runtime.links.mavlink.link import Link, Source
from zarco_runtime.links.mavlink.protocol import UINT16_MAX, mav

#: no track update for this long: the AUV falls silent (s)
QUIET_S = 3.0
#: GLOBAL_POSITION_INT at most this often (s)
POSITION_MIN_S = 0.1
#: below this speed the course is not known (m/s)
COURSE_MIN_MPS = 0.01
#: MAV_STATE of each track status
STATE = {
    "tracking": mav.MAV_STATE_ACTIVE,
    "turning": mav.MAV_STATE_ACTIVE,
    "acquiring": mav.MAV_STATE_STANDBY,
    "stale": mav.MAV_STATE_CRITICAL,
    "lost": mav.MAV_STATE_EMERGENCY,
}
#: what a ground station may send the AUV that gets an answer (the rest is ignored)
COMMANDS = ("COMMAND_LONG", "COMMAND_INT", "SET_MODE")
MISSION_CHANGES = ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_CLEAR_ALL")


def track_status(tr: AuvTrack) -> str:
    """The track's status in one word (as the shore link's ``auv`` key says it):
    lost, stale, acquiring, turning or tracking."""
    f = TrackFlags(tr.flags)
    if tr.lost or TrackFlags.LOST in f:
        return "lost"
    if TrackFlags.STALE in f:
        return "stale"
    if TrackFlags.INITIALISED not in f:
        return "acquiring"
    if TrackFlags.TURNING in f:
        return "turning"
    return "tracking"


def target_system(m: Any) -> int | None:
    """The system a message is addressed to (None: not addressed)."""
    for name in ("target_system", "target"):
        v = getattr(m, name, None)
        if v is not None:
            return int(v)
    return None


class AuvSystem:
    """Speaks for the tracked AUV (see the module docstring)."""

    def __init__(self, core: Core) -> None:
        self.core = core
        self.sysid = core.s.auv_sysid()
        self.source: Source = (self.sysid, int(mav.MAV_COMP_ID_AUTOPILOT1))
        self.depth_m = core.cfg.tracker.auv_depth_m
        self.track: AuvTrack | None = None
        self.track_t = -math.inf  # clock time of the last update (s)
        self.position_t = -math.inf
        self.heartbeats = 0
        self.positions = 0
        self.refused = 0

    def on_track(self, tr: AuvTrack) -> None:
        now = self.core.clock.now()
        self.track, self.track_t = tr, now
        if now - self.position_t >= POSITION_MIN_S and self.position(tr) is not None:
            self.position_t = now
            self.positions += 1
            for ln in self.core.links:  # a message object per link
                ln.send(self.position(tr), reply=False, source=self.source)

    def after_boat_heartbeat(self, link: Link) -> None:
        """The AUV's heartbeat on ``link``, right after the boat's (so a ground
        station hears the boat first and makes it its vehicle), while the track
        is heard."""
        tr = self.track
        if tr is None or self.core.clock.now() - self.track_t > QUIET_S:
            return
        self.heartbeats += 1
        link.send(self.heartbeat(tr), source=self.source)

    def heartbeat(self, tr: AuvTrack) -> Any:
        return mav.MAVLink_heartbeat_message(
            mav.MAV_TYPE_SUBMARINE, mav.MAV_AUTOPILOT_GENERIC, 0, 0,
            STATE[track_status(tr)], 3)

    def position(self, tr: AuvTrack) -> Any:
        """GLOBAL_POSITION_INT of the track at its time, or None (lost, no position)."""
        if track_status(tr) == "lost":
            return None
        dt = tr.t - tr.t0
        x = tr.x0_m + tr.vx_mps * dt
        y = tr.y0_m + tr.vy_mps * dt
        if not (math.isfinite(x) and math.isfinite(y)):
            return None
        c = self.core
        lat, lon, _ = c.frame.to_geodetic(x, y)
        if not (math.isfinite(lat) and math.isfinite(lon)):
            return None
        speed = math.hypot(tr.vx_mps, tr.vy_mps)
        hdg = UINT16_MAX
        if math.isfinite(speed) and speed >= COURSE_MIN_MPS:
            hdg = r_int(math.degrees(math.atan2(tr.vy_mps, tr.vx_mps)) * 100.0) % 36000
        depth_mm = r_int(self.depth_m * 1000.0)
        return mav.MAVLink_global_position_int_message(
            int(tr.t * 1000.0) & 0xFFFFFFFF, r_int(lat * 1e7), r_int(lon * 1e7),
            r_int(c.cfg.origin.alt_m * 1000.0) - depth_mm, -depth_mm,
            max(-32768, min(32767, r_int(tr.vx_mps * 100.0))),
            max(-32768, min(32767, r_int(tr.vy_mps * 100.0))), 0, hdg)

    # ------------------------------------------------------------ requests

    def addressed(self, m: Any) -> bool:
        """Is ``m`` addressed to the AUV's system (and to no other)?"""
        return target_system(m) == self.sysid

    def on_message(self, link: Link, m: Any, name: str) -> None:
        """Something a ground station asked of the AUV: refused (see the module
        docstring)."""
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        if name in COMMANDS:
            self.refused += 1
            cmd = (int(mav.MAVLINK_MSG_ID_SET_MODE) if name == "SET_MODE"
                   else int(m.command))
            link.send(mav.MAVLink_command_ack_message(cmd, mav.MAV_RESULT_DENIED, 0, 0,
                                                     src, comp), source=self.source)
        elif name in MISSION_CHANGES:
            self.refused += 1
            link.send(mav.MAVLink_mission_ack_message(
                src, comp, mav.MAV_MISSION_DENIED, int(getattr(m, "mission_type", 0))),
                source=self.source)
        elif name == "MISSION_REQUEST_LIST":
            link.send(mav.MAVLink_mission_count_message(
                src, comp, 0, int(getattr(m, "mission_type", 0))), source=self.source)
