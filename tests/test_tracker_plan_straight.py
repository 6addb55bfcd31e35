"""On its plan's straight legs the AUV flies straight: the turn rate a sharp
corner left in the IMM's quiet model is set back to 0 once the AUV is on the
straight part of the next leg (the acoustic rig, a lawnmower U-turn with the
plan given to the tracker: the filter's course on the new leg nearer the truth
than without the plan's check), also while the IMM still holds the turn (its
turning models then forget the turn's rate as well: the filter's course is
never worse for it), and never on a leg too short to be straight."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tracker_rig import uturn_course_errors

from zarco_runtime.tracking.imm import Imm
from zarco_runtime.tracking.maneuver import ManeuverDetector
from zarco_runtime.tracking.params import TrackerParams
from zarco_runtime.tracking.plan_geometry import Plan
from zarco_runtime.tracking.plan_progress import STRAIGHT_MIN_M, AlongPlan
from zarco_runtime.tracking.tracker import imm_bank


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


def _turned_bank(params: TrackerParams, rate_dps: float) -> Imm:
    """The tracker's IMM flying north at 1.2 m/s, every model's turn rate at
    ``rate_dps`` (what a U-turn leaves) and the probabilities spread (the
    manoeuvre not yet over)."""
    f = imm_bank(params)
    f.init(0.0, 0.0, 0.0, 1.2, 0.0, 1.0, 0.05)
    for m in f.models:
        m.x[4] = math.radians(rate_dps)
    f.mu = [0.5, 0.05, 0.15, 0.1, 0.2]
    return f


def test_while_the_imm_holds_the_turn_every_model_forgets_its_rate() -> None:
    params = TrackerParams()
    w0 = math.radians(params.turn_rate_dps)
    det = ManeuverDetector(params)
    det.maneuvering = True
    f = _turned_bank(params, -8.0)
    assert det.plan_straight(f)
    expect = [0.0, None, 0.0, w0, -w0]  # the turning models back to what they expect
    for m, w in zip(f.models, expect, strict=True):
        if w is not None:
            assert m.x[4] == pytest.approx(w)
            assert m.P[4][4] <= max(m.omega0_var, math.radians(0.5) ** 2) * (1 + 1e-9)
    # the combined turn rate is no longer the turn's: within the turning
    # models' share of ±w0
    assert abs(f.omega) <= (f.mu[3] + f.mu[4]) * w0 + 1e-9
    # the IMM taken to fly straight: the turning models keep what they learnt
    det.maneuvering = False
    g = _turned_bank(params, -8.0)
    assert det.plan_straight(g)
    assert g.models[0].x[4] == 0.0
    assert all(m.x[4] == pytest.approx(math.radians(-8.0)) for m in g.models[2:])


def test_the_check_holds_while_the_imm_still_takes_the_auv_to_turn(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # U-turns of fast AUVs on tight lawnmowers: the IMM's probability of a
    # manoeuvre lingers about 0.5 on the next leg (every model has the turn's
    # rate, none predicts better)
    cases = [(speed, rate, spacing, seed) for seed in (1, 2, 3)
             for speed, rate, spacing in ((1.0, 8.0, 15.0), (1.25, 10.0, 12.0))]
    held: list[bool] = []
    check = ManeuverDetector.plan_straight

    def seen(self: ManeuverDetector, kf: Imm) -> bool:
        held.append(self.maneuvering)
        return check(self, kf)

    monkeypatch.setattr(ManeuverDetector, "plan_straight", seen)
    now = [uturn_course_errors(*c, (5.0, 30.0), "fix.plan_straight", plan=True)[0]
           for c in cases]
    assert any(held)  # checked while the IMM held the turn

    def only_when_straight(self: ManeuverDetector, kf: Imm) -> bool:
        return False if self.maneuvering else check(self, kf)

    monkeypatch.setattr(ManeuverDetector, "plan_straight", only_when_straight)
    before = [uturn_course_errors(*c, (5.0, 30.0), "fix.plan_straight", plan=True)[0]
              for c in cases]
    gains = [b - a for a, b in zip(now, before, strict=True)]
    assert min(gains) >= -1.0
    assert max(gains) >= 2.0
