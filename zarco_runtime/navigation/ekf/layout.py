"""The EKF's state layout, its measurements and the filter state it copies.

State (16)
----------
======  ============  ======================================================
index   symbol        meaning
======  ============  ======================================================
0, 1    x, y          position of the centre of mass, NED (m)
2, 3    u, v          surge / sway speed *through the water*, body (m/s)
4       ψ             true heading (rad)
5       r             yaw rate (rad/s)
6       b_g           gyro (ROT) bias (rad/s): ROT = r + b_g + noise
7       b_c           compass bias (rad): compass = ψ + b_c + noise
8, 9    c_n, c_e      water current, NED (m/s)
10, 11  b_n, b_e      offset of the GPS solution (m): fix = x + b + noise
12      η             thrust/drag scale of the surge model (1: as modelled)
13      ε             thruster mismatch: F1 = (1 + ε) f1, F2 = (1 − ε) f2
14, 15  φ_s, φ_d      common and differential thruster misalignment (rad): the
                      side force φ_s (F1 + F2) + φ_d (F1 − F2)
======  ============  ======================================================

Frames and units: local NED about the configured origin (x north, y east,
metres), heading ψ clockwise from north (rad, wrapped to [−π, π]), body x
forward / y starboard, yaw rate r positive clockwise (rad/s).

The mean is a list of Python floats (scalar ``math`` for the nonlinear parts);
the covariance a numpy array.  :class:`FilterState` is everything fusing a
measurement changes: the history keeps copies of it as snapshots.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zarco_core.messages import FixQuality
from zarco_runtime.navigation.ekf_config import EkfSettings

# state indices
IX, IY, IU, IV, IPSI, IR, IBG, IBC, ICN, ICE, IBN, IBE, IETA, IEPS, IPS, IPD = range(16)
NX = 16
STATE_NAMES = ("x_m", "y_m", "u_water_mps", "v_water_mps", "psi_rad", "r_rps",
               "gyro_bias_rps", "compass_bias_rad", "current_n_mps", "current_e_mps",
               "gps_bias_n_m", "gps_bias_e_m", "thrust_scale", "thrust_mismatch",
               "misalign_common_rad", "misalign_diff_rad")

# measurement kinds
K_POS, K_VEL, K_SOG, K_COMPASS, K_TRUE_HDG, K_ROT = range(6)
KIND_NAMES = ("pos", "vel", "sog", "compass", "true_heading", "rot")
OK_KEYS = tuple(f"{k}_ok" for k in KIND_NAMES)
REJECTED_KEYS = tuple(f"{k}_rejected" for k in KIND_NAMES)
RESET_KEYS = tuple(f"resets_{k}" for k in KIND_NAMES)

TAU = math.tau
#: prior σ of states nobody has measured yet (m, m/s, rad, rad/s)
INIT_POS_SIGMA_M = 1e3
INIT_SPEED_SIGMA_MPS = 2.0
INIT_PSI_SIGMA_RAD = math.pi
INIT_R_SIGMA_RPS = 0.3
#: times of validity closer than this (s) are the same instant (they are rounded to 1 µs)
SAME_TIME_S = 1e-7

# flat indices of the diagonal and of the position and heading variances
DIAG = np.arange(NX) * (NX + 1)
PXX, PYY, PPSI = IX * (NX + 1), IY * (NX + 1), IPSI * (NX + 1)


def tov(t: float, latency: float) -> float:
    """Time of validity (s): arrival − latency, rounded to the microsecond so that
    measurements of one instant compare equal whatever the float arithmetic."""
    return round(t - latency, 6)


def row(entries: dict[int, float]) -> np.ndarray:
    """A measurement row (NX) with the given entries."""
    h = np.zeros(NX)
    for i, v in entries.items():
        h[i] = v
    return h


@dataclass(slots=True)
class Measurement:
    """One measurement in filter units: ``z1, z2`` (m, m/s or rad), variances
    ``r1, r2``, its time of validity ``tov`` (s) and, for a position, its fix type."""

    kind: int
    tov: float
    z1: float
    z2: float = 0.0
    r1: float = 0.0
    r2: float = 0.0
    fix: FixQuality = FixQuality.NONE


def kind_of(m: Measurement) -> int:
    """Sort key: the measurement kind."""
    return m.kind


class FilterState:
    """Everything fusing a measurement changes; copied as the history snapshot."""

    __slots__ = ("P", "cmd_seq", "f1", "f2", "fix", "glide", "hdg_course", "hdg_init",
                 "pos_init", "rej",
                 "steps", "t", "t_cmd", "t_hdg", "t_pos", "t_rot", "t_vel", "thr1", "thr2",
                 "vel_init", "x")

    def __init__(self) -> None:
        self.t = -math.inf
        self.x = [0.0] * NX
        self.x[IETA] = 1.0
        self.P = np.zeros((NX, NX))
        self.pos_init = False
        self.hdg_init = False
        self.hdg_course = False  # ψ from the GPS course, no heading sensor yet
        self.vel_init = False
        self.fix = FixQuality.NONE  # fix type of the last fused position
        self.t_pos = -math.inf  # time of validity of the last fused position
        self.t_vel = -math.inf
        self.t_hdg = -math.inf  # last fused heading from a sensor (compass or true)
        self.t_rot = -math.inf
        #: per measurement kind: start of the current run of gate rejections (nan: none)
        self.rej = [math.nan] * 6
        #: published-position offset after a fix upgrade: (time s, north m, east m)
        self.glide: tuple[float, float, float] | None = None
        #: thrust input: time of the last command (s), its steady thrusts f_i(U_i)
        #: and the lagged thrusts now (N, port and starboard)
        self.t_cmd = -math.inf
        self.cmd_seq = 0  # the last command taken up
        self.steps = 0  # prediction steps so far
        self.thr1 = self.thr2 = 0.0
        self.f1 = self.f2 = 0.0

    def copy(self) -> FilterState:
        c = FilterState.__new__(FilterState)
        c.t = self.t
        c.x = self.x[:]
        c.P = self.P.copy()
        c.pos_init = self.pos_init
        c.hdg_init = self.hdg_init
        c.hdg_course = self.hdg_course
        c.vel_init = self.vel_init
        c.fix = self.fix
        c.t_pos = self.t_pos
        c.t_vel = self.t_vel
        c.t_hdg = self.t_hdg
        c.t_rot = self.t_rot
        c.rej = self.rej[:]
        c.glide = self.glide
        c.t_cmd = self.t_cmd
        c.cmd_seq = self.cmd_seq
        c.steps = self.steps
        c.thr1, c.thr2, c.f1, c.f2 = self.thr1, self.thr2, self.f1, self.f2
        return c


class Counters:
    """Event counters, not counted while the history re-runs measurements."""

    __slots__ = ("counts", "replaying")

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}
        self.replaying = False

    def count(self, key: str) -> None:
        if not self.replaying:
            c = self.counts
            c[key] = c.get(key, 0) + 1


def initial_state(cfg: EkfSettings) -> FilterState:
    """The filter state before any measurement: the priors of the settings."""
    c = FilterState()
    P = c.P
    d2r = math.radians
    P[IX, IX] = P[IY, IY] = INIT_POS_SIGMA_M**2
    P[IU, IU] = INIT_SPEED_SIGMA_MPS**2
    P[IV, IV] = cfg.sway_sigma_mps**2
    P[IPSI, IPSI] = INIT_PSI_SIGMA_RAD**2
    P[IR, IR] = INIT_R_SIGMA_RPS**2
    P[IBG, IBG] = d2r(cfg.gyro_bias_sigma_dps) ** 2
    P[IBC, IBC] = d2r(cfg.compass_bias_sigma_deg) ** 2
    if cfg.estimate_current:
        P[ICN, ICN] = P[ICE, ICE] = cfg.current_sigma_mps**2
    P[IBN, IBN] = P[IBE, IBE] = cfg.bias_single_m**2
    P[IETA, IETA] = cfg.thrust_scale_sigma**2
    P[IEPS, IEPS] = cfg.yaw_mismatch_sigma**2
    P[IPD, IPD] = d2r(cfg.misalignment_sigma_deg) ** 2
    P[IPS, IPS] = d2r(cfg.misalignment_common_sigma_deg) ** 2
    return c
