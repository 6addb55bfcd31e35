"""The supervisor: the one owner of the vessel's mode.

It takes :class:`~zarco_core.messages.Command` messages from any source
(local, scenario, shore, MAVLink), answers each with exactly one
:class:`~zarco_core.messages.CommandAck` (accepted, or refused with a reason
a person can read), evaluates the failsafe table at ``supervisor.rate_hz``,
tells the control loop what to do through a
:class:`~zarco_runtime.guidance.directive.Directive` (republished so that a
silent supervisor stops the boat), and publishes the 1 Hz
:class:`~zarco_core.messages.VesselStatus` snapshot and an
:class:`~zarco_core.messages.Event` for every mode change, acknowledgement,
failsafe entry and exit, fault and component failure.

The vessel boots ``idle``.  A configured mission starts at boot only with
``mission.autostart`` (once the position and heading are valid).  After a
restart the last mission is known (``supervisor.state_file``) but is only
continued by a ``resume`` command.
"""

from __future__ import annotations

import json
import logging
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from zarco_core.auv_messages import AuvPlan, AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.component import ComponentContext
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    Command,
    CommandAck,
    ComponentState,
    DeviceHealth,
    DeviceSummary,
    Event,
    Fault,
    GuidanceStatus,
    Heading,
    HealthState,
    MissionProgress,
    Mode,
    NavState,
    OperatorHeartbeat,
    ThrusterCommand,
    ThrusterStatus,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive, ManualThrust
from zarco_runtime.guidance.mission import Leg, Mission, legs_from_points
from zarco_runtime.supervision.failsafes import SEVERITY, FailsafeMonitor, Inputs
from zarco_runtime.supervision.geofence import Fence
from zarco_runtime.tracking.plan import geodetic_plan

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.supervisor")

#: counters of a device that are not refusals (the rest are reasons a sentence was dropped)
_NOT_REFUSALS = frozenset({
    "bytes", "sentences_ok", "status_ok", "reconnects", "open_failures", "bytes_discarded",
    "corrections_bytes", "corrections_dropped_bytes", "corrections_source_errors",
    "commands_sent", "watchdog_zero", "not_sent_disconnected", "write_errors",
    "nonfinite_commands", "rtcm_frames", "rtcm_dropped_bytes", "rtcm_bad_frames",
})


@dataclass(slots=True)
class Capabilities:
    """Which devices this runtime drives (a mode needing a disabled one is refused)."""

    gps: bool = True
    compass: bool = True
    thrusters: bool = True
    buoy: bool = False


@dataclass(slots=True)
class Boot:
    """The configured mission and whether it starts at boot."""

    mission: Mission | None = None
    autostart: bool = False


@dataclass(slots=True)
class _Saved:
    """The last lines/follow mission and how far it got (kept across restarts)."""

    mission: Mission
    leg: int = 0
    complete: bool = False


@dataclass(slots=True)
class _Health:
    devices: dict[str, DeviceHealth] = field(default_factory=dict)
    components: dict[str, ComponentState] = field(default_factory=dict)


def mission_to_json(m: Mission) -> dict[str, Any]:
    return {"kind": m.kind, "name": m.name, "waypoints": [list(w) for w in m.waypoints],
            "legs": [[lg.n0, lg.e0, lg.n1, lg.e1, lg.speed_mps] for lg in m.legs],
            "auv_plan": [list(p) for p in m.auv_plan]}


def mission_from_json(d: dict[str, Any]) -> Mission:
    legs = tuple(Leg(i, *map(float, lg)) for i, lg in enumerate(d.get("legs", [])))
    wps = tuple((float(a), float(b)) for a, b in d.get("waypoints", []))
    plan = tuple((float(a), float(b)) for a, b in d.get("auv_plan", []))
    return Mission(str(d["kind"]), legs, str(d.get("name", "")), wps, plan)


