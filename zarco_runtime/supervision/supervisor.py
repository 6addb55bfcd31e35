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
``failsafe.clear_after_s``.  While a driving failsafe (``position_lost``,
``heading_lost``, ``thruster_silent``) is active, from its entry until it
clears, the directive carries it (``driving_failsafes``) and the control task
sends zero thrust whatever the mode and the action (``hold``, ``return``,
``continue``): the action sets the mode the boat is in when it clears.  An
``idle`` action disarms, so the boat stays still until an operator acts;
``failsafe.after_clear`` applies only to a boat a ``hold`` or ``return``
action kept under way; after ``continue`` the mode goes on.

**Parameters** are ``param`` commands (:mod:`.params`): validated, refused
under way where unsafe, applied to the live configuration, published as
:class:`~zarco_core.messages.ParamChange` and recorded.

**No input ends or restarts it**: any exception while handling a command
becomes a refusal and a counted fault.  Each source is rate limited
(:mod:`.rate_limit`; ``stop`` and ``disarm`` never are).  The state file is
written by a task of its own (:mod:`.state_file`), never in a listener.

After a restart the last mission is known (``supervisor.state_file``) but is
only continued by a ``resume`` command.

The :class:`Supervisor` owns the state, its listeners, the mode change
(:meth:`Supervisor.set_mode`) and the loop; what it does is in modules of its
own, functions of the supervisor: :mod:`.command_handlers` (every command,
answered once), :mod:`.arming` (arming, and whether a mode may be entered),
:mod:`.failsafe_actions` (the table evaluated, actions, after clearing,
autostart) and :mod:`.status` (the status snapshot).
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
from zarco_core.component import ComponentContext
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
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
    ThrusterCommand,
    ThrusterStatus,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.guidance.mission import Mission
from zarco_runtime.supervision import arming, command_handlers, failsafe_actions, status
from zarco_runtime.supervision.failsafes import FailsafeMonitor
from zarco_runtime.supervision.geofence import Fence
from zarco_runtime.supervision.rate_limit import EventBudget, TokenBuckets
from zarco_runtime.supervision.state_file import (
    SavedMission,
    StateFile,
    mission_from_json,
    mission_to_json,
)
from zarco_runtime.supervision.status import NOT_REFUSALS

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
        self.home_ll: tuple[tuple[float, float], tuple[float, float]] | None = None
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
        self.shown: tuple[Mission | None, tuple[tuple[float, float], ...]] = (None, ())
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
                    self.save_state()
            if g.complete:
                self.mission_complete()
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
            self.set_mode(Mode.HOLD, "arrived home; holding", point=self.home,
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

    def position(self) -> tuple[float, float] | None:
        n = self.nav.value
        if n is None or not n.pos_valid:
            return None
        age = self.now() - n.t
        return n.x_m + n.vn_mps * age, n.y_m + n.ve_mps * age

    def driving_failsafes(self) -> tuple[str, ...]:
        """The driving failsafes active now (zero thrust until they clear)."""
        return tuple(sorted(self.failsafes.driving()))

    def publish_directive(self) -> None:
        """The current directive again, now, with the current arming and driving
        failsafes (the same ``seq``: what to do has not changed, only whether
        thrust is allowed)."""
        d = self.directive
        self.directive = Directive(self.now(), d.seq, d.mode, d.mission, d.start_leg,
                                   d.point, d.reason, d.since, self.armed,
                                   self.driving_failsafes())
        self.bus.publish(self.directive)
        self.status_due = True

    def set_mode(self, mode: Mode, reason: str, *, mission: Mission | None = None,
                 start_leg: int = 0, point: tuple[float, float] | None = None,
                 by_failsafe: bool = False, keep_operator: bool = False) -> None:
        old = self.mode
        if old in (Mode.LINES, Mode.FOLLOW) and mode not in (Mode.LINES, Mode.FOLLOW) \
                and self.mission is not None:
            self.save_state()
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
                                   armed=self.armed,
                                   driving_failsafes=self.driving_failsafes())
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

    def mission_complete(self) -> None:
        m = self.mission
        if self.saved is not None and m is self.saved.mission:
            self.saved.complete = True
            self.save_state()
        end = (m.legs[-1].n1, m.legs[-1].e1) if m is not None and m.legs else self.position()
        self.event("mission", f"mission {m.name if m else ''} complete")
        self.set_mode(Mode.HOLD, "mission complete; holding at its last waypoint", point=end,
                      keep_operator=True)

    def save_state(self) -> None:
        """Hand the mission to the state file's writer task (nothing written here)."""
        if self.saved is not None:
            self.state.save(self.saved, self.clock.utc())

    # ------------------------------------------------- commands, failsafes, status

    def on_command(self, cmd: Command) -> None:
        """Handle one command; exactly one CommandAck (:mod:`.command_handlers`)."""
        command_handlers.on_command(self, cmd)

    def _on_ack(self, ack: CommandAck) -> None:
        command_handlers.on_ack(self, ack)

    def arm_refusal(self) -> str:
        """Why the boat cannot be armed now ("" when it can; :mod:`.arming`)."""
        return arming.arm_refusal(self)

    def evaluate(self, now: float) -> None:
        """One evaluation of the failsafe table (:mod:`.failsafe_actions`)."""
        failsafe_actions.evaluate(self, now)

    def snapshot(self, now: float) -> VesselStatus:
        """The status snapshot at ``now`` (:mod:`.status`)."""
        return status.snapshot(self, now)

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
                                           d.point, d.reason, d.since, d.armed,
                                           d.driving_failsafes)
                self.bus.publish(self.directive)
                next_directive = now + sup.directive_period_s
            if now >= next_status or self.status_due:
                self.status_due = False
                self.status_msg = self.snapshot(now)
                self.bus.publish(self.status_msg)
                next_status = now + sup.status_period_s
