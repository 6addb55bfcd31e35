"""Guidance and control task: at the control rate, NavState → thruster commands.

Each tick: take the latest NavState (extrapolated to now), update the line
guidance, compute the demands, allocate them to the thrusters through f⁻¹,
and publish ThrusterCommand, ControlStatus and GuidanceStatus.

Safety: a demand or command that is not finite becomes zero thrust and a
Fault; an invalid navigation state (no valid fix or heading) for longer than
``failsafe.nav_invalid_s`` commands zero thrust with the reason, and control
resumes when it is valid again.  On GPS loss (``NavState.gps_age_s`` beyond
``failsafe.gps_lost_after_s``) the ``failsafe.gps_lost`` policy holds thrust at
zero or continues on dead reckoning for ``failsafe.gps_lost_continue_s``.
"""

from __future__ import annotations

import asyncio
import logging
import math
from typing import TYPE_CHECKING

from zarco_core.auv_messages import AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.messages import (
    ControlStatus,
    Fault,
    GuidanceStatus,
    NavState,
    ThrusterCommand,
    ThrusterStatus,
)
from zarco_core.thruster_map import ThrusterMap
from zarco_runtime.control.allocation import ZERO, Allocation, allocate
from zarco_runtime.control.line_tracking import Demand, LineController
from zarco_runtime.control.settings import xtrack_rate_tau_s
from zarco_runtime.guidance.follow import FollowGuidance
from zarco_runtime.guidance.lines import LineGuidance
from zarco_runtime.guidance.mission import Leg

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.control")
#: histogram of the control period jitter |period − dt|: JITTER_BINS bins of
#: JITTER_BIN_S, the last one for everything beyond (``zarco run --status``, HIL)
JITTER_BIN_S = 5e-5
JITTER_BINS = 400


