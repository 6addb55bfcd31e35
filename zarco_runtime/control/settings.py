"""Settings of the control layer: the vessel model the controllers are designed on,
the thruster maps f, and the line-tracking and speed gains."""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec

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


def xtrack_rate_tau_s(ctl: Control, estimator: str = "simple") -> float:
    """``control.xtrack_rate_tau_s`` (s), or the ``estimator``'s default when unset."""
    tau = ctl.xtrack_rate_tau_s
    return tau if tau is not None else XTRACK_RATE_TAU_S[estimator]
