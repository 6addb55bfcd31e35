"""Above an AUV waiting at the start of its a-priori plan, in the simulator:
with the water current along its first leg (which drifted the boat to 4-5 m
ahead of the AUV, where it waited), the boat holds a station just ahead of it,
facing the leg: its median distance over the wait within 3.5 m, its p95
within 6 m.
Missions drawn from the field's ranges (the AUV waiting 60-90 s, current
0.15-0.35 m/s within 40 deg of the first leg, the boat starting 3 m off)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario

FOLLOW = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "follow_turn.toml"


@pytest.mark.parametrize("seed", [31, 32, 33])
def test_above_an_auv_waiting_on_its_plan_the_boat_keeps_within_4_m(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.0, math.tau)
    ux, uy = math.cos(a), math.sin(a)
    x0, y0 = 170.0 + rng.uniform(-20, 20), 150.0 + rng.uniform(-20, 20)
    pts = [[round(x0, 2), round(y0, 2)], [round(x0 + 50.0 * ux, 2), round(y0 + 50.0 * uy, 2)]]
    wait = rng.uniform(60.0, 90.0)
    current_dir = math.degrees(a) + rng.uniform(-40.0, 40.0)
    sets = [f"auv.waypoints={json.dumps(pts)}", "auv.speed_mps=0.8",
            f"auv.start_delay_s={wait:.1f}", f"mission.auv_plan={json.dumps(pts)}",
            f"world.x_m={x0 - 3.0 * uy:.2f}", f"world.y_m={y0 + 3.0 * ux:.2f}",
            f"runtime.tracker.prior_north_m={x0:.2f}",
            f"runtime.tracker.prior_east_m={y0:.2f}",
            f"world.current.speed_mps={rng.uniform(0.15, 0.35):.3f}",
            f"world.current.direction_deg={current_dir % 360.0:.1f}",
            f"scenario.max_duration_s={wait:.1f}"]
    res = run_scenario(load_scenario(FOLLOW, sets, seed))
    log, auv = res.log, res.extra["auv_log"]
    acquired = res.report["acquired_s"]
    assert acquired is not None and acquired < 20.0
    d = [math.hypot(bx - a_[1], by - a_[2])
         for t, bx, by, a_ in zip(log.t, log.x, log.y, auv, strict=False) if t >= acquired + 10.0]
    # a station a little ahead, not anywhere up to 5 m ahead: most of the wait
    # well within 4 m, and never far off (the p95 target over the wait, 4 m, is
    # met on most missions of this kind but not all: docs/operating.md)
    assert len(d) > 100
    assert float(np.median(d)) <= 3.5, f"median {np.median(d):.2f} m"
    assert float(np.percentile(d, 95)) <= 6.0, f"p95 {np.percentile(d, 95):.2f} m"


@pytest.mark.parametrize("seed", [41, 42])
def test_before_the_auv_is_heard_the_boat_waits_above_its_plans_start(seed: int) -> None:
    """The buoy's feed silent for the first 40 s (the AUV not yet heard), the
    boat 20-30 m from the start of the AUV's plan: with the plan it is within
    4 m of the AUV when the first fixes come; without it, it has waited where it
    was (more than 15 m off; no current here to drift it)."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.0, math.tau)
    x0, y0 = 150.0 + rng.uniform(-20, 20), 120.0 + rng.uniform(-20, 20)
    pts = [[round(x0, 2), round(y0, 2)],
           [round(x0 + 60.0 * math.cos(a), 2), round(y0 + 60.0 * math.sin(a), 2)]]
    b, r = rng.uniform(0.0, math.tau), rng.uniform(20.0, 30.0)
    sets = [f"auv.waypoints={json.dumps(pts)}", "auv.speed_mps=0.8", "auv.start_delay_s=90",
            f"world.x_m={x0 + r * math.cos(b):.2f}", f"world.y_m={y0 + r * math.sin(b):.2f}",
            f"runtime.tracker.prior_north_m={x0:.2f}", f"runtime.tracker.prior_east_m={y0:.2f}",
            'faults=[{kind="silence", device="buoy", at_s=0.0, duration_s=40.0}]',
            "world.current.speed_mps=0.0", "scenario.max_duration_s=60"]
    for plan in (True, False):
        res = run_scenario(load_scenario(
            FOLLOW, [*sets, f"mission.auv_plan={json.dumps(pts)}"] if plan else sets, seed))
        log, auv = res.log, res.extra["auv_log"]
        acquired = res.report["acquired_s"]
        assert acquired is not None and acquired >= 40.0
        d = [math.hypot(bx - a_[1], by - a_[2])
             for t, bx, by, a_ in zip(log.t, log.x, log.y, auv, strict=False)
             if abs(t - acquired) <= 0.5]
        assert d, "no sample at acquisition"
        if plan:
            assert max(d) <= 4.0, f"{max(d):.2f} m from the AUV at its first fix"
        else:
            assert min(d) > 15.0, f"{min(d):.2f} m: the boat moved before the AUV was heard"
