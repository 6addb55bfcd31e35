"""What the boat does through the water: surge and sway speed, the water
current, and how unequally the two thrusters push, from the thrust commanded,
the GPS ground velocity and the heading.

An eight-state Kalman filter run at the control rate,
x = [u, v, c_n, c_e, Δ, κ, w, w_x]:

* u, v: surge and sway speed through the water (body frame, m/s), predicted by
  the nominal hull model (the paper's, section III)

      (m − X_u') u' = X_u u + X_|u|u |u| u + X + w_x
      (m − Y_v') v' = Y_v v − m u r + w

  with X the surge force the thrusters give (commanded, through the thruster
  lag), and w_x, w the surge and sway forces of gusts and chop, Gauss–Markov
  processes.  The line tracking counters w before it has moved the boat
  (``lqr.py``).  Modelling the gusts matters for the other states too: the
  speed and heading controllers answer the gusts, so a filter that took them
  for white noise would read the controllers' answers as a thrust or current
  error;
* c_n, c_e: the water current (NED, m/s, the direction it flows towards);
* Δ: thruster mismatch: port gives (1 + Δ) f, starboard (1 − Δ) f of the
  calibrated table f, so that the commands X_c, N_c really give

      X = X_c + Δ N_c / b        N = N_c + Δ b X_c

  (every yaw command also pushes the boat ahead or astern by Δ N_c / b);
* κ: surge model error, as a scale on the thrust: the surge force is
  (1 + κ)(X_c + Δ N_c / b).  It takes up a thrust curve or a drag that is not
  the model's, so that u is the speed through the water and not the model's.

Measurements: the ground velocity along the heading, u + c·h, and across it,
v + c·h⊥.  The current is taken from the across-heading component only (the
along-heading one is fused for u with the current as a known offset): along the
heading, an error of the surge model (thrust curve, drag) and the current
cannot be told apart on a straight leg, and letting the model's error into the
current would tilt the crab angle.  Across the heading the sway model carries
no thrust term, so the current there is clean; as the heading changes (legs,
and the small heading swings of tracking) both of its components are seen.
(Along the line it stays the least certain part: while tracking, the heading
swings against the gusts, so sway and heading are correlated by the controller
itself and a few cm/s of sway can be read as current along the line.  That
part only sets the gain schedule and the speed feedforward; the crab angle
uses the part across the line.)

Δ is seen in the surge that every yaw command makes: at 0.1 a 30 N m command
pushes 8 N, a quarter of what holds 0.5 m/s.
"""

from __future__ import annotations

import math

import numpy as np

from zarco_core.messages import NavState
from zarco_core.vessel import VesselModel

#: state indices
IU, IV, ICN, ICE, ID, IK, IW, IWX = range(8)
#: largest mismatch the estimate may take (a 25 % difference between thrusters
#: is a fault, not a calibration error)
MISMATCH_MAX = 0.25


