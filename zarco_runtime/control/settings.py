"""Settings of the control layer: the line-tracking, speed and heading gains."""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec

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
    max_intercept_deg: float = spec(35.0, "deg", "largest heading offset from the crab "
                                    "heading ψ0: at low speed through the water a wider "
                                    "swing outruns the yaw rate the thrusters can give and "
                                    "the line tracking cycles", min=1.0, max=90.0)
    current_feedforward: bool = spec(True, "", "steer the crab angle of the estimated "
                                     "water current (off: the integral alone absorbs it)")
    gust_feedforward: bool = spec(False, "", "counter the sway force of gusts the observer "
                                  "estimates (the LQR's gain on it).  Off: the force is seen "
                                  "only through the sway it has already caused, ~1 s late, and "
                                  "at 0.15 m/s through the water it gained 3 % of cross-track "
                                  "RMS for 12 % more thruster command steps")
    mismatch_compensation: bool = spec(True, "", "estimate the port/starboard thrust "
                                       "mismatch and command through its inverse")
    speed_kp: float = spec(150.0, "N/(m/s)", "speed controller proportional gain (a gust "
                           "that slows the boat through the water at low speed also takes its "
                           "steering: 150 rather than 60 holds it, 10 % less cross-track RMS "
                           "with a following current)", min=0.0, max=1e4)
    speed_ki: float = spec(10.0, "N/m", "speed controller integral gain", min=0.0, max=1e4)
    heading_kp: float = spec(40.0, "N m/rad", "heading-hold proportional gain", min=0.0, max=1e4)
    heading_kd: float = spec(20.0, "N m s/rad", "heading-hold rate gain", min=0.0, max=1e4)


def xtrack_rate_tau_s(ctl: Control, estimator: str = "simple") -> float:
    """``control.xtrack_rate_tau_s`` (s), or the ``estimator``'s default when unset."""
    tau = ctl.xtrack_rate_tau_s
    return tau if tau is not None else XTRACK_RATE_TAU_S[estimator]
