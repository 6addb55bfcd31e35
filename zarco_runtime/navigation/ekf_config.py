"""Settings of the navigation EKF (:mod:`zarco_runtime.navigation.ekf`).

Same conventions as :mod:`zarco_runtime.settings`: every field carries its
unit, its doc and its range; :func:`zarco_core.config.build` validates a
TOML table against this dataclass (the lead hooks it in as
``[navigation.ekf]`` or similar).  Angles are degrees at this edge (``_deg``,
``_dps`` in the names), the filter converts to radians.  Defaults are the Zarco
sensor noise of the vessel's instruments and the vessel model (for the sideslip).

Noise densities are given per √s (random walks): a value q means the state's
standard deviation grows by q·√t over t seconds without measurements.
"""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec

FIX_CHOICES = ["single", "dgps", "rtk_float", "rtk_fixed"]


@dataclass(slots=True)
class EkfSettings:
    """Navigation EKF: sensor noise and latency, process model, gates, validity."""

    # ------------------------------------------------------------ timing
    gps_latency_s: float = spec(0.0, "s", "GPS sentences (and HDT/THS from the GPS) arrive "
                                "this long after their time of validity", min=0.0, max=2.0)
    compass_latency_s: float = spec(0.0, "s", "compass heading latency", min=0.0, max=2.0)
    gyro_latency_s: float = spec(0.0, "s", "rate-of-turn (ROT) latency", min=0.0, max=2.0)
    history_s: float = spec(1.0, "s", "how far back a late measurement is still fused "
                            "(states are re-run from its time of validity); older ones are "
                            "dropped and counted", min=0.05, max=10.0)
    max_step_s: float = spec(0.1, "s", "longest single prediction step", min=0.005, max=1.0)

    # ----------------------------------------------------- GPS position
    min_fix: str = spec("single", "", "worst fix fused (worse fixes count as no GPS)",
                        choices=FIX_CHOICES)
    sigma_rtk_fixed_m: float = spec(0.02, "m", "1σ white position noise per axis, RTK fixed "
                                    "(used when no fresh GST)", min=1e-4, max=100.0)
    sigma_rtk_float_m: float = spec(0.35, "m", "same, RTK float", min=1e-4, max=100.0)
    sigma_dgps_m: float = spec(0.7, "m", "same, DGPS", min=1e-4, max=100.0)
    sigma_single_m: float = spec(1.5, "m", "same, single point", min=1e-4, max=100.0)
    bias_rtk_fixed_m: float = spec(0.003, "m", "1σ of the slowly varying position offset of "
                                   "an RTK-fixed solution (Gauss–Markov state)", min=1e-4,
                                   max=100.0)
    bias_rtk_float_m: float = spec(0.2, "m", "same, RTK float", min=1e-4, max=100.0)
    bias_dgps_m: float = spec(0.5, "m", "same, DGPS", min=1e-4, max=100.0)
    bias_single_m: float = spec(1.5, "m", "same, single point", min=1e-4, max=100.0)
    bias_tau_rtk_fixed_s: float = spec(60.0, "s", "correlation time of the RTK-fixed offset",
                                       min=0.5, max=1e5)
    bias_tau_rtk_float_s: float = spec(60.0, "s", "same, RTK float", min=0.5, max=1e5)
    bias_tau_dgps_s: float = spec(120.0, "s", "same, DGPS", min=0.5, max=1e5)
    bias_tau_single_s: float = spec(300.0, "s", "same, single point", min=0.5, max=1e5)
    upgrade_glide_s: float = spec(10.0, "s", "on a fix upgrade (e.g. single → RTK fixed) the "
                                  "published position glides onto the new solution with this "
                                  "time constant instead of jumping (0: jump); the filter "
                                  "itself takes the new solution at once", min=0.0, max=600.0)
    gst_max_age_s: float = spec(2.0, "s", "use GST σ (instead of the fix-type σ) while "
                                "this fresh and the fix type has not changed", min=0.0,
                                max=60.0)
    gst_floor_m: float = spec(0.005, "m", "smallest white position σ accepted from GST",
                              min=1e-5, max=10.0)
    lever_x_m: float = spec(0.0, "m", "GPS antenna forward of the centre of mass (body x)",
                            min=-10.0, max=10.0)
    lever_y_m: float = spec(0.0, "m", "GPS antenna to starboard of the centre of mass",
                            min=-10.0, max=10.0)

    # ----------------------------------------------------- GPS velocity
    sigma_vel_mps: float = spec(0.05, "m/s", "1σ of each N/E component of the GPS velocity "
                                "(SOG/COG)", min=1e-4, max=10.0)

    # ---------------------------------------------------------- heading
    sigma_compass_deg: float = spec(1.0, "deg", "1σ white noise of the compass heading",
                                    min=0.01, max=45.0)
    sigma_true_heading_deg: float = spec(0.3, "deg", "1σ of a true heading (HDT/THS) from a "
                                         "source in true_heading_sources", min=0.01, max=45.0)
    true_heading_sources: list[str] = spec(lambda: ["gps"], "", "message sources whose "
                                           "HDT/THS is an unbiased true heading (dual-antenna "
                                           "GNSS); any other heading is a compass, with a bias")
    compass_bias_sigma_deg: float = spec(3.0, "deg", "1σ prior of the compass bias (residual "
                                         "after calibration, 1–3°)", min=0.0,
                                         max=45.0)
    compass_bias_walk_deg: float = spec(0.005, "deg/√s", "random walk of the compass bias",
                                        min=0.0, max=10.0)

    # ------------------------------------------------------------- gyro
    sigma_rot_dps: float = spec(0.1, "deg/s", "1σ white noise of the rate of turn (ROT)",
                                min=1e-4, max=100.0)
    gyro_bias_sigma_dps: float = spec(1.0, "deg/s", "1σ prior of the gyro bias (turn-on "
                                      "bias ≈ 0.5°/s)", min=0.0, max=100.0)
    gyro_bias_walk_dps: float = spec(0.002, "deg/s/√s", "random walk of the gyro bias",
                                     min=0.0, max=10.0)
    yaw_accel_walk_dps: float = spec(10.0, "deg/s/√s", "random forcing of the yaw rate "
                                     "(how fast r may change between measurements beyond the "
                                     "model's: yaw gusts of 2 N m on Zarco ≈ 7°/s/√s)",
                                     min=0.01, max=1e4)

    # ------------------------------------------- vessel model (thrusters)
    thrust_model: bool = spec(True, "", "predict surge and yaw from the thruster commands "
                              "(ThrusterCommand) through the vessel model and the thruster "
                              "maps while commands arrive; otherwise (or without commands) "
                              "surge speed and yaw rate are random walks")
    command_timeout_s: float = spec(0.5, "s", "thruster commands older than this stop being "
                                    "a prediction input", min=0.05, max=10.0)
    yaw_damping_quad: float = spec(-250.0, "N m s²", "quadratic yaw damping N_|r|r of the "
                                   "hull for the prediction (the runtime's [vessel] model, "
                                   "which control designs its gains on, is linear in yaw; "
                                   "the vessel model: −250)", min=-1e5, max=0.0)
    surge_noise_mps: float = spec(0.07, "m/s/√s", "random forcing of the surge speed about "
                                  "the model's (gusts, chop: 5 N on Zarco ≈ 0.026 m/s about "
                                  "a 0.26 s surge time constant)", min=1e-4, max=10.0)
    model_accel_error: float = spec(0.3, "", "relative 1σ of the model's net surge and yaw "
                                    "accelerations (mass and inertia ±25 %, thrust lag "
                                    "0.1–0.3 s): process noise while the boat speeds up, "
                                    "slows down or turns", min=0.0, max=5.0)
    lag_error: float = spec(0.5, "", "relative 1σ of the thrust lag (0.1–0.3 s about the "
                            "model's 0.15 s): the thrust still to come after a command "
                            "change is that uncertain", min=0.0, max=5.0)
    model_error_tau_s: float = spec(0.5, "s", "correlation time of that model error (turns "
                                    "its 1σ into a noise density)", min=0.01, max=10.0)
    thrust_scale_sigma: float = spec(0.25, "", "1σ prior of the thrust/drag scale η (the "
                                     "model's thrust is η·(F1 + F2): hull drag ±25 %, thrust "
                                     "curve ±15 %)", min=0.0, max=2.0)
    thrust_scale_walk: float = spec(0.003, "1/√s", "random walk of η (fouling, payload, "
                                    "sea state)", min=0.0, max=1.0)
    yaw_mismatch_sigma: float = spec(0.1, "", "1σ prior of the thruster mismatch ε (the "
                                     "model's thrusts are (1 + ε) f1 and (1 − ε) f2: Δf up to "
                                     "10 %; a misalignment's yaw moment looks alike)",
                                     min=0.0, max=2.0)
    misalignment_sigma_deg: float = spec(2.0, "deg", "1σ prior of the thrusters' "
                                         "differential misalignment (φ1 − φ2)/2: its side "
                                         "force (φ1 − φ2)/2·(F1 − F2) makes the hull slip in "
                                         "hard turns (up to ±3° per thruster, set at launch)",
                                         min=0.0, max=30.0)
    misalignment_common_sigma_deg: float = spec(0.0, "deg", "1σ prior of the common "
                                                "misalignment (φ1 + φ2)/2, whose side force "
                                                "makes a steady crab that on a line looks "
                                                "like a compass bias (0: held at zero; the "
                                                "bias takes it)", min=0.0, max=30.0)
    yaw_mismatch_walk: float = spec(0.003, "1/√s", "random walk of ε", min=0.0, max=1.0)
    rest_speed_sigma_mps: float = spec(0.05, "m/s", "1σ of the speed through the water of a "
                                       "boat whose thrusters are stopped (it drifts with the "
                                       "water; wind, chop): with the thrust model, the first "
                                       "GPS velocity then measures the current", min=0.001,
                                       max=5.0)
    rest_max_speed_mps: float = spec(0.6, "m/s", "a first GPS velocity with no thrust "
                                     "applied yet counts as the boat at rest in the water "
                                     "(drifting with the current) below this speed over "
                                     "ground; above it, as a boat still coasting", min=0.0,
                                     max=5.0)
    sway_model_error: float = spec(0.3, "", "relative 1σ of the turn-induced sway a·u·r "
                                   "(hull ±25 %)", min=0.0, max=5.0)

    # ------------------------------------------------- motion / current
    accel_walk_mps: float = spec(0.01, "m/s/√s", "random walk of the surge speed through the "
                                 "water without the thrust model (speed changes)", min=1e-4,
                                 max=100.0)
    max_accel_mps2: float = spec(5.0, "m/s²", "a GPS velocity beyond its gate but within "
                                 "this acceleration of the last one is a manoeuvre: the speed "
                                 "and position variances are opened and it is fused (250 N on "
                                 "50 kg ≈ 5 m/s² for Zarco)", min=0.1, max=100.0)
    sway_sigma_mps: float = spec(0.035, "m/s", "stationary 1σ of the sway speed through the "
                                 "water about its turn-induced value (gusts, chop)",
                                 min=1e-4, max=10.0)
    sway_tau_s: float = spec(1.0, "s", "sway time constant (m − Y_v')/(−Y_v): 112.5/112.5 "
                             "for Zarco (with a vessel model, taken from it)", min=0.05,
                             max=60.0)
    sway_coupling: float = spec(0.4, "", "sway response to a turn, v' = −a·u·r − v/τ: "
                                "a = m/(m − Y_v') = 45/112.5 for Zarco (steady sideslip "
                                "v = −a·τ·u·r; with a vessel model, taken from it)",
                                min=0.0, max=1.0)
    estimate_current: bool = spec(True, "", "estimate a constant water current (observable "
                                  "from the crab angle over different headings)")
    current_sigma_mps: float = spec(0.3, "m/s", "1σ prior of each current component "
                                    "(0–0.5 m/s)", min=0.0, max=5.0)
    current_walk_mps: float = spec(0.001, "m/s/√s", "random walk of the current", min=0.0,
                                   max=1.0)
    course_init_speed_mps: float = spec(0.5, "m/s", "without any heading sensor, initialise "
                                        "the heading from the GPS course above this speed "
                                        "(heading stays flagged invalid)", min=0.05,
                                        max=10.0)

    # ------------------------------------------------------------ gates
    gate_1d: float = spec(10.83, "", "NIS gate of scalar measurements (χ²₁, 99.9 %)",
                          min=1.0, max=1e6)
    gate_2d: float = spec(13.82, "", "NIS gate of 2-D measurements (χ²₂, 99.9 %)",
                          min=1.0, max=1e6)
    reset_after_s: float = spec(3.0, "s", "a sensor rejected by its gate continuously for "
                                "this long re-initialises its part of the state (and counts "
                                "a reset)", min=0.1, max=600.0)
    frozen_count: int = spec(8, "", "identical compass readings in a row that, with the gyro "
                             "turning, mean a frozen compass", min=2, max=10000)
    frozen_turn_deg: float = spec(3.0, "deg", "heading change (gyro) during a repeated "
                                  "compass value that flags it frozen", min=0.1, max=180.0)
    jump_deg: float = spec(10.0, "deg", "compass step not explained by the gyro that counts as "
                           "a jump", min=0.5, max=180.0)
    jump_count: int = spec(3, "", "jumps within jump_window_s that flag the compass as "
                           "jumping (all its readings rejected)", min=1, max=1000)
    jump_window_s: float = spec(2.0, "s", "window of the jump count", min=0.05, max=600.0)
    jump_clear_s: float = spec(3.0, "s", "no jump for this long clears the flag", min=0.05,
                               max=600.0)

    # --------------------------------------------------------- validity
    dr_max_s: float = spec(10.0, "s", "position stays valid this long without GPS "
                           "(dead reckoning)", min=0.0, max=3600.0)
    pos_sigma_max_m: float = spec(3.0, "m", "position invalid when its 1σ (worse axis) "
                                  "exceeds this", min=0.01, max=1e4)
    heading_dr_max_s: float = spec(30.0, "s", "heading stays valid this long on the gyro "
                                   "alone", min=0.0, max=3600.0)
    heading_sigma_max_deg: float = spec(10.0, "deg", "heading invalid when its 1σ exceeds "
                                        "this", min=0.01, max=180.0)
    sensor_timeout_s: float = spec(1.0, "s", "a sensor silent this long counts as absent "
                                   "(has_gyro)", min=0.05, max=60.0)

    def validate(self) -> None:
        pairs = (("bias_rtk_fixed_m", "bias_rtk_float_m"), ("bias_rtk_float_m", "bias_dgps_m"),
                 ("bias_dgps_m", "bias_single_m"))
        for better, worse in pairs:
            if getattr(self, better) > getattr(self, worse):
                raise ValueError(f"{better}: must not exceed {worse} (a better fix has the "
                                 "smaller offset; the order decides upgrade vs downgrade)")
