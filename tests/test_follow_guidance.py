"""The follow guidance: line of sight to the AUV, catch-up speed, which estimate
it follows, holding above a still AUV."""

from __future__ import annotations

import dataclasses
import itertools
import math

import pytest

from zarco_core.auv_messages import AuvPlan, AuvTrack, TrackFlags
from zarco_runtime.guidance import follow_motion
from zarco_runtime.guidance.follow import (
    ABOVE_STATION_M,
    FACE_COURSE_MPS,
    PLAN_SETTLE_CROSS_M,
    PLAN_SETTLE_MAX_S,
    TRAIL_BEFORE_M,
    TRAIL_M,
    FollowGuidance,
    FollowSettings,
    target_now,
)
from zarco_runtime.tracking.plan import Plan

VALID = int(TrackFlags.INITIALISED | TrackFlags.LINE_VALID)


#: the runtime's rule for a track just acquired (the fixture below sets it aside)
FRESH_S = follow_motion.FRESH_S


@pytest.fixture(autouse=True)
def _seasoned_track(monkeypatch: pytest.MonkeyPatch) -> None:
    """These tests are about a track past its first seconds (the tracks they
    build are taken as seen long before); the tests of the rule for a track
    just acquired put it back (:func:`_fresh_rule`)."""
    monkeypatch.setattr(follow_motion, "FRESH_S", 0.0)


