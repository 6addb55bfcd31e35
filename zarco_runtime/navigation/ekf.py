"""Navigation EKF: RTK GPS, compass, true heading, gyro and the thruster commands → NavState.

A drop-in replacement for :class:`~zarco_runtime.navigation.simple.SimpleNavigator`
(same ``on_fix``, ``on_velocity``, ``on_heading``, ``on_rate``, ``has_gyro``,
``state``), plus ``on_gst``, ``on_command`` (the thruster commands, with the
vessel model given by :meth:`EkfNavigator.set_vessel`) and
:meth:`EkfNavigator.status`.

Frames and units (DESIGN.md §3): local NED about the configured origin (x
north, y east, metres), heading ψ clockwise from north (rad, wrapped to
[−π, π]), body x forward / y starboard, yaw rate r positive clockwise (rad/s).

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

The ground velocity is ``R(ψ)·(u, v) + c`` (DESIGN.md §4 kinematics); NavState
reports it as (vn, ve), and as (u, v) rotated into the body frame (ground
relative, as the first estimator did), with the covariance of (x, y, vn, ve, ψ)
obtained through that Jacobian.

Process model: the vessel model driven by the thrusters
-------------------------------------------------------
While thruster commands arrive (``ThrusterCommand`` on the bus, no older than
``command_timeout_s``; ``thrust_model`` on, vessel model set) they are the
prediction's input: each command U_i goes through the thruster's calibrated map
f_i (the tables control allocates with) and the first-order thrust lag to a
thrust F_i, and the vessel model of DESIGN.md §4 (the runtime's ``[vessel]``)
gives the accelerations::

    (m − X_u') u' = η·(F1 + F2) + X_u u + X_|u|u |u| u + m v r
    (Iz − N_r') r' = N_r r + N_|r|r |r| r + b·(F1 − F2)
    F1 = (1 + ε)·f1(U1),  F2 = (1 − ε)·f2(U2)   (lagged)
    v' = −a·u·r − v/τ_v      (a = m/(m − Y_v'), τ_v = (m − Y_v')/(−Y_v))
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
the surge thrust too.  What is left
of the model's error is process noise that grows with the net acceleration
(``model_accel_error`` of it, over ``model_error_tau_s``: mass and inertia
±25 %) and, in yaw, with the size of the moments (the damping, and the
differential thrust the controller balances), and with the thrust still to
come after a command change (``lag_error``: a lag of 0.1–0.3 s against the
model's), so the filter is sure of the model at steady speed on a line and not
while the boat accelerates or turns: a model error then goes to the speed and
the yaw rate, which the GPS and the gyro measure, and not to the slow states
(biases, current).  A turn's sway is trusted to ``sway_model_error``.

Start from rest: with the thrust model and no thrust applied yet, a first GPS
velocity slower than ``rest_max_speed_mps`` is taken as the boat drifting with
the water (u = 0 ± ``rest_speed_sigma_mps``): it measures the current, which
then tells the compass bias from the crab as the boat speeds up.

Gusts and chop are ``surge_noise_mps`` and ``yaw_accel_walk_dps``.  Each step
integrates the mean with the exponential Euler method (exact for the linear
damping; the surge time constant is 0.2–0.3 s at speed, shorter than a step is
long) and the thrust lag exactly.

Without commands (another pilot, a replayed capture, ``thrust_model`` off) the
surge speed u is a slow random walk (``accel_walk_mps``) and r a random walk
(``yaw_accel_walk_dps``); η and ε are then frozen.

The sway model ties the heading to the GPS velocity and makes the compass
bias, the gyro bias and the current observable; the GPS offset b is a
first-order Gauss–Markov process whose σ and τ depend on the fix type (RTK
fixed: millimetres; single point: 1.5 m over minutes, DESIGN.md §4).

Measurements, each at its time of validity (arrival − configured latency):
GPS position (σ from GST when fresh, else from the fix type), GPS velocity
(SOG/COG as N/E components; SOG alone from a VTG without course), true heading
(HDT/THS from a dual-antenna source, unbiased), compass heading (magnetic +
variation, biased), ROT (biased).  Thruster commands take their place in the
same time line.

Compass bias vs current (and crab)
----------------------------------
On a straight leg at constant speed a compass bias b_c and a cross-track
current c⊥ show the same thing, a constant angle between heading and course:
only U·b_c + c⊥ is seen.  What separates them is a change of the boat's
velocity through the water that the current does not share: a turn (on
headings ψ and ψ + 180° the current's share changes sign and the bias's does
not), and a change of speed along the heading — the acceleration from rest at
the start of a mission, which the thrust model predicts, shows the heading
directly.  The filter keeps both states with honest priors (b_c:
``compass_bias_sigma_deg``, 3°; current: ``current_sigma_mps``, 0.3 m/s).
With ``estimate_current = false`` the bias alone explains any crab: best
without current, wrong with one.  A true heading (HDT/THS) makes the bias
directly observable.  A constant sideways thrust (thrusters misaligned the
same way) cannot be told from a compass bias with these sensors: it ends up in
b_c (the heading then is the direction the boat moves through the water, which
is what line tracking needs).

EKF rather than UKF
-------------------
The nonlinearities are mild and smooth (rotations by ψ in the kinematics and
the velocity measurement, the products u·r, |u|·u in the model), all
measurements but the velocity are linear, and the state is observed at
10–20 Hz, so the linearisation error between updates is tiny.  A UKF needs
2n+1 = 29 sigma points per predict and per update, some twenty times the
arithmetic of the EKF.  Heading wrap-around is handled explicitly (innovations
wrapped to (−π, π]), as a UKF would need too.

Representation and cost
-----------------------
The mean is a list of Python floats (scalar ``math`` for the nonlinear parts);
the 14×14 covariance is a numpy array, and every product is one numpy call on
preallocated Jacobians (``F``, the velocity and output rows are filled in place
through precomputed flat indices, never allocated per step).  Heading and ROT
are scalar updates; GPS position and velocity are 2-D updates (2×2 inverse by
hand) so that their gate is the joint χ²₂.  The update is P − K·(PHᵀ)ᵀ; P is
symmetrised at every prediction.  Measurements that share a time of validity
(an epoch's GGA and RMC, a compass epoch's HDG and ROT) share one prediction and
one history snapshot.  ``state(t)`` at the filter's own time does not predict.

Manoeuvres without the thrust model: a GPS velocity beyond its gate but within
``max_accel_mps2`` of the last one is taken as a manoeuvre (the speed and
position variances are opened by the innovation and it is fused), not as a
fault; so is an RTK position beyond its gate when no GPS velocity comes
(GGA-only receivers).

Late measurements
-----------------
Every fused measurement is logged for ``history_s`` seconds, with a snapshot
of the filter taken before the first measurement of each time of validity.  A
measurement whose time of validity is before the filter time rolls the filter
back to the snapshot before the first logged measurement that is later than
it, fuses it, and re-fuses the later ones: the result is what in-order arrival
would have given (tested).  Older than the history: dropped and counted
(``late_dropped``).

Gating and faults
-----------------
* NIS gates (χ²₁ / χ²₂ at 99.9 %) per measurement; a sensor rejected
  continuously for ``reset_after_s`` re-initialises its part of the state.
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
* Compass (and any heading source, by message source): a reading repeated
  ``frozen_count`` times while the gyro turned more than ``frozen_turn_deg`` is
  *frozen*; steps not explained by the gyro larger than ``jump_deg``,
  ``jump_count`` times in ``jump_window_s``, mean *jumping*.  Either flag
  rejects that source's readings until it behaves again; both are reported by
  :meth:`EkfNavigator.status`.

Outages: without GPS the filter dead-reckons (heading from compass and gyro,
speed through the water from the model or held, sway model, current) with
growing covariance; ``pos_valid`` goes false after ``dr_max_s`` without a fused
fix or when the position σ (worse axis) exceeds ``pos_sigma_max_m``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from zarco_core.angles import wrap
from zarco_core.geodesy import LocalFrame
from zarco_core.localgeo import FastLocalFrame
from zarco_core.messages import (
    FixQuality,
    GpsErrorStats,
    GpsFix,
    GpsVelocity,
    Heading,
    NavState,
    RateOfTurn,
    ThrusterCommand,
)
from zarco_core.thruster_map import ThrusterMap
from zarco_core.vessel import VesselModel
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
#: 1σ of a heading initialised from the GPS course (no heading sensor), rad
COURSE_INIT_SIGMA_RAD = math.radians(10.0)
#: sentences that carry a true heading measured by a dual-antenna receiver
TRUE_HEADING_SENTENCES = frozenset({"HDT", "THS"})
#: a GpsVelocity from VTG (or a GpsFix from RMC) is ignored while RMC velocities
#: (GGA fixes) arrived within this (s): one measurement per epoch
PREFERRED_WITHIN_S = 2.0
#: most prediction sub-steps for one interval (longer intervals take longer steps)
MAX_SUBSTEPS = 200
#: thrust (N, both thrusters) below which the boat counts as not driven (at rest in the water)
REST_THRUST_N = 0.5
#: times of validity closer than this (s) are the same instant (they are rounded to 1 µs)
SAME_TIME_S = 1e-7

# entries of F (beyond the identity) and of the output Jacobians filled per step
_F_IDX = np.ravel_multi_index(np.array([
    (IX, IU), (IX, IV), (IX, IPSI), (IX, ICN), (IY, IU), (IY, IV), (IY, IPSI), (IY, ICE),
    (IU, IU), (IU, IV), (IU, IR), (IU, IETA), (IU, IEPS), (IV, IV), (IV, IU), (IV, IR),
    (IV, IPS), (IV, IPD), (IPSI, IR), (IR, IR), (IR, IEPS), (IR, IPS), (IR, IPD),
    (IBN, IBN), (IBE, IBE)]).T, (NX, NX))
_H_VEL_IDX = np.ravel_multi_index(np.array([
    (0, IU), (0, IV), (0, IPSI), (1, IU), (1, IV), (1, IPSI)]).T, (2, NX))
_J_IDX = np.ravel_multi_index(np.array([
    (2, IU), (2, IV), (2, IPSI), (3, IU), (3, IV), (3, IPSI)]).T, (5, NX))
_DIAG = np.arange(NX) * (NX + 1)
_PXX, _PYY, _PPSI = IX * (NX + 1), IY * (NX + 1), IPSI * (NX + 1)


def _kind(m: _Meas) -> int:
    return m.kind


def _tov(t: float, latency: float) -> float:
    """Time of validity (s): arrival − latency, rounded to the microsecond so that
    measurements of one instant compare equal whatever the float arithmetic."""
    return round(t - latency, 6)


@dataclass(slots=True)
class _Meas:
    """One measurement in filter units: ``z1, z2`` (m, m/s or rad; N for a command's
    thrusts), variances ``r1, r2``."""

    kind: int
    tov: float
    z1: float
    z2: float = 0.0
    r1: float = 0.0
    r2: float = 0.0
    fix: FixQuality = FixQuality.NONE


class _Core:
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

    def copy(self) -> _Core:
        c = _Core.__new__(_Core)
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


@dataclass(frozen=True, slots=True)
class _Model:
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
    def of(cls, v: VesselModel, n_rr: float, port: ThrusterMap, stbd: ThrusterMap) -> _Model:
        m_v = v.m_kg - v.y_vdot
        return cls(v.m_kg, v.m_kg - v.x_udot, m_v, v.iz_kgm2 - v.n_rdot, v.x_u, v.x_uu,
                   v.n_r, n_rr, v.b_m, v.l_m, v.thruster_lag_s, v.m_kg / m_v,
                   m_v / max(1e-9, -v.y_v), port, stbd)


@dataclass(slots=True)
class _CompassMonitor:
    """Frozen / jumping detection for one compass (message source)."""

    last_raw: float = math.nan
    repeats: int = 0
    psi_at_change: float = math.nan
    frozen: bool = False
    last_z: float = math.nan
    last_psi: float = math.nan
    last_t: float = -math.inf
    jumps: deque[float] = field(default_factory=deque)
    jumping: bool = False


@dataclass(slots=True)
class EkfStatus:
    """Health of the estimator at ``t`` (s), for the supervisor and telemetry.

    ``gps_age_s``: time since the last fused GPS position (inf: never);
    ``pos_sigma_m`` / ``heading_sigma_deg``: 1σ of the estimate (worse position
    axis); ``compass_frozen`` / ``compass_jumping``: a compass is being
    rejected by its fault detector (sources in ``compass_faults``);
    ``counters``: ``<kind>_ok`` / ``<kind>_rejected`` per measurement kind
    (pos, vel, sog, compass, true_heading, rot), ``late_dropped``, ``replays``,
    ``fix_changes``, ``resets_<kind>``, ``compass_frozen`` / ``compass_jumping``
    (events), ``compass_rejected_fault``, ``vel_manoeuvre``, ``pos_manoeuvre``,
    ``heading_from_course``, ``commands``.  ``state`` is the full mean (see
    :data:`STATE_NAMES`), ``sigma`` its 1σ.  ``thrust_model``: the thruster
    commands are a prediction input at ``t``.
    """

    t: float
    pos_valid: bool
    heading_valid: bool
    gps_age_s: float
    pos_sigma_m: float
    heading_sigma_deg: float
    compass_frozen: bool
    compass_jumping: bool
    compass_faults: tuple[str, ...]
    fix: FixQuality
    counters: dict[str, int]
    state: dict[str, float]
    sigma: dict[str, float]
    #: what the published position still has to glide after a fix upgrade (m)
    glide_m: float = 0.0
    thrust_model: bool = False


class EkfNavigator:
    """GPS + GST + true heading + compass + gyro (+ thruster commands) → NavState,
    by an EKF in local NED.

    ``frame`` is the local NED frame (its origin is used through the scalar
    :class:`~zarco_core.localgeo.FastLocalFrame`);
    ``variation_deg`` (east positive) is added to headings that arrive magnetic
    (``Heading.true`` false), as :class:`SimpleNavigator` does.  The thrust
    model needs :meth:`set_vessel` (the navigation task does it from the
    runtime's ``[vessel]`` and ``[thrusters]``).
    """

    def __init__(self, cfg: EkfSettings, frame: LocalFrame,
                 variation_deg: float | None = None) -> None:
        self.cfg = cfg
        self.frame = frame
        self.geo = FastLocalFrame(frame.lat0, frame.lon0, frame.h0)
        self.variation_deg = variation_deg
        self.min_fix = FixQuality.from_label(cfg.min_fix)
        d2r = math.radians
        self._sigma_white = {
            FixQuality.RTK_FIXED: cfg.sigma_rtk_fixed_m,
            FixQuality.RTK_FLOAT: cfg.sigma_rtk_float_m,
            FixQuality.DGPS: cfg.sigma_dgps_m, FixQuality.SINGLE: cfg.sigma_single_m,
        }
        self._bias_sigma = {
            FixQuality.RTK_FIXED: cfg.bias_rtk_fixed_m,
            FixQuality.RTK_FLOAT: cfg.bias_rtk_float_m,
            FixQuality.DGPS: cfg.bias_dgps_m, FixQuality.SINGLE: cfg.bias_single_m,
            FixQuality.NONE: cfg.bias_single_m,
        }
        self._bias_tau = {
            FixQuality.RTK_FIXED: cfg.bias_tau_rtk_fixed_s,
            FixQuality.RTK_FLOAT: cfg.bias_tau_rtk_float_s,
            FixQuality.DGPS: cfg.bias_tau_dgps_s, FixQuality.SINGLE: cfg.bias_tau_single_s,
            FixQuality.NONE: cfg.bias_tau_single_s,
        }
        self._r_vel = cfg.sigma_vel_mps**2
        self._r_compass = d2r(cfg.sigma_compass_deg) ** 2
        self._r_true = d2r(cfg.sigma_true_heading_deg) ** 2
        self._r_rot = d2r(cfg.sigma_rot_dps) ** 2
        self._true_sources = frozenset(cfg.true_heading_sources)
        self._lever = (cfg.lever_x_m, cfg.lever_y_m)
        self._has_lever = cfg.lever_x_m != 0.0 or cfg.lever_y_m != 0.0
        # process noise densities (variance per second); the sway and the GPS
        # offset are Gauss–Markov and handled in _step
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
        self._model: _Model | None = None
        self._mc: tuple[float, ...] | None = None  # its constants, for the prediction
        self._cmd_timeout = cfg.command_timeout_s
        self._sway_tau, self._sway_a = cfg.sway_tau_s, cfg.sway_coupling
        self._q_sway = cfg.sway_sigma_mps**2
        self._F = np.eye(NX)
        self._J = np.zeros((5, NX))
        self._J[0, IX] = self._J[1, IY] = self._J[4, IPSI] = 1.0
        self._J[2, ICN] = self._J[3, ICE] = 1.0
        self._h_compass = _row({IPSI: 1.0, IBC: 1.0})
        self._h_true = _row({IPSI: 1.0})
        self._h_rot = _row({IR: 1.0, IBG: 1.0})
        self._h_pos = np.zeros((2, NX))
        self._h_pos[0, IX] = self._h_pos[0, IBN] = 1.0
        self._h_pos[1, IY] = self._h_pos[1, IBE] = 1.0
        self._h_vel = np.zeros((2, NX))
        self._h_vel[0, ICN] = self._h_vel[1, ICE] = 1.0
        self._gates = (cfg.gate_2d, cfg.gate_2d, cfg.gate_1d, cfg.gate_1d, cfg.gate_1d,
                       cfg.gate_1d)
        self._frozen_turn = d2r(cfg.frozen_turn_deg)
        self._jump = d2r(cfg.jump_deg)
        self._pos_var_max = cfg.pos_sigma_max_m**2
        #: commands kept: the history's span at 100 Hz, and at least 200
        self._cmds_max = max(200, int(cfg.history_s * 100.0) * 2)
        self._hdg_var_max = d2r(cfg.heading_sigma_max_deg) ** 2
        self.reset()

    def set_vessel(self, vessel: VesselModel, port: ThrusterMap, stbd: ThrusterMap) -> None:
        """The vessel model and the thrusters' maps f (command → N) that turn thruster
        commands into the prediction's input (see the module doc).  Without it, or with
        ``thrust_model`` off, commands are ignored."""
        cfg = self.cfg
        self._model = (_Model.of(vessel, cfg.yaw_damping_quad, port, stbd)
                       if cfg.thrust_model else None)
        md = self._model
        self._mc = None if md is None else (
            md.m, md.m_u, md.m_v, md.i_r, md.x_u, md.x_uu, md.n_r, md.n_rr, md.b, md.arm,
            md.lag_s, md.sway_a, md.sway_tau_s, self._k_model, self._k_lag, self._q_u_model,
            self._q_r, self._q_eta, self._q_eps)

    # ------------------------------------------------------------ set-up
    def reset(self) -> None:
        """Forget everything (state, history, detectors, counters)."""
        cfg = self.cfg
        c = _Core()
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
        self._c = c
        #: (time of validity, snapshot before it or None within a group of equal
        #: times of validity, measurement)
        self._hist: deque[tuple[float, _Core | None, list[_Meas]]] = deque()
        #: measurements of one time of validity not yet fused
        self._pending: list[_Meas] = []
        #: thruster commands (sequence number, time s, steady thrusts f1(U1), f2(U2) N)
        self._cmds: list[tuple[int, float, float, float]] = []
        self._cmd_seq = 0
        self._replaying = False
        self.fix = FixQuality.NONE  # last fix quality received (any), for NavState
        self.lat = math.nan
        self.lon = math.nan
        self._fix_key: tuple[str, float] | None = None
        self._t_gga = -math.inf
        self._t_rmc_vel = -math.inf
        self._gst: tuple[float, float, float, FixQuality] | None = None  # t, σn, σe, fix
        self._t_rot_rx = -math.inf
        self._heading_sensor_seen = False
        self._compass: dict[str, _CompassMonitor] = {}
        self._counters: dict[str, int] = {}

    @property
    def counters(self) -> dict[str, int]:
        """Event counters (see :class:`EkfStatus`), with every measurement received fused."""
        self._flush()
        return self._counters

    def _count(self, key: str) -> None:
        if not self._replaying:
            c = self._counters
            c[key] = c.get(key, 0) + 1

    # ------------------------------------------------------ message input
    def handler(self, m: object) -> Callable[[Any], object] | None:
        """The ``on_*`` method that takes message ``m`` (None: a message it does not use)."""
        if isinstance(m, GpsFix):
            return self.on_fix
        if isinstance(m, GpsVelocity):
            return self.on_velocity
        if isinstance(m, GpsErrorStats):
            return self.on_gst
        if isinstance(m, Heading):
            return self.on_heading
        if isinstance(m, RateOfTurn):
            return self.on_rate
        if isinstance(m, ThrusterCommand):
            return self.on_command
        return None

    def on_fix(self, m: GpsFix) -> bool:
        """A GPS position (GGA, or RMC when no GGA comes): one per receiver epoch.
        Returns whether it was taken (False: another sentence of the epoch carries it)."""
        cfg = self.cfg
        if m.sentence == "GGA":
            self._t_gga = m.t
        elif m.t - self._t_gga < PREFERRED_WITHIN_S:
            return False  # the GGA of this epoch carries it, with the RTK quality
        self.fix = m.fix
        if m.lat_deg is None or m.lon_deg is None or m.fix is FixQuality.NONE:
            return True
        if m.fix < self.min_fix:
            self._count("pos_below_min_fix")
            return True
        if not (math.isfinite(m.lat_deg) and math.isfinite(m.lon_deg)):
            self._count("pos_invalid")
            return True
        if m.utc_s is not None:
            key = (m.sentence, m.utc_s)
            if key == self._fix_key:
                return False  # the same epoch again
            self._fix_key = key
        self.lat, self.lon = m.lat_deg, m.lon_deg
        n, e = self.geo.to_ned(m.lat_deg, m.lon_deg)
        r1 = r2 = self._sigma_white.get(m.fix, self.cfg.sigma_single_m) ** 2
        g = self._gst
        if g is not None and m.t - g[0] <= self.cfg.gst_max_age_s and g[3] == m.fix:
            sb2 = self._bias_sigma[m.fix] ** 2
            floor2 = self.cfg.gst_floor_m**2
            r1 = max(floor2, g[1] * g[1] - sb2)
            r2 = max(floor2, g[2] * g[2] - sb2)
        self._process(_Meas(K_POS, _tov(m.t, cfg.gps_latency_s), n, e, r1, r2, m.fix))
        return True

    def on_gst(self, m: GpsErrorStats) -> None:
        """GST error statistics: per-axis 1σ (m), used for the next fixes of the same type.

        GST's σ is the receiver's total error; the filter's slowly varying
        offset state takes ``bias_*_m`` of it, the rest is white noise."""
        s_n, s_e = m.std_lat_m, m.std_lon_m
        if s_n is None or s_e is None or not (math.isfinite(s_n) and math.isfinite(s_e)):
            return
        self._gst = (m.t, s_n, s_e, self.fix)

    def on_velocity(self, m: GpsVelocity) -> None:
        """GPS speed and course over ground (RMC preferred over VTG)."""
        if m.sentence == "RMC":
            self._t_rmc_vel = m.t
        elif m.t - self._t_rmc_vel < PREFERRED_WITHIN_S:
            return
        sog = m.sog_mps
        if not math.isfinite(sog):
            self._count("vel_invalid")
            return
        tov = _tov(m.t, self.cfg.gps_latency_s)
        if m.cog_rad is None or not math.isfinite(m.cog_rad):
            self._process(_Meas(K_SOG, tov, sog, 0.0, self._r_vel))
            return
        self._process(_Meas(K_VEL, tov, sog * math.cos(m.cog_rad), sog * math.sin(m.cog_rad),
                            self._r_vel, self._r_vel))

    def on_heading(self, m: Heading) -> None:
        """A heading: true (HDT/THS from a ``true_heading_sources`` device) or compass."""
        cfg = self.cfg
        z = m.heading_rad
        if not m.true and self.variation_deg is not None:
            z += math.radians(self.variation_deg)
        if not math.isfinite(z):
            self._count("heading_invalid")
            return
        z = wrap(z)
        is_true = (m.true and m.sentence in TRUE_HEADING_SENTENCES
                   and m.source in self._true_sources)
        if is_true:
            meas = _Meas(K_TRUE_HDG, _tov(m.t, cfg.gps_latency_s), z, 0.0, self._r_true)
        else:
            meas = _Meas(K_COMPASS, _tov(m.t, cfg.compass_latency_s), z, 0.0, self._r_compass)
        if not self._compass_ok(m, z, meas.tov):
            return
        self._heading_sensor_seen = True
        self._process(meas)

    def on_rate(self, m: RateOfTurn) -> None:
        """Rate of turn (rad/s, clockwise), biased."""
        if not math.isfinite(m.rate_rps):
            self._count("rot_invalid")
            return
        self._t_rot_rx = m.t
        self._process(_Meas(K_ROT, _tov(m.t, self.cfg.gyro_latency_s), m.rate_rps, 0.0,
                            self._r_rot))

    def on_command(self, m: ThrusterCommand) -> None:
        """A thruster command (−100..100, port and starboard) as control sent it at
        ``m.t``: from then on the prediction's input (ignored without a vessel model)."""
        mdl = self._model
        if mdl is None:
            return
        u1 = m.u1 if math.isfinite(m.u1) else 0.0
        u2 = m.u2 if math.isfinite(m.u2) else 0.0
        self._count("commands")
        cmds = self._cmds
        self._cmd_seq += 1
        cmds.append((self._cmd_seq, round(m.t, 6), mdl.port.forward(u1), mdl.stbd.forward(u2)))
        if len(cmds) > self._cmds_max:  # older than any snapshot in the history
            del cmds[: len(cmds) - self._cmds_max // 2]

    def has_gyro(self, t: float) -> bool:
        """True while yaw-rate measurements are arriving."""
        return t - self._t_rot_rx < self.cfg.sensor_timeout_s

    def thrust_model_active(self, t: float) -> bool:
        """True while the thruster commands are a prediction input (at time ``t``, s)."""
        cmds = self._cmds
        return (self._model is not None and bool(cmds)
                and t - cmds[-1][1] <= self.cfg.command_timeout_s)

    # -------------------------------------------------- compass monitor
    def _compass_ok(self, m: Heading, z: float, tov: float) -> bool:
        """Frozen / jumping detection of a heading source (a compass, or a true
        heading: a receiver can freeze too) at arrival; False: reject this reading."""
        cfg = self.cfg
        mon = self._compass.get(m.source)
        if mon is None:
            mon = self._compass[m.source] = _CompassMonitor()
        c = self._c
        psi = wrap(c.x[IPSI] + c.x[IR] * (tov - c.t)) if c.hdg_init else math.nan
        # frozen: the same raw value again and again while the gyro says we turn
        if m.raw_deg == mon.last_raw:
            mon.repeats += 1
            if (not mon.frozen and mon.repeats + 1 >= cfg.frozen_count and self.has_gyro(m.t)
                    and abs(wrap(psi - mon.psi_at_change)) > self._frozen_turn):
                mon.frozen = True
                self._count("compass_frozen")
        else:
            mon.last_raw = m.raw_deg
            mon.repeats = 0
            mon.psi_at_change = psi
            mon.frozen = False
        # jumping: steps the gyro does not explain
        if tov - mon.last_t < 1.0 and math.isfinite(psi) and math.isfinite(mon.last_psi):
            step = wrap((z - mon.last_z) - (psi - mon.last_psi))
            if abs(step) > self._jump:
                mon.jumps.append(tov)
        mon.last_z, mon.last_psi, mon.last_t = z, psi, tov
        jumps = mon.jumps
        while jumps and jumps[0] < tov - cfg.jump_window_s:
            jumps.popleft()
        if not mon.jumping and len(jumps) >= cfg.jump_count:
            mon.jumping = True
            self._count("compass_jumping")
        elif mon.jumping and (not jumps or tov - jumps[-1] > cfg.jump_clear_s):
            mon.jumping = False
        if mon.frozen or mon.jumping:
            self._count("compass_rejected_fault")
            return False
        return True

    # ------------------------------------------------- history / replay
    def _process(self, m: _Meas) -> None:
        """Fuse ``m`` at its time of validity, re-running later ones if it is late.

        Measurements of one time of validity are collected and fused together when
        the next time of validity (or a read of the state) comes: one prediction,
        one history snapshot and, for the plain ones, one joint update."""
        pend = self._pending
        if pend:
            if m.tov == pend[0].tov:
                pend.append(m)
                return
            self._flush()
        c = self._c
        hist = self._hist
        if m.tov > c.t or (m.tov == c.t and not (hist and hist[-1][0] == m.tov)):
            self._pending.append(m)
            return
        # late, or of an instant already fused: re-run from before that instant
        first = hist[0][1] if hist else None
        if first is None or m.tov < first.t:
            self._count("late_dropped")
            return
        popped: list[tuple[float, _Core | None, list[_Meas]]] = []
        while hist and hist[-1][0] >= m.tov:
            popped.append(hist.pop())
        self._count("replays")
        snap = popped[-1][1]  # the first of its time of validity: it has a snapshot
        assert snap is not None
        self._c = snap
        # m joins the measurements of its own time of validity, as if it had come in time
        group = [m]
        while popped and popped[-1][0] == m.tov:
            group += popped.pop()[2]
        was = self._replaying
        self._replaying = True
        try:
            self._apply_logged(group)
            for _tov, _snap, later in reversed(popped):
                self._apply_logged(later)
        finally:
            self._replaying = was

    def _flush(self) -> None:
        """Fuse the measurements waiting for their time of validity to end."""
        if self._pending:
            group, self._pending = self._pending, []
            self._apply_logged(group)

    def _apply_logged(self, group: list[_Meas]) -> None:
        hist = self._hist
        tov = group[0].tov
        snap = None if hist and hist[-1][0] == tov else self._c.copy()
        self._apply(group)
        hist.append((tov, snap, group))
        horizon = self._c.t - self.cfg.history_s
        while len(hist) > 1 and hist[0][0] < horizon:
            hist.popleft()
            while hist and hist[0][1] is None:  # the rest of that time of validity
                hist.popleft()

    def _apply(self, group: list[_Meas]) -> None:
        """Fuse one time of validity's measurements, in an order that does not
        depend on their arrival (a replay gives what in-order arrival gives)."""
        c = self._c
        self._predict(c, group[0].tov)
        if len(group) > 1:
            group.sort(key=_kind)
            if self._fuse_joint(c, group):
                return
        for m in group:
            self._fuse(c, m)

    def _fuse(self, c: _Core, m: _Meas) -> None:
        kind = m.kind
        if kind == K_POS:
            self._fuse_pos(c, m)
        elif kind in (K_VEL, K_SOG):
            self._fuse_vel(c, m)
        elif kind == K_ROT:
            self._fuse_rot(c, m)
        else:
            self._fuse_heading(c, m)

    def _fuse_joint(self, c: _Core, group: list[_Meas]) -> bool:
        """One joint update of a group's plain measurements (GPS velocity, heading,
        ROT: no initialisation or fault handling due), each block within its own
        gate; the rest (and any block beyond its gate) is fused alone, afterwards.
        False: nothing joint to do (the caller fuses the group one by one)."""
        rows: list[np.ndarray] = []
        nus: list[float] = []
        rs: list[float] = []
        blocks: list[tuple[_Meas, int]] = []  # measurement, its first row
        rest: list[_Meas] = []
        x = c.x
        for m in group:
            k = m.kind
            if k == K_VEL and c.hdg_init and c.vel_init:
                vn, ve, H = self._ground_velocity(x)
                blocks.append((m, len(nus)))
                rows += (H[0], H[1])
                nus += (m.z1 - vn, m.z2 - ve)
                rs += (m.r1, m.r2)
            elif k in (K_COMPASS, K_TRUE_HDG) and c.hdg_init and not c.hdg_course:
                compass = k == K_COMPASS
                blocks.append((m, len(nus)))
                rows.append(self._h_compass if compass else self._h_true)
                nus.append(wrap(m.z1 - x[IPSI] - (x[IBC] if compass else 0.0)))
                rs.append(m.r1)
            elif k == K_ROT:
                blocks.append((m, len(nus)))
                rows.append(self._h_rot)
                nus.append(m.z1 - (x[IR] + x[IBG]))
                rs.append(m.r1)
            else:
                rest.append(m)
        n = len(nus)
        if n < 2:
            return False
        H = np.array(rows)
        P = c.P
        pht = P.dot(H.T)
        S = H.dot(pht)
        S.flat[:: n + 1] += rs
        sl = S.tolist()
        keep: list[int] = []
        for m, i in blocks:
            if m.kind == K_VEL:
                a, b, d = sl[i][i], sl[i][i + 1], sl[i + 1][i + 1]
                det = a * d - b * b
                n1, n2 = nus[i], nus[i + 1]
                ok = det > 0.0 and (n1 * (d * n1 - b * n2) + n2 * (a * n2 - b * n1)) <= (
                    self._gates[K_VEL] * det)
                if ok:
                    keep += (i, i + 1)
            else:
                ok = nus[i] * nus[i] <= self._gates[m.kind] * sl[i][i]
                if ok:
                    keep.append(i)
            if not ok:
                rest.append(m)
        if keep:
            if len(keep) < n:
                sl = [[sl[i][j] for j in keep] for i in keep]
                pht = pht[:, keep]
                nus = [nus[i] for i in keep]
            K = pht.dot(np.array(_spd_inverse(sl)))
            x[:] = [a_ + b_ for a_, b_ in zip(x, K.dot(np.array(nus)).tolist(), strict=True)]
            x[IPSI] = wrap(x[IPSI])
            P -= K.dot(pht.T)
            for m, _i in blocks:
                if m not in rest:
                    self._joint_accepted(c, m)
        for m in rest:
            self._fuse(c, m)
        return True

    def _joint_accepted(self, c: _Core, m: _Meas) -> None:
        k = m.kind
        self._accepted(c, k)
        if k == K_VEL:
            c.t_vel = m.tov
        elif k == K_ROT:
            c.t_rot = m.tov
        else:
            c.t_hdg = m.tov

    # ------------------------------------------------------- prediction
    def _predict(self, c: _Core, t: float) -> None:
        """Propagate ``c`` to time ``t`` (s), taking up the thruster commands on the way."""
        cmds = self._cmds
        if cmds and cmds[-1][0] > c.cmd_seq:
            for k in range(max(0, len(cmds) - (cmds[-1][0] - c.cmd_seq)), len(cmds)):
                seq, tc, thr1, thr2 = cmds[k]
                if seq <= c.cmd_seq:
                    continue
                if tc > t:
                    break
                self._predict_to(c, tc)
                c.thr1, c.thr2, c.t_cmd, c.cmd_seq = thr1, thr2, tc, seq
        self._predict_to(c, t)

    def _predict_to(self, c: _Core, t: float) -> None:
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
            self._step(c, dt)
        c.t = t

    def _step(self, c: _Core, dt: float) -> None:
        """One prediction step of ``dt`` seconds from ``c.t`` (advances ``c.t``)."""
        x = c.x
        u, v, psi, r = x[IU], x[IV], x[IPSI], x[IR]
        mc = self._mc
        if mc is not None and c.t - c.t_cmd <= self._cmd_timeout:
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
        dec = math.exp(-dt / self._bias_tau[c.fix])
        x[IBN] *= dec
        x[IBE] *= dec
        F = self._F
        dsm, dcm = dt * sm, dt * cm
        F.flat[_F_IDX] = (
            dcm, -dsm, -(um * dsm + vm * dcm), dt, dsm, dcm, um * dcm - vm * dsm, dt,
            eu, d_u_v, d_u_r, d_u_eta, d_u_eps, ev, -gain * r, -gain * u,
            tve * d_v_phs, tve * d_v_phd, dt, er, d_r_eps, d_r_phs, d_r_phd, dec, dec)
        P = F.dot(c.P).dot(F.T)
        gm = self._bias_sigma[c.fix] ** 2 * (1.0 - dec * dec)
        P.ravel()[:: NX + 1] += (0.0, 0.0, q_u, q_v, 0.0, q_r, self._q_bg * dt,
                                 self._q_bc * dt, self._q_c * dt, self._q_c * dt, gm, gm,
                                 q_eta, q_eps, 0.0, 0.0)
        c.steps += 1
        if not c.steps & 7:  # F P Fᵀ is symmetric to rounding: re-symmetrise now and then
            P += P.T
            P *= 0.5
        c.P = P
        c.t += dt

    # ----------------------------------------------------------- updates
    def _update1(self, c: _Core, h: np.ndarray, nu: float, r: float, gate: float) -> bool:
        """Scalar update with row ``h``, innovation ``nu``, variance ``r``; False if gated."""
        P = c.P
        pht = P.dot(h)
        s = h.dot(pht).item() + r
        if nu * nu > gate * s:
            return False
        k = pht * (1.0 / s)
        x = c.x
        x[:] = [a + b for a, b in zip(x, (k * nu).tolist(), strict=True)]
        x[IPSI] = wrap(x[IPSI])
        P -= np.multiply.outer(k, pht)
        return True

    def _update2(self, c: _Core, H: np.ndarray, nu1: float, nu2: float, r1: float, r2: float,
                 gate: float) -> bool:
        """2-D update (rows ``H``, 2×NX), independent noises ``r1``, ``r2``; False if gated."""
        P = c.P
        pht = P.dot(H.T)
        (a, b), (_b, d) = H.dot(pht).tolist()
        a += r1
        d += r2
        det = a * d - b * b
        if det <= 0.0:
            return False
        ia, ib, id_ = d / det, -b / det, a / det
        nis = nu1 * (ia * nu1 + ib * nu2) + nu2 * (ib * nu1 + id_ * nu2)
        if nis > gate:
            return False
        k = pht.dot(np.array(((ia, ib), (ib, id_))))
        x = c.x
        x[:] = [a_ + b_ for a_, b_ in
                zip(x, k.dot(np.array((nu1, nu2))).tolist(), strict=True)]
        x[IPSI] = wrap(x[IPSI])
        P -= k.dot(pht.T)
        return True

    def _rejected(self, c: _Core, kind: int, tov: float) -> bool:
        """Note a gate rejection; True when the sensor has now been rejected for
        ``reset_after_s`` (the caller re-initialises)."""
        self._count(REJECTED_KEYS[kind])
        start = c.rej[kind]
        if math.isnan(start):
            c.rej[kind] = tov
            return False
        if tov - start >= self.cfg.reset_after_s:
            c.rej[kind] = math.nan
            self._count(RESET_KEYS[kind])
            return True
        return False

    def _accepted(self, c: _Core, kind: int) -> None:
        c.rej[kind] = math.nan
        self._count(OK_KEYS[kind])

    def _lever_ned(self, psi: float) -> tuple[float, float, float, float]:
        """Antenna offset in NED (m) and its derivative with respect to ψ (m/rad)."""
        lx, ly = self._lever
        s, co = math.sin(psi), math.cos(psi)
        return lx * co - ly * s, lx * s + ly * co, -lx * s - ly * co, lx * co - ly * s

    # .................................................... GPS position
    def _fuse_pos(self, c: _Core, m: _Meas) -> None:
        x = c.x
        ln = le = dln = dle = 0.0
        if self._has_lever:
            ln, le, dln, dle = self._lever_ned(x[IPSI])
        if not c.pos_init:
            self._init_pos(c, m, ln, le)
            return
        if m.tov - c.t_pos > self.cfg.dr_max_s:
            # dead reckoning has run out (the position went invalid): start again from
            # this fix rather than gate it against a stale estimate
            self._count("pos_restarts")
            self._init_pos(c, m, ln, le)
            return
        glide = m.fix != c.fix and self._fix_change(c, m)
        x0, y0 = x[IX], x[IY]
        nu1 = m.z1 - (x[IX] + x[IBN] + ln)
        nu2 = m.z2 - (x[IY] + x[IBE] + le)
        H = self._h_pos
        if self._has_lever:
            H = H.copy()
            H[0, IPSI], H[1, IPSI] = dln, dle
        if self._update2(c, H, nu1, nu2, m.r1, m.r2, self._gates[K_POS]):
            self._accepted(c, K_POS)
            c.t_pos = m.tov
            if glide:
                gn, ge = self._glide_offset(c, m.tov)
                c.glide = (m.tov, gn + x0 - x[IX], ge + y0 - x[IY])
        elif self._pos_manoeuvre(c, m, nu1, nu2):
            self._update2(c, H, nu1, nu2, m.r1, m.r2, math.inf)
            self._count("pos_manoeuvre")
            c.rej[K_POS] = math.nan
            c.t_pos = m.tov
        elif self._rejected(c, K_POS, m.tov):
            self._init_pos(c, m, ln, le)

    def _pos_manoeuvre(self, c: _Core, m: _Meas, nu1: float, nu2: float) -> bool:
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

    def _init_pos(self, c: _Core, m: _Meas, ln: float, le: float) -> None:
        """(Re-)initialise position and GPS offset on fix ``m`` (a hard reset)."""
        x, P = c.x, c.P
        sb2 = self._bias_sigma[m.fix] ** 2
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

    def _fix_change(self, c: _Core, m: _Meas) -> bool:
        """Re-prime the GPS offset state for a new fix type (see the module doc);
        True if the published position should glide over the coming jump."""
        x, P = c.x, c.P
        self._count("fix_changes")
        sb_new = self._bias_sigma[m.fix]
        upgrade = sb_new < self._bias_sigma[c.fix]
        for i in (IBN, IBE):
            P[i, :] = 0.0
            P[:, i] = 0.0
        P[IBN, IBN] = P[IBE, IBE] = sb_new**2
        x[IBN] = x[IBE] = 0.0  # a fresh, independent offset of the new solution
        c.fix = m.fix
        return upgrade and self.cfg.upgrade_glide_s > 0.0

    def _glide_offset(self, c: _Core, t: float) -> tuple[float, float]:
        """Published-position offset (north, east m) still to glide off at ``t`` (s)."""
        g = c.glide
        if g is None or t < g[0]:
            return 0.0, 0.0
        k = math.exp(-(t - g[0]) / self.cfg.upgrade_glide_s)
        return g[1] * k, g[2] * k

    # .................................................... GPS velocity
    def _ground_velocity(self, x: list[float]) -> tuple[float, float, np.ndarray]:
        """Ground velocity (vn, ve) of the antenna (m/s) and its Jacobian (2×NX)."""
        u, v, psi, r = x[IU], x[IV], x[IPSI], x[IR]
        s, co = math.sin(psi), math.cos(psi)
        vn = u * co - v * s + x[ICN]
        ve = u * s + v * co + x[ICE]
        H = self._h_vel
        H.flat[_H_VEL_IDX] = (co, -s, -(u * s + v * co), s, co, u * co - v * s)
        if self._has_lever:
            ln, le, dln, dle = self._lever_ned(psi)
            vn += r * dln
            ve += r * dle
            H = H.copy()
            H[0, IR], H[1, IR] = dln, dle
            H[0, IPSI] -= r * ln
            H[1, IPSI] -= r * le
        return vn, ve, H

    def _fuse_vel(self, c: _Core, m: _Meas) -> None:
        x = c.x
        if not c.hdg_init:
            if m.kind == K_VEL and not self._heading_sensor_seen:
                self._init_heading_from_course(c, m)
            return
        if not c.vel_init:
            if m.kind == K_SOG:
                return
            self._init_speed(c, m)
        vn, ve, H = self._ground_velocity(x)
        if m.kind == K_SOG:
            speed = math.hypot(vn, ve)
            if speed < 0.1 or m.z1 < 0.1:
                return
            h = (vn / speed) * H[0] + (ve / speed) * H[1]
            if self._update1(c, h, m.z1 - speed, m.r1, self._gates[K_SOG]):
                self._accepted(c, K_SOG)
            else:
                self._rejected(c, K_SOG, m.tov)
            return
        nu1, nu2 = m.z1 - vn, m.z2 - ve
        if self._update2(c, H, nu1, nu2, m.r1, m.r2, self._gates[K_VEL]):
            self._accepted(c, K_VEL)
            c.t_vel = m.tov
        elif self._manoeuvre(c, m, nu1, nu2):
            self._update2(c, H, nu1, nu2, m.r1, m.r2, math.inf)
            self._count("vel_manoeuvre")
            c.rej[K_VEL] = math.nan
            c.t_vel = m.tov
        elif self._rejected(c, K_VEL, m.tov):
            # velocity lost: restart the speed through the water from this one
            self._init_speed(c, m)
            vn, ve, H = self._ground_velocity(x)
            self._update2(c, H, m.z1 - vn, m.z2 - ve, m.r1, m.r2, math.inf)

    def _manoeuvre(self, c: _Core, m: _Meas, nu1: float, nu2: float) -> bool:
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

    def _init_speed(self, c: _Core, m: _Meas) -> None:
        """Start the surge speed at the GPS velocity's component along the heading
        (less the current), so that the first velocity update is linearised about the
        right speed (about u = 0 the crab would all go to the current); with the
        thrusters stopped, at rest in the water."""
        x = c.x
        psi = x[IPSI]
        if (self._mc is not None and c.t - c.t_cmd <= self._cmd_timeout
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
        self._reset_block(c, (IU, IV), (su2, self.cfg.sway_sigma_mps**2))
        c.vel_init = True

    def _init_heading_from_course(self, c: _Core, m: _Meas) -> None:
        """No heading sensor: start ψ at the course (heading stays flagged invalid)."""
        speed = math.hypot(m.z1, m.z2)
        if speed < self.cfg.course_init_speed_mps:
            return
        x = c.x
        # a heading from the course leaves nothing to tell a current by: held at zero
        # (with its random walk) until a heading sensor speaks
        self._reset_block(c, (IPSI, IU, IV, ICN, ICE), (COURSE_INIT_SIGMA_RAD**2, m.r1 + m.r2,
                                                        self.cfg.sway_sigma_mps**2, 0.0, 0.0))
        x[IPSI] = math.atan2(m.z2, m.z1)
        x[IU], x[IV] = speed, 0.0
        x[ICN] = x[ICE] = 0.0
        c.hdg_init = c.vel_init = c.hdg_course = True
        self._count("heading_from_course")

    # ......................................................... heading
    def _fuse_heading(self, c: _Core, m: _Meas) -> None:
        x = c.x
        compass = m.kind == K_COMPASS
        if not c.hdg_init or c.hdg_course:
            self._init_heading(c, m, compass)
            return
        nu = wrap(m.z1 - x[IPSI] - (x[IBC] if compass else 0.0))
        h = self._h_compass if compass else self._h_true
        if self._update1(c, h, nu, m.r1, self._gates[m.kind]):
            self._accepted(c, m.kind)
            c.t_hdg = m.tov
        elif self._rejected(c, m.kind, m.tov):
            self._init_heading(c, m, compass)

    def _init_heading(self, c: _Core, m: _Meas, compass: bool) -> None:
        """(Re-)initialise ψ from a heading measurement (ψ = z − b_c for a compass)."""
        x, P = c.x, c.P
        if c.hdg_course and self.cfg.estimate_current:
            # the first heading sensor after a heading from the course: now a current
            # can be told from the course, starting from its prior
            self._reset_block(c, (ICN, ICE), (self.cfg.current_sigma_mps**2,) * 2)
        c.hdg_course = False
        P[IPSI, :] = 0.0
        P[:, IPSI] = 0.0
        if compass:
            # ψ = z − b_c: ψ's covariance with everything is minus b_c's
            row = -P[IBC, :]
            row[IPSI] = P[IBC, IBC] + m.r1
            P[IPSI, :] = row
            P[:, IPSI] = row
            x[IPSI] = wrap(m.z1 - x[IBC])
        else:
            x[IPSI] = m.z1
            P[IPSI, IPSI] = m.r1
        c.hdg_init = True
        c.t_hdg = m.tov

    # ............................................................ gyro
    def _fuse_rot(self, c: _Core, m: _Meas) -> None:
        x = c.x
        nu = m.z1 - (x[IR] + x[IBG])
        if self._update1(c, self._h_rot, nu, m.r1, self._gates[K_ROT]):
            self._accepted(c, K_ROT)
            c.t_rot = m.tov
        elif self._rejected(c, K_ROT, m.tov):
            self._reset_block(c, (IR,), (nu * nu,))
            self._update1(c, self._h_rot, nu, m.r1, math.inf)

    def _reset_block(self, c: _Core, idx: tuple[int, ...], var: tuple[float, ...]) -> None:
        """Decorrelate states ``idx`` from the rest and give them variances ``var``."""
        P = c.P
        for i, v in zip(idx, var, strict=True):
            P[i, :] = 0.0
            P[:, i] = 0.0
            P[i, i] = v

    # ------------------------------------------------------------- output
    def _at(self, t: float) -> _Core:
        self._flush()
        c = self._c
        if t - c.t <= SAME_TIME_S or not math.isfinite(c.t):
            return c
        c = c.copy()
        self._predict(c, t)
        return c

    def state(self, t: float) -> NavState:
        """The estimate predicted to time ``t`` (s); ``cov`` is that of (x, y, vn, ve, ψ)."""
        c = self._at(t)
        x, P = c.x, c.P
        psi = x[IPSI]
        s, co = math.sin(psi), math.cos(psi)
        u, v = x[IU], x[IV]
        vn = u * co - v * s + x[ICN]
        ve = u * s + v * co + x[ICE]
        J = self._J
        J.flat[_J_IDX] = (co, -s, -(u * s + v * co), s, co, u * co - v * s)
        cov = J.dot(P).dot(J.T)
        pos_valid, hdg_valid = self._validity(c, t)
        pn, pe = x[IX], x[IY]
        if c.glide is not None:
            gn, ge = self._glide_offset(c, t)
            pn += gn
            pe += ge
            cov[0, 0] += gn * gn
            cov[0, 1] += gn * ge
            cov[1, 0] += gn * ge
            cov[1, 1] += ge * ge
        if c.pos_init:
            lat, lon, _h = self.geo.to_geodetic(pn, pe)
        else:
            lat = lon = math.nan
        return NavState(
            t=t, x_m=pn, y_m=pe, vn_mps=vn, ve_mps=ve, psi_rad=psi, r_rps=x[IR],
            u_mps=co * vn + s * ve, v_mps=-s * vn + co * ve, lat_deg=lat, lon_deg=lon,
            fix=self.fix, pos_valid=pos_valid, heading_valid=hdg_valid,
            cov=tuple(cov.ravel().tolist()),
            gps_age_s=t - c.t_pos if c.pos_init else math.inf,
            current_n_mps=x[ICN], current_e_mps=x[ICE],
        )

    def _validity(self, c: _Core, t: float) -> tuple[bool, bool]:
        cfg = self.cfg
        item = c.P.item
        pos_valid = (c.pos_init and t - c.t_pos <= cfg.dr_max_s
                     and max(item(_PXX), item(_PYY)) <= self._pos_var_max)
        hdg_valid = (c.hdg_init and t - c.t_hdg <= cfg.heading_dr_max_s
                     and item(_PPSI) <= self._hdg_var_max)
        return pos_valid, hdg_valid

    def status(self, t: float) -> EkfStatus:
        """Health, flags, counters and the full state at ``t`` (s)."""
        c = self._at(t)
        pos_valid, hdg_valid = self._validity(c, t)
        sig = np.sqrt(np.maximum(np.diag(c.P), 0.0)).tolist()
        frozen = tuple(k for k, v in self._compass.items() if v.frozen)
        jumping = tuple(k for k, v in self._compass.items() if v.jumping)
        return EkfStatus(
            t=t, pos_valid=pos_valid, heading_valid=hdg_valid,
            gps_age_s=t - c.t_pos if c.pos_init else math.inf,
            pos_sigma_m=max(sig[IX], sig[IY]), heading_sigma_deg=math.degrees(sig[IPSI]),
            compass_frozen=bool(frozen), compass_jumping=bool(jumping),
            compass_faults=tuple(sorted(set(frozen + jumping))), fix=self.fix,
            counters=dict(self.counters),
            state=dict(zip(STATE_NAMES, c.x, strict=True)),
            sigma=dict(zip(STATE_NAMES, sig, strict=True)),
            glide_m=math.hypot(*self._glide_offset(c, t)),
            thrust_model=self.thrust_model_active(t),
        )


def _inv2(p: float, q: float, r: float) -> tuple[float, float, float]:
    """Inverse (a, b, d) of the symmetric 2×2 matrix [[p, q], [q, r]]."""
    det = p * r - q * q
    return r / det, -q / det, p / det


def _spd_inverse(a: list[list[float]]) -> list[list[float]]:
    """Inverse of a small symmetric positive-definite matrix (nested lists): 1–4 rows in
    closed form by 2×2 blocks (more: numpy): a joint update's few rows cost less so than any
    numpy.linalg call.  S = [[A, B], [Bᵀ, D]], M = A⁻¹ B, W = (D − Bᵀ M)⁻¹:
    S⁻¹ = [[A⁻¹ + M W Mᵀ, −M W], [−W Mᵀ, W]]."""
    n = len(a)
    if n == 1:
        return [[1.0 / a[0][0]]]
    if n > 4:  # more measurements of one instant than the closed forms cover
        inv: list[list[float]] = np.linalg.inv(np.array(a)).tolist()
        return inv
    r0, r1 = a[0], a[1]
    ia, ib, id_ = _inv2(r0[0], r0[1], r1[1])
    if n == 2:
        return [[ia, ib], [ib, id_]]
    b0, b1 = r0[2], r1[2]  # first column of B
    m00, m10 = ia * b0 + ib * b1, ib * b0 + id_ * b1  # first column of M
    if n == 3:
        w = 1.0 / (a[2][2] - (b0 * m00 + b1 * m10))
        x0, x1 = m00 * w, m10 * w
        return [[ia + x0 * m00, ib + x0 * m10, -x0],
                [ib + x1 * m00, id_ + x1 * m10, -x1],
                [-x0, -x1, w]]
    c0, c1 = r0[3], r1[3]  # second column of B
    m01, m11 = ia * c0 + ib * c1, ib * c0 + id_ * c1
    wa, wb, wd = _inv2(a[2][2] - (b0 * m00 + b1 * m10), a[2][3] - (b0 * m01 + b1 * m11),
                       a[3][3] - (c0 * m01 + c1 * m11))
    x00, x01 = m00 * wa + m01 * wb, m00 * wb + m01 * wd  # M W
    x10, x11 = m10 * wa + m11 * wb, m10 * wb + m11 * wd
    e00 = ia + x00 * m00 + x01 * m01
    e01 = ib + x00 * m10 + x01 * m11
    e11 = id_ + x10 * m10 + x11 * m11
    return [[e00, e01, -x00, -x01], [e01, e11, -x10, -x11],
            [-x00, -x10, wa, wb], [-x01, -x11, wb, wd]]


def _row(entries: dict[int, float]) -> np.ndarray:
    h = np.zeros(NX)
    for i, v in entries.items():
        h[i] = v
    return h
