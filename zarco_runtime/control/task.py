"""Guidance and control task: at the control rate, the supervisor's directive and
the NavState → thruster commands.

Each tick: take the latest :class:`~zarco_runtime.guidance.directive.Directive`
(the mode, with its mission or point), the latest NavState (extrapolated to
now), run the mode's guidance, compute the demands, allocate them to the
thrusters through f⁻¹ and publish ThrusterCommand (every tick, zero when
there is nothing to do: the thruster controller expects a steady stream),
ControlStatus and GuidanceStatus.

The mode is the supervisor's; this task only executes it.  It still refuses,
on its own, to drive on what it cannot trust: a directive older than
``supervisor.directive_timeout_s`` counts as ``idle``, a directive that is
not armed gives zero thrust whatever its mode, so do a lost position, a lost
heading and a silent thruster controller (the drive interlock,
:mod:`.interlock`, judged at every tick with the failsafe table's limits and
held until healthy for ``failsafe.clear_after_s``) and a driving failsafe the
supervisor holds (the directive's ``driving_failsafes``, from the failsafe's
entry until it clears, whatever its action), and a demand or command that is
not finite becomes zero thrust and a Fault.

The line-tracking gains come from LQR designs cached per configuration
(:mod:`.lqr`): a mode change takes its design from the cache; a configuration
not designed yet keeps the previous design while the new one is solved off the
tick (on a worker thread; at once on the simulator's virtual clock, where it
costs no time).
"""

from __future__ import annotations

import asyncio
import logging
import math
from typing import TYPE_CHECKING

from zarco_core.angles import wrap
from zarco_core.auv_messages import AuvPlan, AuvTrack
from zarco_core.bus import Bus, Listen
from zarco_core.clock import Clock, VirtualTimeEventLoop
from zarco_core.messages import (
    ControlStatus,
    Fault,
    GuidanceStatus,
    Heading,
    Mode,
    NavState,
    ParamChange,
    ThrusterCommand,
    ThrusterStatus,
)
from zarco_core.thruster_map import ThrusterMap
from zarco_runtime.control.allocation import ZERO, Allocation, allocate
from zarco_runtime.control.interlock import DriveInterlock
from zarco_runtime.control.line_tracking import Demand, LineController
from zarco_runtime.control.lqr import GainSchedule, cached_schedule, design_schedule
from zarco_runtime.control.settings import xtrack_rate_tau_s
from zarco_runtime.guidance.directive import Directive, ManualThrust
from zarco_runtime.guidance.follow import FollowGuidance
from zarco_runtime.guidance.hold import HoldGuidance
from zarco_runtime.guidance.lines import LineGuidance

if TYPE_CHECKING:
    from zarco_core.vessel import VesselModel
    from zarco_runtime.control.settings import Control
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.control")
#: histogram of the control period jitter |period − dt|: JITTER_BINS bins of
#: JITTER_BIN_S, the last one for everything beyond (status, HIL)
JITTER_BIN_S = 5e-5
JITTER_BINS = 400
#: largest manual command magnitude (normalised thruster scale)
U_MAX = 100.0


def _manual_allocation(u1: float, u2: float) -> Allocation:
    """The operator's commands as an allocation (clamped, NaN → 0)."""
    a = [max(-U_MAX, min(U_MAX, u)) if math.isfinite(u) else 0.0 for u in (u1, u2)]
    return Allocation(0.0, 0.0, 0.0, 0.0, a[0], a[1], 0, 0)


