"""On its plan's straight legs the AUV flies straight: the turn rate a sharp
corner left in the IMM's quiet model is set back to 0 once the AUV is on the
straight part of the next leg (the acoustic rig, a lawnmower U-turn with the
plan given to the tracker: the filter's course on the new leg nearer the truth
than without the plan's check), and never on a leg too short to be straight."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tracker_rig import uturn_course_errors

from zarco_runtime.tracking.maneuver import ManeuverDetector
from zarco_runtime.tracking.plan_geometry import Plan
from zarco_runtime.tracking.plan_progress import STRAIGHT_MIN_M, AlongPlan


def test_a_corners_leftover_turn_rate_is_set_back_on_the_plans_straight_leg(
        monkeypatch: pytest.MonkeyPatch) -> None:
    cases = [(speed, rate, spacing, seed) for seed in (1, 2, 3)
             for speed, rate, spacing in ((0.6, 7.5, 15.0), (0.9, 10.0, 12.0),
                                          (1.2, 8.0, 20.0))]
    # the check on a filter fed whole cycles (as the spin check's test)
    whole = {"half_cycles": False}
    with_plan = [uturn_course_errors(*c, (5.0, 30.0), "fix.plan_straight", plan=True,
                                     trk=whole) for c in cases]
    # once per leg at most (the first leg's start has no corner before it)
    assert all(n <= 2 for _, n in with_plan)
    assert 3 * sum(1 for _, n in with_plan if n >= 1) >= 2 * len(cases)
    # the filter's course on the new leg: better on the whole, never notably worse
    monkeypatch.setattr(ManeuverDetector, "plan_straight", lambda self, kf: False)
    without = [uturn_course_errors(*c, (5.0, 30.0), "fix.plan_straight", plan=True,
                                   trk=whole)[0] for c in cases]
    gains = [b - a for (a, _), b in zip(with_plan, without, strict=True)]
    assert min(gains) >= -2.0
    assert float(np.mean(gains)) >= 3.0


def test_only_a_legs_straight_part_counts() -> None:
    # 60 m legs joined by a 12 m step: the step is all corner at a 6 m radius
    plan = Plan([(0.0, 0.0), (60.0, 0.0), (60.0, 12.0), (0.0, 12.0)])
    radius = 6.0
    def at(s: float) -> int:
        al = AlongPlan.start(plan, 0.0, s, 1.0, 1.0, 0.0, radius)
        al.radius = radius
        return al.on_straight(3.0)
    arc = radius * math.tan(math.radians(45.0))
    assert at(30.0) == 0
    assert at(60.0 - arc - 2.0) == -1  # about the first corner
    assert at(60.0 + 6.0) == -1  # the step: shorter than STRAIGHT_MIN_M between its arcs
    assert 12.0 - 2.0 * (arc + 3.0) < STRAIGHT_MIN_M
    assert at(72.0 + arc + 3.5) == 2
    assert at(72.0 + arc + 2.5) == -1
