"""3-DOF surface-vessel model of the paper (section III), fixed-step RK4.

Frames (the project's conventions): position (x, y) = (north, east) metres in the local NED
frame; heading ψ clockwise from north; body velocities (u, v) forward and
starboard *relative to the water*; yaw rate r positive clockwise (seen from
above, z down).  The current (c_x, c_y) is constant and uniform, so the
water-relative formulation is exact: it only enters the kinematics.

Dynamics (added mass on the left, rigid-body Coriolis as in the paper)::

    (m − X_u') u' =  m v r + X_u u + X_|u|u |u| u + X_act + X_dist
    (m − Y_v') v' = −m u r + Y_v v + Y_|v|v |v| v + Y_act + Y_dist
    (Iz − N_r') r' =         N_r r + N_|r|r |r| r + N_act + N_dist
    x' = u cosψ − v sinψ + c_x     y' = u sinψ + v cosψ + c_y     ψ' = r
    F_i' = (f_i(U_i) − F_i) / lag_s

Actuation, thruster 1 (port) at body (−l, −b), thruster 2 (starboard) at
(−l, +b), each pointing φ_i to starboard of the body x axis (small angles, as
in the paper)::

    X_act = F1 + F2     Y_act = F1 φ1 + F2 φ2     N_act = b(F1 − F2) − l(F1 φ1 + F2 φ2)

N_act is the z component of Σ r_i × F_i with r_i = (−l, ∓b), F_i = F_i(1, φ_i):
x F_y − y F_x = −l F_i φ_i ± b F_i, so F1 > F2 gives N > 0, r > 0: the boat
turns to starboard (clockwise).  The added-mass Coriolis/Munk terms are left
out, as in the paper's equations.

The step is written with plain floats and ``math`` (numpy on an 8-element
state is several times slower than this); commands and the disturbance are
held constant over a step, the thrust lag is part of the RK4 state.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from drivers.sim.params import CurrentParams, ThrusterParams, VesselParams
from drivers.sim.thruster_model import thruster_thrust

_Deriv = Callable[..., tuple[float, float, float, float, float, float, float, float]]


@dataclass(slots=True)
class VesselState:
    """True state of the vessel.

    ``x_m``/``y_m`` north/east (m, local NED); ``psi_rad`` heading (rad,
    clockwise from north, not wrapped: it accumulates turns); ``u_mps``/``v_mps``
    surge/sway velocity relative to the water (m/s, body frame); ``r_rps`` yaw
    rate (rad/s, clockwise positive); ``f1_n``/``f2_n`` actual thrusts of the
    port/starboard thrusters after the first-order lag (N).
    """

    x_m: float = 0.0
    y_m: float = 0.0
    psi_rad: float = 0.0
    u_mps: float = 0.0
    v_mps: float = 0.0
    r_rps: float = 0.0
    f1_n: float = 0.0
    f2_n: float = 0.0


def _make_deriv(vp: VesselParams, tp: ThrusterParams, cx: float, cy: float) -> _Deriv:
    """Derivative of (x, y, ψ, u, v, r, F1, F2) with the model constants bound."""
    m = vp.m_kg
    inv_mu = 1.0 / (vp.m_kg - vp.x_udot)
    inv_mv = 1.0 / (vp.m_kg - vp.y_vdot)
    inv_iz = 1.0 / (vp.iz_kgm2 - vp.n_rdot)
    xu, xuu, yv, yvv, nr, nrr = vp.x_u, vp.x_uu, vp.y_v, vp.y_vv, vp.n_r, vp.n_rr
    b, lever = vp.b_m, vp.l_m
    phi1 = math.radians(tp.phi1_deg)
    phi2 = math.radians(tp.phi2_deg)
    inv_lag = 1.0 / tp.lag_s
    cos, sin = math.cos, math.sin

    def deriv(psi: float, u: float, v: float, r: float, f1: float, f2: float,
              t1: float, t2: float, xd: float, yd: float, nd: float
              ) -> tuple[float, float, float, float, float, float, float, float]:
        c = cos(psi)
        s = sin(psi)
        y_act = f1 * phi1 + f2 * phi2
        return (
            u * c - v * s + cx,
            u * s + v * c + cy,
            r,
            (m * v * r + (xu + xuu * abs(u)) * u + f1 + f2 + xd) * inv_mu,
            (-m * u * r + (yv + yvv * abs(v)) * v + y_act + yd) * inv_mv,
            ((nr + nrr * abs(r)) * r + b * (f1 - f2) - lever * y_act + nd) * inv_iz,
            (t1 - f1) * inv_lag,
            (t2 - f2) * inv_lag,
        )

    return deriv


def current_ned(p: CurrentParams) -> tuple[float, float]:
    """Current (c_x, c_y) north/east (m/s) from speed and the direction it flows towards."""
    d = math.radians(p.direction_deg)
    return p.speed_mps * math.cos(d), p.speed_mps * math.sin(d)


class Vessel:
    """The vessel's true motion, integrated with fixed-step RK4.

    ``state`` is mutated in place by :meth:`step`.
    """

    def __init__(self, vessel: VesselParams, thrusters: ThrusterParams,
                 current: CurrentParams | None = None,
                 state: VesselState | None = None) -> None:
        self.vp = vessel
        self.tp = thrusters
        self.cx, self.cy = current_ned(current) if current is not None else (0.0, 0.0)
        self.state = state if state is not None else VesselState()
        self._deriv = _make_deriv(vessel, thrusters, self.cx, self.cy)
        # f_i(U_i) of the last commands (commands change at most at the control rate)
        self._cmd = (0.0, 0.0)
        self._target = (0.0, 0.0)

    def thrust_targets(self, u1_cmd: float, u2_cmd: float) -> tuple[float, float]:
        """Steady thrusts f1(U1), f2(U2) (N) for commands U1, U2 (−100..100)."""
        if (u1_cmd, u2_cmd) != self._cmd:
            self._cmd = (u1_cmd, u2_cmd)
            self._target = (thruster_thrust(u1_cmd, self.tp, 1),
                            thruster_thrust(u2_cmd, self.tp, 2))
        return self._target

    def step(self, dt: float, u1_cmd: float, u2_cmd: float,
             dist: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        """Advance by ``dt`` seconds with commands U1, U2 and body-frame disturbance
        (X N, Y N, N N m), all held constant over the step (classic RK4)."""
        t1, t2 = self.thrust_targets(u1_cmd, u2_cmd)
        xd, yd, nd = dist
        f = self._deriv
        s = self.state
        x, y, p, u, v, r, a, b = (s.x_m, s.y_m, s.psi_rad, s.u_mps, s.v_mps, s.r_rps,
                                  s.f1_n, s.f2_n)
        h = 0.5 * dt
        k1 = f(p, u, v, r, a, b, t1, t2, xd, yd, nd)
        k2 = f(p + h * k1[2], u + h * k1[3], v + h * k1[4], r + h * k1[5],
               a + h * k1[6], b + h * k1[7], t1, t2, xd, yd, nd)
        k3 = f(p + h * k2[2], u + h * k2[3], v + h * k2[4], r + h * k2[5],
               a + h * k2[6], b + h * k2[7], t1, t2, xd, yd, nd)
        k4 = f(p + dt * k3[2], u + dt * k3[3], v + dt * k3[4], r + dt * k3[5],
               a + dt * k3[6], b + dt * k3[7], t1, t2, xd, yd, nd)
        w = dt / 6.0
        s.x_m = x + w * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
        s.y_m = y + w * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
        s.psi_rad = p + w * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2])
        s.u_mps = u + w * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3])
        s.v_mps = v + w * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4])
        s.r_rps = r + w * (k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5])
        s.f1_n = a + w * (k1[6] + 2.0 * (k2[6] + k3[6]) + k4[6])
        s.f2_n = b + w * (k1[7] + 2.0 * (k2[7] + k3[7]) + k4[7])

    def ground_velocity_ned(self) -> tuple[float, float]:
        """Velocity over ground (north, east) in m/s: body velocity rotated by ψ plus current."""
        s = self.state
        c = math.cos(s.psi_rad)
        sn = math.sin(s.psi_rad)
        return (s.u_mps * c - s.v_mps * sn + self.cx,
                s.u_mps * sn + s.v_mps * c + self.cy)
