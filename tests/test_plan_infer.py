"""The lawnmower the AUV's legs make, inferred without a plan given."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.sim.auv import Auv, AuvParams
from tests.test_auv_plan import duration, lawnmower
from tests.tracker_rig import run
from zarco_runtime.tracking.plan import INFERRED_SOURCE
from zarco_runtime.tracking.plan_infer import MAX_LEG_POINTS, LawnmowerInference

Point = tuple[float, float]


def _plans(pts: list[list[float]], v: float, rate: float, rng: np.random.Generator,
           t_end: float) -> list[tuple[float, tuple[Point, ...]]]:
    """What the inference returns, fed once a second until ``t_end`` with the
    state of the simulator's AUV (the campaign's) flying ``pts`` at ``v`` m/s,
    turning at ``rate`` °/s, after hovering 10 s at the first point: the
    position with 0.5 m 1σ of noise, the velocity with 0.05 m/s."""
    auv = Auv(AuvParams(waypoints=pts, speed_mps=v, turn_rate_dps=rate, at_end="stop",
                        start_delay_s=10.0))
    inf = LawnmowerInference()
    got = []
    t = 0.0
    while t < t_end:
        a = auv.truth(t)
        ex, ey = rng.normal(0.0, 0.5, 2)
        p = inf.update(t, a.x_m + ex, a.y_m + ey, a.vx_mps + rng.normal(0.0, 0.05),
                       a.vy_mps + rng.normal(0.0, 0.05))
        if p is not None:
            got.append((t, p))
        t += 1.0
    return got


def _nearest(p: Point, pts: list[list[float]]) -> float:
    return min(math.dist(p, (q[0], q[1])) for q in pts)


@pytest.mark.parametrize("seed", range(12))
def test_a_tight_lawnmower_is_inferred_and_its_next_u_turn_predicted(seed: int) -> None:
    """Tight lawnmowers of the field's range (legs 40–80 m, 10–20 m apart, any
    orientation and sweep, 0.5–1.4 m/s, 6–15 °/s): a plan is inferred before
    the second U-turn when the AUV flies the spacing straight for seconds (a
    short leg square to the long ones), before the third when its turning
    circle is too wide for that (a reversal alone could be any route's).  Its
    first four corners — where the last long leg ends, across the spacing,
    and the U-turn after — are the survey's within 2 m: the AUV begins each
    turn up to a turning radius (here 2.5–8.3 m) before the waypoint, and the
    corner is where its turn reached, not where it began.  An AUV whose
    turning circle is wider than the spacing swings past its corners (within
    4 m)."""
    rng = np.random.default_rng(300 + seed)
    pts, v, rate = lawnmower(rng)
    # a straight stretch of 8 s between the two quarter turns
    straight_spacing = 2.0 * v / math.radians(rate) + 8.0 * v < math.dist(pts[1], pts[2])
    legs_before = 5 if straight_spacing else 7
    plans = _plans(pts, v, rate, rng, 10.0 + duration(pts[:legs_before], v))
    if not plans:
        # a survey whose spacing leaves no straight stretch and whose long legs
        # the noise makes disagree: nothing guessed, which the boat survives
        assert not straight_spacing, (seed, v, rate)
        return
    first = plans[0][1]
    radius = v / math.radians(rate)
    bound = 2.0 if 2.0 * radius <= math.dist(pts[1], pts[2]) else 4.0
    for p in first[:4]:
        assert _nearest(p, pts) < bound, (seed, p, radius)


@pytest.mark.parametrize("seed", range(6))
def test_legs_of_random_lengths_and_turns_make_no_lawnmower(seed: int) -> None:
    """Legs of 40–100 m joined by turns of 30–150° either way: nothing inferred."""
    rng = np.random.default_rng(400 + seed)
    pts = [[0.0, 0.0]]
    c = rng.uniform(-math.pi, math.pi)
    for _ in range(5):
        d = rng.uniform(40.0, 100.0)
        pts.append([pts[-1][0] + d * math.cos(c), pts[-1][1] + d * math.sin(c)])
        c += math.radians(rng.choice([-1.0, 1.0]) * rng.uniform(30.0, 150.0))
    v = float(rng.uniform(0.5, 1.4))
    assert not _plans(pts, v, 10.0, rng, 10.0 + duration(pts, v)), pts


def test_a_straight_run_makes_no_lawnmower() -> None:
    rng = np.random.default_rng(7)
    assert not _plans([[0.0, 0.0], [300.0, 0.0]], 1.0, 10.0, rng, 320.0)


def test_the_tracker_infers_a_lawnmower_from_real_fixes_and_takes_the_auv_on_it() -> None:
    """The LBL simulator (three beacons, missed and false detections) and the
    AUV flying a lawnmower (70 m legs, 25 m apart) without a plan given: the
    tracker infers it from its fixes, queues it for publishing, matches the
    AUV to it, and the AUV stays on it through the next U-turn; a plan given
    afterwards replaces it and stops the inference, and the tracker's own
    plan coming back from the bus changes nothing."""
    pts = [[100.0 + x, 100.0 + y] for x, y in (
        (0, 0), (70, 0), (70, 25), (0, 25), (0, 50), (70, 50), (70, 75), (0, 75))]
    r = run(pts, 20.0 + duration(pts[:6], 1.0), start_delay_s=20.0)  # the second U-turn
    tracker = r.tracker
    legs = [(sm.t, sm.track.plan_leg if sm.track is not None else -1) for sm in r.samples]
    assert tracker.inferred, tracker.plan.events
    first = tracker.inferred[0]
    assert any("from tracker" in e for e in tracker.plan.events)
    assert any(e.startswith("AUV on its plan") for e in tracker.plan.events)
    assert tracker.plan.left == 0, tracker.plan.events
    # the corners of the second U-turn, predicted after the first
    for p in first[2:4]:
        assert _nearest(p, pts) < 3.0 + 1.0 / math.radians(10.0), p
    # on the plan from the join to the end
    joined = next(t for t, leg in legs if leg >= 0)
    assert all(leg >= 0 for t, leg in legs if t > joined)
    tracker.set_plan(first, INFERRED_SOURCE)  # its own, back from the bus
    assert tracker.plan.plan is not None and tracker.plan.leg >= 0
    given = ((0.0, 0.0), (10.0, 0.0))
    tracker.set_plan(given, "mission")
    assert tracker.plan.plan is not None and len(tracker.plan.plan.legs) == 1
    n = len(tracker.inferred)
    tracker.set_plan((), "")  # the given plan cleared: the inferred one serves again
    assert len(tracker.inferred) == n + 1 and tracker.plan.plan is not None
    assert len(tracker.plan.plan.legs) == len(first) - 1


def test_a_long_straight_run_keeps_the_legs_work_bounded() -> None:
    """An hour of fixes along one line: the leg being flown keeps at most its
    latest ``MAX_LEG_POINTS`` positions (the work per update and the memory
    stay bounded) and nothing is inferred."""
    rng = np.random.default_rng(9)
    inf = LawnmowerInference()
    for k in range(3600):
        got = inf.update(float(k), float(k) + rng.normal(0.0, 0.5), rng.normal(0.0, 0.5), 1.0,
                         rng.normal(0.0, 0.03))
        assert got is None
    assert 0 < len(inf._cur) <= MAX_LEG_POINTS


@pytest.mark.parametrize("seed", range(4))
def test_a_swing_of_the_course_early_on_the_first_leg_does_not_lose_the_set_off(
        seed: int) -> None:
    """The filter's course swinging 40° off for a few updates soon after the
    AUV set off (a settling filter) cuts the first long leg in two; the leg
    flown is still one, from the set-off point: the lawnmower is inferred
    after the first U-turn, in time for the second (with the set-off point
    lost it came only after the second), its corners the survey's."""
    rng = np.random.default_rng(500 + seed)
    c = rng.uniform(-math.pi, math.pi)
    ux, uy, sx, sy = math.cos(c), math.sin(c), -math.sin(c), math.cos(c)
    length, w = rng.uniform(60.0, 90.0), rng.uniform(15.0, 25.0)
    pts = [[ux * a * length + sx * b * w, uy * a * length + sy * b * w]
           for a, b in ((0, 0), (1, 0), (1, 1), (0, 1), (0, 2), (1, 2), (1, 3), (0, 3))]
    v, rate = float(rng.uniform(0.7, 1.2)), 10.0
    auv = Auv(AuvParams(waypoints=pts, speed_mps=v, turn_rate_dps=rate, at_end="stop",
                        start_delay_s=10.0))
    inf = LawnmowerInference()
    swing = math.radians(40.0 * rng.choice([-1.0, 1.0]))
    t, got = 0.0, None
    second = 10.0 + duration(pts[:5], v)  # the second U-turn begins about here
    while t < second and got is None:
        a = auv.truth(t)
        vx, vy = a.vx_mps, a.vy_mps
        if 22.0 <= t < 25.0:  # 12-15 s after the set-off
            vx, vy = (vx * math.cos(swing) - vy * math.sin(swing),
                      vx * math.sin(swing) + vy * math.cos(swing))
        ex, ey = rng.normal(0.0, 0.3, 2)
        got = inf.update(t, a.x_m + ex, a.y_m + ey, vx, vy)
        t += 1.0
    assert got, (seed, [(round(leg.t0), round(leg.t1), leg.start) for leg in inf.legs])
    assert len([leg for leg in inf.legs if leg.t0 < 40.0]) >= 2  # the leg was cut
    for p in got[:4]:
        assert _nearest(p, pts) < 2.0 + v / math.radians(rate), (seed, p)
