"""The simulated AUV's continuous turns: arcs, circles and spirals."""

from __future__ import annotations

import math

import pytest

from drivers.sim.auv import Auv, AuvParams


def test_a_circle_keeps_its_radius_about_its_centre_and_ends_where_it_began() -> None:
    # north 100 m, then a full circle of 30 m to starboard (centre 30 m east of
    # the waypoint), then on north
    auv = Auv(AuvParams(waypoints=[[0.0, 0.0], [100.0, 0.0], [300.0, 0.0]], speed_mps=1.0,
                        turn_rate_dps=10.0, arcs=[[1, 30.0, 360.0, 0.0]], at_end="continue"))
    auv.truth(500.0)
    (arc,) = auv.manoeuvres()
    assert arc.arc and arc.angle_rad == pytest.approx(math.tau)
    assert arc.start_s == pytest.approx(100.0, abs=0.15)  # within a step or two
    assert arc.end_s - arc.start_s == pytest.approx(math.tau * 30.0, abs=0.1)
    t = arc.start_s
    while t < arc.end_s:
        tr = auv.truth(t)
        assert math.hypot(tr.x_m - 100.0, tr.y_m - 30.0) == pytest.approx(30.0, abs=0.1)
        assert tr.speed_mps == pytest.approx(1.0, abs=1e-3)
        t += 7.0
    quarter = auv.truth(arc.start_s + 0.25 * math.tau * 30.0)
    assert (quarter.x_m, quarter.y_m) == pytest.approx((130.0, 30.0), abs=0.1)
    assert math.degrees(quarter.psi_rad) == pytest.approx(90.0, abs=0.5)
    after = auv.truth(arc.end_s + 50.0)
    assert (after.x_m, after.y_m) == pytest.approx((150.0, 0.0), abs=0.2)
    # one manoeuvre: the exit onto the next leg is no turn
    assert auv.turn_angles() == []


def test_a_spiral_grows_its_radius_with_the_angle_turned() -> None:
    # two turns to port from 20 m, growing 10 m per turn: the yaw rate v/R falls
    # from 1/20 to 1/40 rad/s
    auv = Auv(AuvParams(waypoints=[[0.0, 0.0], [50.0, 0.0], [500.0, 0.0]], speed_mps=1.0,
                        turn_rate_dps=10.0, arcs=[[1, 20.0, -720.0, 10.0]]))
    auv.truth(900.0)
    spiral = auv.manoeuvres()[0]
    assert spiral.arc and math.degrees(spiral.angle_rad) == pytest.approx(-720.0)
    # time to turn 4π with R(θ) = 20 + 10 θ/2π at 1 m/s: ∫ R dθ
    expect = 20.0 * 4 * math.pi + 10.0 / math.tau * (4 * math.pi) ** 2 / 2
    assert spiral.end_s - spiral.start_s == pytest.approx(expect, rel=2e-3)

    def rate(t: float) -> float:
        a, b = auv.truth(t - 0.5), auv.truth(t + 0.5)
        return math.remainder(b.psi_rad - a.psi_rad, math.tau)

    assert rate(spiral.start_s + 5.0) == pytest.approx(-1.0 / 20.4, rel=0.03)
    assert rate(spiral.end_s - 5.0) == pytest.approx(-1.0 / 39.6, rel=0.03)


def test_a_tight_arc_is_flown_at_the_largest_turn_rate() -> None:
    # 2 m radius at 1 m/s would need 29°/s: the AUV turns at its 10°/s instead
    auv = Auv(AuvParams(waypoints=[[0.0, 0.0], [20.0, 0.0], [200.0, 0.0]], speed_mps=1.0,
                        turn_rate_dps=10.0, arcs=[[1, 2.0, 90.0, 0.0]]))
    auv.truth(100.0)
    arc = auv.manoeuvres()[0]
    assert arc.end_s - arc.start_s == pytest.approx(9.0, abs=0.06)


@pytest.mark.parametrize(("arcs", "why"), [
    ([[0, 20.0, 90.0, 0.0]], "waypoint index"),
    ([[3, 20.0, 90.0, 0.0]], "waypoint index"),
    ([[1.5, 20.0, 90.0, 0.0]], "waypoint index"),
    ([[1, 0.5, 90.0, 0.0]], "radius"),
    ([[1, 20.0, 0.0, 0.0]], "angle"),
    ([[1, 20.0, 720.0, -15.0]], "radius at the arc's end"),
    ([[1, 20.0, 90.0]], "must be"),
    ([[1, 20.0, 90.0, 0.0], [1, 30.0, 90.0, 0.0]], "already has an arc"),
])
def test_a_bad_arc_is_refused_with_its_reason(arcs: list[list[float]], why: str) -> None:
    with pytest.raises(ValueError, match=why):
        Auv(AuvParams(waypoints=[[0.0, 0.0], [50.0, 0.0], [100.0, 0.0]], arcs=arcs))
