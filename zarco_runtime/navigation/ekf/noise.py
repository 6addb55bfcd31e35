"""Sensor noise, GPS offset model and gates of the EKF, in filter units, from its settings.

GPS position: white noise of the fix type's σ (or GST's, when fresh) plus a
slowly varying offset state b, a first-order Gauss–Markov process whose σ and
τ depend on the fix type (RTK fixed: millimetres; single point: 1.5 m over
minutes).  Gates: NIS χ²₁ / χ²₂ at 99.9 % per measurement kind.
"""

from __future__ import annotations

import math

from zarco_core.messages import FixQuality
from zarco_runtime.navigation.ekf.layout import IBC, IBG, IPSI, IR, row
from zarco_runtime.navigation.ekf_config import EkfSettings


class SensorNoise:
    """The settings' sensor noise as variances (m², (m/s)², rad², (rad/s)²), the GPS
    offset's σ and τ per fix type, the gates per measurement kind and the constant
    measurement rows."""

    def __init__(self, cfg: EkfSettings) -> None:
        d2r = math.radians
        self.sigma_white = {
            FixQuality.RTK_FIXED: cfg.sigma_rtk_fixed_m,
            FixQuality.RTK_FLOAT: cfg.sigma_rtk_float_m,
            FixQuality.DGPS: cfg.sigma_dgps_m, FixQuality.SINGLE: cfg.sigma_single_m,
        }
        self.bias_sigma = {
            FixQuality.RTK_FIXED: cfg.bias_rtk_fixed_m,
            FixQuality.RTK_FLOAT: cfg.bias_rtk_float_m,
            FixQuality.DGPS: cfg.bias_dgps_m, FixQuality.SINGLE: cfg.bias_single_m,
            FixQuality.NONE: cfg.bias_single_m,
        }
        self.bias_tau = {
            FixQuality.RTK_FIXED: cfg.bias_tau_rtk_fixed_s,
            FixQuality.RTK_FLOAT: cfg.bias_tau_rtk_float_s,
            FixQuality.DGPS: cfg.bias_tau_dgps_s, FixQuality.SINGLE: cfg.bias_tau_single_s,
            FixQuality.NONE: cfg.bias_tau_single_s,
        }
        self.r_vel = cfg.sigma_vel_mps**2
        self.r_compass = d2r(cfg.sigma_compass_deg) ** 2
        self.r_true = d2r(cfg.sigma_true_heading_deg) ** 2
        self.r_rot = d2r(cfg.sigma_rot_dps) ** 2
        self.gates = (cfg.gate_2d, cfg.gate_2d, cfg.gate_1d, cfg.gate_1d, cfg.gate_1d,
                      cfg.gate_1d)
        self.h_compass = row({IPSI: 1.0, IBC: 1.0})
        self.h_true = row({IPSI: 1.0})
        self.h_rot = row({IR: 1.0, IBG: 1.0})
