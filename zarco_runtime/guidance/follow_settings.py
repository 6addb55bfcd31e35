"""Settings of following the AUV (``[follow]``)."""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec

#: the follow laws (``follow.law``)
LAWS = ("los", "paper")


@dataclass(slots=True)
class FollowSettings:
    """``[follow]`` table of the runtime configuration."""

    law: str = spec("los", "", "the follow law: 'los' (line of sight to an aim point a "
                    "look-ahead ahead of the AUV on its path, the catch-up in the speed "
                    "reference) or 'paper' (the paper's: the AUV's line tracked with the "
                    "line controller, the surge force on the along-track lead)",
                    choices=list(LAWS))
    k_s: float = spec(5.0, "N/m", "los: surge force per metre the AUV is ahead along its "
                      "track (the speed reference already closes the gap)", min=0.0, max=1e4)
    k_i: float = spec(0.0, "N/(m s)", "los: integral of the along-track lead (the speed "
                      "loop's integral already removes a steady lag)", min=0.0, max=1e4)
    paper_k_s: float = spec(40.0, "N/m", "paper: k_s, surge force per metre of along-track "
                            "lead s_AUV − s (the law's only catch-up)", min=0.0, max=1e4)
    paper_k_i: float = spec(1.0, "N/(m s)", "paper: k_i, on the integral of the lead",
                            min=0.0, max=1e4)
    along_clamp_m: float = spec(8.0, "m", "along-track lead (either sign) used at most by "
                                "the surge law", min=0.1, max=1e4)
    min_speed_mps: float = spec(0.3, "m/s", "slowest speed reference while following (ahead "
                                "of the AUV): enough to steer across a current",
                                min=0.0, max=3.0)
    max_speed_mps: float = spec(2.0, "m/s", "fastest speed reference while catching up "
                                "(above the boat's top speed: behind a fast AUV the boat "
                                "closes at full thrust)",
                                min=0.1, max=3.0)
    lookahead_m: float = spec(3.0, "m", "line-of-sight look-ahead Δ: the ASV converges "
                              "onto the AUV's track at atan(offset/Δ); shorter turns the "
                              "boat sooner after the AUV turns, too short steers the fixes' "
                              "noise", min=0.5, max=100.0)
    max_turn_rate_dps: float = spec(40.0, "deg/s", "the virtual leg's course turns no "
                                    "faster than this (the estimate's jitter is not "
                                    "steered; slower lets the boat trail turns)",
                                    min=1.0, max=360.0)
    catchup_tau_s: float = spec(3.0, "s", "time constant of closing an along-track gap "
                                "(speed reference v_AUV + gap/τ; a metre behind is a "
                                "third of a metre per second more)", min=0.5, max=600.0)
    target_tau_s: float = spec(3.0, "s", "the AUV's position is low-passed over this about "
                               "its velocity (fixes move the aim smoothly; about three "
                               "fixes at the usual 1 s cycle)", min=0.01, max=60.0)
    line_gate_m: float = spec(3.0, "m", "the RLS line is used only while its position "
                              "agrees with the Kalman filter's within this plus 3σ",
                              min=0.1, max=1000.0)
    line_course_gate_deg: float = spec(20.0, "deg", "… and while its course agrees with the "
                                       "Kalman filter's within this", min=1.0, max=180.0)
    lost_after_s: float = spec(20.0, "s", "no accepted fix for this long → track lost",
                               min=1.0, max=3600.0)
    max_pos_sigma_m: float = spec(15.0, "m", "track position σ above this → track lost",
                                  min=0.1, max=1e4)
    new_line_deg: float = spec(20.0, "deg", "course change that starts a new virtual leg "
                               "(the line controller resets its cross-track states)",
                               min=1.0, max=180.0)
    hold_radius_m: float = spec(1.5, "m", "while holding, drift freely within this radius",
                                min=0.5, max=1000.0)
    hold_above_sigma_m: float = spec(2.0, "m", "hold above a still AUV only once its "
                                     "position σ is below this", min=0.1, max=100.0)
    still_speed_mps: float = spec(0.3, "m/s", "a still AUV starts moving when its speed "
                                  "exceeds this (and 1.5σ); a moving one stops when its "
                                  "speed plus 2σ is below it", min=0.01, max=2.0)
    hold_speed_mps: float = spec(0.5, "m/s", "speed back to the hold point", min=0.05,
                                 max=2.0)
