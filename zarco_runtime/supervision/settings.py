"""Settings of the supervisor's failsafes (``[failsafe]``)."""

from __future__ import annotations

import math  # noqa: F401
from dataclasses import dataclass

from zarco_core.config import spec


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
