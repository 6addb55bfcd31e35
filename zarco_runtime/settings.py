"""The runtime's configuration schema (``config/zarco.toml`` and the
``[runtime]`` table of a scenario).

Every field carries its unit and range; :func:`zarco_runtime.config.build`
validates a TOML table against these dataclasses.  Defaults are the Zarco
values of DESIGN.md §4 and the tuned gains of the line-tracking controller.
"""

from __future__ import annotations

from dataclasses import dataclass

from zarco_runtime.config import spec
from zarco_runtime.guidance.follow import FollowSettings
from zarco_runtime.navigation.ekf_config import EkfSettings
from zarco_runtime.tracking.params import TrackerParams

# Bollard-pull calibration of one Zarco thruster (command → thrust, N), sampled
# from the design curve of DESIGN.md §4 (deadband ±5, 125 N forward, 75 N
# reverse, convex).  On the boat, replace with the thruster's measured table.
DEFAULT_TABLE_U = [
    -100.0, -90.0, -80.0, -70.0, -60.0, -50.0, -40.0, -30.0, -20.0, -15.0, -10.0, -5.0,
    5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0,
]
DEFAULT_TABLE_F = [
    -75.0, -62.161, -50.485, -39.972, -30.623, -22.438, -15.416, -9.557, -4.861, -2.95,
    -1.33, 0.0, 0.0, 2.216, 4.917, 8.102, 15.928, 25.693, 37.396, 51.039, 66.62, 84.141,
    103.601, 125.0,
]


@dataclass(slots=True)
class Origin:
    """Geodetic origin of the local NED frame (WGS-84)."""

    lat_deg: float = spec(41.185, "deg", "origin latitude", min=-90.0, max=90.0)
    lon_deg: float = spec(-8.705, "deg", "origin longitude", min=-180.0, max=180.0)
    alt_m: float = spec(0.0, "m", "origin height", min=-500.0, max=9000.0)


@dataclass(slots=True)
class Device:
    """One device: where it is (a URL, as pyserial names ports) and how to judge it.

    ``url`` forms: ``/dev/ttyUSB0`` or ``serial:///dev/ttyUSB0``
    (serial port at ``baudrate``), ``tcp://host:port``, ``sim://NAME`` (the
    simulated backend's in-memory port), ``loop://`` (pyserial loopback).
    """

    url: str = spec("", "", "device address")
    baudrate: int = spec(115200, "bit/s", "serial speed", min=1200, max=4_000_000)
    enabled: bool = spec(True, "", "read this device")
    stale_s: float = spec(1.0, "s", "no valid sentence for this long → stale", min=0.05, max=60.0)
    corrections_url: str = spec("", "", "RTCM3 corrections written to this device's port, "
                                "from a serial port, tcp://HOST:PORT or file://PATH "
                                "(empty: none; the shore relay comes with the shore link)")
    corrections_rate_bps: float = spec(4000.0, "B/s", "pace of a file:// corrections "
                                       "source", min=1.0, max=1e7)
    reopen_s: float = spec(3.0, "s", "no bytes at all for this long → close and reopen the "
                           "port (0: never)", min=0.0, max=600.0)
    variation_deg: float | None = spec(
        None, "deg", "magnetic variation (east +) when the sentences carry none",
        min=-90.0, max=90.0,
    )


@dataclass(slots=True)
class Devices:
    gps: Device = spec(lambda: Device(url="sim://gps"))
    compass: Device = spec(lambda: Device(url="sim://compass"))
    thrusters: Device = spec(lambda: Device(url="sim://thrusters"))
    buoy: Device = spec(lambda: Device(url="sim://buoy", enabled=False, stale_s=5.0),
                        doc="radio feed of the LBL listening buoy ($PZBAE, $PZBST)")


@dataclass(slots=True)
class VesselModel:
    """The runtime's nominal model of the vessel (DESIGN.md §4), for feedforward
    and gain design.  Damping coefficients are negative (they oppose motion)."""

    m_kg: float = spec(45.0, "kg", "mass", min=1.0, max=1000.0)
    iz_kgm2: float = spec(9.0, "kg m²", "yaw inertia", min=0.01, max=1000.0)
    x_udot: float = spec(-4.5, "kg", "surge added mass", max=0.0)
    y_vdot: float = spec(-67.5, "kg", "sway added mass", max=0.0)
    n_rdot: float = spec(-15.3, "kg m²", "yaw added inertia", max=0.0)
    x_u: float = spec(-25.0, "N s/m", "linear surge damping", max=0.0)
    x_uu: float = spec(-82.0, "N s²/m²", "quadratic surge damping", max=0.0)
    y_v: float = spec(-112.5, "N s/m", "linear sway damping", max=0.0)
    n_r: float = spec(-24.3, "N m s", "linear yaw damping", max=0.0)
    b_m: float = spec(0.38, "m", "thruster half-spacing", min=0.01, max=5.0)
    l_m: float = spec(0.65, "m", "thruster distance aft of CM", min=0.0, max=5.0)
    thruster_lag_s: float = spec(0.15, "s", "thruster first-order time constant",
                                 min=0.001, max=5.0)