class ControlTask:
    """Executes the supervisor's directive at ``control.rate_hz``."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock,
                 listen: Listen | None = None) -> None:
        self.cfg = cfg
        self.bus = bus
        self.clock = clock
        self.dt = 1.0 / cfg.control.rate_hz
        self.interlock = DriveInterlock(cfg.failsafe, cfg.devices.thrusters.enabled)
        on = listen or bus.listen
        on(Heading, self.interlock.on_heading)
        on(ThrusterStatus, self.interlock.on_status)
        on(ParamChange, self._on_param)
        #: the gain schedule in use, and a design under way off the tick (its key)
        self.schedule = design_schedule(*self._schedule_args())  # at start: not in a tick
        self._designing: tuple[float, ...] | None = None
        th = cfg.thrusters
        self.port = ThrusterMap.from_table(th.port.u, th.port.f_n)
        self.stbd = ThrusterMap.from_table(th.starboard.u, th.starboard.f_n)
        self.nav = bus.latest(NavState)
        self.track = bus.latest(AuvTrack)
        self.auv_plan = bus.latest(AuvPlan)
        self.directive = bus.latest(Directive)
        self.manual = bus.latest(ManualThrust)
        self.period_jitter_hist = [0] * (JITTER_BINS + 1)
        self.ctl = self._new_controller()
        self.seq = -1
        self.entered_t = -math.inf
        self.mode = Mode.IDLE
        self.lines: LineGuidance | None = None
        self.follow: FollowGuidance | None = None
        self.hold: HoldGuidance | None = None
        self._psi_hold: float | None = None
        self._still_leg = 0
        self._still_int = 0.0
        #: integral (m s) of the station distance above an AUV waiting on its plan
        self._above_int = 0.0
        self.reason = "idle"
        self.fault = ""
        self.ticks = 0
        self.saturated_ticks = 0
        self.faults = 0

    def _schedule_args(self) -> tuple[VesselModel, Control, float, float]:
        cfg = self.cfg
        return cfg.vessel, cfg.control, cfg.vessel.thruster_lag_s, self.dt

    def _new_controller(self) -> LineController:
        cfg = self.cfg
        sched = cached_schedule(*self._schedule_args())
        if sched is None:
            self._design_later()  # the configuration changed: keep the last design meanwhile
        else:
            self.schedule = sched
        return LineController(cfg.vessel, cfg.control, cfg.vessel.thruster_lag_s, self.dt,
                              xtrack_rate_tau_s(cfg.control, cfg.navigation.estimator),
                              schedule=self.schedule)

    def _on_param(self, m: ParamChange) -> None:
        """A parameter changed: a new LQR weight is designed now, off the tick, so
        that the next mode change finds it ready."""
        if m.name.startswith("control.lqr_") and \
                cached_schedule(*self._schedule_args()) is None:
            self._design_later()

    def _design_later(self) -> None:
        """Design the gain schedule of the current configuration off the tick."""
        args = self._schedule_args()
        key = GainSchedule.key(*args)
        if self._designing == key:
            return
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            loop = None
        if loop is None or isinstance(loop, VirtualTimeEventLoop):
            design_schedule(*args)  # virtual time: no tick waits for it
            return
        self._designing = key
        fut = loop.run_in_executor(None, design_schedule, *args)

        def done(f: asyncio.Future[GainSchedule]) -> None:
            if self._designing == key:
                self._designing = None
            if not f.cancelled() and f.exception() is not None:
                self._raise_fault(self.clock.now(), f"LQR design failed: {f.exception()}")

        fut.add_done_callback(done)

    # ------------------------------------------------------------- directive

    def _enter(self, d: Directive) -> None:
        """A new directive: build the guidance of its mode, reset the controllers."""
        self.seq = d.seq
        self.entered_t = d.t  # when this directive began (republishing keeps its seq)
        self.mode = d.mode
        self.lines = self.follow = self.hold = None
        self._psi_hold = None
        cfg = self.cfg
        self.ctl = self._new_controller()
        if d.mode is Mode.LINES and d.mission is not None and d.mission.legs:
            g = cfg.guidance
            self.lines = LineGuidance(list(d.mission.legs), g.switching,
                                      math.radians(g.turn_rate_dps))
            self.lines.index = max(0, min(d.start_leg, len(d.mission.legs) - 1))
        elif d.mode is Mode.FOLLOW:
            self.follow = FollowGuidance(cfg.follow)
        elif d.mode in (Mode.HOLD, Mode.RETURN) and d.point is not None:
            self.hold = HoldGuidance(d.point, cfg.hold)

    def _raise_fault(self, t: float, reason: str) -> None:
        if reason != self.fault:
            log.warning("control: %s", reason)
            self.bus.publish(Fault(t, "control", reason))
        self.fault = reason
        self.faults += 1

    # ------------------------------------------------------------------ tick

    def tick(self, t: float) -> Allocation:
        """One control step at time ``t``; returns the allocation commanded."""
        self.ticks += 1
        d = self.directive.value
        if d is None or t - d.t > self.cfg.supervisor.directive_timeout_s:
            if self.mode is not Mode.IDLE:
                self._raise_fault(t, "no directive from the supervisor; zero thrust")
            self.mode = Mode.IDLE
            self.seq = -1
            self.reason = "no directive from the supervisor"
            return ZERO
        if d.seq != self.seq:
            self._enter(d)
        mode = d.mode
        if mode is Mode.IDLE:
            self.reason = "idle"
            return ZERO
        if not d.armed:
            self.reason = "disarmed"
            return ZERO
        nav = self.nav.value
        hazard = self.interlock.hazard(t, nav)
        if hazard:
            self.reason = f"not driving: {hazard}"
            return ZERO
        if d.driving_failsafes:
            self.reason = (f"not driving: failsafe {', '.join(d.driving_failsafes)} "
                           "until it clears")
            return ZERO
        if mode is Mode.MANUAL:
            m = self.manual.value
            if m is None or t > m.until or m.t < self.entered_t:
                self.reason = "manual: no operator command within the lease"
                return ZERO
            self.reason = "manual"
            return _manual_allocation(m.u1, m.u2)
        if nav is None:
            self.reason = "no navigation estimate yet"
            return ZERO
        age = t - nav.t
        x = nav.x_m + nav.vn_mps * age
        y = nav.y_m + nav.ve_mps * age
        psi = wrap(nav.psi_rad + nav.r_rps * age)
        if not (nav.pos_valid and nav.heading_valid):
            self.reason = ("no valid position" if not nav.pos_valid else "no valid heading")
            return ZERO
        nav_now = NavState(t, x, y, nav.vn_mps, nav.ve_mps, psi, nav.r_rps, nav.u_mps,
                           nav.v_mps, nav.lat_deg, nav.lon_deg, nav.fix, nav.pos_valid,
                           nav.heading_valid, nav.cov, nav.gps_age_s + age,
                           nav.current_n_mps, nav.current_e_mps)
        self.reason = mode.value
        if self.lines is not None:
            return self._tick_lines(t, nav_now)
        if self.follow is not None:
            return self._tick_follow(t, nav_now)
        if self.hold is not None:
            return self._tick_hold(t, nav_now, mode)
        self.reason = f"{mode.value}: nothing to execute"
        return ZERO

    def _tick_lines(self, t: float, nav: NavState) -> Allocation:
        g = self.lines
        assert g is not None
        ls = g.update(nav.x_m, nav.y_m)
        self.bus.publish(GuidanceStatus(t, "lines", ls.leg.index, len(g.legs), ls.along_m,
                                        ls.xtrack_m, ls.leg.course_rad, ls.leg.speed_mps,
                                        ls.complete))
        if ls.complete:
            self.reason = "mission complete"
            return ZERO
        return self._apply(t, nav, self.ctl.step(nav, ls.leg, ls.xtrack_m))

    def _tick_follow(self, t: float, nav: NavState) -> Allocation:
        f = self.follow
        assert f is not None
        fcfg = self.cfg.follow
        f.set_plan(self.auv_plan.value)
        fs = f.update(self.track.value, t, nav.x_m, nav.y_m)
        self.bus.publish(GuidanceStatus(t, f"follow:{fs.mode}", fs.leg.index if fs.leg else -1,
                                        0, fs.along_error_m, fs.d_m,
                                        fs.leg.course_rad if fs.leg else nav.psi_rad,
                                        fs.speed_ref_mps))
        if fs.leg is None:
            if math.isfinite(fs.heading_rad):
                self._psi_hold = fs.heading_rad
            elif self._psi_hold is None:
                self._psi_hold = nav.psi_rad
            if fs.station is not None:
                # above an AUV waiting on its plan: hold the station along the
                # heading, forward or astern (while the boat pivots to the
                # heading, only what lies along it)
                ahead = ((fs.station[0] - nav.x_m) * math.cos(nav.psi_rad)
                         + (fs.station[1] - nav.y_m) * math.sin(nav.psi_rad))
                dem, self._above_int = self._hold_along(nav, self._psi_hold, ahead,
                                                        self._above_int)
            else:
                dem = self.ctl.hold(nav, self._psi_hold)
                self._above_int = 0.0
        else:
            self._psi_hold = None
            self._above_int = 0.0
            along = fs.along_error_m if fs.mode == "follow" else None
            dem = self.ctl.step(nav, fs.leg, fs.leg.project(nav.x_m, nav.y_m)[1], along,
                                fs.k_s, fs.k_i, fcfg.along_clamp_m)
        return self._apply(t, nav, dem)

    def _tick_hold(self, t: float, nav: NavState, mode: Mode) -> Allocation:
        h = self.hold
        assert h is not None
        hs = h.update(nav, nav.x_m, nav.y_m)
        d = hs.leg.project(nav.x_m, nav.y_m)[1]
        self.bus.publish(GuidanceStatus(t, f"{mode.value}:{hs.phase}", -1, 0, hs.along_m, d,
                                        hs.leg.course_rad, hs.leg.speed_mps,
                                        hs.phase == "station"))
        hc = self.cfg.hold
        if hs.phase == "station" and hs.still:
            # nothing to steer against: hold the line's heading, PI on the along-line
            # distance to the point (forward or astern)
            if hs.leg.index != self._still_leg:
                self._still_leg, self._still_int = hs.leg.index, 0.0
            dem, self._still_int = self._hold_along(nav, hs.leg.course_rad, hs.along_m,
                                                    self._still_int)
        elif hs.phase == "station":
            dem = self.ctl.step(nav, hs.leg, d, hs.along_m, hc.k_s, hc.k_i, hc.along_clamp_m)
        else:
            dem = self.ctl.step(nav, hs.leg, d)
        return self._apply(t, nav, dem)

    def _hold_along(self, nav: NavState, psi: float, ahead_m: float, integral: float
                    ) -> tuple[Demand, float]:
        """Station keeping along the heading: hold heading ``psi`` (rad) and push
        the boat towards a point ``ahead_m`` (m, < 0 astern) along it with the
        ``hold`` mode's surge law (``k_s``, ``k_i`` on ``integral``, m s, the
        distance clamped to ``along_clamp_m``).  Returns the demand and the
        integral carried on."""
        hc = self.cfg.hold
        lead = max(-hc.along_clamp_m, min(hc.along_clamp_m, ahead_m))
        integral += lead * self.dt
        hd = self.ctl.hold(nav, psi)
        return Demand(hd.x_n + hc.k_s * lead + hc.k_i * integral, hd.n_nm, hd.psi_ref_rad,
                      hd.psi0_rad), integral

    def _apply(self, t: float, nav_now: NavState, dem: Demand) -> Allocation:
        alloc = allocate(dem.x_n, dem.n_nm, self.cfg.vessel.b_m, self.port, self.stbd)
        if alloc.fault or not (math.isfinite(alloc.u1) and math.isfinite(alloc.u2)):
            self._raise_fault(t, f"non-finite control output ({alloc.fault or 'command'}); "
                              "zero thrust")
            return ZERO
        if self.fault:
            log.info("control: fault cleared (%s)", self.fault)
            self.fault = ""
        self.ctl.commit(nav_now, alloc)
        if alloc.saturated:
            self.saturated_ticks += 1
        self.bus.publish(ControlStatus(t, dem.psi_ref_rad, alloc.x_n, alloc.n_nm, alloc.f1_n,
                                       alloc.f2_n, alloc.u1, alloc.u2, alloc.saturated))
        return alloc

    async def run(self) -> None:
        clock = self.clock
        t0 = clock.now()
        k = 0
        last: float | None = None
        hist = self.period_jitter_hist
        while True:
            k += 1
            await clock.sleep_until(t0 + k * self.dt)
            t = clock.now()
            if last is not None:
                hist[min(JITTER_BINS, int(abs(t - last - self.dt) / JITTER_BIN_S))] += 1
            last = t
            try:
                alloc = self.tick(t)
            except Exception as exc:  # never let a control bug leave thrust on
                self.bus.publish(ThrusterCommand(t, 0.0, 0.0, f"control error: {exc!r}"))
                raise
            # a held (zero) command says why: idle, disarmed, a failsafe, a fault
            reason = self.fault or (self.reason if alloc is ZERO else "")
            cmd = ThrusterCommand(t, alloc.u1, alloc.u2, reason)
            self.interlock.on_command(cmd)
            self.bus.publish(cmd)
