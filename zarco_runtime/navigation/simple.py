"""First navigation estimate: the fallback behind the EKF (``navigation.estimator = "simple"``).

* Position and ground velocity: per NED axis, a two-state constant-velocity
  Kalman filter fed with GPS positions (σ from the fix type) and with the
  GPS speed/course (RMC/VTG), predicted to the requested time.
* Heading: complementary filter of compass heading and gyro rate (ROT),
  with the gyro bias estimated by the integral path (Mahony-style); without
  a gyro the rate comes from filtered heading differences.

Pure: feed messages with ``on_*`` and read :meth:`state` at any time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.angles import wrap
from zarco_core.geodesy import LocalFrame
from zarco_core.localgeo import FastLocalFrame
from zarco_core.messages import (
    FixQuality,
    GpsFix,
    GpsVelocity,
    Heading,
    NavState,
    RateOfTurn,
)
from zarco_runtime.navigation.settings import Navigation

#: 1σ horizontal position noise assumed per fix type (m), from the receivers' specifications.
FIX_SIGMA_M = {
    FixQuality.RTK_FIXED: 0.02,
    FixQuality.RTK_FLOAT: 0.35,
    FixQuality.DGPS: 0.7,
    FixQuality.SINGLE: 2.0,
}


@dataclass(slots=True)
class _Axis:
    """Two-state (position, velocity) Kalman filter along one axis."""

    p: float = 0.0
    v: float = 0.0
    pp: float = 1e6
    pv: float = 0.0
    vv: float = 100.0

    def predict(self, dt: float, q: float) -> None:
        if dt <= 0.0:
            return
        self.p += self.v * dt
        pp, pv, vv = self.pp, self.pv, self.vv
        self.pp = pp + 2 * dt * pv + dt * dt * vv + q * dt**3 / 3.0
        self.pv = pv + dt * vv + q * dt * dt / 2.0
        self.vv = vv + q * dt

    def update_pos(self, z: float, r: float) -> None:
        s = self.pp + r
        k0, k1 = self.pp / s, self.pv / s
        y = z - self.p
        self.p += k0 * y
        self.v += k1 * y
        pp, pv, vv = self.pp, self.pv, self.vv
        self.pp = (1 - k0) * pp
        self.pv = (1 - k0) * pv
        self.vv = vv - k1 * pv

    def update_vel(self, z: float, r: float) -> None:
        s = self.vv + r
        k0, k1 = self.pv / s, self.vv / s
        y = z - self.v
        self.p += k0 * y
        self.v += k1 * y
        pp, pv, vv = self.pp, self.pv, self.vv
        self.pp = pp - k0 * pv
        self.pv = (1 - k1) * pv
        self.vv = (1 - k1) * vv


class SimpleNavigator:
    """GPS + compass + gyro → NavState."""

    def __init__(self, cfg: Navigation, frame: LocalFrame,
                 variation_deg: float | None = None) -> None:
        self.cfg = cfg
        self.frame = frame
        # the same plane in plain math (checked against pymap3d to < 1 µm in
        # tests/test_ekf.py): pymap3d's ~15 µs per call is the estimator's largest cost
        self._geo = FastLocalFrame(frame.lat0, frame.lon0, frame.h0)
        self.variation_deg = variation_deg
        self.min_fix = FixQuality.from_label(cfg.min_fix)
        self.n = _Axis()
        self.e = _Axis()
        self.t_pos: float | None = None
        self.t_fix: float | None = None
        self.fix_utc_s: float | None = None
        self.fix = FixQuality.NONE
        self.lat = math.nan
        self.lon = math.nan
        # heading
        self.psi = 0.0
        self.t_psi: float | None = None
        self.t_compass: float | None = None
        self.rate = 0.0
        self.t_rate: float | None = None
        self.gyro_bias = 0.0
        self.r_est = 0.0
        self.rejected = 0

    # ---------------------------------------------------------- position
    def _predict_pos(self, t: float) -> None:
        if self.t_pos is None:
            self.t_pos = t
            return
        dt = t - self.t_pos
        if dt > 0:
            self.n.predict(dt, self.cfg.accel_psd)
            self.e.predict(dt, self.cfg.accel_psd)
            self.t_pos = t

    def on_fix(self, m: GpsFix) -> bool:
        """A GPS position; False when it repeats one already taken (nothing changed)."""
        if m.lat_deg is None or m.lon_deg is None or m.fix < self.min_fix:
            self.fix = m.fix if m.lat_deg is None or m.fix < self.min_fix else self.fix
            return True
        if not (math.isfinite(m.lat_deg) and math.isfinite(m.lon_deg)):
            self.rejected += 1
            return True
        if m.utc_s is not None and m.utc_s == self.fix_utc_s and m.t - (self.t_fix or 0.0) < 0.5:
            return False  # GGA and RMC of one epoch carry the same measurement: use it once
        self.fix_utc_s = m.utc_s
        x, y = self._geo.to_ned(m.lat_deg, m.lon_deg)
        sigma = FIX_SIGMA_M.get(m.fix, 2.0)
        r = sigma * sigma
        if self.t_fix is None:
            self.n.p, self.e.p = x, y
            self.n.pp = self.e.pp = r
            self.t_pos = m.t
        else:
            self._predict_pos(m.t)
            self.n.update_pos(x, r)
            self.e.update_pos(y, r)
        self.t_fix = m.t
        self.fix = m.fix
        self.lat, self.lon = m.lat_deg, m.lon_deg
        return True

    def on_velocity(self, m: GpsVelocity) -> None:
        if self.t_fix is None or m.cog_rad is None or not math.isfinite(m.sog_mps):
            return
        self._predict_pos(m.t)
        r = self.cfg.sog_sigma_mps**2
        self.n.update_vel(m.sog_mps * math.cos(m.cog_rad), r)
        self.e.update_vel(m.sog_mps * math.sin(m.cog_rad), r)

    # ----------------------------------------------------------- heading
    def _integrate_heading(self, t: float) -> None:
        if self.t_psi is None:
            return
        dt = t - self.t_psi
        if dt > 0:
            self.psi = wrap(self.psi + self.r_est * dt)
            self.t_psi = t

    def on_rate(self, m: RateOfTurn) -> None:
        self._integrate_heading(m.t)
        self.rate = m.rate_rps
        self.t_rate = m.t
        self.r_est = m.rate_rps - self.gyro_bias

    def has_gyro(self, t: float) -> bool:
        """True while yaw-rate measurements are arriving."""
        return self.t_rate is not None and t - self.t_rate < self.cfg.heading_timeout_s

    def on_heading(self, m: Heading) -> None:
        psi_m = m.heading_rad
        if not m.true:
            var = self.variation_deg
            if var is not None:
                psi_m = psi_m + math.radians(var)
        if not math.isfinite(psi_m):
            self.rejected += 1
            return
        if self.t_psi is None:
            self.psi = wrap(psi_m)
            self.t_psi = m.t
            self.t_compass = m.t
            return
        dt = m.t - (self.t_compass if self.t_compass is not None else m.t)
        self._integrate_heading(m.t)
        err = wrap(psi_m - self.psi)
        k = min(1.0, max(dt, 1e-3) / self.cfg.heading_tau_s)
        self.psi = wrap(self.psi + k * err)
        have_gyro = self.t_rate is not None and m.t - self.t_rate < self.cfg.heading_timeout_s
        if have_gyro:
            kb = min(1.0, max(dt, 1e-3) / self.cfg.gyro_bias_tau_s)
            self.gyro_bias -= kb * err / self.cfg.heading_tau_s
        else:
            # no gyro: rate from heading differences, low-passed
            if dt > 0:
                a = min(1.0, dt / self.cfg.heading_tau_s)
                self.r_est += a * (err / max(dt, 1e-3) * k - self.r_est)
        self.t_compass = m.t

    # ------------------------------------------------------------- state
    def state(self, t: float) -> NavState:
        """The estimate predicted to time ``t``."""
        cfg = self.cfg
        if self.t_pos is not None:
            dt = max(0.0, t - self.t_pos)
            x = self.n.p + self.n.v * dt
            y = self.e.p + self.e.v * dt
        else:
            x = y = 0.0
        psi = self.psi
        if self.t_psi is not None:
            psi = wrap(psi + self.r_est * max(0.0, t - self.t_psi))
        vn, ve = self.n.v, self.e.v
        c, s = math.cos(psi), math.sin(psi)
        pos_valid = (self.t_fix is not None and t - self.t_fix <= cfg.gps_timeout_s
                     and self.fix >= self.min_fix)
        hdg_valid = self.t_compass is not None and t - self.t_compass <= cfg.heading_timeout_s
        cov = (
            self.n.pp, 0.0, self.n.pv, 0.0, 0.0,
            0.0, self.e.pp, 0.0, self.e.pv, 0.0,
            self.n.pv, 0.0, self.n.vv, 0.0, 0.0,
            0.0, self.e.pv, 0.0, self.e.vv, 0.0,
            0.0, 0.0, 0.0, 0.0, math.radians(1.0) ** 2,
        )
        return NavState(
            t=t, x_m=x, y_m=y, vn_mps=vn, ve_mps=ve, psi_rad=psi, r_rps=self.r_est,
            u_mps=c * vn + s * ve, v_mps=-s * vn + c * ve,
            lat_deg=self.lat, lon_deg=self.lon, fix=self.fix,
            pos_valid=pos_valid, heading_valid=hdg_valid, cov=cov,
            gps_age_s=t - self.t_fix if self.t_fix is not None else math.inf,
        )