class ControlTask:
    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock, legs: list[Leg],
                 mode: str = "lines") -> None:
        self.cfg = cfg
        self.bus = bus
        self.clock = clock
        self.dt = 1.0 / cfg.control.rate_hz
        th = cfg.thrusters
        self.port = ThrusterMap.from_table(th.port.u, th.port.f_n)
        self.stbd = ThrusterMap.from_table(th.starboard.u, th.starboard.f_n)
        self.nav = bus.latest(NavState)
        self.period_jitter_hist = [0] * (JITTER_BINS + 1)
        self.status = bus.latest(ThrusterStatus)
        self.guidance = LineGuidance(
            legs, cfg.guidance.switching, math.radians(cfg.guidance.turn_rate_dps)
        ) if legs else None
        self.ctl = LineController(cfg.vessel, cfg.control, cfg.vessel.thruster_lag_s, self.dt,
                                  xtrack_rate_tau_s(cfg.control, cfg.navigation.estimator))
        self.mode = mode
        self.follow = FollowGuidance(cfg.follow) if mode == "follow" else None
        self.track = bus.latest(AuvTrack)
        self._psi_hold: float | None = None
        self.complete = asyncio.Event()
        self.invalid_since: float | None = None
        self.fault = ""
        self.ticks = 0
        self.saturated_ticks = 0
        self.faults = 0

    def _raise_fault(self, t: float, reason: str) -> None:
        if reason != self.fault:
            log.warning("control: %s", reason)
            self.bus.publish(Fault(t, "control", reason))
        self.fault = reason
        self.faults += 1

    def tick(self, t: float) -> Allocation:
        """One control step at time ``t``; returns the allocation commanded."""
        bus = self.bus
        nav = self.nav.value
        self.ticks += 1
        # the thruster controller answered once and has stopped: it may not be
        # obeying (or its port is gone); command zero until it answers again
        silent = self.cfg.failsafe.thruster_silent_s
        st = self.status.value
        if silent > 0.0 and st is not None and t - st.t > silent:
            self._raise_fault(t, f"failsafe: no status from the thruster controller for "
                                 f"{silent:g} s; zero thrust")
            return ZERO
        if nav is None or (self.guidance is None and self.follow is None):
            return ZERO
        # extrapolate the estimate to now
        age = t - nav.t
        x = nav.x_m + nav.vn_mps * age
        y = nav.y_m + nav.ve_mps * age
        psi = nav.psi_rad + nav.r_rps * age
        valid = nav.pos_valid and nav.heading_valid
        if not valid:
            if self.invalid_since is None:
                self.invalid_since = t
            if t - self.invalid_since >= self.cfg.failsafe.nav_invalid_s:
                why = "no valid position" if not nav.pos_valid else "no valid heading"
                self._raise_fault(t, f"failsafe: {why}; zero thrust")
                return ZERO
        else:
            self.invalid_since = None
        gps_age = nav.gps_age_s + age
        fs = self.cfg.failsafe
        if fs.gps_lost_after_s < gps_age < math.inf:  # before the first fix: pos_valid
            if fs.gps_lost == "zero":
                self._raise_fault(t, "failsafe: GPS lost (gps_lost = zero); zero thrust")
                return ZERO
            if gps_age > fs.gps_lost_continue_s:
                self._raise_fault(t, f"failsafe: GPS lost for more than "
                                     f"{fs.gps_lost_continue_s:g} s; zero thrust")
                return ZERO
        nav_now = NavState(t, x, y, nav.vn_mps, nav.ve_mps, psi, nav.r_rps, nav.u_mps,
                           nav.v_mps, nav.lat_deg, nav.lon_deg, nav.fix, nav.pos_valid,
                           nav.heading_valid, nav.cov, gps_age)
        if self.follow is not None:
            return self._tick_follow(t, nav_now)
        ls = self.guidance.update(x, y)
        bus.publish(GuidanceStatus(t, "lines", ls.leg.index, len(self.guidance.legs),
                                   ls.along_m, ls.xtrack_m, ls.leg.course_rad,
                                   ls.leg.speed_mps, ls.complete))
        if ls.complete:
            self.complete.set()
            return ZERO
        dem = self.ctl.step(nav_now, ls.leg, ls.xtrack_m)
        return self._apply(t, nav_now, dem)

    def _tick_follow(self, t: float, nav: NavState) -> Allocation:
        assert self.follow is not None
        fcfg = self.cfg.follow
        fs = self.follow.update(self.track.value, t, nav.x_m, nav.y_m)
        if fs.mode != "follow" and fs.reason and fs.reason != self.fault:
            log.info("follow: %s: %s", fs.mode, fs.reason)
        self.bus.publish(GuidanceStatus(t, f"follow:{fs.mode}", fs.leg.index if fs.leg else -1,
                                        0, fs.along_error_m, fs.d_m,
                                        fs.leg.course_rad if fs.leg else nav.psi_rad,
                                        fs.speed_ref_mps))
        if fs.leg is None:
            if self._psi_hold is None:
                self._psi_hold = nav.psi_rad
            dem = self.ctl.hold(nav, self._psi_hold)
        else:
            self._psi_hold = None
            along = fs.along_error_m if fs.mode == "follow" else None
            dem = self.ctl.step(nav, fs.leg, fs.leg.project(nav.x_m, nav.y_m)[1], along,
                                fcfg.k_s, fcfg.k_i, fcfg.along_clamp_m)
        return self._apply(t, nav, dem)

    def _apply(self, t: float, nav_now: NavState, dem: Demand) -> Allocation:
        bus = self.bus
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
        bus.publish(ControlStatus(t, dem.psi_ref_rad, alloc.x_n, alloc.n_nm, alloc.f1_n,
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
                log.exception("control tick failed")
                self._raise_fault(t, f"control error: {exc!r}; zero thrust")
                alloc = ZERO
            reason = self.fault
            self.bus.publish(ThrusterCommand(t, alloc.u1, alloc.u2, reason))
