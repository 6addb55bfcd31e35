"""Settings of the supervisor (``[supervisor]``), its failsafe table
(``[failsafe]``) and the geofence (``[geofence]``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.config import spec

#: what a failsafe does: nothing but say so, hold where the vessel is, stop, go home
ACTIONS = ["continue", "hold", "idle", "return"]
#: the failsafe conditions, in the order they are evaluated and reported
CONDITIONS = ("position_lost", "heading_lost", "thruster_silent", "link_lost", "geofence",
              "auv_lost", "component_failed")


@dataclass(slots=True)
class Failsafe:
    """The failsafe table: for each condition, the action and its time.

    ==================  =====================================================  =========
    condition           true when (in every mode, armed or not, unless said)   default
    ==================  =====================================================  =========
    position_lost       no GPS position fused for ``position_lost_s`` (dead   idle, 10 s
                        reckoning until then), or the estimator calls its
                        position invalid
    heading_lost        no compass heading for ``heading_lost_s``, or the     idle, 0.5 s
                        heading estimate invalid
    thruster_silent     no ``$PZTHS`` from the thruster controller for         idle, 0.6 s
                        ``thruster_silent_s`` (counted from the first command
                        if it never answered)
    link_lost           armed and no operator heartbeat on ``link`` for       hold, 10 s
                        ``link_lost_s`` (once one has been heard)
    geofence            outside the geofence for ``geofence_s``               hold, 0 s
    auv_lost            following and the AUV track lost for ``auv_lost_s``    hold, 30 s
    component_failed    a component on the control path failed and is being   idle, 0 s
                        restarted (for ``component_failed_s``)
    ==================  =====================================================  =========

    Before the first position estimate and the first compass heading their
    conditions are not judged yet: the boat cannot be armed without them
    (the control loop gives zero thrust then too).

    A failsafe fires once when its condition becomes true and applies its
    action (the more severe wins: idle > hold > return > continue); it
    *latches*: it clears only when its condition has been false for
    ``clear_after_s``.  Each entry and exit is an event with its reason.
    ``idle`` disarms: the boat stays still until an operator arms it again.
    While position_lost, heading_lost or thruster_silent is active no
    thruster command but zero is sent, whatever the mode and the action.
    When the last failsafe clears, a vessel that a ``hold`` or ``return``
    action kept under way does ``after_clear``: ``hold`` where it is (and says
    so; a ``resume`` command continues the mission), ``resume`` the interrupted
    mode by itself, or go ``idle``.
    """

    position_lost: str = spec("idle", "", "action on position lost", choices=ACTIONS)
    position_lost_s: float = spec(10.0, "s", "GPS age at which the position counts as lost "
                                  "(the EKF dead-reckons until then: ~1 m after 10 s at "
                                  "1 m/s)", min=0.0, max=3600.0)
    heading_lost: str = spec("idle", "", "action on heading lost", choices=ACTIONS)
    heading_lost_s: float = spec(0.5, "s", "no compass heading for this long → heading lost "
                                 "(10 epochs at 20 Hz)", min=0.0, max=60.0)
    thruster_silent: str = spec("idle", "", "action on a silent thruster controller",
                                choices=ACTIONS)
    thruster_silent_s: float = spec(0.6, "s", "no $PZTHS for this long while thrust is "
                                    "commanded (3 status periods at 5 Hz)", min=0.05,
                                    max=60.0)
    link_lost: str = spec("hold", "", "action on operator link lost", choices=ACTIONS)
    link_lost_s: float = spec(10.0, "s", "no operator heartbeat for this long while under way",
                              min=0.5, max=3600.0)
    link: str = spec("shore", "", "whose heartbeat counts: the shore link, a MAVLink ground "
                     "station, or either", choices=["shore", "mavlink", "any"])
    geofence: str = spec("hold", "", "action outside the geofence", choices=ACTIONS)
    geofence_s: float = spec(0.0, "s", "outside the geofence for this long", min=0.0,
                             max=600.0)
    auv_lost: str = spec("hold", "", "action on AUV track lost (follow)", choices=ACTIONS)
    auv_lost_s: float = spec(30.0, "s", "AUV track lost for this long while following",
                             min=0.0, max=3600.0)
    component_failed: str = spec("idle", "", "action when a component on the control path "
                                 "fails", choices=ACTIONS)
    component_failed_s: float = spec(0.0, "s", "a component failed (and restarting) for this "
                                     "long", min=0.0, max=600.0)
    clear_after_s: float = spec(2.0, "s", "a failsafe clears only after its condition has "
                                "been false (healthy) this long", min=0.0, max=600.0)
    after_clear: str = spec("hold", "", "when every failsafe has cleared: hold where the "
                            "vessel is, resume the interrupted mode, or stay idle",
                            choices=["hold", "resume", "idle"])

    def validate(self) -> None:
        for cond in ("position_lost", "heading_lost"):
            if getattr(self, cond) in ("hold", "return"):
                raise ValueError(f"{cond}: {getattr(self, cond)!r} needs the "
                                 f"{cond.split('_')[0]} that is lost; use idle or continue")

    def action(self, cond: str) -> str:
        return str(getattr(self, cond))

    def delay_s(self, cond: str) -> float:
        return float(getattr(self, f"{cond}_s"))


@dataclass(slots=True)
class Geofence:
    """Where the vessel may be: a circle about home and/or a polygon (both when
    both are set).  Outside → the ``geofence`` failsafe."""

    radius_m: float = spec(0.0, "m", "largest distance from home (0: no circle)", min=0.0,
                           max=1e6)
    polygon: list[list[float]] = spec(list, "deg", "[[lat_deg, lon_deg], ...] at least 3 "
                                      "vertices (empty: no polygon)")

    def validate(self) -> None:
        if self.polygon and len(self.polygon) < 3:
            raise ValueError(f"polygon: needs at least 3 vertices, got {len(self.polygon)}")
        for i, p in enumerate(self.polygon):
            if len(p) != 2 or not all(math.isfinite(v) for v in p):
                raise ValueError(f"polygon: vertex {i} must be [lat_deg, lon_deg]")
            if not (-90.0 <= p[0] <= 90.0 and -180.0 <= p[1] <= 180.0):
                raise ValueError(f"polygon: vertex {i} {p} is not a latitude, longitude")


@dataclass(slots=True)
class Supervisor:
    """The supervisor: modes, commands, home, status."""

    rate_hz: float = spec(20.0, "Hz", "how often the failsafe table is evaluated", min=1.0,
                          max=200.0)
    directive_period_s: float = spec(0.2, "s", "the directive is republished this often",
                                     min=0.01, max=10.0)
    directive_timeout_s: float = spec(1.0, "s", "control treats a directive older than this "
                                      "as idle (a stopped supervisor stops the boat)",
                                      min=0.1, max=60.0)
    status_period_s: float = spec(1.0, "s", "period of the status snapshot", min=0.1,
                                  max=60.0)
    manual_lease_s: float = spec(1.0, "s", "a manual thrust command holds for this long",
                                 min=0.1, max=10.0)
    home: list[float] = spec(list, "deg", "[lat_deg, lon_deg] of home (empty: the first "
                             "valid position after start)")
    state_file: str = spec("", "", "file that keeps the last mission across restarts "
                           "(empty: none)")
    control_socket: str = spec("", "", "unix socket for local commands (`zarco ctl`); "
                               "empty: none")
    max_speed_mps: float = spec(2.0, "m/s", "fastest speed a commanded mission may ask",
                                min=0.1, max=3.0)
    command_rate_hz: float = spec(50.0, "1/s", "commands accepted per second from one "
                                  "source, sustained (beyond: refused \"rate limited\"; "
                                  "stop and disarm are never limited)", min=1.0, max=10000.0)
    command_burst: int = spec(100, "", "commands one source may send at once before the "
                              "rate applies", min=1, max=100000)

    def validate(self) -> None:
        if self.home and (len(self.home) != 2 or not (-90.0 <= self.home[0] <= 90.0)
                          or not (-180.0 <= self.home[1] <= 180.0)):
            raise ValueError(f"home: must be [lat_deg, lon_deg], got {self.home}")
