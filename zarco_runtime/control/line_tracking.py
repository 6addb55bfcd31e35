"""Line-tracking and speed control (paper III.B), as pure objects.

Steering, in the paper's arctan anti-windup form:

    ψ_ref = ψ0 − arctan(σ),   σ = (K_d d + K_l ∫d dt + K_v ḋ + K_w ŵ) / K_ψ
    N_cmd = K_ψ (ψ_ref − ψ) − K_r r − K_n N̂t

(ŵ, the estimated sway force of gusts, only with ``control.gust_feedforward``.)

* K come from the LQR design scheduled on the leg speed (``lqr.py``).  With
  σ small this is exactly the LQR state feedback, the unmeasured sway v
  replaced by the measured cross-track rate ḋ = U e + v (GPS velocity: this
  is how the gust-driven sway is seen), and N̂t the moment the thrusters are
  producing (our own command through the thruster lag).
* ψ0 = ψ_traj − arctan(c_⊥ / (U_ref − c_∥)) is the crab angle that cancels
  the cross-line component c_⊥ of the water current while the speed loop
  holds U_ref over ground (the water then passes at U_ref − c_∥ along the
  line and c_⊥ across it); the current comes from
  :class:`~zarco_runtime.control.water_observer.WaterObserver`.  The integral
  then only has to absorb what is left (compass bias, misalignment), so it
  does not re-wind at every corner.
* The gains are scheduled on the speed through the water along the line
  (U_ref − c_∥, capped by the observed water speed): that, not the speed over
  ground, is what turns a heading error into cross-track motion.  At 0.5 m/s
  with a 0.35 m/s current behind the boat it is 0.15 m/s.
* The integral of d grows only while |d| is inside a window and the yaw
  moment is not saturated in the direction it would push (anti-windup).

Speed: X_cmd = F_f(u_w,ref) + k_p (U_ref − U) + k_i ∫(U_ref − U) dt with the
feedforward F_f from the nominal surge damping, U the ground speed along the
line, and the integral frozen when the surge demand is cut by allocation.

Thrusters that do not match (port and starboard giving (1 ± Δ) times the
calibrated table) turn every yaw command into a surge force X = Δ N / b.  At
low speed through the water that changes the speed, and when the boat crabs
across a current it moves it across the line: each correction pushes the wrong
way first.  The observer estimates Δ from the surge each yaw command makes,
and the demands are passed through its inverse
(:meth:`~zarco_runtime.control.water_observer.WaterObserver.command_for`),
so that what the thrusters really give is what the controller asked for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.angles import wrap
from zarco_core.messages import NavState
from zarco_core.vessel import VesselModel
from zarco_runtime.control.allocation import Allocation
from zarco_runtime.control.lqr import GainSchedule, design_schedule
from zarco_runtime.control.settings import Control, xtrack_rate_tau_s
from zarco_runtime.control.water_observer import WaterObserver
from zarco_runtime.guidance.mission import Leg

#: heading errors beyond this (rad) commit to the direction of the turn
TURN_COMMIT_RAD = math.radians(150.0)

#: the observed water speed may exceed the scheduling speed by this much before it
#: caps it (m/s): the observer's speed is noisy, the cap is for a boat that cannot
#: reach its speed (full thrust against a current)
_SCHED_MARGIN_MPS = 0.1


@dataclass(frozen=True, slots=True)
class Demand:
    """One tick's demands: surge force (N), yaw moment (N m), heading reference."""

    x_n: float
    n_nm: float
    psi_ref_rad: float
    psi0_rad: float


