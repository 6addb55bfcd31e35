"""The simulated world: vessel, disturbances, devices, on a fixed time grid.

Pure and deterministic: the caller (``drivers.sim.backend``) owns the clock
and the transports.  Time ``t_s`` is seconds since the start of the run; the
physics advances in whole steps of ``dt_s`` on the grid t_k = k · dt_s (k
integer, so no drift accumulates), and every query first brings the world up
to the last grid point ≤ t_s.  The thruster commands applied over step k are
the controller's outputs at t_k, the disturbance is the Gauss–Markov value at
t_k; both are held over the step.

Seeding: ``numpy.random.SeedSequence(seed).spawn(len(STREAMS))`` gives one
independent child stream per component, in the fixed order of
:data:`STREAMS`.  A component only ever draws from its own stream, so changing
one (a fix mode, a sentence list, disabling the disturbance) never shifts
another's draws; new components are appended to the end (a SeedSequence child
depends only on its index, so existing streams are unchanged).  One seed gives
bit-identical truth and bytes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drivers.sim.disturbance import GaussMarkov, NormalStream
from drivers.sim.params import WorldParams, start_epoch_s
from drivers.sim.sensors import SimCompass, SimGps, SimThrusterController
from drivers.sim.vessel import Vessel, VesselState

#: child random streams, by index: never reorder, only append
STREAMS = ("disturbance_surge", "disturbance_sway", "disturbance_yaw", "gps", "compass")
#: tolerance (s) when mapping a time onto the integration grid
GRID_EPS_S = 1e-9


@dataclass(frozen=True, slots=True)
class Truth:
    """A snapshot of the true state at ``t_s`` (s).

    Fields as :class:`VesselState` (NED metres, heading rad clockwise from
    north, water-relative body velocities m/s, yaw rate rad/s clockwise, lagged
    thrusts N), plus the ground velocity ``vn_mps``/``ve_mps`` (north/east m/s),
    the commands applied ``u1_cmd``/``u2_cmd`` (−100..100) and the disturbance
    held over the current step (``dist_x_n``, ``dist_y_n`` N, ``dist_n_nm`` N m,
    body frame).
    """

    t_s: float
    x_m: float
    y_m: float
    psi_rad: float
    u_mps: float
    v_mps: float
    r_rps: float
    f1_n: float
    f2_n: float
    vn_mps: float
    ve_mps: float
    u1_cmd: float
    u2_cmd: float
    dist_x_n: float
    dist_y_n: float
    dist_n_nm: float


class SimWorld:
    """Owns the vessel, its disturbances, the GPS, the compass and the thruster
    controller of one simulated run."""

    def __init__(self, params: WorldParams, seed: int) -> None:
        self.params = params
        self.seed = seed
        self.dt = params.dt_s
        self.epoch0_s = start_epoch_s(params.start_utc)
        children = np.random.SeedSequence(seed).spawn(len(STREAMS))
        rng = {name: np.random.default_rng(ss) for name, ss in zip(STREAMS, children,
                                                                     strict=True)}
        state = VesselState(x_m=params.x_m, y_m=params.y_m,
                            psi_rad=math.radians(params.heading_deg), u_mps=params.u_mps)
        self.vessel = Vessel(params.vessel, params.thrusters, params.current, state)
        d = params.disturbance
        self.disturbance: tuple[GaussMarkov, GaussMarkov, GaussMarkov] | None = None
        if d.enabled:
            self.disturbance = (
                GaussMarkov(d.surge_n, d.tau_s, NormalStream(rng["disturbance_surge"])),
                GaussMarkov(d.sway_n, d.tau_s, NormalStream(rng["disturbance_sway"])),
                GaussMarkov(d.yaw_nm, d.tau_s, NormalStream(rng["disturbance_yaw"])),
            )
        self.gps = SimGps(params.gps, (params.origin_lat_deg, params.origin_lon_deg),
                          rng["gps"])
        self.compass = SimCompass(params.compass, rng["compass"])
        self.thrusters = SimThrusterController(params.thrusters)
        self.k = 0  # steps integrated: the world is at t = k · dt

    @property
    def t_s(self) -> float:
        """Time (s) the world has been integrated to (a grid point)."""
        return self.k * self.dt

    def utc_epoch_s(self, t_s: float) -> float:
        """UTC (s since 1970) at simulation time ``t_s``."""
        return self.epoch0_s + t_s

    def advance_to(self, t_s: float) -> None:
        """Integrate whole steps up to the last grid point ≤ ``t_s`` (+1 ns);
        a time in the past is a no-op."""
        dt = self.dt
        n = math.floor((t_s + GRID_EPS_S) / dt)
        k = self.k
        if k >= n:
            return
        step = self.vessel.step
        outputs = self.thrusters.outputs
        dist = self.disturbance
        if dist is None:
            while k < n:
                u1, u2 = outputs(k * dt)
                step(dt, u1, u2)
                k += 1
        else:
            gx, gy, gn = dist
            while k < n:
                u1, u2 = outputs(k * dt)
                step(dt, u1, u2, (gx.value, gy.value, gn.value))
                gx.step(dt)
                gy.step(dt)
                gn.step(dt)
                k += 1
        self.k = k

    def truth(self) -> Truth:
        """The true state at the current grid time."""
        s = self.vessel.state
        t = self.t_s
        vn, ve = self.vessel.ground_velocity_ned()
        u1, u2 = self.thrusters.outputs(t)
        d = self.disturbance
        dx, dy, dn = (d[0].value, d[1].value, d[2].value) if d is not None else (0.0, 0.0, 0.0)
        return Truth(t, s.x_m, s.y_m, s.psi_rad, s.u_mps, s.v_mps, s.r_rps, s.f1_n, s.f2_n,
                     vn, ve, u1, u2, dx, dy, dn)

    def gps_bytes(self, t_s: float) -> bytes:
        """One GPS epoch at ``t_s`` (advances the world first)."""
        self.advance_to(t_s)
        s = self.vessel.state
        vn, ve = self.vessel.ground_velocity_ned()
        return self.gps.sentences(t_s, self.utc_epoch_s(t_s), s.x_m, s.y_m, vn, ve)

    def compass_bytes(self, t_s: float) -> bytes:
        """HDG, ROT and XDR at ``t_s`` (advances the world first; the 3-DOF model
        has no pitch or roll, so those are noise about zero)."""
        self.advance_to(t_s)
        s = self.vessel.state
        return self.compass.sentences(t_s, s.psi_rad, s.r_rps, 0.0, 0.0)

    def thruster_status_bytes(self, t_s: float) -> bytes:
        """``$PZTHS`` at ``t_s`` (advances the world first)."""
        self.advance_to(t_s)
        s = self.vessel.state
        return self.thrusters.status_sentence(t_s, s.f1_n, s.f2_n)

    def command(self, t_s: float, u1: float, u2: float) -> bool:
        """A valid ``$PZTHR`` arrived at ``t_s``: advance to ``t_s``, then apply it
        from the next step on.  False if the values were not finite (ignored)."""
        self.advance_to(t_s)
        return self.thrusters.on_command(t_s, u1, u2)

    def set_fix(self, mode: str) -> None:
        """Change the GPS fix mode mid-run."""
        self.gps.set_fix(mode)
