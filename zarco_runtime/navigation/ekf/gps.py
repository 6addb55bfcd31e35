"""GPS position and velocity in the EKF: updates, initialisation, manoeuvres, fix changes.

Position: σ from GST when fresh, else from the fix type; the fix is the centre
of mass plus the GPS offset state b (plus the antenna's lever arm).  Velocity:
SOG/COG as N/E components (SOG alone from a VTG without course), the ground
velocity ``R(ψ)·(u, v) + c`` of the model.

* Fix-type changes: on a downgrade (e.g. RTK fixed → single) the GPS offset
  state b gets a fresh prior of the new fix's bias σ, so the 3 m jump goes into
  b: position, velocity and heading do not move, and the position σ grows
  honestly as the single-point fixes take over.  On an upgrade (single → RTK
  fixed) the better solution is right and the filter takes it at once (b
  fresh, near zero); the *published* position then glides onto it: NavState
  adds the jump back as an offset decaying with ``upgrade_glide_s`` (and adds
  its square to the position covariance), so the controller sees no step.
  (Modelling the glide inside the filter, as an offset state that decays, does
  not work: with centimetre fixes the filter sees at once that the offset does
  not decay as modelled and jumps anyway.)
* Manoeuvres without the thrust model: a GPS velocity beyond its gate but
  within ``max_accel_mps2`` of the last one is taken as a manoeuvre (the speed
  and position variances are opened by the innovation and it is fused), not as
  a fault; so is an RTK position beyond its gate when no GPS velocity comes
  (GGA-only receivers).
* Start from rest: with the thrust model and no thrust applied yet, a first GPS
  velocity slower than ``rest_max_speed_mps`` is taken as the boat drifting
  with the water (u = 0 ± ``rest_speed_sigma_mps``): it measures the current,
  which then tells the compass bias from the crab as the boat speeds up.
"""

from __future__ import annotations

import math

import numpy as np

from zarco_runtime.navigation.ekf.layout import (
    IBE,
    IBN,
    ICE,
    ICN,
    IPSI,
    IR,
    IU,
    IV,
    IX,
    IY,
    K_POS,
    K_SOG,
    K_VEL,
    NX,
    Counters,
    FilterState,
    Measurement,
)
from zarco_runtime.navigation.ekf.model import Prediction
from zarco_runtime.navigation.ekf.noise import SensorNoise
from zarco_runtime.navigation.ekf.updates import Gatekeeping, reset_block, update1, update2
from zarco_runtime.navigation.ekf_config import EkfSettings

#: 1σ of a heading initialised from the GPS course (no heading sensor), rad
COURSE_INIT_SIGMA_RAD = math.radians(10.0)
#: thrust (N, both thrusters) below which the boat counts as not driven (at rest in the water)
REST_THRUST_N = 0.5

_H_VEL_IDX = np.ravel_multi_index(np.array([
    (0, IU), (0, IV), (0, IPSI), (1, IU), (1, IV), (1, IPSI)]).T, (2, NX))