class LineController:
    """Steering + speed control along the active leg."""

    def __init__(self, vm: VesselModel, ctl: Control, lag_s: float, dt: float,
                 rate_tau_s: float | None = None, schedule: GainSchedule | None = None) -> None:
        """``rate_tau_s``: low-pass of the GPS part of the cross-track rate (s);
        None: :func:`~zarco_runtime.settings.xtrack_rate_tau_s` for the first estimate.
        ``schedule``: the LQR gain schedule to use (None: this configuration's,
        from the cache or designed now)."""
        self.vm = vm
        self.ctl = ctl
        self.tau_r = rate_tau_s if rate_tau_s is not None else xtrack_rate_tau_s(ctl)
        self.dt = dt
        self.lag_s = lag_s
        self.schedule = schedule if schedule is not None else \
            design_schedule(vm, ctl, lag_s, dt)
        self.water = WaterObserver(vm, lag_s, estimate_mismatch=ctl.mismatch_compensation)
        self.l_int = 0.0
        self.u_int = 0.0
        self.nt = 0.0
        self.leg_index = -1
        self._last_sigma_parts = (0.0, 0.0, 0.0)
        self._k: tuple[float, ...] = self.schedule.at(1.0)
        self._d = 0.0
        self.rho = 0.0
        self.d_hat = 0.0
        self.s_int = 0.0
        self._lead = 0.0
        self._fresh_leg = True
        self._turn = 0.0

    def heading_error(self, psi_ref: float, psi: float, course: float = math.nan) -> float:
        """ψ_ref − ψ wrapped to (−π, π], but once the error is beyond
        ``TURN_COMMIT_RAD`` the turn keeps its direction until it is under it:
        at an error near 180° the wrapped error flips sign at every tick and the
        boat would sit on the wrong heading, chattering, instead of turning.
        The direction committed to is the shorter way to ``course`` (rad, the
        leg's course the reference is an intercept about) when it is given:
        from a standstill, an intercept of tens of degrees on a cross-track
        drift can put the reference just past 180° the other way, and the boat
        pivoted the long way round."""
        e = wrap(psi_ref - psi)
        if abs(e) > TURN_COMMIT_RAD:
            if self._turn == 0.0:
                toward = wrap(course - psi) if math.isfinite(course) else e
                self._turn = 1.0 if toward >= 0.0 else -1.0
            if e * self._turn < 0.0:
                e += self._turn * math.tau
        else:
            self._turn = 0.0
        return e

    def feedforward_n(self, u_w: float) -> float:
        """F_f(u): thrust (N) that balances surge damping at water speed u_w."""
        return -(self.vm.x_u * u_w + self.vm.x_uu * abs(u_w) * u_w)

    def reset_leg(self, leg: Leg) -> None:
        self.leg_index = leg.index
        self.l_int = 0.0
        self._fresh_leg = True

    def step(self, nav: NavState, leg: Leg, d: float, along_err: float | None = None,
             k_s: float = 0.0, k_i: float = 0.0, along_clamp: float = 10.0) -> Demand:
        """Demands for this tick from the navigation state and line geometry.

        ``along_err`` (following the AUV): s_AUV − s, how far the target is ahead
        along the line (m); it adds k_s·lead + k_i·∫lead to the surge force.
        """
        if leg.index != self.leg_index:
            self.reset_leg(leg)
        ctl = self.ctl
        u_ref = leg.speed_mps
        psi_t = leg.course_rad
        ct, st = math.cos(psi_t), math.sin(psi_t)
        # cross-track rate: the part the heading explains (u_w sin e, clean: compass +
        # gyro) plus the rest (sway, current, bias) seen from GPS velocity and
        # low-passed; cross-track error: GPS d, smoothed along that rate
        u_g = nav.vn_mps * ct + nav.ve_mps * st
        d_dot_gps = -nav.vn_mps * st + nav.ve_mps * ct
        u_w = max(0.0, self.water.u_w)
        d_dot_hdg = u_w * math.sin(wrap(nav.psi_rad - psi_t))
        tau_r, tau_d = self.tau_r, ctl.xtrack_tau_s
        if self._fresh_leg:
            self.rho = d_dot_gps - d_dot_hdg
            self.d_hat = d
            self._fresh_leg = False
        else:
            self.rho += min(1.0, self.dt / tau_r) * (d_dot_gps - d_dot_hdg - self.rho)
            self.d_hat += (d_dot_hdg + self.rho) * self.dt
            self.d_hat += min(1.0, self.dt / tau_d) * (d - self.d_hat)
        d_dot = d_dot_hdg + self.rho
        d = self.d_hat
        # current: cross-line component → crab angle; along-line → water speed
        cn, ce = (self.water.cn, self.water.ce) if ctl.current_feedforward else (0.0, 0.0)
        c_perp = -cn * st + ce * ct
        c_along = cn * ct + ce * st
        u_w_ref = max(0.05, u_ref - c_along)
        crab = math.atan2(c_perp, u_w_ref)
        psi0 = psi_t - crab
        # speed through the water along the line: what the speed loop aims at,
        # unless the boat is observed slower (thrust limit against a current)
        u_s = max(0.05, min(u_w_ref, u_w * math.cos(crab) + _SCHED_MARGIN_MPS))
        k_d, k_l, k_e, k_r, k_v, k_n, k_w = self.schedule.at(u_s)
        self._k = (k_d, k_l, k_e, k_r, k_v, k_n, k_w)
        w = self.water.sway_force if ctl.gust_feedforward else 0.0
        k_psi = max(1e-3, k_e - k_v * u_s * math.cos(crab))
        sigma = (k_d * d + k_l * self.l_int + k_v * d_dot + k_w * w) / k_psi
        lim = math.radians(ctl.max_intercept_deg)
        offset = max(-lim, min(lim, math.atan(sigma)))
        psi_ref = wrap(psi0 - offset)
        n_cmd = (k_psi * self.heading_error(psi_ref, nav.psi_rad, psi0) - k_r * nav.r_rps
                 - k_n * self.nt)
        x_cmd = (self.feedforward_n(u_w_ref) + ctl.speed_kp * (u_ref - u_g)
                 + ctl.speed_ki * self.u_int)
        self._lead = 0.0
        if along_err is not None and math.isfinite(along_err):
            self._lead = max(-along_clamp, min(along_clamp, along_err))
            x_cmd += k_s * self._lead + k_i * self.s_int
        self._d = d
        self._u_err = u_ref - u_g
        self._sigma_sat = abs(math.atan(sigma)) >= lim
        return self._demand(x_cmd, n_cmd, psi_ref, psi0)

    def _demand(self, x_n: float, n_nm: float, psi_ref: float, psi0: float) -> Demand:
        """The demand that makes the thrusters give ``x_n``, ``n_nm`` (their estimated
        mismatch undone)."""
        if self.ctl.mismatch_compensation:
            x_n, n_nm = self.water.command_for(x_n, n_nm)
        return Demand(x_n, n_nm, psi_ref, psi0)

    def hold(self, nav: NavState, psi_hold: float) -> Demand:
        """Slow down and keep heading ``psi_hold`` (track lost, or inside the hold
        radius): brake with the speed gain, heading-hold PD on yaw."""
        ctl = self.ctl
        u_g = nav.vn_mps * math.cos(nav.psi_rad) + nav.ve_mps * math.sin(nav.psi_rad)
        self._d = 0.0
        self._u_err = 0.0
        self._lead = 0.0
        self._sigma_sat = True  # no cross-track integration while holding
        x_cmd = -ctl.speed_kp * u_g
        n_cmd = (ctl.heading_kp * self.heading_error(psi_hold, nav.psi_rad)
                 - ctl.heading_kd * nav.r_rps)
        return self._demand(x_cmd, n_cmd, psi_hold, psi_hold)

    def commit(self, nav: NavState, alloc: Allocation) -> None:
        """Update integrators and internal states with what was actually commanded."""
        dt = self.dt
        # integral of cross-track error with anti-windup
        d = self._d
        push = -d  # integrating d makes N more negative for d > 0
        blocked = (alloc.sat_n > 0 and push > 0) or (alloc.sat_n < 0 and push < 0)
        if abs(d) < self.ctl.integral_window_m and not blocked and not self._sigma_sat:
            self.l_int += d * dt
        # speed integral, frozen when surge is cut in the direction it pushes
        ue = self._u_err
        if not ((alloc.sat_x > 0 and ue > 0) or (alloc.sat_x < 0 and ue < 0)):
            self.u_int += ue * dt
        le = self._lead
        if le and not ((alloc.sat_x > 0 and le > 0) or (alloc.sat_x < 0 and le < 0)):
            self.s_int += le * dt
        # moment actually produced, through the thruster lag
        n_real = self.water.actual(alloc.x_n, alloc.n_nm)[1]
        self.nt += (n_real - self.nt) * min(1.0, dt / self.lag_s)
        self.water.step(nav, alloc.x_n, alloc.n_nm, dt)