class Supervisor:
    """Owns the mode; see the module docstring."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock, ctx: ComponentContext,
                 boot: Boot | None = None, caps: Capabilities | None = None,
                 counters: Callable[[], dict[str, int]] | None = None,
                 control_path: frozenset[str] = frozenset(),
                 components: Callable[[], dict[str, ComponentState]] | None = None) -> None:
        self.cfg = cfg
        self.bus = bus
        self.clock = clock
        self.boot = boot or Boot()
        self.caps = caps or Capabilities()
        self.counters_fn = counters
        self.components_fn = components
        self.control_path = control_path
        o = cfg.origin
        self.frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
        self.failsafes = FailsafeMonitor(cfg.failsafe)
        self.fence = Fence(cfg.geofence, self.frame)
        self.home: tuple[float, float] | None = None
        #: the last home converted to geodetic: (home, (lat_deg, lon_deg))
        self._home_ll: tuple[tuple[float, float], tuple[float, float]] | None = None
        if cfg.supervisor.home:
            self.home = self.frame.to_ned(cfg.supervisor.home[0], cfg.supervisor.home[1])
            self.fence.home = self.home
        self.mode = Mode.IDLE
        self.armed = False
        self.seq = 0
        self.directive = Directive(clock.now(), 0, Mode.IDLE, reason="boot")
        self.directive_t0 = self.directive.t
        self.auv_held = False
        self.mission: Mission | None = None  # the mission of the current mode
        #: who gave the AUV plan of the follow mission being started
        self.plan_source = "mission"
        self.saved: _Saved | None = self._load_state()
        self.loaded: Mission | None = self.boot.mission  # a mission given but not started
        self.pending_start = self.boot.autostart and self.boot.mission is not None
        self.fs_applied = False  # the mode is a failsafe's (no operator command since)
        self.fs_interrupted: tuple[Mode, Mission | None, int] | None = None
        self.progress = MissionProgress()
        self.health = _Health()
        self.nav = bus.latest(NavState)
        self.track = bus.latest(AuvTrack)
        self.last_heading_t: float | None = None
        self.last_status_t: float | None = None
        self.first_cmd_t: float | None = None
        self.heartbeat_t: float | None = None
        self.status_msg: VesselStatus | None = None
        self.status_due = False
        self.last_eval = -1e9
        self.acks = {"accepted": 0, "refused": 0}
        ctx.listen(Command, self.on_command)
        ctx.listen(Heading, self._on_heading)
        ctx.listen(ThrusterStatus, self._on_status)
        ctx.listen(ThrusterCommand, self._on_thrust)
        ctx.listen(OperatorHeartbeat, self._on_heartbeat)
        ctx.listen(GuidanceStatus, self._on_guidance)
        ctx.listen(DeviceHealth, self._on_health)
        ctx.listen(ComponentState, self._on_component)
        ctx.listen(Fault, self._on_fault)

    # ------------------------------------------------------------ listeners

    def _on_heading(self, m: Heading) -> None:
        self.last_heading_t = m.t

    def _on_status(self, m: ThrusterStatus) -> None:
        self.last_status_t = m.t

    def _on_thrust(self, m: ThrusterCommand) -> None:
        if self.first_cmd_t is None and (m.u1 != 0.0 or m.u2 != 0.0):
            self.first_cmd_t = m.t

    def _on_heartbeat(self, m: OperatorHeartbeat) -> None:
        link = self.cfg.failsafe.link
        if link == "any" or m.link == link:
            self.heartbeat_t = m.t

    def _on_guidance(self, g: GuidanceStatus) -> None:
        p = self.progress
        if self.mode is Mode.LINES and g.mode == "lines":
            changed = g.leg != p.leg
            p.leg, p.legs, p.complete = g.leg, g.legs, g.complete
            p.xtrack_m, p.along_m = g.xtrack_m, g.along_m
            if self.saved is not None and self.mission is self.saved.mission:
                self.saved.leg = g.leg
                if changed:
                    self._save_state()
            if g.complete:
                self._mission_complete()
        elif self.mode is Mode.FOLLOW and g.mode.startswith("follow:"):
            phase = g.mode.split(":", 1)[1]
            p.xtrack_m, p.along_m = g.xtrack_m, g.along_m
            if phase != p.phase:
                was, p.phase = p.phase, phase
                text = {"follow": "AUV acquired; following",
                        "hold": "AUV track lost; holding where it was lost",
                        "wait": "waiting for the AUV track"}.get(phase, phase)
                if was or phase != "wait":
                    self.event("mission", text)
        elif self.mode is Mode.RETURN and g.mode == "return:station" and g.complete:
            self._set_mode(Mode.HOLD, "arrived home; holding", point=self.home,
                           keep_operator=True)
        else:
            p.xtrack_m, p.along_m = g.xtrack_m, g.along_m

    def _on_health(self, m: DeviceHealth) -> None:
        old = self.health.devices.get(m.device)
        self.health.devices[m.device] = m
        if (old is None or (old.state, old.reason) != (m.state, m.reason)) \
                and m.state is not HealthState.OK:
            self.event("fault", f"{m.device}: {m.state.value}: {m.reason}", m.device)
        elif (old is None or old.state is not HealthState.OK) and m.state is HealthState.OK:
            self.event("fault", f"{m.device}: ok", m.device)

    def _on_component(self, m: ComponentState) -> None:
        self.health.components[m.component] = m
        if m.state == "failed":
            self.event("component", f"{m.component} failed ({m.error}); restarting",
                       m.component)

    def _on_fault(self, m: Fault) -> None:
        self.event("fault", f"{m.source}: {m.reason}", m.source)

    # -------------------------------------------------------------- helpers

    def now(self) -> float:
        return self.clock.now()

    def event(self, kind: str, text: str, source: str = "supervisor") -> None:
        log.info("%s: %s", kind, text)
        self.bus.publish(Event(self.now(), kind, text, source))

    def _position(self) -> tuple[float, float] | None:
        n = self.nav.value
        if n is None or not n.pos_valid:
            return None
        age = self.now() - n.t
        return n.x_m + n.vn_mps * age, n.y_m + n.ve_mps * age

    def _set_mode(self, mode: Mode, reason: str, *, mission: Mission | None = None,
                  start_leg: int = 0, point: tuple[float, float] | None = None,
                  by_failsafe: bool = False, keep_operator: bool = False) -> None:
        old = self.mode
        if old in (Mode.LINES, Mode.FOLLOW) and mode not in (Mode.LINES, Mode.FOLLOW) \
                and self.mission is not None:
            self._save_state()
        if mode is Mode.FOLLOW or old is Mode.FOLLOW:
            # the AUV's plan is in force while following: given when it starts,
            # cleared when it ends
            plan = mission.auv_plan if mode is Mode.FOLLOW and mission is not None else ()
            self.bus.publish(AuvPlan(self.now(), plan, self.plan_source if plan else ""))
        self.mode = mode
        self.mission = mission
        self.seq += 1
        if mode is Mode.IDLE:
            self.armed = False
        else:
            self.armed = True
        if not keep_operator:
            self.fs_applied = by_failsafe
        if mode is Mode.LINES and mission is not None:
            self.progress = MissionProgress("lines", mission.name, start_leg, len(mission.legs))
        elif mode is Mode.FOLLOW:
            self.progress = MissionProgress("follow", mission.name if mission else "follow")
        self.directive = Directive(self.now(), self.seq, mode, mission, start_leg, point, reason)
        self.directive_t0 = self.directive.t
        self.auv_held = False
        self.bus.publish(self.directive)
        self.status_due = True
        where = ""
        if point is not None:
            lat, lon, _ = self.frame.to_geodetic(point[0], point[1])
            where = f" at {lat:.6f}, {lon:.6f}"
        self.event("mode", f"mode {mode.value}{where}: {reason}"
                   + (f" (was {old.value})" if old is not mode else ""))

    def _mission_complete(self) -> None:
        m = self.mission
        if self.saved is not None and m is self.saved.mission:
            self.saved.complete = True
            self._save_state()
        end = (m.legs[-1].n1, m.legs[-1].e1) if m is not None and m.legs else self._position()
        self.event("mission", f"mission {m.name if m else ''} complete")
        self._set_mode(Mode.HOLD, "mission complete; holding at its last waypoint", point=end,
                       keep_operator=True)

    # --------------------------------------------------------- preconditions

    def _cannot(self, mode: Mode) -> str:
        """Why ``mode`` cannot be entered now ("" when it can)."""
        caps = self.caps
        if mode is Mode.IDLE:
            return ""
        if not caps.thrusters:
            return "thrusters disabled (devices.thrusters.enabled = false)"
        if "thruster_silent" in self.failsafes.active:
            return "the thruster controller is not answering"
        if "component_failed" in self.failsafes.active:
            return self.failsafes.active["component_failed"]
        if mode is Mode.MANUAL:
            return ""
        if not caps.gps:
            return "GPS disabled (devices.gps.enabled = false)"
        if not caps.compass:
            return "compass disabled (devices.compass.enabled = false)"
        n = self.nav.value
        if n is None or not n.pos_valid:
            return "no valid position"
        if not n.heading_valid:
            return "no valid heading"
        if self.last_heading_t is None or \
                self.now() - self.last_heading_t > self.cfg.failsafe.heading_lost_s:
            return "no compass heading"
        if mode is Mode.FOLLOW and not caps.buoy:
            return "buoy feed disabled (devices.buoy.enabled = false)"
        if mode is Mode.RETURN and self.home is None:
            return "home unknown"
        return ""

    # -------------------------------------------------------------- commands

    def on_command(self, cmd: Command) -> None:
        """Handle one command; publishes exactly one CommandAck."""
        try:
            reason = self._handle(cmd)
        except (KeyError, TypeError, ValueError) as exc:
            reason = f"bad arguments: {exc}"
        ok = not reason
        self.acks["accepted" if ok else "refused"] += 1
        ack = CommandAck(self.now(), cmd.id, cmd.source, cmd.name, ok, self.mode.value, reason)
        self.bus.publish(ack)
        if ok and cmd.name == "thrust":
            self.acks["thrust"] = self.acks.get("thrust", 0) + 1  # a lease renewal: counted
            return
        self.event("ack", f"{cmd.name} from {cmd.source}: "
                   + ("accepted" if ok else f"refused: {reason}"))

    def _handle(self, cmd: Command) -> str:
        a = cmd.args or {}
        name = cmd.name
        src = cmd.source
        if name in ("stop", "disarm"):
            self.pending_start = False
            self._set_mode(Mode.IDLE, f"{name} from {src}")
            return ""
        if name == "arm":
            self.armed = True
            self.event("mode", f"armed by {src}")
            return ""
        if name == "mode":
            try:
                mode = Mode(str(a.get("mode", "")))
            except ValueError:
                return f"unknown mode {a.get('mode')!r} (one of {', '.join(m.value for m in Mode)})"
            if mode is Mode.IDLE:
                self.pending_start = False
                self._set_mode(Mode.IDLE, f"mode idle from {src}")
                return ""
            if mode is Mode.HOLD:
                return self._hold(a, src)
            if mode is Mode.FOLLOW:
                return self._follow(src, {})
            if mode is Mode.LINES:
                m = self.loaded or (self.saved.mission if self.saved and not self.saved.complete
                                    and self.saved.mission.kind == "lines" else None)
                if m is None:
                    return "no mission loaded"
                return self._start(m, 0, src)
            why = self._cannot(mode)
            if why:
                return why
            if mode is Mode.RETURN:
                self._set_mode(Mode.RETURN, f"return from {src}", point=self.home)
            else:
                self._set_mode(Mode.MANUAL, f"manual from {src}")
            return ""
        if name == "mission":
            return self._mission(a, src)
        if name == "follow":
            return self._follow(src, a)
        if name == "thrust":
            if self.mode is not Mode.MANUAL:
                return "not in manual mode"
            u1, u2 = float(a["u1"]), float(a["u2"])  # type: ignore[arg-type]
            for k, u in (("u1", u1), ("u2", u2)):
                if not (math.isfinite(u) and -100.0 <= u <= 100.0):
                    return f"{k} must be a number within -100..100, got {a[k]!r}"
            t = self.now()
            self.bus.publish(ManualThrust(t, u1, u2, t + self.cfg.supervisor.manual_lease_s))
            return ""
        if name == "resume":
            return self._resume(src)
        return f"unknown command {name!r}"

    def _hold(self, a: dict[str, object], src: str) -> str:
        why = self._cannot(Mode.HOLD)
        if why:
            return why
        if "lat_deg" in a or "lon_deg" in a:
            lat, lon = float(a["lat_deg"]), float(a["lon_deg"])  # type: ignore[arg-type]
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                return f"not a latitude, longitude: {lat}, {lon}"
            point = self.frame.to_ned(lat, lon)
            out = self.fence.outside(*point) if self.fence.enabled else ""
            if out:
                return f"hold point outside the geofence ({out})"
        else:
            p = self._position()
            if p is None:
                return "no valid position"
            point = p
        self._set_mode(Mode.HOLD, f"hold from {src}", point=point)
        return ""

    def _follow(self, src: str, a: dict[str, object], m: Mission | None = None) -> str:
        """Follow the AUV: with the mission ``m`` (a resumed or configured one), or
        with the command's ``auv_plan`` ([[lat_deg, lon_deg], ...]; [] for none),
        or without one, with the configured follow mission's plan."""
        why = self._cannot(Mode.FOLLOW)
        if why:
            return why
        if m is None:
            boot = self.boot.mission
            plan = boot.auv_plan if boot is not None and boot.kind == "follow" else ()
            self.plan_source = "mission"
            if "auv_plan" in a:
                try:
                    plan = geodetic_plan(a["auv_plan"], self.frame.to_ned)
                except ValueError as exc:
                    return f"auv_plan: {exc}"
                self.plan_source = src
            m = Mission("follow", name="follow", auv_plan=plan)
        else:
            self.plan_source = "mission" if m is self.boot.mission else src
        self.saved = _Saved(m)
        self._save_state()
        self._set_mode(Mode.FOLLOW, f"follow from {src}"
                       + (f" with an AUV plan of {len(m.auv_plan)} points" if m.auv_plan
                          else ""), mission=m)
        return ""

    def _mission(self, a: dict[str, object], src: str) -> str:
        if a.get("clear"):
            if self.mode is Mode.LINES:
                return "a mission is running: stop or hold first"
            self.loaded = None
            if self.saved is not None and self.saved.mission.kind == "lines":
                self.saved.complete = True  # nothing left to start or resume
                self._save_state()
            self.event("mission", f"loaded mission cleared by {src}")
            return ""
        wps_raw = a.get("waypoints")
        if not isinstance(wps_raw, list) or len(wps_raw) < 2:
            return "waypoints: need a list of at least 2 [lat_deg, lon_deg]"
        wps: list[tuple[float, float]] = []
        for i, w in enumerate(wps_raw):
            if not (isinstance(w, (list, tuple)) and len(w) == 2):
                return f"waypoint {i}: must be [lat_deg, lon_deg]"
            lat, lon = float(w[0]), float(w[1])
            if not (math.isfinite(lat) and math.isfinite(lon) and -90.0 <= lat <= 90.0
                    and -180.0 <= lon <= 180.0):
                return f"waypoint {i}: not a latitude, longitude: {w}"
            wps.append((lat, lon))
        speed = float(a.get("speed_mps", 1.0))  # type: ignore[arg-type]
        vmax = self.cfg.supervisor.max_speed_mps
        if not (math.isfinite(speed) and 0.05 <= speed <= vmax):
            return f"speed_mps must be within 0.05..{vmax:g} m/s, got {a.get('speed_mps')!r}"
        speeds_raw = a.get("leg_speeds_mps")
        speeds: list[float] = []
        if speeds_raw is not None:
            if not isinstance(speeds_raw, list) or len(speeds_raw) != len(wps) - 1:
                return f"leg_speeds_mps: need one speed per leg ({len(wps) - 1})"
            for i, v in enumerate(speeds_raw):
                sv = float(v)
                if not (math.isfinite(sv) and 0.05 <= sv <= vmax):
                    return f"leg_speeds_mps: leg {i} must be within 0.05..{vmax:g} m/s, got {v!r}"
                speeds.append(sv)
        start_leg = int(a.get("start_leg", 0))  # type: ignore[call-overload]
        if not 0 <= start_leg < len(wps) - 1:
            return f"start_leg must be within 0..{len(wps) - 2}, got {start_leg}"
        pts = [self.frame.to_ned(lat, lon) for lat, lon in wps]
        for i, p in enumerate(pts):
            if math.hypot(*p) > 50_000.0:
                return f"waypoint {i} is {math.hypot(*p) / 1000:.0f} km from the origin"
            if i and math.hypot(p[0] - pts[i - 1][0], p[1] - pts[i - 1][1]) < 1.0:
                return f"waypoints {i - 1} and {i} are less than 1 m apart"
            if self.fence.enabled:
                out = self.fence.outside(*p)
                if out:
                    return f"waypoint {i} is outside the geofence ({out})"
        name = str(a.get("name", f"{len(wps)} waypoints from {src}"))
        legs = legs_from_points(pts, speed)
        if speeds:
            legs = tuple(Leg(lg.index, lg.n0, lg.e0, lg.n1, lg.e1, v)
                         for lg, v in zip(legs, speeds, strict=True))
        m = Mission("lines", legs, name, tuple(wps))
        start = bool(a.get("start", True))
        if start:
            why = self._start(m, start_leg, src)
            if why:
                return why
        else:
            self.loaded = m
            self.event("mission", f"mission loaded: {name}")
        return ""

    def _start(self, m: Mission, leg: int, src: str) -> str:
        if m.kind == "follow":
            return self._follow(src, {}, m)
        why = self._cannot(Mode.LINES)
        if why:
            return why
        self.loaded = m
        self.saved = _Saved(m, leg)
        self._save_state()
        self._set_mode(Mode.LINES, f"mission {m.name} from {src}"
                       + (f", from leg {leg + 1}" if leg else ""), mission=m, start_leg=leg)
        return ""

    def _resume(self, src: str) -> str:
        s = self.saved
        if s is None:
            return "no mission to resume"
        if s.complete:
            return f"the last mission ({s.mission.name}) is complete"
        return self._start(s.mission, s.leg, f"{src} (resume)")

    # ------------------------------------------------------------ state file

    def _load_state(self) -> _Saved | None:
        path = self.cfg.supervisor.state_file
        if not path or not os.path.exists(path):
            return None
        try:
            d = json.loads(Path(path).read_text())
            return _Saved(mission_from_json(d["mission"]), int(d.get("leg", 0)),
                          bool(d.get("complete", False)))
        except (OSError, ValueError, KeyError, TypeError) as exc:
            log.warning("state file %s unreadable (%s); no last mission", path, exc)
            return None

    def _save_state(self) -> None:
        path = self.cfg.supervisor.state_file
        s = self.saved
        if not path or s is None:
            return
        data = {"mission": mission_to_json(s.mission), "leg": s.leg, "complete": s.complete,
                "utc_s": self.clock.utc()}
        tmp = f"{path}.tmp"
        try:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            with open(tmp, "w") as fh:
                json.dump(data, fh)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except OSError as exc:
            log.warning("cannot write the state file %s: %s", path, exc)

    # ------------------------------------------------------------ failsafes

    def _inputs(self, now: float) -> Inputs:
        pos = self._position()
        outside = ""
        if self.fence.enabled and pos is not None:
            outside = self.fence.outside(*pos)
        auv_lost = ""
        if self.mode is Mode.FOLLOW:
            tr = self.track.value
            # lost once it was held since following began (acquiring is not losing)
            if tr is not None and tr.t >= self.directive_t0 and not tr.lost:
                self.auv_held = True
            if tr is not None and tr.lost and self.auv_held:
                auv_lost = "AUV track lost"
        status_ref = self.last_status_t if self.last_status_t is not None else self.first_cmd_t
        if self.first_cmd_t is None and self.last_status_t is None:
            status_ref = None
        failed = [c for c, s in self.health.components.items()
                  if s.state != "running" and c in self.control_path]
        return Inputs(now, self.mode, self.nav.value, self.last_heading_t, status_ref,
                      self.heartbeat_t, outside, auv_lost, failed)

    def evaluate(self, now: float) -> None:
        """One evaluation of the failsafe table (and of a pending autostart)."""
        self.last_eval = now
        if self.home is None:
            p = self._position()
            if p is not None:
                self.home = p
                self.fence.home = p
                lat, lon, _ = self.frame.to_geodetic(*p)
                self.event("mission", f"home set at {lat:.6f}, {lon:.6f} (first position)")
        for tr in self.failsafes.evaluate(self._inputs(now)):
            self.status_due = True
            if tr.entered:
                self.event("failsafe", f"{tr.name}: {tr.reason}; action {tr.action} "
                           f"(condition since {now - tr.t_condition:.2f} s)")
                self._apply(tr.action, f"failsafe {tr.name}: {tr.reason}")
            else:
                self.event("failsafe", f"{tr.name} {tr.reason}")
                if not self.failsafes.active:
                    self._after_clear()
        bm = self.boot.mission
        if self.pending_start and bm is not None and \
                not self._cannot(Mode.LINES if bm.kind == "lines" else Mode.FOLLOW):
            self.pending_start = False
            why = self._start(bm, 0, "autostart")
            if why:
                self.event("mission", f"autostart refused: {why}")

    def _apply(self, action: str, reason: str) -> None:
        if action == "continue":
            return
        current = {Mode.IDLE: "idle", Mode.HOLD: "hold", Mode.RETURN: "return"}.get(self.mode)
        if current is not None and SEVERITY[current] >= SEVERITY[action]:
            return
        if self.fs_interrupted is None and self.mode is not Mode.IDLE:
            leg = self.progress.leg if self.mode is Mode.LINES else 0
            self.fs_interrupted = (self.mode, self.mission, leg)
        if action == "idle":
            self._set_mode(Mode.IDLE, reason, by_failsafe=True)
        elif action == "hold":
            p = self._position()
            if p is None:
                self._set_mode(Mode.IDLE, reason + " (no position to hold: idle)",
                               by_failsafe=True)
            else:
                self._set_mode(Mode.HOLD, reason, point=p, by_failsafe=True)
        elif action == "return":
            if self.home is None or self._position() is None:
                self._set_mode(Mode.IDLE, reason + " (cannot return: idle)", by_failsafe=True)
            else:
                self._set_mode(Mode.RETURN, reason, point=self.home, by_failsafe=True)

    def _after_clear(self) -> None:
        interrupted, self.fs_interrupted = self.fs_interrupted, None
        if not self.fs_applied:
            return  # the operator took over since: nothing to undo
        policy = self.cfg.failsafe.after_clear
        if policy == "resume" and interrupted is not None:
            mode, mission, leg = interrupted
            why = self._cannot(mode)
            if not why:
                self._set_mode(mode, "failsafes cleared: resuming", mission=mission,
                               start_leg=leg, point=self.home if mode is Mode.RETURN else None,
                               keep_operator=True)
                self.fs_applied = False
                return
            self.event("failsafe", f"cannot resume: {why}")
        if policy in ("hold", "resume"):
            p = self._position()
            if p is not None and not self._cannot(Mode.HOLD):
                self._set_mode(Mode.HOLD, "failsafes cleared: holding here; send resume to "
                               "continue the mission", point=p, keep_operator=True)
                self.fs_applied = False
                return
        self.event("failsafe", f"failsafes cleared; staying {self.mode.value}")
        self.fs_applied = False

    # --------------------------------------------------------------- status

    def snapshot(self, now: float) -> VesselStatus:
        devs: dict[str, DeviceSummary] = {}
        for name, h in self.health.devices.items():
            c = h.counters
            ok = c.get("sentences_ok", 0) + c.get("status_ok", 0)
            bad = sum(v for k, v in c.items() if k not in _NOT_REFUSALS)
            age = None if h.last_ok_t is None else round(now - h.last_ok_t, 3)
            devs[name] = DeviceSummary(h.state.value, h.reason, age, ok, bad, dict(c))
        counters = dict(self.counters_fn()) if self.counters_fn is not None else {}
        counters["bus_published"] = self.bus.published
        counters["bus_listener_errors"] = self.bus.listener_errors
        counters["commands_accepted"] = self.acks["accepted"]
        counters["commands_refused"] = self.acks["refused"]
        home_lat = home_lon = None
        if self.home is not None:
            home_lat, home_lon = self._home_geodetic(self.home)
        p = self.progress
        prog = MissionProgress(p.kind, p.name, p.leg, p.legs, p.complete, p.xtrack_m, p.along_m,
                               p.phase)
        return VesselStatus(now, self.clock.utc(now), self.mode.value, self.armed or
                            self.mode is not Mode.IDLE, prog,
                            sorted(self.failsafes.active), devs,
                            self._components(), counters, self.directive.reason,
                            home_lat, home_lon)

    def _home_geodetic(self, home: tuple[float, float]) -> tuple[float, float]:
        """(lat, lon) degrees of ``home``, converted once per home (pymap3d costs
        a fraction of a millisecond a call, and a status goes out every second)."""
        if self._home_ll is None or self._home_ll[0] != home:
            lat, lon, _ = self.frame.to_geodetic(*home)
            self._home_ll = (home, (lat, lon))
        return self._home_ll[1]

    def _components(self) -> dict[str, ComponentState]:
        """Every component's state: the runtime's account, with what the bus said."""
        out = dict(self.health.components)
        if self.components_fn is not None:
            out.update(self.components_fn())
        return out

    async def run(self) -> None:
        clock = self.clock
        sup = self.cfg.supervisor
        self.bus.publish(self.directive)
        self.event("mode", "supervisor started: mode idle"
                   + (f"; last mission {self.saved.mission.name!r} can be resumed"
                      if self.saved and not self.saved.complete else ""))
        if self.boot.mission is not None and not self.boot.autostart:
            self.event("mission", f"mission {self.boot.mission.name!r} loaded; not started "
                       "(mission.autostart = false): send mode lines or follow to start it")
        dt = 1.0 / sup.rate_hz
        t0 = clock.now()
        next_directive = t0 + sup.directive_period_s
        next_status = t0
        k = 0
        while True:
            k += 1
            await clock.sleep_until(t0 + k * dt)
            now = clock.now()
            self.evaluate(now)
            if now >= next_directive:
                d = self.directive  # the same directive, still meant
                self.directive = Directive(now, d.seq, d.mode, d.mission, d.start_leg,
                                           d.point, d.reason, d.since)
                self.bus.publish(self.directive)
                next_directive = now + sup.directive_period_s
            if now >= next_status or self.status_due:
                self.status_due = False
                self.status_msg = self.snapshot(now)
                self.bus.publish(self.status_msg)
                next_status = now + sup.status_period_s