class GpsFusion(Gatekeeping):
    """Fuses GPS positions and velocities into a :class:`FilterState`."""

    def __init__(self, cfg: EkfSettings, noise: SensorNoise, counters: Counters,
                 prediction: Prediction) -> None:
        super().__init__(cfg, noise, counters)
        self.prediction = prediction
        #: a heading sensor has spoken (no heading from the course then)
        self.heading_sensor_seen = False
        self._lever = (cfg.lever_x_m, cfg.lever_y_m)
        self.has_lever = cfg.lever_x_m != 0.0 or cfg.lever_y_m != 0.0
        self._h_pos = np.zeros((2, NX))
        self._h_pos[0, IX] = self._h_pos[0, IBN] = 1.0
        self._h_pos[1, IY] = self._h_pos[1, IBE] = 1.0
        self._h_vel = np.zeros((2, NX))
        self._h_vel[0, ICN] = self._h_vel[1, ICE] = 1.0

    def lever_ned(self, psi: float) -> tuple[float, float, float, float]:
        """Antenna offset in NED (m) and its derivative with respect to ψ (m/rad)."""
        lx, ly = self._lever
        s, co = math.sin(psi), math.cos(psi)
        return lx * co - ly * s, lx * s + ly * co, -lx * s - ly * co, lx * co - ly * s

    # .................................................... GPS position
    def fuse_pos(self, c: FilterState, m: Measurement) -> None:
        x = c.x
        ln = le = dln = dle = 0.0
        if self.has_lever:
            ln, le, dln, dle = self.lever_ned(x[IPSI])
        if not c.pos_init:
            self._init_pos(c, m, ln, le)
            return
        if m.tov - c.t_pos > self.cfg.dr_max_s:
            # dead reckoning has run out (the position went invalid): start again from
            # this fix rather than gate it against a stale estimate
            self.counters.count("pos_restarts")
            self._init_pos(c, m, ln, le)
            return
        glide = m.fix != c.fix and self._fix_change(c, m)
        x0, y0 = x[IX], x[IY]
        nu1 = m.z1 - (x[IX] + x[IBN] + ln)
        nu2 = m.z2 - (x[IY] + x[IBE] + le)
        H = self._h_pos
        if self.has_lever:
            H = H.copy()
            H[0, IPSI], H[1, IPSI] = dln, dle
        if update2(c, H, nu1, nu2, m.r1, m.r2, self.gates[K_POS]):
            self.accepted(c, K_POS)
            c.t_pos = m.tov
            if glide:
                gn, ge = self.glide_offset(c, m.tov)
                c.glide = (m.tov, gn + x0 - x[IX], ge + y0 - x[IY])
        elif self._pos_manoeuvre(c, m, nu1, nu2):
            update2(c, H, nu1, nu2, m.r1, m.r2, math.inf)
            self.counters.count("pos_manoeuvre")
            c.rej[K_POS] = math.nan
            c.t_pos = m.tov
        elif self.rejected(c, K_POS, m.tov):
            self._init_pos(c, m, ln, le)

    def _pos_manoeuvre(self, c: FilterState, m: Measurement, nu1: float, nu2: float) -> bool:
        """Without GPS velocity (none fused for 1 s), an RTK position beyond its
        gate by no more than ``max_accel_mps2`` could have moved the boat since the
        last fused fix is a manoeuvre: open up the speed by the implied velocity error, and the
        position, and return True (the caller fuses it).  Only for centimetre
        fixes (white σ < 0.1 m): with metre-level noise a gate failure is an outlier."""
        if max(m.r1, m.r2) >= 0.01 or m.tov - c.t_vel < 1.0:
            return False  # metre-level noise, or a GPS velocity that says otherwise
        dt = min(1.0, m.tov - c.t_pos)
        mag = math.hypot(nu1, nu2)
        if dt <= 0.0 or mag > 0.5 * self.cfg.max_accel_mps2 * dt * dt + 0.05:
            return False
        P = c.P
        s, co = math.sin(c.x[IPSI]), math.cos(c.x[IPSI])
        P[IU, IU] += ((co * nu1 + s * nu2) / dt) ** 2
        P[IV, IV] += ((-s * nu1 + co * nu2) / dt) ** 2
        P[IX, IX] += mag * mag
        P[IY, IY] += mag * mag
        return True

    def _init_pos(self, c: FilterState, m: Measurement, ln: float, le: float) -> None:
        """(Re-)initialise position and GPS offset on fix ``m`` (a hard reset)."""
        x, P = c.x, c.P
        sb2 = self.noise.bias_sigma[m.fix] ** 2
        for i in (IX, IY, IBN, IBE):
            P[i, :] = 0.0
            P[:, i] = 0.0
        x[IX], x[IY] = m.z1 - ln, m.z2 - le
        x[IBN] = x[IBE] = 0.0
        P[IX, IX], P[IY, IY] = m.r1 + sb2, m.r2 + sb2
        P[IBN, IBN] = P[IBE, IBE] = sb2
        P[IX, IBN] = P[IBN, IX] = P[IY, IBE] = P[IBE, IY] = -sb2
        c.fix = m.fix
        c.pos_init = True
        c.t_pos = m.tov

    def _fix_change(self, c: FilterState, m: Measurement) -> bool:
        """Re-prime the GPS offset state for a new fix type (see the module doc);
        True if the published position should glide over the coming jump."""
        x, P = c.x, c.P
        self.counters.count("fix_changes")
        bias_sigma = self.noise.bias_sigma
        sb_new = bias_sigma[m.fix]
        upgrade = sb_new < bias_sigma[c.fix]
        for i in (IBN, IBE):
            P[i, :] = 0.0
            P[:, i] = 0.0
        P[IBN, IBN] = P[IBE, IBE] = sb_new**2
        x[IBN] = x[IBE] = 0.0  # a fresh, independent offset of the new solution
        c.fix = m.fix
        return upgrade and self.cfg.upgrade_glide_s > 0.0

    def glide_offset(self, c: FilterState, t: float) -> tuple[float, float]:
        """Published-position offset (north, east m) still to glide off at ``t`` (s)."""
        g = c.glide
        if g is None or t < g[0]:
            return 0.0, 0.0
        k = math.exp(-(t - g[0]) / self.cfg.upgrade_glide_s)
        return g[1] * k, g[2] * k

    # .................................................... GPS velocity
    def ground_velocity(self, x: list[float]) -> tuple[float, float, np.ndarray]:
        """Ground velocity (vn, ve) of the antenna (m/s) and its Jacobian (2×NX)."""
        u, v, psi, r = x[IU], x[IV], x[IPSI], x[IR]
        s, co = math.sin(psi), math.cos(psi)
        vn = u * co - v * s + x[ICN]
        ve = u * s + v * co + x[ICE]
        H = self._h_vel
        H.flat[_H_VEL_IDX] = (co, -s, -(u * s + v * co), s, co, u * co - v * s)
        if self.has_lever:
            ln, le, dln, dle = self.lever_ned(psi)
            vn += r * dln
            ve += r * dle
            H = H.copy()
            H[0, IR], H[1, IR] = dln, dle
            H[0, IPSI] -= r * ln
            H[1, IPSI] -= r * le
        return vn, ve, H

    def fuse_vel(self, c: FilterState, m: Measurement) -> None:
        x = c.x
        if not c.hdg_init:
            if m.kind == K_VEL and not self.heading_sensor_seen:
                self._init_heading_from_course(c, m)
            return
        if not c.vel_init:
            if m.kind == K_SOG:
                return
            self._init_speed(c, m)
        vn, ve, H = self.ground_velocity(x)
        if m.kind == K_SOG:
            speed = math.hypot(vn, ve)
            if speed < 0.1 or m.z1 < 0.1:
                return
            h = (vn / speed) * H[0] + (ve / speed) * H[1]
            if update1(c, h, m.z1 - speed, m.r1, self.gates[K_SOG]):
                self.accepted(c, K_SOG)
            else:
                self.rejected(c, K_SOG, m.tov)
            return
        nu1, nu2 = m.z1 - vn, m.z2 - ve
        if update2(c, H, nu1, nu2, m.r1, m.r2, self.gates[K_VEL]):
            self.accepted(c, K_VEL)
            c.t_vel = m.tov
        elif self._manoeuvre(c, m, nu1, nu2):
            update2(c, H, nu1, nu2, m.r1, m.r2, math.inf)
            self.counters.count("vel_manoeuvre")
            c.rej[K_VEL] = math.nan
            c.t_vel = m.tov
        elif self.rejected(c, K_VEL, m.tov):
            # velocity lost: restart the speed through the water from this one
            self._init_speed(c, m)
            vn, ve, H = self.ground_velocity(x)
            update2(c, H, m.z1 - vn, m.z2 - ve, m.r1, m.r2, math.inf)

    def _manoeuvre(self, c: FilterState, m: Measurement, nu1: float, nu2: float) -> bool:
        """A velocity innovation beyond the gate but within what the boat can do
        since the last fused velocity (``max_accel_mps2``) is a manoeuvre the
        random-walk model did not foresee, not a bad measurement: open up the
        speed (body frame, along and across) and the position by what it implies,
        and return True (the caller fuses it).  GPS (Doppler) velocity is the
        most reliable thing the receiver gives."""
        dt = min(1.0, m.tov - c.t_vel)
        mag = math.hypot(nu1, nu2)
        if not (mag <= self.cfg.max_accel_mps2 * dt + 5.0 * math.sqrt(m.r1 + m.r2)):
            return False
        P = c.P
        s, co = math.sin(c.x[IPSI]), math.cos(c.x[IPSI])
        P[IU, IU] += (co * nu1 + s * nu2) ** 2
        P[IV, IV] += (-s * nu1 + co * nu2) ** 2
        dp = (mag * dt) ** 2
        P[IX, IX] += dp
        P[IY, IY] += dp
        return True

    def _init_speed(self, c: FilterState, m: Measurement) -> None:
        """Start the surge speed at the GPS velocity's component along the heading
        (less the current), so that the first velocity update is linearised about the
        right speed (about u = 0 the crab would all go to the current); with the
        thrusters stopped, at rest in the water."""
        x = c.x
        psi = x[IPSI]
        if (self.prediction.driven(c)
                and abs(c.f1) + abs(c.f2) < REST_THRUST_N
                and math.hypot(m.z1, m.z2) < self.cfg.rest_max_speed_mps):
            # no thrust so far and a current's speed over ground: a boat without thrust
            # moves with the water, so the GPS velocity is the current's (the start of
            # a mission, from rest; a boat still coasting after a restart goes faster)
            x[IU] = 0.0
            su2 = self.cfg.rest_speed_sigma_mps**2
        else:
            x[IU] = math.cos(psi) * (m.z1 - x[ICN]) + math.sin(psi) * (m.z2 - x[ICE])
            su2 = m.r1 + 0.01
        x[IV] = 0.0
        reset_block(c, (IU, IV), (su2, self.cfg.sway_sigma_mps**2))
        c.vel_init = True

    def _init_heading_from_course(self, c: FilterState, m: Measurement) -> None:
        """No heading sensor: start ψ at the course (heading stays flagged invalid)."""
        speed = math.hypot(m.z1, m.z2)
        if speed < self.cfg.course_init_speed_mps:
            return
        x = c.x
        # a heading from the course leaves nothing to tell a current by: held at zero
        # (with its random walk) until a heading sensor speaks
        reset_block(c, (IPSI, IU, IV, ICN, ICE), (COURSE_INIT_SIGMA_RAD**2, m.r1 + m.r2,
                                                  self.cfg.sway_sigma_mps**2, 0.0, 0.0))
        x[IPSI] = math.atan2(m.z2, m.z1)
        x[IU], x[IV] = speed, 0.0
        x[ICN] = x[ICE] = 0.0
        c.hdg_init = c.vel_init = c.hdg_course = True
        self.counters.count("heading_from_course")
