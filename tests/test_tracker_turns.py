"""Turns: an arc, a circle or a spiral is followed without a steady course lag
(the quiet model's turn rate follows it, the track says turning and is brought
forward along it between fixes); a sharp turn is declared while the AUV turns
(or within 5 s of its end: the fixes show it no sooner), never on the straight
leg before it, the filter's position stays within the follow campaign's turn
peak through it (the boat is no nearer the AUV than its track), and a minute on
the line is the new leg's (the peaks on the whole: :mod:`test_tracker_half_cycle`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tracker_rig import EPOCH, run

#: the follow campaign's turn target (``turn_max_m``, m): the boat can be no
#: nearer the AUV than its track
TURN_PEAK_M = 12.0


def _course_error(track_vx: float, track_vy: float, psi: float) -> float:
    return math.degrees(math.remainder(math.atan2(track_vy, track_vx) - psi, math.tau))


@pytest.mark.parametrize(("radius", "speed", "angle", "growth", "seed"), [
    (20.0, 0.8, 270.0, 0.0, 1),     # an arc, 2.3 °/s
    (45.0, 1.2, -360.0, 0.0, 2),    # a circle to port, 1.5 °/s
    (60.0, 0.6, 300.0, 0.0, 3),     # a slow one, 0.6 °/s
    (15.0, 1.0, 720.0, 20.0, 4),    # a spiral, 3.8 → 1.9 °/s
    (30.0, 1.4, -200.0, 0.0, 5),    # fast, 2.7 °/s
])
def test_a_continuous_turn_is_followed_without_a_steady_course_lag(
        radius: float, speed: float, angle: float, growth: float, seed: int) -> None:
    wps = [[100.0, 150.0], [200.0, 150.0], [300.0, 150.0]]
    arc_len = abs(angle) / 360.0 * math.tau * (radius + growth * abs(angle) / 720.0)
    r = run(wps, 30.0 + (100.0 + arc_len) / speed + 60.0, seed=seed, speed_mps=speed,
            start_delay_s=30.0, arcs=[[1, radius, angle, growth]])
    (arc,) = [m for m in r.auv.manoeuvres() if m.arc]
    during = [s for s in r.samples if arc.start_s + 20.0 <= s.t <= arc.end_s
              and s.track is not None]
    assert len(during) > 40
    # the course the track gives now (the filter's velocity, brought forward)
    errs = np.array([_course_error(s.track.kf_vx_mps, s.track.kf_vy_mps, s.truth.psi_rad)
                     for s in during if s.track is not None])
    lag = float(np.mean(errs)) * math.copysign(1.0, angle)
    assert abs(lag) <= 2.5  # the line's lag was 5–10° here
    turning = np.mean([bool(s.track.flags & 4) for s in during if s.track is not None])
    assert turning >= 0.8  # the guidance follows the filter, not the lagging line
    pos = sorted(r.position_error(s) for s in during)
    assert pos[len(pos) // 2] <= 1.0 and pos[int(0.95 * len(pos))] <= 2.5


@pytest.mark.parametrize(("speed", "rate", "angle", "seed"), [
    (0.5, 6.0, 90.0, 11), (1.0, 10.0, -90.0, 12), (1.4, 15.0, 90.0, 13),
    (1.2, 8.0, 120.0, 14), (1.0, 10.0, -150.0, 15),
])
def test_a_sharp_turn_is_declared_while_the_auv_turns(speed: float, rate: float,
                                                     angle: float, seed: int) -> None:
    a = math.radians(angle)
    wps = [[100.0, 150.0], [250.0, 150.0],
           [250.0 + 150.0 * math.cos(a), 150.0 + 150.0 * math.sin(a)]]
    r = run(wps, 30.0 + 300.0 / speed + 30.0, seed=seed, speed_mps=speed,
            turn_rate_dps=rate, start_delay_s=30.0)
    (t_turn,) = r.auv.turn_times()
    lasts = abs(angle) / rate
    flagged = next(s.t for s in r.samples
                   if s.t >= t_turn and s.track is not None and s.track.flags & 4)
    assert flagged - t_turn <= lasts + 5.0
    # no turn declared on the straight leg before it
    assert not any(s.track.flags & 4 for s in r.samples
                   if 60.0 + 20.0 <= s.t < t_turn - 2.0 and s.track is not None)
    peak = max(r.position_error(s) for s in r.samples if t_turn <= s.t <= t_turn + 40.0)
    assert peak <= TURN_PEAK_M
    # and a minute on, the line the guidance follows is the new leg
    late = [s for s in r.samples if t_turn + 60.0 <= s.t and s.track is not None]
    errs = [abs(math.degrees(math.remainder(
        s.track.psi_auv_rad - r.auv.truth(s.track.t0_utc_s - EPOCH).psi_rad, math.tau)))
        for s in late if s.track is not None]
    assert len(errs) > 20 and float(np.median(errs)) <= 1.0
