"""Typed messages exchanged on the in-process bus.

Every message is a frozen dataclass whose first field ``t`` is the runtime clock
time (seconds, monotonic on the boat, virtual in simulation) at which the
message became valid.  Messages are shared by every subscriber: treat them
as immutable.  (They are not ``frozen``: a frozen dataclass costs five times
as much to build, and the simulation builds a few hundred per simulated
second.)  Units are SI and angles radians unless the field name
says otherwise (``*_deg``).  Frames, everywhere in the project: local NED about the
configured origin (x north, y east, metres), heading ψ clockwise from north,
body x forward / y starboard, yaw rate r positive clockwise.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

from zarco_core.commands import CommandArgs
from zarco_core.modes import MOVING, UNDER_WAY, Mode

__all__ = ["MOVING", "UNDER_WAY", "Mode"]  # re-exported: the modes live in zarco_core.modes


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
    """Normalised thruster commands, -100..+100 (1 = port, 2 = starboard);
    ``reason``: why a held (zero) command is zero ("idle", "disarmed", "not
    driving: …", a fault), "" while the controller drives."""

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
    (``failsafe.position_lost_s``) decides when the vessel stops.
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
    """A device driver's health and counters; ``last_ok_t`` is the time of its
    last valid sentence (None: none yet)."""

    t: float
    device: str
    state: HealthState
    reason: str = ""
    counters: dict[str, int] = field(default_factory=dict)
    last_ok_t: float | None = None


@dataclass(slots=True)
class Fault:
    """A fault raised by a task (``source``) with a human-readable reason."""

    t: float
    source: str
    reason: str


# ------------------------------------------------------------ supervision


@dataclass(slots=True)
class Command:
    """An operator's (or a script's) command to the supervisor.

    ``id`` is chosen by the sender and echoed in the acknowledgement;
    ``source`` says who sent it (``local``, ``scenario``, ``shore:<user>``,
    ``mavlink:<system id>``).  ``name`` is the command and ``args`` its typed,
    bounded arguments (:mod:`zarco_core.commands`: ``decode(name, payload)``
    builds them from what a link received, or refuses it).
    """

    t: float
    id: str
    source: str
    name: str
    args: CommandArgs


#: a parameter's value: a number, a flag, a word (one of its choices) or a list of
#: [lat_deg, lon_deg] points (the geofence polygon)
ParamValue = float | int | bool | str | list[list[float]]


@dataclass(slots=True)
class ParamChange:
    """A parameter of the running configuration changed: the supervisor accepted
    a ``param`` command.  ``name`` is the dotted configuration key
    (``failsafe.link_lost_s``), ``value`` the new value and ``old`` the one it
    replaced, ``source`` and ``id`` those of the command.  Recorded, and applied
    again by ``zarco log replay``."""

    t: float
    name: str
    value: ParamValue
    old: ParamValue
    source: str = ""
    id: str = ""


@dataclass(slots=True)
class CommandAck:
    """Exactly one per Command: accepted (``ok``) or refused with ``reason``.
    ``mode`` is the vessel's mode after the command."""

    t: float
    id: str
    source: str
    name: str
    ok: bool
    mode: str
    reason: str = ""


@dataclass(slots=True)
class Event:
    """Something an operator should know, in words: ``kind`` is ``mode``,
    ``arming``, ``failsafe``, ``ack``, ``param``, ``fault``, ``component`` or
    ``mission``."""

    t: float
    kind: str
    text: str
    source: str = "supervisor"


@dataclass(slots=True)
class OperatorHeartbeat:
    """An operator's link is alive (shore link or ground station): ``link`` names
    the link (``shore``, ``mavlink``), ``user`` the operator."""

    t: float
    link: str
    user: str = ""


@dataclass(slots=True)
class ComponentState:
    """A supervised component (task) changed state: ``running``, ``failed``
    (it raised; ``error`` says what) or ``restarting`` (after a backoff)."""

    t: float
    component: str
    state: str
    restarts: int = 0
    failures: int = 0
    error: str = ""


@dataclass(slots=True)
class DeviceSummary:
    """One device in the status snapshot: health ``state`` and ``reason``,
    ``age_s`` since its last valid sentence (None: never), ``ok`` sentences
    accepted and ``bad`` refused, and its raw counters."""

    state: str
    reason: str
    age_s: float | None
    ok: int
    bad: int
    counters: dict[str, int] = field(default_factory=dict)


@dataclass(slots=True)
class MissionProgress:
    """Where the active (or last) mission stands: ``kind`` lines/follow, ``leg``
    0-based of ``legs``, ``complete``; ``xtrack_m`` the cross-track error;
    ``phase`` of a follow mission: ``wait`` (no AUV track yet), ``follow``,
    ``hold`` (track lost)."""

    kind: str = ""
    name: str = ""
    leg: int = 0
    legs: int = 0
    complete: bool = False
    xtrack_m: float | None = None
    along_m: float | None = None
    phase: str = ""


@dataclass(slots=True)
class VesselStatus:
    """The 1 Hz status snapshot: the single source for ``zarco run --status``,
    HIL and the shore link's health.

    ``utc_s`` is UTC seconds since the epoch at ``t``; ``armed`` whether the
    supervisor lets the thrusters turn (``arm``; a disarmed boat never moves);
    ``failsafes`` the active failsafe conditions; ``components`` maps a
    component to its state and restart count; ``counters`` gathers the control
    loop's and the bus's; ``home_lat_deg``/``home_lon_deg`` where ``return``
    goes (None: not known yet); ``mission_points`` the waypoints
    ([lat_deg, lon_deg]) of the lines mission loaded or running (empty: none,
    or cleared) and ``mission_id`` a number that changes whenever they do
    (the MAVLink endpoint serves its mission from these, never a copy of its
    own).  Published once a second and at once on every change of mode, of
    arming, of the loaded mission or of the active failsafes.
    """

    t: float
    utc_s: float
    mode: str
    armed: bool
    mission: MissionProgress
    failsafes: list[str]
    devices: dict[str, DeviceSummary]
    components: dict[str, ComponentState]
    counters: dict[str, int]
    reason: str = ""
    home_lat_deg: float | None = None
    home_lon_deg: float | None = None
    mission_points: tuple[tuple[float, float], ...] = ()
    mission_id: int = 0


@dataclass(slots=True)
class RtcmCorrections:
    """RTCM3 correction bytes for the GPS receiver from a corrections source
    (``source``: ``shore``, ``mavlink``, or the GPS device's own
    ``corrections_url``).  The GPS driver passes on only whole RTCM3 frames
    with a valid CRC-24Q."""

    t: float
    source: str
    data: bytes
