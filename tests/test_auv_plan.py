"""The AUV's a-priori plan: its geometry, matching the AUV to it, noticing when
the AUV leaves it (an adaptive mission) and comes back, the corners the
tracker's prediction reaches.  The AUV is the simulator's (its turns anticipate
the corner by its turning radius), sampled as the tracker's filter would see
it: every 1.5–2.5 s, with position noise."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from drivers.sim.auv import Auv, AuvParams
from zarco_core.auv_messages import AuvFix
from zarco_runtime.tracking.kalman import CvKalman
from zarco_runtime.tracking.plan import (
    MAX_POINTS,
    Plan,
    PlanError,
    PlanMatcher,
    PlanParams,
    check_points,
    geodetic_plan,
)
from zarco_runtime.tracking.plan_flown import Flown


def lawnmower(rng: np.random.Generator) -> tuple[list[list[float]], float, float]:
    """A tight lawnmower of the field's range: legs 40–80 m, 10–20 m apart,
    4–6 long legs, any orientation; its AUV speed (0.5–1.4 m/s) and turn rate
    (6–15 °/s)."""
    length = rng.uniform(40.0, 80.0)
    gap = rng.uniform(10.0, 20.0)
    a = rng.uniform(0.0, math.tau)
    side = rng.choice([-1.0, 1.0])
    ux, uy = math.cos(a), math.sin(a)
    nx, ny = -uy * side, ux * side
    x0, y0 = rng.uniform(-100.0, 100.0, 2)
    pts = []
    for i in range(int(rng.integers(4, 7))):
        along = (0.0, length) if i % 2 == 0 else (length, 0.0)
        for s in along:
            pts.append([x0 + s * ux + i * gap * nx, y0 + s * uy + i * gap * ny])
    return pts, float(rng.uniform(0.5, 1.4)), float(rng.uniform(6.0, 15.0))


def fly(matcher: PlanMatcher, auv: Auv, t_end: float, rng: np.random.Generator,
        sigma: float = 1.0) -> list[tuple[float, int]]:
    """Feed the matcher the AUV's state (position with ``sigma`` noise, velocity
    with 0.05 m/s noise), that position as the fix, at 1.5–2.5 s intervals
    until ``t_end``; the (t, leg) history."""
    out = []
    t = 0.0
    while t < t_end:
        a = auv.truth(t)
        ex, ey = rng.normal(0.0, sigma, 2)
        evx, evy = rng.normal(0.0, 0.05, 2)
        fx, fy = a.x_m + ex, a.y_m + ey
        fix = AuvFix(t, t, 1, fx, fy, fx, fy, 0.0, 0.0, 0.0, True, False, sigma ** 2, 0.0,
                     sigma ** 2)
        matcher.fix(fix)
        matcher.update(t, fx, fy, a.vx_mps + evx, a.vy_mps + evy, sigma)
        out.append((t, matcher.leg))
        t += float(rng.uniform(1.5, 2.5))
    return out


def fly_tracked(matcher: PlanMatcher, auv: Auv, t_end: float, rng: np.random.Generator,
                sigma: float = 1.0, accel_psd: float = 0.004,
                beacon: tuple[float, float] | None = None,
                ranges: bool = True) -> list[tuple[float, int]]:
    """As :func:`fly`, with a constant-velocity Kalman filter (white
    acceleration ``accel_psd``, m²/s³: the tracker's quiet model, slow to
    turn) fed with the fixes: its prediction to each fix goes to the matcher
    with the fix, its state after the update to :meth:`PlanMatcher.update`.
    With a ``beacon`` (NED, m), a two-beacon network: every other cycle is a
    range alone (``sigma`` m of noise) to it, which the filter takes as a
    one-row update and the matcher is given with the filter's prediction
    (:meth:`PlanMatcher.range_fix`; not with ``ranges`` false)."""
    out = []
    kf = CvKalman(accel_psd)
    t = 0.0
    for i in itertools.count():
        if t >= t_end:
            break
        a = auv.truth(t)
        if beacon is not None and i % 2 == 1:
            bx, by = beacon
            r = math.hypot(a.x_m - bx, a.y_m - by) + float(rng.normal(0.0, sigma))
            if ranges:
                matcher.range_fix(t, bx, by, r, sigma ** 2, kf.predicted(t))
            kf.predict(t)
            px, py = kf.x[0], kf.x[1]
            h = math.hypot(px - bx, py - by)
            row = ((px - bx) / h, (py - by) / h)
            kf.update([row], [r - h + row[0] * px + row[1] * py], [sigma ** 2])
        else:
            ex, ey = rng.normal(0.0, sigma, 2)
            fx, fy = a.x_m + ex, a.y_m + ey
            if not kf.initialised:
                kf.init(t, fx, fy, a.vx_mps, a.vy_mps, sigma ** 2, 0.05 ** 2)
            fix = AuvFix(t, t, 1, fx, fy, fx, fy, 0.0, 0.0, 0.0, True, False, sigma ** 2,
                         0.0, sigma ** 2)
            matcher.fix(fix, kf.predicted(t))
            kf.predict(t)
            kf.update([(1.0, 0.0), (0.0, 1.0)], [fx, fy], [sigma ** 2, sigma ** 2])
        matcher.update(t, kf.x[0], kf.x[1], kf.x[2], kf.x[3], kf.pos_sigma(),
                       math.sqrt(0.5 * (kf.P[2][2] + kf.P[3][3])))
        out.append((t, matcher.leg))
        t += float(rng.uniform(1.5, 2.5))
    return out


def auv_on(points: list[list[float]], speed: float, rate: float) -> Auv:
    return Auv(AuvParams(waypoints=points, speed_mps=speed, turn_rate_dps=rate,
                         at_end="stop"))


def duration(points: list[list[float]], speed: float) -> float:
    return sum(math.dist(a, b) for a, b in itertools.pairwise(points)) / speed


# ------------------------------------------------------------------ geometry


def test_legs_corners_and_the_path_coordinate() -> None:
    plan = Plan([(0.0, 0.0), (100.0, 0.0), (100.0, 20.0), (0.0, 20.0)])
    assert [lg.length_m for lg in plan.legs] == pytest.approx([100.0, 20.0, 100.0])
    assert [lg.s0_m for lg in plan.legs] == pytest.approx([0.0, 100.0, 120.0])
    assert plan.length_m == pytest.approx(220.0)
    # north then east: a turn to starboard (+90°); east then south-west... back north-side
    assert math.degrees(plan.turn_rad(0)) == pytest.approx(90.0)
    assert math.degrees(plan.turn_rad(1)) == pytest.approx(90.0)
    assert plan.turn_rad(2) == 0.0  # after the last leg
    x, y, course = plan.point_at(110.0)
    assert (x, y) == pytest.approx((100.0, 10.0)) and course == pytest.approx(math.pi / 2)
    # 2 m to starboard of the third leg (heading south: starboard is west)
    x, y, _ = plan.point_at(170.0, 2.0)
    assert (x, y) == pytest.approx((50.0, 18.0))
    # beyond the ends the first and last legs go on
    assert plan.point_at(-10.0)[:2] == pytest.approx((-10.0, 0.0))
    assert plan.point_at(230.0)[:2] == pytest.approx((-10.0, 20.0))


def test_nearest_looks_only_in_its_window() -> None:
    """Two legs 20 m apart: a point between them belongs to the one the window
    holds (the AUV's neighbourhood on the path), not the nearer overall."""
    plan = Plan([(0.0, 0.0), (100.0, 0.0), (100.0, 20.0), (0.0, 20.0)])
    s, c = plan.nearest(50.0, 12.0, 0.0, 100.0)  # the first leg only
    assert s == pytest.approx(50.0) and c == pytest.approx(12.0)
    s, c = plan.nearest(50.0, 12.0, 130.0, 220.0)  # the last leg only
    assert s == pytest.approx(170.0) and c == pytest.approx(8.0)  # starboard of southward
    s, _ = plan.nearest(50.0, 12.0, 0.0, 220.0)
    assert s == pytest.approx(170.0)


def test_a_corner_is_rounded_by_the_arc_tangent_to_both_legs() -> None:
    """A 90° corner with turning radius R: the arc leaves the first leg R before
    the corner and joins the next R after it; half-way (the path coordinate of
    the corner itself) it passes R(√2 − 1) inside the corner, heading 45° off."""
    plan = Plan([(0.0, 0.0), (100.0, 0.0), (100.0, 50.0)])
    for r in (2.0, 6.0, 11.0):
        x, y, c = plan.point_at(100.0, 0.0, r)
        assert math.hypot(100.0 - x, 0.0 - y) == pytest.approx(r * (math.sqrt(2.0) - 1.0))
        assert (100.0 - x) == pytest.approx(y)  # on the corner's bisector, inside
        assert c == pytest.approx(math.pi / 4)
        assert plan.point_at(100.0 - r, 0.0, r)[:2] == pytest.approx((100.0 - r, 0.0))
        assert plan.point_at(100.0 + r, 0.0, r)[:2] == pytest.approx((100.0, r))
        # the arc is a quarter circle: πR/2 metres of path cover 2R of the plan
        assert plan.advance(100.0 - r, math.pi * r / 2.0, r) == pytest.approx(100.0 + r)
        assert plan.advance(100.0 + r, -math.pi * r / 2.0, r) == pytest.approx(100.0 - r)
        assert plan.advance(10.0, 30.0, r) == pytest.approx(40.0)  # straight: metre for metre


@pytest.mark.parametrize(("route", "speed", "rate_dps"), [
    ([(0.0, 0.0), (65.0, 0.0), (65.0, 18.0), (0.0, 18.0), (0.0, 36.0), (65.0, 36.0)],
     1.23, 6.5),                                 # lines closer than the turning circle
    ([(0.0, 0.0), (70.0, 0.0), (70.0, 11.0), (0.0, 11.0)], 1.1, 9.6),
    ([(0.0, 0.0), (90.0, 0.0), (10.0, 1.0), (60.0, 40.0)], 1.0, 10.0),  # a reversal
    ([(0.0, 0.0), (80.0, 0.0), (30.0, 30.0), (90.0, 60.0)], 0.6, 12.0),  # 149°, then −123°
])
def test_where_no_arc_fits_the_path_is_where_the_simulated_auv_flies(
        route: list[tuple[float, float]], speed: float, rate_dps: float) -> None:
    """A reversal, or lines closer than the AUV's turning circle: the path is
    the AUV's own guidance flown (the simulated AUV is the truth here, flying
    the route at its speed and turn rate), within 0.3 m all along — an arc
    clamped to fit was metres off for tens of seconds — and it joins the legs
    either side without a step."""
    auv = Auv(AuvParams(waypoints=[list(p) for p in route], speed_mps=speed,
                        turn_rate_dps=rate_dps, at_end="continue"))
    plan = Plan(route)
    r = speed / math.radians(rate_dps)
    worst = 0.0
    t = 0.0
    while t < plan.length_m / speed:
        x, y, _ = auv.position(t)
        s, c = plan.nearest(x, y, -1e9, 1e9, r)
        worst = max(worst, abs(c))
        t += 0.5
    assert worst <= 0.3
    sharp = max(abs(plan.nearest(*auv.position(t)[:2], -1e9, 1e9, 0.0)[1])
                for t in np.arange(0.0, plan.length_m / speed, 0.5))
    assert sharp >= 2.0  # what is modelled here is not a rounding error
    for k in range(len(plan.legs) - 1):
        lo, hi = plan.span(k, r)
        for s in (lo, hi):
            leg = plan.leg_at(s)
            on_leg = leg.point(s - leg.s0_m)
            assert plan.point_at(s - 1e-6, 0.0, r)[:2] == pytest.approx(on_leg, abs=0.15)
            assert plan.point_at(s + 1e-6, 0.0, r)[:2] == pytest.approx(on_leg, abs=0.15)


@pytest.mark.parametrize("seed", range(4))
def test_a_point_of_the_rounded_path_is_found_again_where_it_is(seed: int) -> None:
    """nearest() undoes point_at() anywhere on a drawn lawnmower rounded with a
    turning radius, straights, arcs and flown stretches alike, for offsets to
    either side well within the radius (further out, about a corner, another
    leg can be nearer; a flown stretch swings out past the next line and back,
    so there within half a metre), to a millimetre (a flown stretch is a
    polyline of quarter-metre steps)."""
    rng = np.random.default_rng(300 + seed)
    pts, _, _ = lawnmower(rng)
    plan = Plan([tuple(p) for p in pts])
    flown = 0
    for _ in range(300):
        r = float(rng.choice([4.0, 8.0, 14.0]))
        s = float(rng.uniform(0.0, plan.length_m))
        c = float(rng.uniform(-0.45, 0.45)) * 4.0
        k = plan.leg_at(s).index
        # (a flown stretch joins its leg within a decimetre: a metre about it too)
        if any(isinstance(plan.corner(j, r), Flown) and plan.span(j, r)[0] - 1.0 < s
               < plan.span(j, r)[1] + 1.0 for j in (k - 1, k) if 0 <= j < len(plan.legs) - 1):
            c /= 4.0
            flown += 1
        x, y, _ = plan.point_at(s, c, r)
        s2, c2 = plan.nearest(x, y, s - 8.0, s + 8.0, r)
        assert (s2, c2) == pytest.approx((s, c), abs=1e-3)
    assert flown >= 10  # the flown stretches were tried


@pytest.mark.parametrize(("points", "why"), [
    ([(0.0, 0.0)], "auv_plan: a plan needs at least 2 points (or none)"),
    ([(0.0, 0.0), (0.5, 0.5)], "auv_plan[1]: less than 1 m from point 0"),
    ([(0.0, 0.0), (math.nan, 1.0)], "auv_plan[1]: not finite"),
    ([(0.0, 0.0), (60_000.0, 0.0)], "auv_plan[1]: 60 km from the origin (at most 50 km)"),
    ([(float(i), 0.0) for i in range(MAX_POINTS + 1)],
     f"auv_plan: has {MAX_POINTS + 1} points, at most {MAX_POINTS}"),
])
def test_points_that_are_not_a_plan_are_refused_with_the_point_and_reason(
        points: list[tuple[float, float]], why: str) -> None:
    err = check_points(points)
    assert err is not None and err.named("auv_plan") == why
    with pytest.raises(PlanError) as exc:
        Plan(points)
    assert exc.value.named("auv_plan") == why
    assert check_points([(0.0, 0.0), (1.0, 0.0)]) is None


def test_an_operators_plan_is_checked_point_by_point() -> None:
    def to_ned(lat: float, lon: float) -> tuple[float, float]:
        return (lat - 41.0) * 111_195.0, (lon + 8.0) * 83_900.0

    assert geodetic_plan([], to_ned) == ()
    pts = geodetic_plan([[41.0, -8.0], [41.001, -8.0]], to_ned)
    assert pts[1][0] == pytest.approx(111.195)
    for raw, why in [("nope", "auv_plan: must be a list of [lat_deg, lon_deg], got str"),
                     ([[41.0, -8.0], [41.0]], "auv_plan[1]: must be [lat_deg, lon_deg]"),
                     ([[41.0, -8.0], [True, -8.0]], "auv_plan[1]: must be [lat_deg, lon_deg]"),
                     ([[41.0, -8.0], [95.0, -8.0]], "auv_plan[1]: not a latitude, longitude"),
                     ([[41.0, -8.0], [41.0, -8.0]], "auv_plan[1]: less than 1 m from point 0"),
                     ([[41.0, -8.0]] * (MAX_POINTS + 1), f"auv_plan: has {MAX_POINTS + 1}")]:
        with pytest.raises(PlanError) as exc:
            geodetic_plan(raw, to_ned)
        assert exc.value.named("auv_plan").startswith(why), exc.value.named("auv_plan")


# ------------------------------------------------------------------ matching


@pytest.mark.parametrize("seed", range(8))
def test_an_auv_on_its_plan_is_followed_leg_by_leg_and_never_lost(seed: int) -> None:
    rng = np.random.default_rng(seed)
    pts, v, rate = lawnmower(rng)
    m = PlanMatcher(PlanParams())
    m.set_plan([tuple(p) for p in pts])
    hist = fly(m, auv_on(pts, v, rate), duration(pts, v) - 2.0, rng)
    legs = [leg for _, leg in hist]
    joined = next(t for t, leg in hist if leg >= 0)
    assert joined <= PlanParams().join_after_s + 8.0
    after = [leg for t, leg in hist if t >= joined]
    assert min(after) == 0 and -1 not in after, legs
    assert all(b - a in (0, 1) for a, b in itertools.pairwise(after)), after
    assert after[-1] == len(pts) - 2
    assert m.left == 0 and m.joined == 1
    assert any("on its plan, leg 1" in e for e in m.events)


@pytest.mark.parametrize("seed", range(6))
def test_the_auvs_turning_radius_is_learnt_from_its_u_turns(seed: int) -> None:
    """Lawnmowers whose lines (10–20 m apart, 50–80 m long) are closer than
    the AUV's turning circle (its speed over its turn rate: 6.4–13 m of
    radius, not the configured 6 m): the AUV swings out past each next line,
    and after its U-turns the radius in use is within 1.5 m of its own.
    (Scored against the offset filter's own estimate, which follows the path
    in use about a corner, the configured radius always won.)"""
    rng = np.random.default_rng(900 + seed)
    v = float(rng.uniform(1.0, 1.4))
    rate = float(rng.uniform(6.0, 9.0))
    radius = v / math.radians(rate)
    gap = float(rng.uniform(10.0, min(20.0, 2.0 * radius - 1.0)))
    length = float(rng.uniform(50.0, 80.0))
    pts = [[x, i * gap] for i in range(5) for x in ((0.0, length) if i % 2 == 0
                                                    else (length, 0.0))]
    m = PlanMatcher(PlanParams())
    m.set_plan([(p[0], p[1]) for p in pts])
    fly(m, auv_on(pts, v, rate), duration(pts, v) - 2.0, rng, sigma=0.5)
    assert m.along is not None
    assert abs(m.along.radius - radius) <= 1.5, (m.along.radius, radius)


@pytest.mark.parametrize("seed", range(6))
def test_an_auv_reversing_on_its_plan_is_not_taken_off_it(seed: int) -> None:
    """Legs of 80–140 m joined by reversals (150–180°), flown at 0.6–1.4 m/s
    turning at 6–15°/s: past each reversal the AUV swings out up to its
    turning circle (9–27 m across) off the next leg and tens of degrees off
    its course for tens of seconds, on the path it flies; it never leaves
    its plan (judged from the sharp legs, it did)."""
    rng = np.random.default_rng(700 + seed)
    pts = [[0.0, 0.0]]
    course = float(rng.uniform(-math.pi, math.pi))
    for i in range(4):
        if i:
            course += float(rng.choice([-1.0, 1.0]) * math.radians(rng.uniform(150.0, 180.0)))
        n = float(rng.uniform(80.0, 140.0))
        pts.append([pts[-1][0] + n * math.cos(course), pts[-1][1] + n * math.sin(course)])
    v, rate = float(rng.uniform(0.6, 1.4)), float(rng.uniform(6.0, 15.0))
    m = PlanMatcher(PlanParams())
    m.set_plan([(p[0], p[1]) for p in pts])
    hist = fly(m, auv_on(pts, v, rate), duration(pts, v) - 2.0, rng, sigma=0.5)
    joined = next(t for t, leg in hist if leg >= 0)
    after = [leg for t, leg in hist if t >= joined]
    assert -1 not in after and m.left == 0, m.events
    assert after[-1] == len(pts) - 2


@pytest.mark.parametrize("seed", range(6))
def test_an_early_turn_onto_a_leg_the_plan_has_not_is_noticed(seed: int) -> None:
    """The AUV abandons the plan half-way along a survey line, turning 40–140°
    onto a course of its own (an adaptive mission): off the plan within seconds
    of being off its leg, and an event says why."""
    rng = np.random.default_rng(100 + seed)
    pts, v, rate = lawnmower(rng)
    k = 2 * int(rng.integers(0, (len(pts) - 1) // 2))  # a survey line (even legs)
    a, b = np.array(pts[k]), np.array(pts[k + 1])
    mid = a + rng.uniform(0.4, 0.6) * (b - a)
    course = math.atan2(*(b - a)[::-1]) + rng.choice([-1.0, 1.0]) * math.radians(
        rng.uniform(40.0, 140.0))
    away = mid + 150.0 * np.array([math.cos(course), math.sin(course)])
    route = [*pts[: k + 1], mid.tolist(), away.tolist()]
    auv = auv_on(route, v, rate)
    m = PlanMatcher(PlanParams())
    m.set_plan([tuple(p) for p in pts])
    t_mid = duration(route[: k + 2], v)
    hist = fly(m, auv, t_mid + 100.0 / v, rng)
    assert any(leg >= 0 for t, leg in hist if t < t_mid), "never on the plan"
    # the true distance from the leg passes the gate (widened by half the
    # turning radius about a corner, where the AUV rounds it) at some time;
    # allow the persistence and two samples after it
    gate = PlanParams().cross_gate_m + 2.0 + 0.5 * PlanParams().turn_radius_m
    t_off = next(t for t, _ in hist if t > t_mid and _dist_to(auv, t, a, b) > gate)
    left_t = next(t for t, leg in hist if t > t_mid and leg == -1)
    assert left_t <= t_off + PlanParams().leave_after_s + 5.0
    assert m.left == 1
    assert any(e.startswith("AUV left its plan (") for e in m.events), m.events


def _dist_to(auv: Auv, t: float, a: np.ndarray, b: np.ndarray) -> float:
    p = auv.truth(t)
    u = (b - a) / np.linalg.norm(b - a)
    d = np.array([p.x_m, p.y_m]) - a
    return float(abs(-d[0] * u[1] + d[1] * u[0]))


@pytest.mark.parametrize("seed", range(6))
def test_a_skipped_corner_is_noticed_and_a_later_leg_rejoined(seed: int) -> None:
    """The AUV does not turn at a corner: it runs on 25–40 m past it, then
    comes back onto the plan two legs later (an adaptive mission that cut a
    lawnmower's crossing): off the plan, then back on it."""
    rng = np.random.default_rng(200 + seed)
    pts, v, rate = lawnmower(rng)
    k = int(rng.integers(1, len(pts) - 4))
    a, b = np.array(pts[k - 1]), np.array(pts[k])
    u = (b - a) / np.linalg.norm(b - a)
    past = b + rng.uniform(25.0, 40.0) * u
    route = [*pts[: k + 1], past.tolist(), *pts[k + 2:]]
    auv = auv_on(route, v, rate)
    m = PlanMatcher(PlanParams())
    m.set_plan([tuple(p) for p in pts])
    hist = fly(m, auv, duration(route, v) - 2.0, rng)
    t_corner = duration(route[: k + 1], v)
    before = [leg for t, leg in hist if t < t_corner - 10.0]
    assert before[-1] == k - 1
    t_left = next(t for t, leg in hist if t > t_corner and leg == -1)
    # past the corner's zone (12 m) at speed v, plus the persistence and two samples
    assert t_left <= t_corner + (PlanParams().corner_zone_m + 5.0) / v + 9.0
    # it went on past the end of the leg it was on, or off the crossing it skipped
    assert any(e.startswith("AUV left its plan (") and (
        f"past the end of leg {k}" in e or f"of leg {k + 1})" in e) for e in m.events), m.events
    back = [leg for t, leg in hist if t > t_left and leg >= 0]
    assert back and back[0] >= k + 1, hist
    assert any(e.startswith("AUV back on its plan") for e in m.events)


def test_a_hovering_auv_is_on_its_plan_only_at_its_start_and_a_cleared_plan_stops() -> None:
    m = PlanMatcher(PlanParams())
    m.set_plan([(0.0, 0.0), (100.0, 0.0)])
    for i in range(20):  # hovering 30 m off the plan, pointing anywhere
        m.update(2.0 * i, 30.0, 20.0, 0.01, -0.01, 1.0)
    assert m.leg == -1 and m.state == "search"
    for i in range(20, 30):  # hovering at its first point: about to fly leg 1
        m.update(2.0 * i, 0.5, -0.5, 0.01, -0.01, 1.0)
    assert m.leg == 0 and m.state == "on"
    m.set_plan(())
    assert m.state == "none" and m.leg == -1
    m.update(80.0, 30.0, 0.0, 1.0, 0.0, 1.0)
    assert m.leg == -1
    assert m.events[-1] == "AUV plan cleared; tracking without it"


@pytest.mark.parametrize("seed", range(4))
def test_a_guessed_plan_is_left_as_soon_as_the_auv_flies_straight_past_a_corner(
        seed: int) -> None:
    """A tentative plan (inferred, not given): the AUV going straight on past
    a corner has left it within 5 s of its speed past the corner (plus the
    filter's samples), long before the corner's zone would say so; flying
    the plan, it never leaves it."""
    rng = np.random.default_rng(500 + seed)
    pts, v, rate = lawnmower(rng)
    m = PlanMatcher(PlanParams())
    m.set_plan([tuple(p) for p in pts], "tracker", tentative=True)
    fly(m, auv_on(pts, v, rate), duration(pts, v) - 2.0, rng)
    assert m.left == 0 and m.joined == 1, m.events
    k = int(rng.integers(2, len(pts) - 2))
    a, b = np.array(pts[k - 1]), np.array(pts[k])
    u = (b - a) / np.linalg.norm(b - a)
    route = [*pts[:k], (b + 60.0 * u).tolist()]  # straight on past corner k
    m = PlanMatcher(PlanParams())
    m.set_plan([tuple(p) for p in pts], "tracker", tentative=True)
    hist = fly(m, auv_on(route, v, rate), duration(route, v) - 2.0, rng)
    t_corner = duration(route[: k + 1], v)
    t_left = next(t for t, leg in hist if t > t_corner - 5.0 and leg == -1)
    assert t_left <= t_corner + max(4.0 / v, 5.0) + 5.0, (t_left, t_corner)
    # pts[k] ends leg k (numbered from 1)
    assert any(f"straight on past the end of leg {k})" in e for e in m.events), m.events


@pytest.mark.parametrize("seed", range(6))
def test_a_filter_slow_to_turn_does_not_take_the_auv_off_its_plan(seed: int) -> None:
    """The fixes are weighed between the plan and the tracker's filter: an AUV
    flying its lawnmower, tracked by a constant-velocity filter that takes
    its U-turns many fixes late (it runs on straight past every corner), is
    explained by its plan, which turns where the AUV does — never off it."""
    rng = np.random.default_rng(1100 + seed)
    pts, v, rate = lawnmower(rng)
    m = PlanMatcher(PlanParams())
    m.set_plan([tuple(p) for p in pts])
    hist = fly_tracked(m, auv_on(pts, v, rate), duration(pts, v) - 2.0, rng)
    assert m.left == 0 and m.joined == 1, m.events
    assert hist[-1][1] == len(pts) - 2


@pytest.mark.parametrize("seed", range(6))
def test_an_auv_running_on_past_a_corner_is_off_its_plan_once_the_filter_explains_it(
        seed: int) -> None:
    """The AUV of a plan given runs straight on past a corner: once the fixes
    follow the tracker's filter (straight on) rather than the plan (turned),
    it has left the plan — within 6 m of its progress past the corner (where
    the two are several fix σ apart) and four fix intervals, well before it
    is past the corner's zone (12 m) and the misfit's persistence (4 s)."""
    rng = np.random.default_rng(1200 + seed)
    pts, v, rate = lawnmower(rng)
    k = int(rng.integers(2, len(pts) - 2))
    a, b = np.array(pts[k - 1]), np.array(pts[k])
    u = (b - a) / np.linalg.norm(b - a)
    route = [*pts[:k], (b + 60.0 * u).tolist()]  # straight on past corner k
    m = PlanMatcher(PlanParams())
    m.set_plan([tuple(p) for p in pts])
    hist = fly_tracked(m, auv_on(route, v, rate), duration(route, v) - 2.0, rng)
    t_corner = duration(pts[: k + 1], v)
    assert all(leg >= 0 for t, leg in hist if 15.0 < t < t_corner - 5.0), hist
    t_left = next(t for t, leg in hist if t > t_corner - 5.0 and leg == -1)
    assert t_left <= t_corner + 6.0 / v + 4 * 2.5, (t_left, t_corner)
    assert any(e.startswith("AUV left its plan (fixes") and "follow the track" in e
               for e in m.events), m.events


@pytest.mark.parametrize("seed", range(6))
def test_a_refused_fix_far_from_the_plan_leaves_the_progress_alone(seed: int) -> None:
    """A fix the tracker's filter refused (a late or false detection paired
    into a cycle) back along the path from where the AUV would be and to one
    side, each within the path's own gates (8–11 and 4–6 variances: χ² of one
    degree of freedom each) but far from the AUV's predicted position (the
    two together: 12–17 > 9), was taken and threw the progress and its speed
    off — about a corner, where such a fix lands on the other leg, for tens
    of seconds.  Now it is left out and counted: the progress after it is the
    one of a twin matcher never given it.  The same fix accepted by the
    filter still moves it (only refused outliers are left out).  Checked
    mid-leg, where along and across the path are exact."""
    rng = np.random.default_rng(1300 + seed)
    pts, v, rate = lawnmower(rng)
    k = 2 * int(rng.integers(1, len(pts) // 2))  # a long leg (not the first)
    t_mid = (duration(pts[: k + 1], v) + duration(pts[: k + 2], v)) / 2.0
    auv = auv_on(pts, v, rate)
    twins = [PlanMatcher(PlanParams()) for _ in range(3)]
    for m in twins:
        m.set_plan([tuple(p) for p in pts])
        fly(m, auv, t_mid, np.random.default_rng(seed))
        assert m.leg >= 0 and m.along is not None
    refused, accepted, never = twins
    al = refused.along
    assert al is not None and refused.plan is not None
    t = al.t + 0.5
    # the variances (m²) along and across the path of the prediction and a fix
    # of 1 m² a side, each with the floor added to fixes
    floor2 = PlanParams().along_floor_m ** 2
    va = al.P[0][0] + 1.0 + floor2
    vc = al.Pc[0][0] + 1.0 + floor2
    back = math.sqrt(float(rng.uniform(8.0, 11.0)) * va)
    side = float(rng.choice([-1.0, 1.0])) * math.sqrt(float(rng.uniform(4.0, 6.0)) * vc)
    s = refused.plan.advance(al.s, al.u * 0.5 - back, al.radius)
    fx, fy, _ = refused.plan.point_at(s, al.cross + side, al.radius)
    for m, ok in ((refused, False), (accepted, True)):
        m.fix(AuvFix(t, t, 1, fx, fy, fx, fy, 0.0, 0.0, 0.0, ok, False, 1.0, 0.0, 1.0))
    assert refused.outliers == 1 and accepted.outliers == 0 and never.outliers == 0
    # taken, it pulls the progress back by metres (left out, it is only predicted)
    r, c = refused.along, accepted.along
    assert r is not None and c is not None and r.t == c.t == t
    assert r.s - c.s > 1.0 or abs(c.cross - r.cross) > 1.0, (r.s, c.s, r.cross, c.cross)
    t2 = t + 1.5
    b = auv.truth(t2)
    nxt = AuvFix(t2, t2, 1, b.x_m, b.y_m, b.x_m, b.y_m, 0.0, 0.0, 0.0, True, False, 1.0, 0.0,
                 1.0)
    for m in twins:
        m.fix(nxt)
    r, n = refused.along, never.along
    assert r is not None and n is not None
    assert r.s == pytest.approx(n.s, abs=1e-6) and r.u == pytest.approx(n.u, abs=1e-6)
    # (the offset's covariance predicted in one step or two differs by a hair)
    assert r.cross == pytest.approx(n.cross, abs=0.02)


def _beacon_near(x: float, y: float, rng: np.random.Generator) -> tuple[float, float]:
    """A beacon 100–300 m from (x, y), any bearing."""
    ang, dist = rng.uniform(0.0, math.tau), rng.uniform(100.0, 300.0)
    return x + dist * math.cos(ang), y + dist * math.sin(ang)


def test_ranges_alone_are_weighed_so_an_auv_leaving_its_plan_is_seen_sooner() -> None:
    """Two beacons: every other cycle is a range alone.  The AUV of a plan
    given runs straight on past a corner; with the ranges weighed between the
    plan and the filter as the fixes are, the departure is declared within
    the bound the fixes alone meet when they come every cycle (6 m of its
    progress past the corner and four fix intervals), and, over 12
    lawnmowers, sooner than with the fixes alone: the median by 2 s or
    more."""
    delays: dict[bool, list[float]] = {True: [], False: []}
    for seed in range(12):
        for ranges in (True, False):
            rng = np.random.default_rng(1200 + seed)
            pts, v, rate = lawnmower(rng)
            k = int(rng.integers(2, len(pts) - 2))
            a, b = np.array(pts[k - 1]), np.array(pts[k])
            u = (b - a) / np.linalg.norm(b - a)
            route = [*pts[:k], (b + 60.0 * u).tolist()]
            beacon = _beacon_near(float(b[0]), float(b[1]), rng)
            m = PlanMatcher(PlanParams())
            m.set_plan([(p[0], p[1]) for p in pts])
            hist = fly_tracked(m, auv_on(route, v, rate), duration(route, v) - 2.0,
                               np.random.default_rng(seed), beacon=beacon, ranges=ranges)
            t_corner = duration(pts[: k + 1], v)
            t_left = next(t for t, leg in hist if t > t_corner - 15.0 and leg == -1)
            delays[ranges].append(t_left - t_corner)
            if ranges:
                assert t_left <= t_corner + 6.0 / v + 4 * 2.5, (seed, t_left, t_corner)
    with_r, without = float(np.median(delays[True])), float(np.median(delays[False]))
    assert with_r <= without - 2.0, (delays[True], delays[False])


@pytest.mark.parametrize("seed", range(6))
def test_ranges_alone_do_not_take_an_auv_flying_its_plan_off_it(seed: int) -> None:
    """The ranges weighed as the fixes are, against a constant-velocity
    filter slow to turn (it runs on past every corner of the lawnmower): the
    plan, which turns where the AUV does, explains them — never off it."""
    rng = np.random.default_rng(1100 + seed)
    pts, v, rate = lawnmower(rng)
    beacon = _beacon_near(pts[0][0], pts[0][1], rng)
    m = PlanMatcher(PlanParams())
    m.set_plan([(p[0], p[1]) for p in pts])
    hist = fly_tracked(m, auv_on(pts, v, rate), duration(pts, v) - 2.0,
                       np.random.default_rng(seed), beacon=beacon)
    assert m.left == 0 and m.joined == 1, m.events
    assert hist[-1][1] == len(pts) - 2