def _fresh_rule(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(follow_motion, "FRESH_S", FRESH_S)


def _track(x: float = 0.0, y: float = 0.0, vx: float = 1.0, vy: float = 0.0,
           flags: int = VALID, kf: tuple[float, float, float, float] | None = None,
           sv: float = 0.05, t: float = 100.0) -> AuvTrack:
    """A track at runtime time ``t`` (origin t0 = t): the line through (x, y)
    with (vx, vy), the filter at ``kf`` (default: on the line)."""
    kx, ky, kvx, kvy = kf if kf is not None else (x, y, vx, vy)
    v2 = sv * sv
    cov = (1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, v2, 0, 0, 0, 0, v2)
    v = math.hypot(vx, vy)
    return AuvTrack(t, x, y, vx, vy, math.atan2(vy, vx), v, 0.0, cov, t, 0.0, 0.5, flags,
                    False, kx, ky, kvx, kvy, 0.5)


def _moving(g: FollowGuidance, tr: AuvTrack, at: tuple[float, float] | None = None) -> None:
    g.update(tr, tr.t, *(at or (tr.x0_m, tr.y0_m)))
    assert g.moving


def test_on_the_auv_the_leg_is_its_course_at_its_speed() -> None:
    g = FollowGuidance(FollowSettings())
    tr = _track(vx=0.0, vy=0.8)  # heading east
    _moving(g, tr)
    st = g.update(tr, tr.t, 0.0, 0.0)
    assert st.mode == "follow" and st.leg is not None
    assert st.leg.course_rad == pytest.approx(math.pi / 2)
    assert st.speed_ref_mps == pytest.approx(0.8)
    assert st.leg.project(0.0, 0.0)[1] == pytest.approx(0.0, abs=1e-9)  # on its leg


def test_behind_it_speeds_up_ahead_it_slows_down() -> None:
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    tr = _track(vx=0.8)
    _moving(g, tr)
    behind = g.update(tr, tr.t, -2.0, 0.0)
    assert behind.along_error_m == pytest.approx(2.0)
    assert behind.speed_ref_mps == pytest.approx(0.8 + 2.0 / cfg.catchup_tau_s)
    assert g.update(tr, tr.t, -30.0, 0.0).speed_ref_mps == cfg.max_speed_mps
    g2 = FollowGuidance(cfg)
    _moving(g2, tr)
    ahead = g2.update(tr, tr.t, 1.0, 0.0)
    assert cfg.min_speed_mps < 0.8 - 1.0 / cfg.catchup_tau_s
    assert ahead.speed_ref_mps == pytest.approx(0.8 - 1.0 / cfg.catchup_tau_s)
    # far ahead: as slow as steering allows, and no reverse thrust
    far = g2.update(tr, tr.t, 20.0, 0.0)
    assert far.speed_ref_mps == cfg.min_speed_mps and far.along_error_m == 0.0


def test_to_starboard_it_converges_to_port_at_the_line_of_sight_angle() -> None:
    cfg = FollowSettings(max_turn_rate_dps=360.0)
    g = FollowGuidance(cfg)
    tr = _track(vx=1.0)  # heading north
    _moving(g, tr, (0.0, 3.0))
    st = g.update(tr, tr.t + 1.0, 0.0, 3.0)  # 3 m east: to starboard, level with it
    assert st.d_m == pytest.approx(3.0)
    assert st.leg is not None
    # the AUV is now 1 m north, so the boat is 1 m behind: it aims Δ ahead of
    # its own projection on the AUV's track, course atan2(−3, Δ) — to port
    assert st.leg.course_rad == pytest.approx(math.atan2(-3.0, cfg.lookahead_m))


def test_the_leg_turns_no_faster_than_the_boat() -> None:
    cfg = FollowSettings(max_turn_rate_dps=20.0)
    g = FollowGuidance(cfg)
    north = _track(vx=1.0)
    _moving(g, north)
    g.update(north, 100.0, 0.0, 0.0)
    east = _track(vx=0.0, vy=1.0, flags=VALID, t=100.0)
    st = g.update(east, 100.5, 0.0, 0.0)  # the estimate swung 90° in 0.5 s
    assert st.leg is not None
    assert abs(st.leg.course_rad) == pytest.approx(math.radians(10.0), abs=1e-6)


def test_follows_the_filter_when_the_line_disagrees_or_is_turning() -> None:
    cfg = FollowSettings()
    line = _track(vx=1.0, kf=(0.5, 0.3, 0.98, 0.05))
    assert target_now(line, 100.0, cfg.line_gate_m, math.radians(20.0)).source == "line"
    swung = _track(vx=1.0, kf=(0.5, 0.3, 0.7, 0.7))  # the filter sees a 45° turn
    tg = target_now(swung, 100.0, cfg.line_gate_m, math.radians(20.0))
    assert tg.source == "kf" and (tg.vx, tg.vy) == (0.7, 0.7)
    turning = _track(vx=1.0, flags=VALID | int(TrackFlags.TURNING))
    assert target_now(turning, 100.0, cfg.line_gate_m).source == "kf"
    # the position is always the filter's, carried forward to now
    tg = target_now(line, 102.0, cfg.line_gate_m, math.radians(20.0))
    assert (tg.x, tg.y) == pytest.approx((0.5 + 2.0, 0.3))


def test_keeps_above_a_still_auv_then_follows_when_it_moves_and_keeps_through_a_turn() -> None:
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    unsettled = _track(x=10.0, y=5.0, vx=0.04, vy=0.0, sv=0.03,
                       flags=int(TrackFlags.INITIALISED))
    # no settled track: stay near it (within 4 σ) ...
    near = AuvTrack(*[getattr(unsettled, f) for f in unsettled.__dataclass_fields__][:18],
                    3.0)
    assert g.update(near, 98.0, 0.0, 0.0).leg is None
    # ... but close in from further (metres of uncertainty do not matter 11 m away)
    far = g.update(unsettled, 99.0, 0.0, 0.0)
    assert far.leg is not None and far.leg.course_rad == pytest.approx(math.atan2(5.0, 10.0),
                                                                      abs=0.01)
    still = _track(x=10.0, y=5.0, vx=0.04, vy=0.0, sv=0.03)
    st = g.update(still, 100.0, 0.0, 0.0)
    assert not g.moving and st.reason == "above a still AUV"
    assert st.leg is not None and st.leg.course_rad == pytest.approx(math.atan2(5.0, 10.0))
    far = math.hypot(10.0, 5.0) / cfg.catchup_tau_s
    assert st.speed_ref_mps == pytest.approx(min(cfg.max_speed_mps, far))
    assert g.update(still, 101.0, 10.5, 5.5).leg is None  # within the hold radius: drift
    going = _track(x=10.0, y=5.0, vx=0.8, vy=0.0, sv=0.2)
    g.update(going, 102.0, 9.0, 5.0)
    assert g.moving
    # in a turn the line's uncertainty grows: that is not a stop
    turning = _track(x=12.0, y=5.0, vx=0.5, vy=0.5, sv=0.6,
                     flags=VALID | int(TrackFlags.TURNING))
    g.update(turning, 103.0, 11.0, 5.0)
    assert g.moving
    stopped = _track(x=14.0, y=5.0, vx=0.03, vy=0.0, sv=0.05)
    g.update(stopped, 110.0, 14.0, 5.0)
    assert not g.moving


def test_a_lost_track_holds_where_the_boat_is() -> None:
    g = FollowGuidance(FollowSettings())
    tr = _track(vx=1.0)
    assert g.update(None, 99.0, 0.0, 0.0).leg is None  # nothing to hold to yet
    _moving(g, tr)
    lost = AuvTrack(*[getattr(tr, f) for f in tr.__dataclass_fields__][:13], True,
                    *[getattr(tr, f) for f in tr.__dataclass_fields__][14:])
    st = g.update(lost, 100.5, 3.0, 4.0)
    assert st.mode == "hold" and "lost" in st.reason
    assert g.hold == (3.0, 4.0)


def test_a_reversal_is_steered_as_a_turn_not_as_a_heading_error_of_180_degrees() -> None:
    cfg = FollowSettings(max_turn_rate_dps=360.0)
    g = FollowGuidance(cfg)
    courses = []
    for k in range(20):  # the boat runs north at 1 m/s ...
        t = 100.0 + 0.1 * k
        g.update(_track(x=0.1 * k + 2.0, vx=1.0, t=t), t, 0.1 * k, 0.0)
    south = _track(x=-10.0, vx=-1.0, t=102.0)  # ... and the AUV is now behind, southbound
    for k in range(3):
        t = 102.0 + 0.1 * k
        st = g.update(south, t, 2.0 + 0.1 * k, 0.0)
        assert st.leg is not None
        courses.append(st.leg.course_rad)
    # the leg leads the boat's course over ground (north) by at most 90°
    assert all(abs(c) <= math.pi / 2 + 1e-9 for c in courses)


def test_above_an_auv_waiting_on_its_plan_the_boat_holds_a_station_just_ahead_on_its_first_leg(
        ) -> None:
    """The AUV hovers at its plan's first point (its speed along the plan a
    little noise, of either sign): the boat goes to its station a little ahead
    on the first leg (not to a place anywhere in a zone 5 m ahead, where it
    waited 4-5 m off); there it faces the leg (turned towards the station, to
    close a sideways offset) and holds the station forward or astern while it
    drifts within bounds, then goes back to the station (not to the AUV)."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    g.set_plan(AuvPlan(0.0, ((0.0, 0.0), (100.0, 0.0), (100.0, 20.0)), "mission"))
    still = dataclasses.replace(_track(vx=0.02, sv=0.03), plan_leg=0, plan_s_m=0.0,
                                plan_speed_mps=-0.05, plan_cross_m=0.0,
                                plan_turn_radius_m=6.0)
    t = still.t
    # coming back from 4 m ahead or 3 m aside: to the station
    for x, y in ((4.0, 0.0), (-4.0, 0.0), (1.0, 3.0), (8.0, 0.0)):
        st = g.update(still, t, x, y)
        assert st.leg is not None, (x, y)
        assert st.station is None
        err = math.remainder(st.leg.course_rad - math.atan2(-y, ABOVE_STATION_M - x), math.tau)
        assert err == pytest.approx(0.0, abs=0.01), (x, y)
    # there (within the hold radius of it): facing the leg (north), turned
    # towards the station — at most 45° — to bring it ahead or astern (the
    # surge law closes a sideways offset then); the station, ahead of the AUV
    a = ABOVE_STATION_M
    for x, y, ahead in ((a + 0.5, 0.5, False), (a + 1.5, 1.0, False), (3.8, 2.2, False),
                        (-2.0, -2.0, True), (a - 0.8, 0.0, True)):
        t += 0.05
        st = g.update(still, t, x, y)
        assert st.leg is None and st.speed_ref_mps == 0.0, (x, y)
        assert st.station == pytest.approx((ABOVE_STATION_M, 0.0), abs=0.01), (x, y)
        assert abs(st.heading_rad) <= math.radians(45.0) + 1e-9, (x, y)
        ex, ey = ABOVE_STATION_M - x, -y
        along = ex * math.cos(st.heading_rad) + ey * math.sin(st.heading_rad)
        aside = -ex * math.sin(st.heading_rad) + ey * math.cos(st.heading_rad)
        assert (along > 0.0) == ahead, (x, y)
        assert abs(aside) <= abs(ey) + 1e-9, (x, y)  # less sideways than on the leg
        if y == 0.0:
            assert st.heading_rad == pytest.approx(0.0)
    # the tracker's match to the plan flickers off for a moment: still held
    off = dataclasses.replace(still, plan_leg=-1, t=t + 0.05, t0=t + 0.05)
    st = g.update(off, off.t, 3.0, 0.5)
    assert st.leg is None and st.station == pytest.approx((ABOVE_STATION_M, 0.0), abs=0.01)
    # drifted out of bounds (to the side, too far ahead): back to the station
    for x, y in ((1.0, 2.6), (4.2, 0.0)):
        g.update(still, off.t, 1.0, 0.0)  # held again
        st = g.update(still, off.t + 0.05, x, y)
        assert st.leg is not None, (x, y)
        err = math.remainder(st.leg.course_rad - math.atan2(-y, ABOVE_STATION_M - x), math.tau)
        assert err == pytest.approx(0.0, abs=0.01), (x, y)
    # without a plan, nothing changes: within the hold radius the boat drifts
    g2 = FollowGuidance(cfg)
    st = g2.update(still, still.t, 1.0, 0.5)
    assert st.leg is None and st.station is None


def test_an_auv_starting_off_is_gone_after_at_its_speed_without_waiting_for_its_track() -> None:
    """Above a still AUV, its estimate moving off below the still speed: the
    boat goes after it at the speed it moves away plus the gap over the
    catch-up time; its filter's σ growing as its track restarts does not stop
    the boat."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    assert g.update(_track(vx=0.02, sv=0.03), 100.0, 0.5, 0.0).leg is None  # above it
    # one low-pass time constant later the target has moved most of the way
    t1 = 100.0 + cfg.target_tau_s
    off = _track(x=4.0, vx=0.25, sv=0.03, t=t1)
    st = g.update(off, t1, 0.5, 0.0)
    assert not g.moving and st.leg is not None and g.target is not None
    gap = g.target.x - 0.5  # the target moves smoothly to where the filter has it
    assert gap > 1.0
    assert st.speed_ref_mps == pytest.approx(0.25 + gap / cfg.catchup_tau_s)
    unsure = dataclasses.replace(off, kf_pos_sigma_m=3.0, flags=int(TrackFlags.INITIALISED))
    st = g.update(unsure, t1 + 0.5, 0.5, 0.0)
    assert st.mode == "follow" and st.leg is not None


def test_a_slow_auv_far_off_is_gone_to_whatever_its_course_says() -> None:
    """At the start the track of a still AUV can say it creeps along a course
    that is mostly noise: 20 m off, the boat goes to it at the catch-up speed,
    not waiting "ahead" of it on that course; near, it waits as for any AUV,
    and a fast AUV far ahead is waited for on its line."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    slow = _track(vx=0.35, sv=0.02)
    _moving(g, slow, at=(1.0, 0.0))
    st = g.update(slow, slow.t, 20.0, 0.0)
    assert st.leg is not None and st.leg.course_rad == pytest.approx(math.pi)
    assert st.speed_ref_mps == cfg.max_speed_mps
    assert st.reason == "closing in on a slow AUV"
    near = g.update(slow, slow.t, 5.0, 0.0)
    assert near.reason == "" and near.speed_ref_mps == cfg.min_speed_mps
    fast = _track(vx=1.0, sv=0.02)
    g2 = FollowGuidance(cfg)
    _moving(g2, fast)
    assert g2.update(fast, fast.t, 20.0, 0.0).speed_ref_mps == cfg.min_speed_mps


def test_going_to_a_still_auv_the_leg_points_at_it_whatever_the_boat_drifts() -> None:
    """The boat drifting backwards (its course over ground 180° off where it
    must go) is sent straight at a still AUV 20 m to the north, not round the
    long way by a leg held within 90° of its course over ground (which is for a
    boat following a moving AUV through a reversal)."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    still = _track(x=20.0, vx=0.02, sv=0.03)
    st = None
    for k in range(15):  # drifting south at 0.9 m/s for 1.4 s
        t = 100.0 + 0.1 * k
        st = g.update(dataclasses.replace(still, t=t, t0=t), t, -0.09 * k, 0.0)
    assert st is not None and st.leg is not None and not g.moving
    assert st.leg.course_rad == pytest.approx(0.0, abs=math.radians(2.0))


def test_an_auv_setting_off_is_followed_on_its_filter_before_its_line_sees_it() -> None:
    """The RLS line, fitted over seconds of fixes, still says 0.05 m/s while
    the filter already has the AUV at 0.6 m/s to the east: the AUV is taken to
    move and the boat steers after it on the filter's course; when the filter
    slows again below the still speed, it is still again."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    still = _track(vx=0.05, sv=0.03)
    assert g.update(still, 100.0, 0.2, 0.0).leg is None and not g.moving
    off = _track(vx=0.05, sv=0.03, kf=(0.0, 0.5, 0.0, 0.6), t=101.0)
    st = g.update(off, 101.0, 0.2, 0.0)
    assert g.moving and g.target is not None and g.target.source == "kf"
    assert st.leg is not None and st.speed_ref_mps > 0.0
    # the leg heads east, the filter's course, not north along the line
    assert st.leg.course_rad == pytest.approx(math.pi / 2, abs=math.radians(20.0))
    # below the speed the filter alone is trusted with, the line decides
    creeping = _track(vx=0.05, sv=0.03, kf=(0.0, 0.5, 0.0, 0.45), t=101.0)
    g2 = FollowGuidance(cfg)
    g2.update(still, 100.0, 0.2, 0.0)
    g2.update(creeping, 101.0, 0.2, 0.0)
    assert not g2.moving
    stopped = _track(vx=0.05, sv=0.03, kf=(0.0, 1.0, 0.0, 0.1), t=103.0)
    g.update(stopped, 103.0, 0.0, 1.0)
    assert not g.moving


def test_the_line_is_not_followed_when_its_speed_lags_the_filter() -> None:
    cfg = FollowSettings()
    lagging = _track(vx=0.05, kf=(0.0, 0.0, 0.6, 0.0))
    tg = target_now(lagging, 100.0, cfg.line_gate_m, math.radians(20.0))
    assert tg.source == "kf" and tg.vx == 0.6
    agreeing = _track(vx=1.0, kf=(0.0, 0.0, 1.2, 0.0))
    assert target_now(agreeing, 100.0, cfg.line_gate_m, math.radians(20.0)).source == "line"


def test_above_a_still_auv_the_boat_faces_the_filter_course_once_it_passes_a_threshold() -> None:
    """Above a hovering AUV (no plan), the filter's speed passing
    ``FACE_COURSE_MPS`` turns the boat, in place, to the filter's course — the
    way the AUV may be setting off; below it the heading is left alone.
    Facing it is all: a boat 3 m ahead of the AUV on that course (a course
    that may be noise) goes back to it rather than waiting there."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    course = math.radians(120.0)

    def kf(speed: float) -> tuple[float, float, float, float]:
        return (0.0, 0.0, speed * math.cos(course), speed * math.sin(course))

    drifting = _track(vx=0.04, sv=0.03, kf=kf(1.5 * FACE_COURSE_MPS))
    st = g.update(drifting, 100.0, 0.3, 0.3)
    assert st.leg is None and not g.moving
    assert st.heading_rad == pytest.approx(course)
    quiet = _track(vx=0.04, sv=0.03, kf=kf(0.7 * FACE_COURSE_MPS))
    assert math.isnan(g.update(quiet, 101.0, 0.3, 0.3).heading_rad)
    ahead = g.update(drifting, 102.0, 3.0 * math.cos(course), 3.0 * math.sin(course))
    assert ahead.leg is not None and ahead.speed_ref_mps > 0.0


def test_an_auv_setting_off_from_under_the_boat_is_steered_at_whatever_the_boat_drifts() -> None:
    """Hovering, the boat drifts south at 0.5 m/s (its course over ground
    180°); the AUV sets off north: the leg points north, after it, not held
    within 90° of the drift (which is for a boat following at speed through
    a reversal)."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    still = _track(vx=0.03, sv=0.03)
    for k in range(10):
        t = 100.0 + 0.2 * k
        g.update(dataclasses.replace(still, t=t, t0=t), t, 0.5 - 0.1 * k, 0.0)
    assert not g.moving
    off = _track(vx=0.03, sv=0.03, kf=(0.5, 0.0, 0.8, 0.0), t=102.0)
    st = g.update(off, 102.0, -0.5, 0.0)
    assert g.moving and st.leg is not None
    assert st.leg.course_rad == pytest.approx(0.0, abs=math.radians(10.0))


def test_a_track_lost_and_back_is_not_a_set_off() -> None:
    """Held above a still AUV, the track is lost; the one that comes back
    starts with a filter velocity of 0.6 m/s (noise of a new track): the AUV
    is not taken to move on it, as it would be from a hover."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    still = _track(vx=0.03, sv=0.03)
    assert g.update(still, 100.0, 0.2, 0.0).leg is None and not g.moving
    g.update(None, 101.0, 0.2, 0.0)
    back = _track(vx=0.03, sv=0.03, kf=(0.0, 0.0, 0.6, 0.0), t=102.0)
    g.update(back, 102.0, 0.2, 0.0)
    assert not g.moving


def test_a_reversal_on_its_plan_is_turned_the_way_the_auv_turns() -> None:
    """At a corner of its plan where the AUV turns back (177° to port), the
    tracker's progress along the plan steps past the corner and the aim point
    lands just to starboard of straight behind a boat a little to port of the
    path: the leg turns to port with the AUV, not the shorter way round to
    starboard, which took the boat away from the AUV's turn circle (a
    campaign mission: its peak distance 8.8 m, 7.1 m turning with it).  The
    AUV's path there is its guidance flown (it starts its turn a turning
    radius before the corner): the boat's leg turns to port with it from
    before the corner, never to starboard."""
    g = FollowGuidance(FollowSettings())
    plan = ((-80.6, -14.0), (-184.6, -33.8), (-80.7, -7.9))
    g.set_plan(AuvPlan(0.0, plan, "mission"))
    c_in = math.atan2(plan[1][1] - plan[0][1], plan[1][0] - plan[0][0])

    def on_plan(t0: float, leg: int, s: float, u: float, cross: float) -> AuvTrack:
        # the filter where the plan's progress puts the AUV, on its course
        x, y, c = Plan(plan).point_at(s, cross, 6.0)
        tr = _track(x=x, y=y, vx=u * math.cos(c), vy=u * math.sin(c), t=t0)
        return dataclasses.replace(tr, plan_leg=leg, plan_s_m=s, plan_speed_mps=u,
                                   plan_cross_m=cross, plan_turn_radius_m=6.0)

    before = on_plan(161.9, 0, 100.84, 1.0, -0.34)  # 5 m before the corner
    after = on_plan(163.0, 1, 107.71, 1.8, 0.25)  # 1.8 m past it
    offs = []
    for k in range(70):
        t = 159.0 + 0.1 * k
        d = t - 164.0  # the boat runs down the first leg at 1 m/s
        st = g.update(before if t < 164.05 else after, t, -181.7 + d * math.cos(c_in),
                      -32.86 + d * math.sin(c_in))
        assert st.leg is not None
        offs.append(math.degrees(math.remainder(st.leg.course_rad - c_in, math.tau)))
    assert max(offs) < 3.0  # never to starboard
    # turning to port as the AUV does, from before the corner
    assert all(b <= a + 0.5 for a, b in itertools.pairwise(offs))
    assert offs[49] < -10.0
    # a second after the corner the leg has turned further to port
    assert offs[-1] < offs[49] - 10.0


def test_a_guessed_plan_target_run_away_from_the_filter_is_not_followed() -> None:
    """The progress along a plan the tracker guessed is carried forward on its
    own: once it is more than 8 m (plus 3σ) from where the filter has the
    AUV — an AUV that left the plan, not yet noticed — the boat follows the
    filter's target.  On a plan given, the plan's (the filter may be the one
    off)."""
    plan = ((0.0, 0.0), (100.0, 0.0), (100.0, 20.0))
    c = math.radians(20.0)  # turning into the corner: the guessed corner is taken
    on = dataclasses.replace(_track(x=97.0, vx=1.0, kf=(97.0, 0.0, math.cos(c), math.sin(c))),
                             plan_leg=0, plan_s_m=97.0, plan_speed_mps=1.0, plan_cross_m=0.0,
                             plan_turn_radius_m=6.0)
    # the filter has the AUV 15 m off, going on south-east; the plan's progress
    # still at the corner
    off = dataclasses.replace(on, kf_x_m=100.0, kf_y_m=-15.0, kf_vx_mps=0.7, kf_vy_mps=-0.7,
                              t=101.0, t0=101.0)
    for source, followed in (("tracker", False), ("mission", True)):
        g = FollowGuidance(FollowSettings())
        g.set_plan(AuvPlan(0.0, plan, source))
        _moving(g, on, (96.0, 0.0))
        assert g.target is not None and g.target.source == "plan", source
        g.update(off, 101.0, 96.5, 0.0)
        assert g.target is not None and (g.target.source == "plan") == followed, source


def test_a_corner_of_a_guessed_plan_is_taken_once_the_auv_turns_there() -> None:
    """On a plan the tracker inferred (source ``tracker``), the boat does not
    cut a corner the AUV may not take (the survey's end): about the corner it
    follows the filter until the filter's course has turned 15° off the leg's,
    then the plan; on a plan given, it cuts the corner at once."""
    plan = ((0.0, 0.0), (100.0, 0.0), (100.0, 20.0), (0.0, 20.0))
    near = dataclasses.replace(_track(x=97.0, vx=1.0), plan_leg=0, plan_s_m=97.0,
                               plan_speed_mps=1.0, plan_cross_m=0.0, plan_turn_radius_m=6.0)
    given = FollowGuidance(FollowSettings())
    given.set_plan(AuvPlan(0.0, plan, "mission"))
    _moving(given, near, (96.0, 0.0))
    assert given.target is not None and given.target.source == "plan"
    guessed = FollowGuidance(FollowSettings())
    guessed.set_plan(AuvPlan(0.0, plan, "tracker"))
    _moving(guessed, near, (96.0, 0.0))
    assert guessed.target is not None and guessed.target.source != "plan"
    c = math.radians(20.0)  # the filter's course turning towards the next leg
    turning = dataclasses.replace(near, kf_vx_mps=math.cos(c), kf_vy_mps=math.sin(c),
                                  t=101.0, t0=101.0)
    guessed.update(turning, 101.0, 96.5, 0.0)
    assert guessed.target is not None and guessed.target.source == "plan"


def test_before_a_guessed_corner_the_boat_drops_back_a_little() -> None:
    """Approaching a corner of a plan the tracker guessed, which the AUV may
    turn or fly straight past, the boat's speed reference drops it back
    ``TRAIL_M`` behind the track's target (it would close a gap of that much
    over ``catchup_tau_s``); further from the corner, past it, or on a plan
    given (whose target it follows round the corner), it does not."""
    cfg = FollowSettings()
    plan = ((0.0, 0.0), (100.0, 0.0), (100.0, 20.0), (0.0, 20.0))

    def ref(source: str | None, x: float) -> float:
        tr = dataclasses.replace(_track(x=x, vx=1.5), plan_leg=0, plan_s_m=x,
                                 plan_speed_mps=1.5, plan_cross_m=0.0,
                                 plan_turn_radius_m=6.0)
        g = FollowGuidance(cfg)
        if source is not None:
            g.set_plan(AuvPlan(0.0, plan, source))
        _moving(g, tr, (x, 0.0))
        return g.update(tr, tr.t, x, 0.0).speed_ref_mps

    for x in (100.0 - TRAIL_BEFORE_M + 1.0, 97.0):
        # on the target, at the AUV's speed without a plan; dropping back with a guessed one
        assert ref(None, x) == pytest.approx(1.5)
        assert ref("tracker", x) == pytest.approx(1.5 - TRAIL_M / cfg.catchup_tau_s)
    assert ref("tracker", 100.0 - TRAIL_BEFORE_M - 10.0) == pytest.approx(1.5)
    assert ref("tracker", 103.0) == pytest.approx(1.5)  # past it, flying on
    # on a plan given the boat is on the plan's target, cutting the corner
    assert ref("mission", 97.0) > 0.0


def test_past_a_corner_the_plan_is_followed_until_the_filter_is_on_the_new_leg() -> None:
    """After a corner of its plan the filter takes tens of seconds to settle on
    the new leg's course: the boat follows the plan's target past the corner's
    zone while the filter's course is more than ``PLAN_SETTLE_DEG`` off the
    leg's, up to ``PLAN_SETTLE_MAX_S`` of progress, then the filter; at once
    when the filter, off the leg, goes further off it (an AUV leaving its
    plan)."""
    plan = ((0.0, 0.0), (100.0, 0.0), (100.0, 200.0))  # north, then east
    side = PLAN_SETTLE_CROSS_M + 0.5  # metres to starboard of the leg (south)
    for past, off_deg, south, followed in (
            (40.0, 25.0, 0.0, True), (40.0, -25.0, 0.0, True), (40.0, 3.0, 0.0, False),
            (PLAN_SETTLE_MAX_S + 10.0, 25.0, 0.0, False),
            (40.0, -25.0, side, True),  # off the leg, coming back to it
            (40.0, 25.0, side, False)):  # off the leg, going further off
        c = math.pi / 2 + math.radians(off_deg)
        x = 100.0 - south
        tr = dataclasses.replace(_track(x=x, y=past, vx=0.0, vy=1.0,
                                        kf=(x, past, math.cos(c), math.sin(c))),
                                 plan_leg=1, plan_s_m=100.0 + past, plan_speed_mps=1.0,
                                 plan_cross_m=0.0, plan_turn_radius_m=6.0)
        g = FollowGuidance(FollowSettings())
        g.set_plan(AuvPlan(0.0, plan, "mission"))
        _moving(g, tr, (x, past - 1.0))
        assert g.target is not None
        assert (g.target.source == "plan") == followed, (past, off_deg, south)


def test_a_track_just_acquired_is_not_taken_to_move_for_its_first_seconds(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The first fixes of a still AUV drift by metres while the calibration
    settles and the boat closes in: a line at 0.8 m/s, 0.05 m/s σ, is not
    taken for a start until the track is ``FRESH_S`` old — meanwhile the boat
    goes to where the filter has the AUV — nor again after a loss."""
    _fresh_rule(monkeypatch)
    g = FollowGuidance(FollowSettings())
    drifting = _track(x=10.0, y=5.0, vx=0.8, vy=0.0, sv=0.05)
    for t in (100.0, 100.0 + 0.5 * FRESH_S, 100.0 + FRESH_S - 0.5):
        st = g.update(dataclasses.replace(drifting, t=t, t0=t), t, 0.0, 0.0)
        assert not g.moving
        assert st.leg is not None and st.leg.course_rad == pytest.approx(math.atan2(5.0, 10.0))
    t = 100.0 + FRESH_S + 0.5
    g.update(dataclasses.replace(drifting, t=t, t0=t), t, 0.0, 0.0)
    assert g.moving
    # a track lost before the AUV moved: the one that comes back is fresh again
    g2 = FollowGuidance(FollowSettings())
    g2.update(drifting, 100.0, 0.0, 0.0)
    lost = dataclasses.replace(drifting, t=110.0, t0=110.0, lost=True)
    assert g2.update(lost, 110.0, 0.0, 0.0).mode == "hold"
    for t in (120.0, 120.0 + FRESH_S - 0.5):
        g2.update(dataclasses.replace(drifting, t=t, t0=t), t, 0.0, 0.0)
        assert not g2.moving
    t = 120.0 + FRESH_S + 0.5
    g2.update(dataclasses.replace(drifting, t=t, t0=t), t, 0.0, 0.0)
    assert g2.moving


def test_a_fresh_track_gone_far_from_where_it_was_first_seen_moves(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """An AUV already under way when acquired: once its filter is
    ``FRESH_ESCAPE_M`` from where it was first seen, it moves whatever the
    track's age."""
    _fresh_rule(monkeypatch)
    g = FollowGuidance(FollowSettings())
    first = _track(x=10.0, y=5.0, vx=1.0, vy=0.0, sv=0.05)
    g.update(first, 100.0, 0.0, 0.0)
    assert not g.moving
    short = follow_motion.FRESH_ESCAPE_M - 1.0
    near = _track(x=10.0 + short, y=5.0, vx=1.0, vy=0.0, sv=0.05, t=100.0 + short)
    g.update(near, near.t, 8.0, 5.0)
    assert not g.moving
    gone = follow_motion.FRESH_ESCAPE_M + 0.5
    far = _track(x=10.0 + gone, y=5.0, vx=1.0, vy=0.0, sv=0.05, t=100.0 + gone)
    g.update(far, far.t, 9.0, 5.0)
    assert g.moving


def test_on_its_plan_a_hovering_auv_is_taken_to_move_only_with_its_filter_moving() -> None:
    """Hovering at its plan's start, the AUV's speed along the plan flickers
    above the still speed while its filter has it nearly still: the boat holds
    its station (before, it ran metres along the plan after a target that was
    not moving); the filter corroborating, it sets off."""
    cfg = FollowSettings()
    g = FollowGuidance(cfg)
    g.set_plan(AuvPlan(0.0, ((0.0, 0.0), (100.0, 0.0), (100.0, 20.0)), "mission"))
    flicker = 1.5 * cfg.still_speed_mps
    base = dataclasses.replace(_track(vx=0.02, sv=0.03), plan_leg=0, plan_s_m=0.0,
                               plan_cross_m=0.0, plan_turn_radius_m=6.0)
    t = base.t
    g.update(dataclasses.replace(base, plan_speed_mps=0.0), t, 1.0, 0.0)
    assert not g.moving
    kf_slow = 0.5 * follow_motion.PLAN_KF_MOVING_MPS
    for k in range(40):
        t += 0.05
        tr = dataclasses.replace(base, t=t, t0=t, plan_speed_mps=flicker,
                                 kf_vx_mps=kf_slow)
        st = g.update(tr, t, 1.0, 0.0)
        assert not g.moving, k
        assert st.leg is None and st.station == pytest.approx((ABOVE_STATION_M, 0.0), abs=0.1)
    t += 0.05
    tr = dataclasses.replace(base, t=t, t0=t, plan_speed_mps=flicker,
                             kf_vx_mps=1.5 * follow_motion.PLAN_KF_MOVING_MPS)
    g.update(tr, t, 1.0, 0.0)
    assert g.moving


def test_before_the_auv_is_heard_the_boat_goes_to_its_plans_start() -> None:
    """No track yet, a plan given: the boat is sent to the plan's start (the
    station ``ABOVE_STATION_M`` ahead on the first leg) and, there, holds that
    station facing the first leg; a plan the tracker guessed, a plan whose start
    is 300 m off, or no plan: it waits where it is."""
    plan = ((50.0, 20.0), (50.0, 120.0), (70.0, 120.0))  # first leg east (course 90°)
    station = (50.0, 20.0 + ABOVE_STATION_M)
    g = FollowGuidance(FollowSettings())
    g.set_plan(AuvPlan(0.0, plan, "mission"))
    st = g.update(None, 1.0, 20.0, 0.0)
    assert st.mode == "wait" and st.leg is not None and st.speed_ref_mps > 0.5
    assert "plan's start" in st.reason
    # the leg points at the station from the boat
    bearing = math.atan2(station[1] - 0.0, station[0] - 20.0)
    assert abs(math.remainder(st.leg.course_rad - bearing, math.tau)) < math.radians(1.0)
    there = g.update(None, 30.0, station[0] + 0.5, station[1] - 0.5)
    assert there.leg is None and there.station == pytest.approx(station)
    assert abs(math.remainder(there.heading_rad - math.pi / 2, math.tau)) < math.radians(46.0)
    for points, source in ((plan, "tracker"),
                           (tuple((n + 300.0, e) for n, e in plan), "mission"), ((), "")):
        w = FollowGuidance(FollowSettings())
        w.set_plan(AuvPlan(0.0, points, source))
        st = w.update(None, 1.0, 20.0, 0.0)
        assert st.leg is None and st.speed_ref_mps == 0.0 and st.station is None, source
