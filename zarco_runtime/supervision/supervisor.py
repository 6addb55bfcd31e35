"""The supervisor: the one owner of the vessel's mode, of arming and of changes.

It takes :class:`~zarco_core.messages.Command` messages (typed arguments,
:mod:`zarco_core.commands`) from any source (local, scenario, shore, MAVLink),
answers each with exactly one :class:`~zarco_core.messages.CommandAck`
(accepted, or refused with a reason a person can read), evaluates the
failsafe table at ``supervisor.rate_hz``, tells the control loop what to do
through a :class:`~zarco_runtime.guidance.directive.Directive` (republished so
that a silent supervisor stops the boat), and publishes the 1 Hz
:class:`~zarco_core.messages.VesselStatus` snapshot and an
:class:`~zarco_core.messages.Event` for every mode change, arming,
acknowledgement, parameter change, failsafe entry and exit, fault and
component failure.

**Arming.**  The vessel boots ``idle`` and disarmed.  ``arm`` is accepted only
with a valid position and heading, the thruster controller answering and no
failsafe active; ``disarm`` and ``stop`` go idle and disarmed.  While
disarmed every command that would move the boat (a moving mode, a mission
start, ``follow``, manual thrust, ``resume``) is refused with "disarmed", and
the directive says so, so the control task sends zero thrust whatever its
mode.  ``mission.autostart`` arms at boot once the checks pass (the
operator's explicit choice) and starts the mission, except after a restart
(the state file holds a mission left unfinished): a restart never drives off.

**Failsafes latch** (:mod:`.failsafes`): conditions are judged in every mode;
one clears only after its condition has been healthy for
``failsafe.clear_after_s``; an ``idle`` action disarms, so the boat stays
still until an operator acts; ``failsafe.after_clear`` applies only to a boat
a ``hold`` or ``return`` action kept under way.

**Parameters** are ``param`` commands (:mod:`.params`): validated, refused
under way where unsafe, applied to the live configuration, published as
:class:`~zarco_core.messages.ParamChange` and recorded.

**No input ends or restarts it**: any exception while handling a command
becomes a refusal and a counted fault.  Each source is rate limited
(:mod:`.rate_limit`; ``stop`` and ``disarm`` never are).  The state file is
written by a task of its own (:mod:`.state_file`), never in a listener.

After a restart the last mission is known (``supervisor.state_file``) but is
only continued by a ``resume`` command.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from zarco_core.auv_messages import AuvPlan, AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.commands import (
    ArmArgs,
    DisarmArgs,
    FollowArgs,
    MissionArgs,
    ModeArgs,
    ParamArgs,
    ResumeArgs,
    StopArgs,
    ThrustArgs,
)
from zarco_core.component import ComponentContext
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    MOVING,
    Command,
    CommandAck,
    ComponentState,
    DeviceHealth,
    Event,
    Fault,
    GuidanceStatus,
    Heading,
    HealthState,
    MissionProgress,
    Mode,
    NavState,
    OperatorHeartbeat,
    ParamChange,
    ThrusterCommand,
    ThrusterStatus,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive, ManualThrust
from zarco_runtime.guidance.mission import Mission
from zarco_runtime.supervision import params
from zarco_runtime.supervision.failsafes import SEVERITY, FailsafeMonitor, Inputs
from zarco_runtime.supervision.geofence import Fence
from zarco_runtime.supervision.missions import lines_mission, mission_points
from zarco_runtime.supervision.rate_limit import EventBudget, TokenBuckets
from zarco_runtime.supervision.state_file import (
    SavedMission,
    StateFile,
    mission_from_json,
    mission_to_json,
)
from zarco_runtime.supervision.status import NOT_REFUSALS, device_summaries
from zarco_runtime.tracking.plan import PlanError, geodetic_plan

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

__all__ = ["Boot", "Capabilities", "Supervisor", "mission_from_json", "mission_to_json"]

log = logging.getLogger("zarco.supervisor")

#: (kept for the tools that read device summaries the supervisor's way)
_NOT_REFUSALS = NOT_REFUSALS


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
class _Health:
    devices: dict[str, DeviceHealth] = field(default_factory=dict)
    components: dict[str, ComponentState] = field(default_factory=dict)


class Supervisor:
    """Owns the mode, arming and changes; see the module docstring."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock, ctx: ComponentContext,
                 boot: Boot | None = None, caps: Capabilities | None = None,
                 counters: Callable[[], dict[str, int]] | None = None,
                 control_path: frozenset[str] = frozenset(),
                 components: Callable[[], dict[str, ComponentState]] | None = None,
                 state: StateFile | None = None) -> None:
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
        self.state = state if state is not None else StateFile(cfg.supervisor.state_file)
        self.saved: SavedMission | None = self.state.load()
        self.loaded: Mission | None = self.boot.mission  # a mission given but not started
        #: a mission left unfinished by the last process (a crash, a kill, a power
        #: cut): this start is a restart, and a restart never drives off on its own,
        #: whatever ``mission.autostart`` says; the operator resumes or starts it
        self.restarted = self.saved is not None and not self.saved.complete
        self.pending_start = (self.boot.autostart and self.boot.mission is not None
                              and not self.restarted)
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
        self.acks = {"accepted": 0, "refused": 0, "thrust": 0}
        self.command_faults = 0
        self.buckets = TokenBuckets(lambda: cfg.supervisor.command_rate_hz,
                                    lambda: cfg.supervisor.command_burst)
        self.ack_events = EventBudget()
        #: the mission the status shows (loaded or running), its points and their id
        self._shown: tuple[Mission | None, tuple[tuple[float, float], ...]] = (None, ())
        self.mission_id = 0
        ctx.listen(Command, self.on_command)
        ctx.listen(CommandAck, self._on_ack)
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
        if self.first_cmd_t is None:  # a controller that never answers is silent from here
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

    def _publish_directive(self) -> None:
        """The current directive again, now, with the current arming (the same
        ``seq``: what to do has not changed, only whether thrust is allowed)."""
        d = self.directive
        self.directive = Directive(self.now(), d.seq, d.mode, d.mission, d.start_leg,
                                   d.point, d.reason, d.since, self.armed)
        self.bus.publish(self.directive)
        self.status_due = True

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
        if not keep_operator:
            self.fs_applied = by_failsafe
        if mode is Mode.LINES and mission is not None:
            self.progress = MissionProgress("lines", mission.name, start_leg, len(mission.legs))
        elif mode is Mode.FOLLOW:
            self.progress = MissionProgress("follow", mission.name if mission else "follow")
        self.directive = Directive(self.now(), self.seq, mode, mission, start_leg, point, reason,
                                   armed=self.armed)
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

    def _arm(self, by: str) -> None:
        self.armed = True
        self.event("arming", f"armed by {by}")
        self._publish_directive()

    def _disarm(self, reason: str, *, by_failsafe: bool = False) -> None:
        """Idle and disarmed (stop, disarm, an ``idle`` failsafe)."""
        was = self.armed
        self.armed = False
        self.pending_start = False
        if self.mode is not Mode.IDLE:
            self._set_mode(Mode.IDLE, reason, by_failsafe=by_failsafe)
        else:
            self._publish_directive()
        if was:
            self.event("arming", f"disarmed: {reason}")

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

    def arm_refusal(self) -> str:
        """Why the boat cannot be armed now ("" when it can)."""
        caps = self.caps
        if not caps.thrusters:
            return "thrusters disabled (devices.thrusters.enabled = false)"
        if not caps.gps:
            return "GPS disabled (devices.gps.enabled = false)"
        if not caps.compass:
            return "compass disabled (devices.compass.enabled = false)"
        n = self.nav.value
        if n is None or not n.pos_valid:
            return "no valid position"
        now = self.now()
        if not n.heading_valid or self.last_heading_t is None or \
                now - self.last_heading_t > self.cfg.failsafe.heading_lost_s:
            return "no valid heading"
        if self.last_status_t is None or \
                now - self.last_status_t > self.cfg.failsafe.thruster_silent_s:
            return "the thruster controller is not answering"
        if self.failsafes.active:
            return "failsafe active: " + ", ".join(
                f"{k} ({v})" for k, v in sorted(self.failsafes.active.items()))
        return ""

    def _cannot(self, mode: Mode) -> str:
        """Why ``mode`` cannot be entered now ("" when it can)."""
        caps = self.caps
        if mode is Mode.IDLE:
            return ""
        if not self.armed:
            return "disarmed"
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

    def _under_way(self) -> str:
        """The mode the boat is under way in ("" when idle or disarmed)."""
        return self.mode.value if self.armed and self.mode in MOVING else ""

    # -------------------------------------------------------------- commands

    def on_command(self, cmd: Command) -> None:
        """Handle one command; publishes exactly one CommandAck.  Nothing a command
        carries can raise out of here: an error in handling it is a refusal and a
        counted fault (``stop`` and ``disarm`` still stop the boat)."""
        a = cmd.args
        safe = isinstance(a, (StopArgs, DisarmArgs))
        try:
            if not safe and not self.buckets.take(cmd.source, self.now()):
                sup = self.cfg.supervisor
                reason = (f"rate limited: more than {sup.command_rate_hz:g} commands a second "
                          f"(burst {sup.command_burst}) from {cmd.source}")
            else:
                reason = self._handle(cmd)
        except Exception as exc:  # a command never restarts the supervisor
            self.command_faults += 1
            log.exception("command %s from %s", cmd.name, cmd.source)
            reason = f"not handled: internal error ({type(exc).__name__})"
            self.bus.publish(Fault(self.now(), "supervisor",
                                   f"command {cmd.name} from {cmd.source}: {exc!r}"[:300]))
            if safe:
                self.armed, self.pending_start = False, False
                self._set_mode(Mode.IDLE, f"{cmd.name} from {cmd.source}")
                reason = ""
        self.bus.publish(CommandAck(self.now(), cmd.id, cmd.source, cmd.name, not reason,
                                    self.mode.value, reason))

    def _on_ack(self, ack: CommandAck) -> None:
        """Every acknowledgement (ours, and a link's refusal of a payload): counted
        and told, within each source's event budget."""
        self.acks["accepted" if ack.ok else "refused"] += 1
        if ack.ok and ack.name == "thrust":
            self.acks["thrust"] += 1  # a lease renewal: counted, not told
            return
        if self.ack_events.allow(ack.source, ack.t):
            self.event("ack", f"{ack.name} from {ack.source}: "
                       + ("accepted" if ack.ok else f"refused: {ack.reason}"))

    def _handle(self, cmd: Command) -> str:
        a = cmd.args
        src = cmd.source
        if isinstance(a, (StopArgs, DisarmArgs)):
            self._disarm(f"{cmd.name} from {src}")
            return ""
        if isinstance(a, ArmArgs):
            why = self.arm_refusal()
            if why:
                return why
            if not self.armed:
                self._arm(src)
            return ""
        if isinstance(a, ParamArgs):
            return self._param(cmd, a)
        if isinstance(a, MissionArgs):
            return self._mission(a, src)
        if isinstance(a, ModeArgs):
            return self._mode(a, src)
        if isinstance(a, FollowArgs):
            return self._follow(src, a)
        if isinstance(a, ThrustArgs):
            if not self.armed:
                return "disarmed"
            if self.mode is not Mode.MANUAL:
                return "not in manual mode"
            t = self.now()
            self.bus.publish(ManualThrust(t, a.u1, a.u2, t + self.cfg.supervisor.manual_lease_s))
            return ""
        if isinstance(a, ResumeArgs):
            return self._resume(src)
        return f"{cmd.name}: not handled by this supervisor"

    def _mode(self, a: ModeArgs, src: str) -> str:
        mode = a.mode
        if mode is Mode.IDLE:
            self.pending_start = False
            self._set_mode(Mode.IDLE, f"mode idle from {src}")
            return ""
        if not self.armed:
            return "disarmed"
        if mode is Mode.HOLD:
            return self._hold(a, src)
        if mode is Mode.FOLLOW:
            return self._follow(src, None)
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

    def _hold(self, a: ModeArgs, src: str) -> str:
        why = self._cannot(Mode.HOLD)
        if why:
            return why
        if a.lat_deg is not None and a.lon_deg is not None:
            point = self.frame.to_ned(a.lat_deg, a.lon_deg)
            out = self.fence.outside(*point) if self.fence.enabled else ""
            if out:
                return f"lat_deg, lon_deg: hold point outside the geofence ({out})"
        else:
            p = self._position()
            if p is None:
                return "no valid position"
            point = p
        self._set_mode(Mode.HOLD, f"hold from {src}", point=point)
        return ""

    def _follow(self, src: str, a: FollowArgs | None, m: Mission | None = None) -> str:
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
            if a is not None and a.auv_plan is not None:
                try:
                    plan = geodetic_plan(a.auv_plan, self.frame.to_ned)
                except PlanError as exc:
                    return exc.named("auv_plan")
                self.plan_source = src
            m = Mission("follow", name="follow", auv_plan=plan)
        else:
            self.plan_source = "mission" if m is self.boot.mission else src
        self.saved = SavedMission(m)
        self._save_state()
        self._set_mode(Mode.FOLLOW, f"follow from {src}"
                       + (f" with an AUV plan of {len(m.auv_plan)} points" if m.auv_plan
                          else ""), mission=m)
        return ""

    def _mission(self, a: MissionArgs, src: str) -> str:
        if a.clear:
            if self.mode is Mode.LINES:
                return "a mission is running: stop or hold first"
            self.loaded = None
            if self.saved is not None and self.saved.mission.kind == "lines":
                self.saved.complete = True  # nothing left to start or resume
                self._save_state()
            self.status_due = True
            self.event("mission", f"loaded mission cleared by {src}")
            return ""
        if a.start and not self.armed:
            return "disarmed"
        m = lines_mission(a, self.frame, self.fence, self.cfg.supervisor.max_speed_mps, src)
        if isinstance(m, str):
            return m
        if a.start:
            return self._start(m, a.start_leg, src)
        self.loaded = m
        self.status_due = True
        self.event("mission", f"mission loaded: {m.name}")
        return ""

    def _start(self, m: Mission, leg: int, src: str) -> str:
        if m.kind == "follow":
            return self._follow(src, None, m)
        why = self._cannot(Mode.LINES)
        if why:
            return why
        self.loaded = m
        self.saved = SavedMission(m, leg)
        self._save_state()
        self._set_mode(Mode.LINES, f"mission {m.name} from {src}"
                       + (f", from leg {leg + 1}" if leg else ""), mission=m, start_leg=leg)
        return ""

    def _resume(self, src: str) -> str:
        if not self.armed:
            return "disarmed"
        s = self.saved
        if s is None:
            return "no mission to resume"
        if s.complete:
            return f"the last mission ({s.mission.name}) is complete"
        return self._start(s.mission, s.leg, f"{src} (resume)")

    def _param(self, cmd: Command, a: ParamArgs) -> str:
        try:
            old, new = params.apply(self.cfg, a.name, a.value, self._under_way())
        except params.ParamRefused as exc:
            return str(exc)
        if a.name.startswith("geofence."):
            home = self.fence.home
            self.fence = Fence(self.cfg.geofence, self.frame)
            self.fence.home = home
        self.bus.publish(ParamChange(self.now(), a.name, new, old, cmd.source, cmd.id))
        self.status_due = True
        shown = repr(new) if len(repr(new)) <= 80 else f"{repr(new)[:77]}..."
        self.event("param", f"{a.name} = {shown} (was {old!r}) by {cmd.source}")
        return ""

    # ------------------------------------------------------------ state file

    def _save_state(self) -> None:
        if self.saved is not None:
            self.state.save(self.saved, self.clock.utc())

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
        status_ref = None
        if self.caps.thrusters:
            status_ref = self.last_status_t if self.last_status_t is not None \
                else self.first_cmd_t
        failed = [c for c, s in self.health.components.items()
                  if s.state != "running" and c in self.control_path]
        return Inputs(now, self.mode, self.nav.value, self.last_heading_t, status_ref,
                      self.heartbeat_t, outside, auv_lost, failed, self.armed)

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
                           f"(condition since {now - tr.t_condition:.2f} s)"
                           + ("" if self.armed else "; disarmed already"))
                self._apply(tr.action, f"failsafe {tr.name}: {tr.reason}")
            else:
                self.event("failsafe", f"{tr.name} {tr.reason}")
                if not self.failsafes.active:
                    self._after_clear()
        bm = self.boot.mission
        if self.pending_start and bm is not None:
            self._autostart(bm)

    def _autostart(self, bm: Mission) -> None:
        """``mission.autostart``: arm once the checks pass, then start the mission."""
        if not self.armed:
            if self.arm_refusal():
                return
            self._arm("autostart (mission.autostart = true)")
        if self._cannot(Mode.LINES if bm.kind == "lines" else Mode.FOLLOW):
            return
        self.pending_start = False
        why = self._start(bm, 0, "autostart")
        if why:
            self.event("mission", f"autostart refused: {why}")

    def _apply(self, action: str, reason: str) -> None:
        if action == "continue" or not self.armed:
            return
        if action == "idle":
            self.fs_interrupted = None
            self._disarm(reason, by_failsafe=True)
            return
        if self.mode is Mode.IDLE:
            return  # armed but still: a failsafe never sets the boat moving
        current = {Mode.HOLD: "hold", Mode.RETURN: "return"}.get(self.mode)
        if current is not None and SEVERITY[current] >= SEVERITY[action]:
            return
        if self.fs_interrupted is None:
            leg = self.progress.leg if self.mode is Mode.LINES else 0
            self.fs_interrupted = (self.mode, self.mission, leg)
        if action == "hold":
            p = self._position()
            if p is None:
                self._disarm(reason + " (no position to hold: idle)", by_failsafe=True)
            else:
                self._set_mode(Mode.HOLD, reason, point=p, by_failsafe=True)
        elif action == "return":
            if self.home is None or self._position() is None:
                self._disarm(reason + " (cannot return: idle)", by_failsafe=True)
            else:
                self._set_mode(Mode.RETURN, reason, point=self.home, by_failsafe=True)

    def _after_clear(self) -> None:
        """Every failsafe has cleared: ``after_clear`` for a boat a failsafe kept
        under way (hold, return); a boat an ``idle`` action stopped stays idle and
        disarmed until an operator acts."""
        interrupted, self.fs_interrupted = self.fs_interrupted, None
        applied, self.fs_applied = self.fs_applied, False
        if not applied or not self.armed or self.mode not in (Mode.HOLD, Mode.RETURN):
            self.event("failsafe", f"failsafes cleared; staying {self.mode.value}"
                       + ("" if self.armed else " and disarmed: arm to go on"))
            return  # the operator took over since, or the boat was stopped
        policy = self.cfg.failsafe.after_clear
        if policy == "resume" and interrupted is not None:
            mode, mission, leg = interrupted
            why = self._cannot(mode)
            if not why:
                self._set_mode(mode, "failsafes cleared: resuming", mission=mission,
                               start_leg=leg, point=self.home if mode is Mode.RETURN else None,
                               keep_operator=True)
                return
            self.event("failsafe", f"cannot resume: {why}")
        if policy in ("hold", "resume"):
            p = self._position()
            if p is not None and not self._cannot(Mode.HOLD):
                self._set_mode(Mode.HOLD, "failsafes cleared: holding here; send resume to "
                               "continue the mission", point=p, keep_operator=True)
                return
        self._disarm("failsafes cleared: idle (failsafe.after_clear)")

    # --------------------------------------------------------------- status

    def _shown_points(self) -> tuple[tuple[float, float], ...]:
        """The waypoints of the lines mission loaded or running (its id changes with them)."""
        m = self.mission if self.mode is Mode.LINES and self.mission is not None \
            else self.loaded
        if m is not self._shown[0]:
            pts = mission_points(m, self.frame)
            if pts != self._shown[1]:
                self.mission_id += 1
            self._shown = (m, pts)
        return self._shown[1]

    def snapshot(self, now: float) -> VesselStatus:
        counters = dict(self.counters_fn()) if self.counters_fn is not None else {}
        counters["bus_published"] = self.bus.published
        counters["bus_listener_errors"] = self.bus.listener_errors
        counters["commands_accepted"] = self.acks["accepted"]
        counters["commands_refused"] = self.acks["refused"]
        counters["commands_rate_limited"] = self.buckets.limited
        counters["command_faults"] = self.command_faults
        counters["state_file_writes"] = self.state.writes
        counters["state_file_write_errors"] = self.state.write_errors
        home_lat = home_lon = None
        if self.home is not None:
            home_lat, home_lon = self._home_geodetic(self.home)
        p = self.progress
        prog = MissionProgress(p.kind, p.name, p.leg, p.legs, p.complete, p.xtrack_m, p.along_m,
                               p.phase)
        points = self._shown_points()
        return VesselStatus(now, self.clock.utc(now), self.mode.value, self.armed, prog,
                            sorted(self.failsafes.active),
                            device_summaries(self.health.devices, now),
                            self._components(), counters, self.directive.reason,
                            home_lat, home_lon, points, self.mission_id)

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
        async with asyncio.TaskGroup() as tg:
            tg.create_task(self.state.run(), name="supervisor.state_file")
            tg.create_task(self._loop(), name="supervisor.loop")

    async def _loop(self) -> None:
        clock = self.clock
        sup = self.cfg.supervisor
        self.bus.publish(self.directive)
        self.event("mode", "supervisor started: mode idle, disarmed"
                   + (f"; last mission {self.saved.mission.name!r} can be resumed"
                      if self.saved and not self.saved.complete else ""))
        if self.boot.mission is not None and self.boot.autostart and self.restarted:
            self.event("mission", f"mission {self.boot.mission.name!r} not started: the "
                       "last mission was left unfinished, so this is a restart and "
                       "mission.autostart does not apply; arm, then resume or start it")
        if self.boot.mission is not None and not self.boot.autostart:
            self.event("mission", f"mission {self.boot.mission.name!r} loaded; not started "
                       "(mission.autostart = false): arm, then send mode lines or follow to "
                       "start it")
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
            for src, n in self.ack_events.overflow(now):
                self.event("ack", f"{n} more acknowledgements to {src} in the last second "
                           "not shown (each was answered)")
            if now >= next_directive:
                d = self.directive  # the same directive, still meant
                self.directive = Directive(now, d.seq, d.mode, d.mission, d.start_leg,
                                           d.point, d.reason, d.since, d.armed)
                self.bus.publish(self.directive)
                next_directive = now + sup.directive_period_s
            if now >= next_status or self.status_due:
                self.status_due = False
                self.status_msg = self.snapshot(now)
                self.bus.publish(self.status_msg)
                next_status = now + sup.status_period_s
