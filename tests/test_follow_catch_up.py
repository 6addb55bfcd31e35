"""Behind an AUV near the boat's top speed, the boat closes at the speed it has.

The follow guidance's speed reference is capped (``follow.max_speed_mps``);
a cap under the boat's own top speed would leave a fast AUV's follower only
part of the little speed it has to close a gap (after a turn, at the start).
Here the AUV runs a straight leg at 1.45 m/s from the start, the boat starts
25 m behind it with thrusters good for about 1.7 m/s, and while it is well
behind its speed over ground must be its top speed through the water (no
current), within the 5 % a boat steering and fighting the disturbance loses.
"""

from __future__ import annotations

import bisect
import math
from pathlib import Path

from zarco_tools.campaign.physics import straight_thrust, top_speed
from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario

ROOT = Path(__file__).resolve().parents[1]
TURN = ROOT / "config" / "scenarios" / "follow_turn.toml"
AUV_MPS = 1.45


def test_well_behind_a_fast_auv_the_boat_goes_at_its_top_speed() -> None:
    scn = load_scenario(TURN, [
        "scenario.max_duration_s=120", "world.x_m=75.0", "world.y_m=100.0",
        "world.current.speed_mps=0.0", "world.thrusters.fwd_max_n=150.0",
        f"auv.speed_mps={AUV_MPS}", "auv.start_delay_s=5.0"], seed=3)
    th, ve = scn.world.thrusters, scn.world.vessel
    u_max = top_speed(ve.x_u, ve.x_uu, straight_thrust(th.fwd_max_n, th.mismatch,
                                                      th.phi1_deg, th.phi2_deg))
    assert u_max >= AUV_MPS + 0.2  # the boat can close, by more than a 1.5 m/s cap allows
    res = run_scenario(scn)
    log, auv = res.log, res.extra["auv_log"]
    acquired = res.report["acquired_s"]
    assert math.isfinite(acquired)
    # speed over ground over 5 s windows, from 15 s after acquisition (turned
    # towards the AUV and up to speed) while the boat is more than 6 m behind
    speeds = []
    for i, t in enumerate(log.t):
        j = bisect.bisect_left(log.t, t + 5.0)
        if t < acquired + 15.0 or j == len(log.t):
            continue
        gap = math.hypot(auv[j][1] - log.x[j], auv[j][2] - log.y[j])
        if gap <= 6.0:
            break
        speeds.append(math.hypot(log.x[j] - log.x[i], log.y[j] - log.y[i]) / (log.t[j] - t))
    assert len(speeds) > 50, "the boat caught up too soon to measure its speed"
    mean = sum(speeds) / len(speeds)
    assert mean >= 0.95 * u_max, f"{mean:.3f} m/s behind the AUV, top speed {u_max:.3f}"
