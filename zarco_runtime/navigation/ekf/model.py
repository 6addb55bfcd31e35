"""The EKF's process model: the vessel model driven by the thruster commands.

While thruster commands arrive (``ThrusterCommand`` on the bus, no older than
``command_timeout_s``; ``thrust_model`` on, vessel model set) they are the
prediction's input: each command U_i goes through the thruster's calibrated map
f_i (the tables control allocates with) and the first-order thrust lag to a
thrust F_i, and the vessel model (the runtime's ``[vessel]``) gives the
accelerations::

    (m − X_u') u' = η·(F1 + F2) + X_u u + X_|u|u |u| u + m v r
    (Iz − N_r') r' = N_r r + N_|r|r |r| r + b·(F1 − F2) − l·Y
    F1 = (1 + ε)·f1(U1),  F2 = (1 − ε)·f2(U2)   (lagged)
    Y = φ_s (F1 + F2) + φ_d (F1 − F2)            (the thrusters' side force)
    v' = −a·u·r − v/τ_v + Y/(m − Y_v')   (a = m/(m − Y_v'), τ_v = (m − Y_v')/(−Y_v))
    ψ' = r,  x' = u cos ψ − v sin ψ + c_n,  y' = u sin ψ + v cos ψ + c_e

So the boat speeding up from rest, slowing down and turning is *predicted*:
the GPS velocity then confirms a change along the heading instead of
surprising the filter, and its direction (the acceleration is along the hull)
is heading information that a compass bias and a current cannot fake.  The
model's steady errors are states: η scales the thrust against the modelled
drag (hull drag ±25 %, thrust curve ±15 % fold into one ratio at any speed),
ε is the mismatch of the two thrusters (Δf; misalignment's yaw moment looks
alike), whose yaw moment the controller's differential thrust cancels on a
straight leg and which, in a hard turn with one thruster in reverse, changes
the surge thrust too.  What is left of the model's error is process noise that
grows with the net acceleration (``model_accel_error`` of it, over
``model_error_tau_s``: mass and inertia ±25 %) and, in yaw, with the size of
the moments (the damping, and the differential thrust the controller
balances), and with the thrust still to come after a command change
(``lag_error``: a lag of 0.1–0.3 s against the model's), so the filter is sure
of the model at steady speed on a line and not while the boat accelerates or
turns: a model error then goes to the speed and the yaw rate, which the GPS
and the gyro measure, and not to the slow states (biases, current).  A turn's
sway is trusted to ``sway_model_error``.

Gusts and chop are ``surge_noise_mps`` and ``yaw_accel_walk_dps``.  Each step
integrates the mean with the exponential Euler method (exact for the linear
damping; the surge time constant is 0.2–0.3 s at speed, shorter than a step is
long) and the thrust lag exactly.

Without commands (another pilot, a replayed capture, ``thrust_model`` off) the
surge speed u is a slow random walk (``accel_walk_mps``) and r a random walk
(``yaw_accel_walk_dps``); η and ε are then frozen.  The GPS offset b decays as
its fix type's Gauss–Markov process.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zarco_core.thruster_map import ThrusterMap
from zarco_core.vessel import VesselModel
from zarco_runtime.navigation.ekf.layout import (
    IBE,
    IBN,
    ICE,
    ICN,
    IEPS,
    IETA,
    IPD,
    IPS,
    IPSI,
    IR,
    IU,
    IV,
    IX,
    IY,
    NX,
    TAU,
    FilterState,
)
from zarco_runtime.navigation.ekf.noise import SensorNoise
from zarco_runtime.navigation.ekf_config import EkfSettings

#: most prediction sub-steps for one interval (longer intervals take longer steps)
MAX_SUBSTEPS = 200

# entries of F (beyond the identity) filled per step
_F_IDX = np.ravel_multi_index(np.array([
    (IX, IU), (IX, IV), (IX, IPSI), (IX, ICN), (IY, IU), (IY, IV), (IY, IPSI), (IY, ICE),
    (IU, IU), (IU, IV), (IU, IR), (IU, IETA), (IU, IEPS), (IV, IV), (IV, IU), (IV, IR),
    (IV, IPS), (IV, IPD), (IPSI, IR), (IR, IR), (IR, IEPS), (IR, IPS), (IR, IPD),
    (IBN, IBN), (IBE, IBE)]).T, (NX, NX))


@dataclass(frozen=True, slots=True)
class VesselConstants:
    """The vessel model's constants as the prediction uses them (SI)."""

    m: float  # rigid-body mass (kg), for the m·v·r term
    m_u: float  # m − X_u' (kg)
    m_v: float  # m − Y_v' (kg)
    i_r: float  # Iz − N_r' (kg m²)
    x_u: float  # N s/m (negative)
    x_uu: float  # N s²/m² (negative)
    n_r: float  # N m s (negative)
    n_rr: float  # N m s² (negative)
    b: float  # thruster half-spacing (m)
    arm: float  # thruster distance aft of the centre of mass (m)
    lag_s: float  # thrust time constant (s)
    sway_a: float  # m/(m − Y_v')
    sway_tau_s: float  # (m − Y_v')/(−Y_v) (s)
    port: ThrusterMap
    stbd: ThrusterMap

    @classmethod
    def of(cls, v: VesselModel, n_rr: float, port: ThrusterMap, stbd: ThrusterMap
           ) -> VesselConstants:
        m_v = v.m_kg - v.y_vdot
        return cls(v.m_kg, v.m_kg - v.x_udot, m_v, v.iz_kgm2 - v.n_rdot, v.x_u, v.x_uu,
                   v.n_r, n_rr, v.b_m, v.l_m, v.thruster_lag_s, v.m_kg / m_v,
                   m_v / max(1e-9, -v.y_v), port, stbd)


