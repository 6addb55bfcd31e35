"""Settings of navigation (``[navigation]``): which estimator, and the first estimate's."""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec


@dataclass(slots=True)
class Navigation:
    """Navigation: the EKF (``navigation/ekf/``, settings in ``[ekf]``) or the
    first estimate (per-axis constant-velocity filter on GPS, and a complementary
    filter of compass heading with the gyro rate; the settings below)."""

    estimator: str = spec("ekf", "", "which estimator feeds the controller: the EKF "
                          "(settings in [ekf]), or the first estimate kept as a fallback "
                          "(settings below)", choices=["ekf", "simple"])

    accel_psd: float = spec(0.02, "m²/s³", "acceleration noise density of the "
                            "constant-velocity position filter", min=1e-6, max=100.0)
    sog_sigma_mps: float = spec(0.05, "m/s", "1σ assumed for GPS speed/course over ground "
                                "(0.05)", min=0.001, max=10.0)
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
