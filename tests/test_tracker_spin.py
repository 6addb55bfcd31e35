"""A turn rate the path does not bear out: what a U-turn leaves in the IMM's
quiet model is set back to 0 on the new leg (the acoustic rig, the filter's
course then nearer the truth than without the check), while a true arc keeps
its rate (the filter and the manoeuvre detector as the tracker builds them,
fed noisy position fixes on a circle).  What a U-turn the IMM declared left in
the quiet model goes when the manoeuvre ends; an arc flown before a sharper
turn keeps its rate through it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tracker_rig import uturn_course_errors

from zarco_core.lbl import LblNetworkParams
from zarco_runtime.tracking.imm import Imm
from zarco_runtime.tracking.maneuver import ManeuverDetector
from zarco_runtime.tracking.params import TrackerParams
from zarco_runtime.tracking.tracker import AuvTracker

XY = [(1.0, 0.0), (0.0, 1.0)]
FIX_INTERVAL_S = 2.0
FIX_SIGMA_M = 1.0
#: 1σ (deg/s) of the quiet model's starting turn rate (a settled filter's)
RATE0_SIGMA_DPS = 0.2


def _filter() -> tuple[Imm, ManeuverDetector]:
    trk = AuvTracker(TrackerParams(network=LblNetworkParams()))
    assert isinstance(trk.kf, Imm)
    return trk.kf, trk.man


def _fly(kf: Imm, man: ManeuverDetector, seed: int, speed: float, rate_dps: float,
         rate0_dps: float, duration_s: float) -> list[tuple[float, float]]:
    """Fixes of an AUV at ``speed`` m/s turning at ``rate_dps`` (0: straight),
    the quiet model starting at ``rate0_dps`` (σ ``RATE0_SIGMA_DPS``); after every
    update the check and the detector run as in the tracker.  Returns (time s, quiet rate
    deg/s) after each update."""
    rng = np.random.default_rng(seed)
    w = math.radians(rate_dps)
    kf.init(0.0, 0.0, 0.0, speed, 0.0, 1.0, 0.01)
    quiet = kf.models[0]
    quiet.x[4] = math.radians(rate0_dps)
    quiet.P[4][4] = math.radians(RATE0_SIGMA_DPS) ** 2
    x = y = 0.0
    psi = 0.0
    out = []
    t = 0.0
    while t < duration_s:
        t += FIX_INTERVAL_S
        if abs(w) > 0.0:
            x += speed / w * (math.sin(psi + w * FIX_INTERVAL_S) - math.sin(psi))
            y += speed / w * (math.cos(psi) - math.cos(psi + w * FIX_INTERVAL_S))
            psi += w * FIX_INTERVAL_S
        else:
            x += speed * FIX_INTERVAL_S
        kf.predict(t)
        z = [x + rng.normal(0.0, FIX_SIGMA_M), y + rng.normal(0.0, FIX_SIGMA_M)]
        ok, _ = kf.update(XY, z, [FIX_SIGMA_M ** 2] * 2, 16.0, 4.0)
        assert ok
        if not man.maneuvering:
            man.spin(kf)
        man.imm_state(kf)
        out.append((t, math.degrees(kf.quiet_turn_rate[0])))
    return out


def test_a_uturns_leftover_turn_rate_is_set_back_on_the_new_leg(
        monkeypatch: pytest.MonkeyPatch) -> None:
    cases = [(speed, rate, spacing, seed) for seed in (1, 2)
             for speed, rate, spacing in ((0.5, 7.5, 15.0), (0.7, 10.0, 12.0),
                                          (0.9, 8.0, 20.0))]
    # the check against the rate a U-turn leaves in a filter fed whole cycles
    # (the half cycles' extra updates correct part of it themselves: with
    # them the check fires in half of these U-turns, never to the course's cost)
    whole = {"half_cycles": False}
    with_check = [uturn_course_errors(*c, (10.0, 60.0), "fix.spin", trk=whole) for c in cases]
    # a U-turn leaves a turn rate the new leg does not bear out: set back at most
    # once (never on a straight leg), in most of them
    assert all(n <= 1 for _, n in with_check)
    assert sum(n for _, n in with_check) >= len(cases) - 2
    monkeypatch.setattr(ManeuverDetector, "spin", lambda self, kf: False)
    without = [uturn_course_errors(*c, (10.0, 60.0), "fix.spin", trk=whole)[0]
               for c in cases]
    # the filter's course on the new leg: never worse, better on the whole
    gains = [b - a for (a, _), b in zip(with_check, without, strict=True)]
    assert min(gains) >= 0.0
    assert float(np.mean(gains)) >= 0.3


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
@pytest.mark.parametrize(("speed", "rate"), [(0.8, 2.3), (1.2, -1.5), (1.0, 3.8),
                                             (0.6, 2.0)])
def test_a_true_arc_keeps_its_rate(seed: int, speed: float, rate: float) -> None:
    kf, man = _filter()
    rates = _fly(kf, man, seed, speed, rate, rate, 150.0)
    assert man.spins == 0
    late = [r for t, r in rates if t >= 60.0]
    assert abs(float(np.mean(late)) - rate) <= 0.5


def _fly_segments(seed: int, speed: float, segments: list[tuple[float, float]]
                  ) -> list[tuple[float, str, float]]:
    """Fixes every second of an AUV at ``speed`` m/s flying ``segments`` (duration
    s, turn rate deg/s), the filter and the detector as the tracker builds and
    runs them.  Returns (time s, IMM manoeuvre state, quiet rate deg/s) after
    each update."""
    trk = AuvTracker(TrackerParams(network=LblNetworkParams()))
    kf, man = trk.kf, trk.man
    assert isinstance(kf, Imm)
    rng = np.random.default_rng(seed)
    kf.init(0.0, 0.0, 0.0, speed, 0.0, 1.0, 0.01)
    x = y = psi = t = 0.0
    out = []
    for duration, rate in segments:
        w = math.radians(rate)
        t_end = t + duration
        while t < t_end - 1e-9:
            t += 1.0
            if w:
                x += speed / w * (math.sin(psi + w) - math.sin(psi))
                y += speed / w * (math.cos(psi) - math.cos(psi + w))
                psi += w
            else:
                x += speed * math.cos(psi)
                y += speed * math.sin(psi)
            kf.predict(t)
            z = [x + rng.normal(0.0, FIX_SIGMA_M), y + rng.normal(0.0, FIX_SIGMA_M)]
            assert kf.update(XY, z, [FIX_SIGMA_M ** 2] * 2, 16.0, 4.0)[0]
            if not man.maneuvering:
                man.spin(kf)
            state = man.imm_state(kf)
            out.append((t, state, math.degrees(kf.quiet_turn_rate[0])))
    return out


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize(("speed", "rate"), [(0.6, 8.0), (0.9, 10.0), (1.2, -8.0)])
def test_what_a_sharp_turn_left_in_the_quiet_model_goes_when_it_ends(
        seed: int, speed: float, rate: float) -> None:
    """A lawnmower's U-turn, declared by the IMM: the turn rate the quiet model
    picked up during it (an arc by its average) is set back to 0 when the
    manoeuvre ends, not left to the path check."""
    out = _fly_segments(seed, speed, [(60.0, 0.0), (180.0 / abs(rate), rate), (60.0, 0.0)])
    exits = [(t, w) for t, state, w in out if state == "exit" and t > 60.0]
    assert exits, "the U-turn was declared and ended"
    assert all(w == 0.0 for _, w in exits)


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
@pytest.mark.parametrize(("speed", "rate"), [(0.8, 3.0), (1.0, -2.5), (1.2, 3.5)])
def test_an_arc_flown_before_a_sharper_turn_keeps_its_rate(seed: int, speed: float,
                                                          rate: float) -> None:
    """An AUV on an arc tightens it for 8 s, then flies the arc on: a manoeuvre
    the IMM declares there ends with the arc's rate kept, and the quiet model
    follows the arc after it."""
    out = _fly_segments(seed, speed, [(20.0, 0.0), (80.0, rate),
                                      (8.0, math.copysign(12.0, rate)), (60.0, rate)])
    exits = [w for t, state, w in out if state == "exit" and t > 100.0]
    assert all(w * rate > 0.0 and abs(w) >= 0.5 * abs(rate) for w in exits)
    late = [w for t, _, w in out if t >= 150.0]
    assert abs(float(np.mean(late)) - rate) <= 0.5