@dataclass(slots=True)
class ThrusterTable:
    """Calibrated map f: command U (-100..100) → thrust F (N), monotone, with deadband."""

    u: list[float] = spec(lambda: list(DEFAULT_TABLE_U), "%", "command points, increasing")
    f_n: list[float] = spec(lambda: list(DEFAULT_TABLE_F), "N", "thrust at each command point")

    def validate(self) -> None:
        if len(self.u) != len(self.f_n):
            raise ValueError(f"f_n: has {len(self.f_n)} points but u has {len(self.u)}")
        if len(self.u) < 2:
            raise ValueError("u: needs at least 2 points")
        for i in range(1, len(self.u)):
            if not self.u[i] > self.u[i - 1]:
                raise ValueError(f"u: not strictly increasing at index {i} ({self.u[i]})")
            if self.f_n[i] < self.f_n[i - 1]:
                raise ValueError(
                    f"f_n: not monotone at index {i} ({self.f_n[i - 1]} → {self.f_n[i]})"
                )
        if self.u[0] < -100 or self.u[-1] > 100:
            raise ValueError("u: points must lie within -100..100")
        if not (self.f_n[0] <= 0.0 <= self.f_n[-1]):
            raise ValueError("f_n: must span zero thrust")


@dataclass(slots=True)
class Thrusters:
    port: ThrusterTable = spec(ThrusterTable)
    starboard: ThrusterTable = spec(ThrusterTable)


@dataclass(slots=True)
class Navigation:
    """Navigation: the EKF (``navigation/ekf.py``, settings in ``[ekf]``) or the
    first estimate (per-axis constant-velocity filter on GPS, and a complementary
    filter of compass heading with the gyro rate; the settings below)."""

    estimator: str = spec("simple", "", "which estimator feeds the controller (the EKF is "
                          "complete but costs ~40 % of the simulation speed; see issue 5)",
                          choices=["ekf", "simple"])

    accel_psd: float = spec(0.02, "m²/s³", "acceleration noise density of the "
                            "constant-velocity position filter", min=1e-6, max=100.0)
    sog_sigma_mps: float = spec(0.05, "m/s", "1σ assumed for GPS speed/course over ground "
                                "(DESIGN.md §4: 0.05)", min=0.001, max=10.0)
    heading_tau_s: float = spec(3.0, "s", "compass/gyro complementary time constant",
                                min=0.05, max=60.0)
    gyro_bias_tau_s: float = spec(60.0, "s", "gyro bias estimation time constant",
                                  min=1.0, max=3600.0)
    gps_timeout_s: float = spec(1.0, "s", "no GPS fix for this long → position invalid",
                                min=0.1, max=30.0)
    heading_timeout_s: float = spec(1.0, "s", "no heading for this long → heading invalid",
                                    min=0.1, max=30.0)
    min_fix: str = spec("single", "", "worst fix used for control",
                        choices=["single", "dgps", "rtk_float", "rtk_fixed"])


#: default low-pass (s) of the GPS part of the cross-track rate per estimator,
#: measured on the rectangle at 1 m/s, seeds 1-3 (tests/bench/navigation.py):
#: shorter behind the first estimate is noisier (command steps 7.5 → 11 at 0.2 s)
XTRACK_RATE_TAU_S = {"simple": 0.5, "ekf": 0.2}