class Prediction:
    """Propagates a :class:`FilterState` in time, taking up the thruster commands."""

    def __init__(self, cfg: EkfSettings, noise: SensorNoise) -> None:
        self.cfg = cfg
        self.noise = noise
        d2r = math.radians
        # process noise densities (variance per second); the sway and the GPS
        # offset are Gauss–Markov and handled in step()
        self._q_u_walk = cfg.accel_walk_mps**2
        self._q_u_model = cfg.surge_noise_mps**2
        self._q_r = d2r(cfg.yaw_accel_walk_dps) ** 2
        self._q_bg = d2r(cfg.gyro_bias_walk_dps) ** 2
        self._q_bc = d2r(cfg.compass_bias_walk_deg) ** 2
        self._q_c = cfg.current_walk_mps**2 if cfg.estimate_current else 0.0
        self._q_eta = cfg.thrust_scale_walk**2
        self._q_eps = cfg.yaw_mismatch_walk**2
        self._k_model = cfg.model_accel_error**2 * cfg.model_error_tau_s
        self._k_lag = cfg.lag_error**2 * cfg.model_error_tau_s
        self._k_sway = cfg.sway_model_error**2
        self.model: VesselConstants | None = None
        self.mc: tuple[float, ...] | None = None  # its constants, for the prediction
        self.cmd_timeout = cfg.command_timeout_s
        self._sway_tau, self._sway_a = cfg.sway_tau_s, cfg.sway_coupling
        self._q_sway = cfg.sway_sigma_mps**2
        self._F = np.eye(NX)
        #: commands kept: the history's span at 100 Hz, and at least 200
        self._cmds_max = max(200, int(cfg.history_s * 100.0) * 2)
        self.reset()

    def reset(self) -> None:
        """Forget the commands."""
        #: thruster commands (sequence number, time s, steady thrusts f1(U1), f2(U2) N)
        self.cmds: list[tuple[int, float, float, float]] = []
        self.cmd_seq = 0

    def set_vessel(self, vessel: VesselModel, port: ThrusterMap, stbd: ThrusterMap) -> None:
        """The vessel model and the thrusters' maps f (command → N); without it, or
        with ``thrust_model`` off, commands are ignored."""
        cfg = self.cfg
        self.model = (VesselConstants.of(vessel, cfg.yaw_damping_quad, port, stbd)
                      if cfg.thrust_model else None)
        md = self.model
        self.mc = None if md is None else (
            md.m, md.m_u, md.m_v, md.i_r, md.x_u, md.x_uu, md.n_r, md.n_rr, md.b, md.arm,
            md.lag_s, md.sway_a, md.sway_tau_s, self._k_model, self._k_lag, self._q_u_model,
            self._q_r, self._q_eta, self._q_eps)

    def add_command(self, t: float, u1: float, u2: float) -> None:
        """A thruster command (−100..100, port and starboard) sent at ``t`` (s)."""
        mdl = self.model
        assert mdl is not None
        cmds = self.cmds
        self.cmd_seq += 1
        cmds.append((self.cmd_seq, round(t, 6), mdl.port.forward(u1), mdl.stbd.forward(u2)))
        if len(cmds) > self._cmds_max:  # older than any snapshot in the history
            del cmds[: len(cmds) - self._cmds_max // 2]

    def active(self, t: float) -> bool:
        """True while the thruster commands are a prediction input (at time ``t``, s)."""
        cmds = self.cmds
        return (self.model is not None and bool(cmds)
                and t - cmds[-1][1] <= self.cfg.command_timeout_s)

    def driven(self, c: FilterState) -> bool:
        """True if ``c``'s last command is fresh at its time (the thrust model runs)."""
        return self.mc is not None and c.t - c.t_cmd <= self.cmd_timeout

    def predict(self, c: FilterState, t: float) -> None:
        """Propagate ``c`` to time ``t`` (s), taking up the thruster commands on the way."""
        cmds = self.cmds
        if cmds and cmds[-1][0] > c.cmd_seq:
            for k in range(max(0, len(cmds) - (cmds[-1][0] - c.cmd_seq)), len(cmds)):
                seq, tc, thr1, thr2 = cmds[k]
                if seq <= c.cmd_seq:
                    continue
                if tc > t:
                    break
                self.predict_to(c, tc)
                c.thr1, c.thr2, c.t_cmd, c.cmd_seq = thr1, thr2, tc, seq
        self.predict_to(c, t)

    def predict_to(self, c: FilterState, t: float) -> None:
        """Propagate ``c`` to time ``t`` (s) in steps ≤ ``max_step_s``."""
        span = t - c.t
        if span <= 0.0:
            return
        if not math.isfinite(span):  # the first measurement: nothing to propagate
            c.t = t
            return
        n = min(MAX_SUBSTEPS, max(1, math.ceil(span / self.cfg.max_step_s - 1e-9)))
        dt = span / n
        for _ in range(n):
            self.step(c, dt)
        c.t = t

    def step(self, c: FilterState, dt: float) -> None:
        """One prediction step of ``dt`` seconds from ``c.t`` (advances ``c.t``)."""
        x = c.x
        u, v, psi, r = x[IU], x[IV], x[IPSI], x[IR]
        mc = self.mc
        if mc is not None and c.t - c.t_cmd <= self.cmd_timeout:
            (m, m_u, m_v, i_r, x_u, x_uu, n_r, n_rr, b, arm, lag, sway_a, tv, k_mod, k_lag,
             q_u0, q_r0, q_eta, q_eps) = mc
            # thrusts: first-order lag towards f_i(U_i), exact; their mean over the step
            el = math.exp(-dt / lag)
            w = (1.0 - el) * lag / dt
            t1, t2 = c.thr1, c.thr2
            g1, g2 = c.f1 - t1, c.f2 - t2
            f1, f2 = t1 + g1 * w, t2 + g2 * w
            c.f1, c.f2 = t1 + g1 * el, t2 + g2 * el
            # thrusts with the mismatch ε: F1 = (1 + ε) f1, F2 = (1 − ε) f2
            fsum, fdif = f1 + f2, f1 - f2
            eta, eps = x[IETA], x[IEPS]
            xs, xd = fsum + eps * fdif, fdif + eps * fsum  # F1 + F2, F1 − F2
            y_act = x[IPS] * xs + x[IPD] * xd  # the thrusters' side force (misalignment)
            # surge: η·(F1 + F2) + X_u u + X_|u|u |u| u + m v r, exponential Euler in u
            au = abs(u)
            a_u = (eta * xs + (x_u + x_uu * au) * u + m * v * r) / m_u
            lam_u = (x_u + 2.0 * x_uu * au) / m_u
            eu = math.exp(lam_u * dt)
            phi_u = (eu - 1.0) / lam_u if lam_u < -1e-9 else dt
            u2 = u + phi_u * a_u
            # yaw: N_r r + N_|r|r |r| r + b (F1 − F2) − l·side force
            ar = abs(r)
            damp = (n_r + n_rr * ar) * r
            n_act = b * xd - arm * y_act
            a_r = (damp + n_act) / i_r
            lam_r = (n_r + 2.0 * n_rr * ar) / i_r
            er = math.exp(lam_r * dt)
            phi_r = (er - 1.0) / lam_r if lam_r < -1e-9 else dt
            r2 = r + phi_r * a_r
            # model error as noise densities: a share of the net surge acceleration
            # (a steady error is η's; a turn's thrusts work against each other), of
            # the yaw moments (hull and inertia, the differential thrust balanced)
            g_u = abs(a_u) + abs(fdif) / m_u
            g_r = (abs(damp) + abs(n_act)) / i_r
            # the thrust still to come (target − lagged): what a wrong lag gets wrong
            lag_f = abs(g1) + abs(g2)
            q_u = (q_u0 + k_mod * g_u * g_u + k_lag * (lag_f / m_u) ** 2) * dt
            q_r = (q_r0 + k_mod * g_r * g_r + k_lag * (b * lag_f / i_r) ** 2) * dt
            q_eta, q_eps = q_eta * dt, q_eps * dt
            pu, pr = phi_u / m_u, phi_r / i_r
            d_u_v, d_u_r, d_u_eta, d_u_eps = pu * m * r, pu * m * v, pu * xs, pu * eta * fdif
            d_r_eps, d_r_phs, d_r_phd = pr * b * fsum, -pr * arm * xs, -pr * arm * xd
            g_side = y_act / m_v  # sway acceleration of the side force
            d_v_phs, d_v_phd = xs / m_v, xd / m_v  # × τ_v (1 − e) below
        else:
            u2, r2, eu, er = u, r, 1.0, 1.0
            tv, sway_a = self._sway_tau, self._sway_a
            q_u, q_r, q_eta, q_eps = self._q_u_walk * dt, self._q_r * dt, 0.0, 0.0
            d_u_v = d_u_r = d_u_eta = d_u_eps = d_r_eps = d_r_phs = d_r_phd = 0.0
            g_side = d_v_phs = d_v_phd = 0.0
        # sway: v' = −a·u·r − v/τ_v + side force (exact for u·r held over the step)
        ev = math.exp(-dt / tv)
        tve = tv * (1.0 - ev)
        gain = sway_a * tve  # ∂v(t+dt)/∂(−u·r)
        um, rm = 0.5 * (u + u2), 0.5 * (r + r2)
        ur = um * rm
        v2 = v * ev - gain * ur + tve * g_side
        sway_ss = sway_a * tv * ur  # the turn's steady sideslip, trusted to sway_model_error
        q_v = (self._q_sway + self._k_sway * sway_ss * sway_ss) * (1.0 - ev * ev)
        pm = psi + 0.5 * rm * dt
        sm, cm = math.sin(pm), math.cos(pm)
        vm = 0.5 * (v + v2)
        x[IX] += dt * (um * cm - vm * sm + x[ICN])
        x[IY] += dt * (um * sm + vm * cm + x[ICE])
        x[IU], x[IV], x[IR] = u2, v2, r2
        x[IPSI] = math.remainder(psi + rm * dt, TAU)
        dec = math.exp(-dt / self.noise.bias_tau[c.fix])
        x[IBN] *= dec
        x[IBE] *= dec
        F = self._F
        dsm, dcm = dt * sm, dt * cm
        F.flat[_F_IDX] = (
            dcm, -dsm, -(um * dsm + vm * dcm), dt, dsm, dcm, um * dcm - vm * dsm, dt,
            eu, d_u_v, d_u_r, d_u_eta, d_u_eps, ev, -gain * r, -gain * u,
            tve * d_v_phs, tve * d_v_phd, dt, er, d_r_eps, d_r_phs, d_r_phd, dec, dec)
        P = F.dot(c.P).dot(F.T)
        gm = self.noise.bias_sigma[c.fix] ** 2 * (1.0 - dec * dec)
        P.ravel()[:: NX + 1] += (0.0, 0.0, q_u, q_v, 0.0, q_r, self._q_bg * dt,
                                 self._q_bc * dt, self._q_c * dt, self._q_c * dt, gm, gm,
                                 q_eta, q_eps, 0.0, 0.0)
        c.steps += 1
        if not c.steps & 7:  # F P Fᵀ is symmetric to rounding: re-symmetrise now and then
            P += P.T
            P *= 0.5
        c.P = P
        c.t += dt