class WaterObserver:
    """Kalman filter of surge and sway through the water, current and mismatch.

    :meth:`step` runs once per control tick with the navigation state and the
    surge force (N) and yaw moment (N m) commanded on the calibrated tables.
    Noise figures are 1σ; the gusts are a Gauss–Markov force of correlation
    time ``gust_tau_s``, taken as white noise of the same low-frequency power.
    """

    def __init__(self, vm: VesselModel, lag_s: float, *, estimate_mismatch: bool = True,
                 current_sigma_mps: float = 0.5, mismatch_sigma: float = 0.1,
                 scale_sigma: float = 0.2, scale_walk: float = 2e-3,
                 surge_force_sigma_n: float = 0.5, sway_force_sigma_n: float = 5.0,
                 sway_model_sigma_n: float = 0.5, surge_gust_sigma_n: float = 5.0,
                 gust_tau_s: float = 2.0, vel_sigma_mps: float = 0.1,
                 current_walk_mps: float = 2e-3, mismatch_walk: float = 2e-3) -> None:
        """``surge_force_sigma_n`` is kept small on purpose: the surge speed is
        used to split the cross-track rate into the part the heading explains,
        and a speed that follows every GPS velocity sample would make the yaw
        command chatter; the current and Δ absorb what the model misses."""
        self.vm = vm
        self.lag_s = lag_s
        self.m_u = vm.m_kg - vm.x_udot
        self.m_v = vm.m_kg - vm.y_vdot
        self.estimate_mismatch = estimate_mismatch
        self.gust_tau_s = gust_tau_s
        self.x = np.zeros(8)
        self.P = np.diag([0.1**2, 0.05**2, current_sigma_mps**2, current_sigma_mps**2,
                          mismatch_sigma**2 if estimate_mismatch else 0.0, scale_sigma**2,
                          sway_force_sigma_n**2, surge_gust_sigma_n**2])
        self._q = np.array([2.0 * (surge_force_sigma_n / self.m_u) ** 2 * gust_tau_s,
                            2.0 * (sway_model_sigma_n / self.m_v) ** 2 * gust_tau_s,
                            current_walk_mps**2, current_walk_mps**2,
                            mismatch_walk**2 if estimate_mismatch else 0.0,
                            scale_walk**2, 2.0 * sway_force_sigma_n**2 / gust_tau_s,
                            2.0 * surge_gust_sigma_n**2 / gust_tau_s])
        self.r_vel = vel_sigma_mps**2
        self.x_lag = 0.0
        self.n_lag = 0.0
        self.updates = 0
        # work arrays, allocated once: a step runs at the control rate and small
        # numpy allocations cost as much as the arithmetic on 8 × 8
        self._P_diag = self.P.reshape(64)[::9]  # a view on P's diagonal
        self._F = np.eye(8)
        self._F_dt = math.nan  # the period the constant part of _F was built for
        self._qdt = np.zeros(8)
        self._FP = np.empty((8, 8))
        self._buf = np.empty((8, 8))
        self._h_along = np.zeros(8)
        self._h_along[IU] = 1.0
        self._h_across = np.zeros(8)
        self._h_across[IV] = 1.0
        self._ph = np.empty(8)
        self._k = np.empty(8)

    # ------------------------------------------------------------------ values
    @property
    def u_w(self) -> float:
        """Surge speed through the water (m/s)."""
        return float(self.x[IU])

    @property
    def cn(self) -> float:
        """Water current, north (m/s)."""
        return float(self.x[ICN])

    @property
    def ce(self) -> float:
        """Water current, east (m/s)."""
        return float(self.x[ICE])

    @property
    def sway_force(self) -> float:
        """w, the sway force of gusts and chop (N, to starboard)."""
        return float(self.x[IW])

    @property
    def mismatch(self) -> float:
        """Δ (port (1 + Δ) f, starboard (1 − Δ) f), within ±MISMATCH_MAX."""
        return max(-MISMATCH_MAX, min(MISMATCH_MAX, float(self.x[ID])))

    def actual(self, x_c: float, n_c: float) -> tuple[float, float]:
        """Surge force (N) and yaw moment (N m) that the commands ``x_c``, ``n_c`` give."""
        dl, b = self.mismatch, self.vm.b_m
        return x_c + dl * n_c / b, n_c + dl * b * x_c

    def command_for(self, x_n: float, n_nm: float) -> tuple[float, float]:
        """Commands that give the surge force ``x_n`` and yaw moment ``n_nm``
        (the inverse of :meth:`actual`)."""
        dl, b = self.mismatch, self.vm.b_m
        g = 1.0 - dl * dl
        return (x_n - dl * n_nm / b) / g, (n_nm - dl * b * x_n) / g

    # -------------------------------------------------------------------- step
    def step(self, nav: NavState, x_c: float, n_c: float, dt: float) -> None:
        """Predict over ``dt`` (s) with the commands ``x_c`` (N), ``n_c`` (N m) and
        fuse the ground velocity of ``nav``."""
        vm = self.vm
        a_lag = min(1.0, dt / self.lag_s)
        self.x_lag += a_lag * (x_c - self.x_lag)
        self.n_lag += a_lag * (n_c - self.n_lag)
        xl, nl, b = self.x_lag, self.n_lag, vm.b_m
        x, P = self.x, self.P
        u, v, dl = float(x[IU]), float(x[IV]), float(x[ID])
        k = max(-0.5, min(0.5, float(x[IK])))
        r = nav.r_rps if math.isfinite(nav.r_rps) else 0.0
        # prediction (Euler: dt is the control period, the hull's time constants ~1 s)
        thrust = xl + dl * nl / b
        wx = float(x[IWX])
        x[IU] = u + dt * (vm.x_u * u + vm.x_uu * abs(u) * u + (1.0 + k) * thrust + wx) / self.m_u
        x[IWX] = wx * (1.0 - dt / self.gust_tau_s)
        w = float(x[IW])
        x[IV] = v + dt * (vm.y_v * v - vm.m_kg * u * r + w) / self.m_v
        x[IW] = w * (1.0 - dt / self.gust_tau_s)
        F = self._F
        if dt != self._F_dt:  # the entries that depend on dt only
            self._F_dt = dt
            F[IV, IV] = 1.0 + dt * vm.y_v / self.m_v
            F[IV, IW] = dt / self.m_v
            F[IW, IW] = 1.0 - dt / self.gust_tau_s
            F[IU, IWX] = dt / self.m_u
            F[IWX, IWX] = 1.0 - dt / self.gust_tau_s
            np.multiply(self._q, dt, out=self._qdt)
        F[IU, IU] = 1.0 + dt * (vm.x_u + 2.0 * vm.x_uu * abs(u)) / self.m_u
        F[IU, ID] = dt * (1.0 + k) * nl / b / self.m_u if self.estimate_mismatch else 0.0
        F[IU, IK] = dt * thrust / self.m_u
        F[IV, IU] = -dt * vm.m_kg * r / self.m_v
        np.matmul(F, P, out=self._FP)
        np.matmul(self._FP, F.T, out=P)
        self._P_diag += self._qdt
        if not (nav.pos_valid and nav.heading_valid and math.isfinite(nav.psi_rad)
                and math.isfinite(nav.vn_mps) and math.isfinite(nav.ve_mps)):
            return
        c, s = math.cos(nav.psi_rad), math.sin(nav.psi_rad)
        along = nav.vn_mps * c + nav.ve_mps * s
        across = -nav.vn_mps * s + nav.ve_mps * c
        self._update(self._h_along, along - float(x[ICN]) * c - float(x[ICE]) * s)
        h = self._h_across
        h[ICN] = -s
        h[ICE] = c
        self._update(h, across)
        self.updates += 1

    def _update(self, h: np.ndarray, z: float) -> None:
        """Scalar measurement z = h·x (variance ``r_vel``), in place."""
        x, P, ph, k, buf = self.x, self.P, self._ph, self._k, self._buf
        np.matmul(P, h, out=ph)
        np.divide(ph, float(h @ ph) + self.r_vel, out=k)
        x += k * (z - float(h @ x))
        np.multiply.outer(k, ph, out=buf)
        P -= buf
        np.add(P, P.T, out=buf)
        np.multiply(buf, 0.5, out=P)