@dataclass(slots=True)
class Control:
    """Guidance and control gains.  The line-tracking gains are designed at
    start-up by LQR on the linearised steering model at each speed (gain
    scheduling); the weights below shape that design."""

    rate_hz: float = spec(20.0, "Hz", "control and thruster command rate", min=1.0, max=200.0)
    # LQR weights: the largest acceptable excursion of each state
    lqr_d_m: float = spec(0.015, "m", "cross-track error scale", min=1e-4, max=100.0)
    lqr_int_ms: float = spec(0.05, "m s", "integral of cross-track error scale", min=1e-4, max=1e4)
    lqr_psi_deg: float = spec(10.0, "deg", "heading error scale", min=0.01, max=90.0)
    lqr_r_dps: float = spec(10.0, "deg/s", "yaw rate scale", min=0.01, max=360.0)
    lqr_v_mps: float = spec(0.5, "m/s", "sway speed scale", min=1e-3, max=10.0)
    lqr_n_nm: float = spec(20.0, "N m", "yaw moment scale", min=0.01, max=1000.0)
    xtrack_rate_tau_s: float | None = spec(
        None, "s", "low-pass of the GPS part of the cross-track rate (sway, current); unset: "
        "the estimator's (XTRACK_RATE_TAU_S: 0.5 s behind the first estimate, whose velocity "
        "is the receiver's raw SOG/COG; 0.2 s behind the EKF, whose velocity is filtered "
        "already)", min=0.001, max=60.0)
    xtrack_tau_s: float = spec(0.5, "s", "time constant pulling the smoothed cross-track "
                               "error to the GPS one", min=0.001, max=60.0)
    integral_window_m: float = spec(1.0, "m", "integrate d only while |d| is below this",
                                    min=0.0, max=100.0)
    max_intercept_deg: float = spec(60.0, "deg", "largest course offset to the line",
                                    min=1.0, max=90.0)
    current_tau_s: float = spec(20.0, "s", "water-current observer time constant "
                                "(0 disables the current feedforward)", min=0.0, max=3600.0)
    speed_kp: float = spec(60.0, "N/(m/s)", "speed controller proportional gain", min=0.0,
                           max=1e4)
    speed_ki: float = spec(10.0, "N/m", "speed controller integral gain", min=0.0, max=1e4)
    heading_kp: float = spec(40.0, "N m/rad", "heading-hold proportional gain", min=0.0, max=1e4)
    heading_kd: float = spec(20.0, "N m s/rad", "heading-hold rate gain", min=0.0, max=1e4)


@dataclass(slots=True)
class Guidance:
    switching: str = spec("cross_end", "", "when the next line starts: 'cross_end' (paper: "
                          "after crossing the end of the line) or 'anticipate' (turn early "
                          "by the turning radius)", choices=["cross_end", "anticipate"])
    turn_rate_dps: float = spec(50.0, "deg/s", "turn rate assumed by 'anticipate' (its lead "
                                "is U/r·tan(turn/2); 50 minimises the corner error here)",
                                min=1.0, max=90.0)


@dataclass(slots=True)
class Failsafe:
    """The supervisor's rules for zero thrust.

    GPS loss: the estimator dead-reckons and says how old its last fix is
    (``NavState.gps_age_s``).  Once that exceeds ``gps_lost_after_s`` the GPS
    counts as lost and ``gps_lost`` decides: ``"zero"`` holds thrust at zero
    until a fix is fused again; ``"continue"`` goes on along the dead-reckoned
    estimate for ``gps_lost_continue_s`` seconds of GPS age, then zero.
    Independently, an estimate its own estimator calls invalid (EKF:
    ``ekf.dr_max_s``, ``ekf.pos_sigma_max_m``) for ``nav_invalid_s`` → zero.
    """

    nav_invalid_s: float = spec(1.0, "s", "position/heading invalid this long → zero thrust",
                                min=0.0, max=60.0)
    gps_lost: str = spec("continue", "", "on GPS loss: hold thrust at zero, or continue on "
                         "dead reckoning for gps_lost_continue_s", choices=["zero", "continue"])
    gps_lost_after_s: float = spec(0.5, "s", "no GPS position fused for this long counts as "
                                   "GPS lost (5 epochs at 10 Hz)", min=0.05, max=60.0)
    gps_lost_continue_s: float = spec(10.0, "s", "with gps_lost = \"continue\": GPS age at "
                                      "which dead reckoning stops and thrust goes to zero "
                                      "(EKF: 1.0 m after 10 s at 1 m/s, issue 5)", min=0.0,
                                      max=3600.0)
    thruster_silent_s: float = spec(1.0, "s", "the thruster controller's $PZTHS stopped for "
                                    "this long → zero thrust (0: off)", min=0.0, max=60.0)


@dataclass(slots=True)
class RuntimeConfig:
    """Everything ``zarco run`` needs."""

    origin: Origin = spec(Origin)
    devices: Devices = spec(Devices)
    vessel: VesselModel = spec(VesselModel)
    thrusters: Thrusters = spec(Thrusters)
    navigation: Navigation = spec(Navigation)
    control: Control = spec(Control)
    guidance: Guidance = spec(Guidance)
    follow: FollowSettings = spec(FollowSettings)
    tracker: TrackerParams = spec(TrackerParams)
    ekf: EkfSettings = spec(EkfSettings)
    failsafe: Failsafe = spec(Failsafe)


def xtrack_rate_tau_s(ctl: Control, estimator: str = "simple") -> float:
    """``control.xtrack_rate_tau_s`` (s), or the ``estimator``'s default when unset."""
    tau = ctl.xtrack_rate_tau_s
    return tau if tau is not None else XTRACK_RATE_TAU_S[estimator]
