"""Typed messages exchanged on the in-process bus.

Every message is a frozen dataclass whose first field ``t`` is the runtime clock
time (seconds, monotonic on the boat, virtual in simulation) at which the
message became valid.  Messages are shared by every subscriber: treat them
as immutable.  (They are not ``frozen``: a frozen dataclass costs five times
as much to build, and the simulation builds a few hundred per simulated
second.)  Units are SI and angles radians unless the field name
says otherwise (``*_deg``).  Frames follow DESIGN.md §3: local NED about the
configured origin (x north, y east, metres), heading ψ clockwise from north,
body x forward / y starboard, yaw rate r positive clockwise.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field


class FixQuality(enum.IntEnum):
    """GNSS fix quality, ordered from worst to best."""

    NONE = 0
    SINGLE = 1
    DGPS = 2
    RTK_FLOAT = 3
    RTK_FIXED = 4

    @property
    def label(self) -> str:
        """Lower-case name used at the edges (JSON, logs): ``rtk_fixed`` etc."""
        return self.name.lower()

    @classmethod
    def from_label(cls, label: str) -> FixQuality:
        return cls[label.upper()]


class HealthState(enum.Enum):
    """Health of a device driver (DUNE-like entity state)."""

    OK = "ok"
    STALE = "stale"
    DISCONNECTED = "disconnected"
    FAULTY = "faulty"


# --------------------------------------------------------------------- GNSS


@dataclass(slots=True)
class GpsFix:
    """A position fix (GGA, RMC or similar).

    ``utc_s`` is the receiver's UTC time of day in seconds (None if absent).
    ``lat_deg``/``lon_deg`` are WGS-84 degrees, ``alt_m`` metres above MSL.
    """

    t: float
    source: str
    sentence: str
    talker: str
    fix: FixQuality
    lat_deg: float | None
    lon_deg: float | None
    alt_m: float | None = None
    utc_s: float | None = None
    num_sats: int | None = None
    hdop: float | None = None
    age_s: float | None = None


@dataclass(slots=True)
class GpsVelocity:
    """Speed and course over ground (RMC, VTG). ``cog_rad`` is true course."""

    t: float
    source: str
    sentence: str
    sog_mps: float
    cog_rad: float | None
    utc_s: float | None = None


@dataclass(slots=True)
class GpsErrorStats:
    """GST pseudorange error statistics: 1σ errors in metres."""

    t: float
    source: str
    std_lat_m: float | None
    std_lon_m: float | None
    std_alt_m: float | None
    rms_m: float | None = None
    utc_s: float | None = None


@dataclass(slots=True)
class GpsTime:
    """ZDA date and time: ``utc_epoch_s`` is seconds since 1970-01-01 UTC."""

    t: float
    source: str
    utc_epoch_s: float


# ------------------------------------------------------------ compass / IMU


@dataclass(slots=True)
class Heading:
    """A heading measurement.

    ``heading_rad`` is the *true* heading in [0, 2π) when it could be
    derived (true sentence, or magnetic + a known variation), else the raw
    magnetic heading with ``true=False``.  ``raw_deg`` is what the sentence
    said; ``variation_deg`` the variation applied (east positive).
    """

    t: float
    source: str
    sentence: str
    heading_rad: float
    true: bool
    raw_deg: float
    variation_deg: float | None = None
    deviation_deg: float | None = None


@dataclass(slots=True)
class RateOfTurn:
    """Yaw rate from ROT (deg/min on the wire), rad/s, positive clockwise."""

    t: float
    source: str
    rate_rps: float


@dataclass(slots=True)
class Attitude:
    """Pitch and roll from XDR transducer sentences, radians (None if absent)."""

    t: float
    source: str
    pitch_rad: float | None
    roll_rad: float | None


# ------------------------------------------------------------- thrusters


@dataclass(slots=True)
class ThrusterCommand:
    """Normalised thruster commands, -100..+100 (1 = port, 2 = starboard)."""

    t: float
    u1: float
    u2: float
    reason: str = ""


@dataclass(slots=True)
class ThrusterStatus:
    """``$PZTHS`` from the thruster controller: commands applied, rpm, amperes."""

    t: float
    u1: float
    u2: float
    rpm1: float
    rpm2: float
    amps1: float
    amps2: float


# ------------------------------------------------------------ navigation


@dataclass(slots=True)
class NavState:
    """The vessel's estimated state in the local NED frame.

    Position ``x_m`` north, ``y_m`` east; ground velocity ``vn_mps``,
    ``ve_mps`` (NED) and ``u_mps``, ``v_mps`` (body: forward, starboard);
    heading ``psi_rad`` true in (-π, π]; yaw rate ``r_rps``.  ``cov`` is the
    row-major covariance of (x, y, vn, ve, ψ) (25 values) or empty when
    unknown.  ``pos_valid`` / ``heading_valid`` say whether each part can
    be trusted for control.  ``gps_age_s`` is the time since the last GPS
    position the estimator fused (s; inf before the first): above a few GPS
    periods the position is dead-reckoned, and the supervisor
    (``failsafe.gps_lost``) decides whether the vessel goes on.
    ``current_n_mps``, ``current_e_mps`` are the estimated water current (NED,
    m/s, the direction the water flows towards; 0 when not estimated).
    """

    t: float
    x_m: float
    y_m: float
    vn_mps: float
    ve_mps: float
    psi_rad: float
    r_rps: float
    u_mps: float
    v_mps: float
    lat_deg: float
    lon_deg: float
    fix: FixQuality
    pos_valid: bool
    heading_valid: bool
    cov: tuple[float, ...] = ()
    gps_age_s: float = 0.0
    current_n_mps: float = 0.0
    current_e_mps: float = 0.0


# --------------------------------------------------- guidance and control


@dataclass(slots=True)
class GuidanceStatus:
    """Where the vessel is on its mission.

    ``leg`` is the active leg index (0-based), ``along_m`` the along-track
    position from the leg's start, ``xtrack_m`` the cross-track error d
    (positive to starboard of the line, i.e. right of the direction of travel).
    """

    t: float
    mode: str
    leg: int
    legs: int
    along_m: float
    xtrack_m: float
    psi_traj_rad: float
    speed_ref_mps: float
    complete: bool = False


@dataclass(slots=True)
class ControlStatus:
    """What the controller decided at one tick."""

    t: float
    psi_ref_rad: float
    x_act_n: float
    n_act_nm: float
    f1_n: float
    f2_n: float
    u1: float
    u2: float
    saturated: bool
    fault: str = ""


# ------------------------------------------------------------ supervision


@dataclass(slots=True)
class DeviceHealth:
    """A device driver's health and counters."""

    t: float
    device: str
    state: HealthState
    reason: str = ""
    counters: dict[str, int] = field(default_factory=dict)


@dataclass(slots=True)
class Fault:
    """A fault raised by a task (``source``) with a human-readable reason."""

    t: float
    source: str
    reason: str
