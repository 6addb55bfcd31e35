"""Messages of the AUV tracking chain (conventions of :mod:`zarco_core.messages`).

``@dataclass(slots=True)``, first field ``t`` = runtime clock time (s) at which
the message became valid, SI units, angles in radians, local NED frame
(x north, y east, metres) about the configured origin.  Acoustic times are
absolute UTC seconds since 1970 (``utc_epoch_s``, ``*_utc_s``) from the buoy's
GPS-disciplined clock; they are a different clock from ``t``.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass


@dataclass(slots=True)
class AcousticEvent:
    """One acoustic detection reported by the buoy (``$PZBAE``).

    ``utc_epoch_s``: detection time at the listener hydrophone, UTC seconds
    since 1970 with µs resolution.  ``kind``: ``"I"`` an AUV interrogation
    (``beacon`` = the beacon addressed) or ``"R"`` a beacon reply (``beacon`` =
    the beacon replying).  ``snr_db``: detection quality (dB).
    """

    t: float
    source: str
    utc_epoch_s: float
    kind: str
    beacon: int
    snr_db: float


@dataclass(slots=True)
class BuoyStatus:
    """Buoy status (``$PZBST``, 1 Hz): position (WGS-84 deg), battery (V), fault code
    (0 = ok)."""

    t: float
    source: str
    utc_epoch_s: float
    lat_deg: float
    lon_deg: float
    battery_v: float
    fault_code: int


class TrackFlags(enum.IntFlag):
    """Quality flags of an :class:`AuvTrack` (bit set = condition holds)."""

    NONE = 0
    #: the Kalman filter is initialised (mirror ambiguity resolved)
    INITIALISED = 1
    #: the RLS line estimate has had enough fixes since its last reset
    LINE_VALID = 2
    #: the RLS covariance was reset recently: the AUV is (or was just) turning
    TURNING = 4
    #: no accepted fix for longer than ``stale_after_s``
    STALE = 8
    #: the track is lost (silent for ``lost_after_s`` or covariance too large)
    LOST = 16
    #: the filter was re-initialised after consecutive gated fixes or a loss
    REACQUIRED = 32
    #: the last fix had poor geometry (circles tangent / near the baseline)
    BAD_GEOMETRY = 64
    #: the buoy reports a fault
    BUOY_FAULT = 128
    #: the last update was a range-only update (cycle on the listener's beacon)
    RANGE_ONLY = 256


@dataclass(slots=True)
class AuvFix:
    """One passive position fix of the AUV (paper section IV), before filtering.

    ``emission_utc_s``: the AUV's emission time T_j of the interrogation, UTC
    seconds since 1970.  ``x_m``/``y_m``: the chosen solution (NED), and
    ``mirror_x_m``/``mirror_y_m`` the other intersection of the two horizontal
    circles (equal when tangent).  ``r_i_m``/``r_l_m``: 3-D ranges to the
    interrogated beacon and to the listener after the motion-bias correction
    ``bias_m`` (already subtracted).  ``accepted``: passed the innovation gate.
    ``range_only``: a cycle on the listener's own beacon (one circle, no
    position: ``x_m``/``y_m`` are then the point of that circle nearest the
    prediction, NaN when there is no prediction).  ``cov_xx_m2``,
    ``cov_xy_m2``, ``cov_yy_m2``: covariance of (x_m, y_m) (m²; NaN when the
    position is not determined, e.g. range-only): with the ranges to other
    beacons heard in the last cycles, brought to this emission time, the fix
    is their joint least-squares solution.
    """

    t: float
    emission_utc_s: float
    beacon: int
    x_m: float
    y_m: float
    mirror_x_m: float
    mirror_y_m: float
    r_i_m: float
    r_l_m: float
    bias_m: float
    accepted: bool
    range_only: bool = False
    cov_xx_m2: float = math.nan
    cov_xy_m2: float = math.nan
    cov_yy_m2: float = math.nan


@dataclass(slots=True)
class AuvTrack:
    """The AUV's estimated straight-line trajectory and filtered state.

    Line model (paper V, RLS): x(t) = x0 + vx (t − t0), y(t) = y0 + vy (t − t0),
    NED metres and m/s.  ``t0`` is the time origin on the *runtime* clock
    (the same clock as ``t``), ``t0_utc_s`` the same instant on the acoustic
    UTC clock; (x0, y0) is the AUV's position at t0 on the fitted line.
    ``psi_auv_rad`` = atan2(vy, vx) clockwise from north, ``v_auv_mps`` = |v|,
    ``h_auv_m`` = (vy x0 − vx y0)/v_auv (the cross-track offset of the
    frame's origin from the line, + when the origin is to starboard of the
    AUV's course; NaN when v_auv = 0).
    ``cov``: 4×4 covariance of (x0, y0, vx, vy), row-major, 16 floats.
    ``kf_*``: the constant-velocity Kalman filter's state at ``t0_utc_s``
    (m, m/s), ``kf_pos_sigma_m`` the RMS of its two position standard
    deviations.  ``fix_age_s``: runtime seconds since the emission time of the
    last accepted fix.  ``flags``: :class:`TrackFlags` bits; ``lost`` mirrors
    the LOST bit.  ``sound_speed_mps``: the sound speed the ranges are
    computed with — the tracker's online estimate (the configured one until
    the geometry makes it observable, and when estimation is off);
    ``sound_speed_sigma_mps`` its 1σ (the configured uncertainty while not
    observable, 0 when estimation is off); ``sound_speed_converged``: that σ
    is within the configured convergence bound.  ``plan_leg``: the leg of the
    AUV's plan (:class:`AuvPlan`, 0 = from its first point to its second) the
    AUV is on, −1 without a plan or off it; then ``plan_s_m``: its progress
    along the plan at ``t0`` (m of path from the plan's first point),
    ``plan_speed_mps`` its speed along the plan, ``plan_cross_m`` its offset
    from the plan (m, + to starboard), ``plan_turn_radius_m`` the radius it
    rounds the plan's corners with (m); NaN off the plan.
    """

    t: float
    x0_m: float
    y0_m: float
    vx_mps: float
    vy_mps: float
    psi_auv_rad: float
    v_auv_mps: float
    h_auv_m: float
    cov: tuple[float, ...]
    t0: float
    t0_utc_s: float
    fix_age_s: float
    flags: int
    lost: bool
    kf_x_m: float
    kf_y_m: float
    kf_vx_mps: float
    kf_vy_mps: float
    kf_pos_sigma_m: float
    sound_speed_mps: float = math.nan
    sound_speed_sigma_mps: float = math.nan
    sound_speed_converged: bool = False
    plan_leg: int = -1
    plan_s_m: float = math.nan
    plan_speed_mps: float = math.nan
    plan_cross_m: float = math.nan
    plan_turn_radius_m: float = math.nan


@dataclass(slots=True)
class AuvPlan:
    """The AUV's a-priori mission (paper V: the lines it flies "according to an a
    priori mission plan"): the waypoints it is expected to fly through, in
    order, as local NED points (north, east; metres).  A prior for the tracker
    (where the legs turn) and the follow guidance (the corners to cut); the
    AUV may still leave it (an adaptive mission), which the tracker detects.

    Published by the supervisor when following starts (from the ``follow``
    command's ``auv_plan`` or ``[mission] auv_plan``) and cleared when it
    ends: an empty ``points`` means no plan.  ``source`` says where it came
    from (``mission``, or the command's source, e.g. ``shore:alice``).
    """

    t: float
    points: tuple[tuple[float, float], ...] = ()
    source: str = ""
