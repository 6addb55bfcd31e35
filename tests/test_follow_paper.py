"""The paper's follow law (paper VI): signs of d and s, h_AUV, s_AUV(t)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from zarco_runtime.guidance.follow_paper import FollowGeometry, follow_geometry
from zarco_runtime.guidance.mission import Leg


def geo(x0: float, y0: float, vx: float, vy: float, x: float, y: float,
        t: float = 0.0) -> FollowGeometry:
    g = follow_geometry(x0, y0, vx, vy, x, y, t)
    assert g is not None
    return g


def test_d_is_positive_to_starboard_heading_north() -> None:
    # AUV heading north along x through the origin; starboard is east (+y)
    assert geo(0.0, 0.0, 1.0, 0.0, 5.0, 3.0).d_m == pytest.approx(3.0)
    assert geo(0.0, 0.0, 1.0, 0.0, 5.0, -3.0).d_m == pytest.approx(-3.0)


def test_d_is_positive_to_starboard_heading_east() -> None:
    # heading east: starboard is south (−x)
    assert geo(0.0, 0.0, 0.0, 1.5, -4.0, 10.0).d_m == pytest.approx(4.0)
    assert geo(0.0, 0.0, 0.0, 1.5, 4.0, 10.0).d_m == pytest.approx(-4.0)


def test_d_is_zero_on_the_line_and_matches_leg_project() -> None:
    """Same convention as the line-tracking guidance (Leg.project)."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        x0, y0 = rng.uniform(-500, 500, size=2)
        vx, vy = rng.uniform(-2, 2, size=2)
        if math.hypot(vx, vy) < 0.1:
            continue
        x, y = rng.uniform(-500, 500, size=2)
        leg = Leg(0, x0, y0, x0 + 100 * vx, y0 + 100 * vy, 1.0)
        along, d_leg = leg.project(x, y)
        g = geo(x0, y0, vx, vy, x, y)
        assert g.d_m == pytest.approx(d_leg, abs=1e-9)
        # s − s_AUV(0) is the along-track distance from (x0, y0)
        assert -g.along_error_m == pytest.approx(along, abs=1e-9)
        for k in (0.0, 3.7, -20.0):  # points on the line give d = 0
            assert geo(x0, y0, vx, vy, x0 + k * vx, y0 + k * vy).d_m == pytest.approx(
                0.0, abs=1e-9)


def test_the_seed_formula_has_the_wrong_sign() -> None:
    """The paper prints d = (vx y + vy x)/v + h: on the line itself it is not 0."""
    x0, y0, vx, vy = 10.0, 20.0, 0.0, 1.0  # heading east through (10, 20)
    x, y = x0, y0 + 50.0  # on the AUV's track, 50 m ahead
    g = geo(x0, y0, vx, vy, x, y)
    seed_d = (vx * y + vy * x) / g.v_auv_mps + g.h_auv_m
    assert abs(seed_d) > 1.0
    assert g.d_m == pytest.approx(0.0)


def test_s_sign_and_s_auv_advances_with_time() -> None:
    x0, y0, vx, vy = 100.0, 50.0, 0.6, 0.8  # 1 m/s, course 53°
    # ASV 10 m behind the AUV on its line
    x, y = x0 - 10 * 0.6, y0 - 10 * 0.8
    g = geo(x0, y0, vx, vy, x, y, 0.0)
    assert g.along_error_m == pytest.approx(10.0)  # positive: speed up
    assert g.d_m == pytest.approx(0.0, abs=1e-9)
    g5 = geo(x0, y0, vx, vy, x, y, 5.0)
    assert g5.s_auv_m - g.s_auv_m == pytest.approx(5.0)
    # ASV ahead: negative
    assert geo(x0, y0, vx, vy, x0 + 6.0, y0 + 8.0).along_error_m == pytest.approx(-10.0)
    assert g.psi_auv_rad == pytest.approx(math.atan2(0.8, 0.6))
    assert g.v_auv_mps == pytest.approx(1.0)


def test_h_is_the_cross_track_offset_of_the_origin() -> None:
    x0, y0, vx, vy = 30.0, -70.0, -0.3, 0.9
    g = geo(x0, y0, vx, vy, 0.0, 0.0)
    assert g.h_auv_m == pytest.approx(g.d_m)  # the origin's own cross-track offset
    # a line through the origin has h = 0
    assert geo(3 * vx, 3 * vy, vx, vy, 1.0, 1.0).h_auv_m == pytest.approx(0.0, abs=1e-12)


def test_still_auv_has_no_line() -> None:
    assert follow_geometry(1.0, 2.0, 0.0, 0.0, 5.0, 5.0, 1.0) is None
    assert follow_geometry(1.0, 2.0, 0.01, 0.0, 5.0, 5.0, 1.0) is None
    assert follow_geometry(1.0, 2.0, math.nan, 0.0, 5.0, 5.0, 1.0) is None
