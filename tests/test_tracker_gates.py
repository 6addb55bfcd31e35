"""Gates that degrade gracefully: a beacon surveyed 2 m off costs about that much
distance, never the track; the gates widen with the residuals they measure (and
stay as configured when the network is as surveyed); a filter that is sure of a
wrong position re-anchors on the fixes instead of coasting."""

from __future__ import annotations

import itertools
import math

import pytest
from tracker_rig import Run, run

from zarco_runtime.tracking.gates import NoiseScale

LAWN = [[100.0, 80.0], [300.0, 80.0], [300.0, 110.0], [100.0, 110.0], [100.0, 140.0],
        [300.0, 140.0]]
BEACONS = [[0.0, 0.0, 30.0], [400.0, 50.0, 30.0], [150.0, 400.0, 30.0]]


def _moved(k: int, dx: float, dy: float) -> list[list[float]]:
    out = [list(b) for b in BEACONS]
    out[k][0] += dx
    out[k][1] += dy
    return out


def _longest_gap(times: list[float]) -> float:
    return max((b - a for a, b in itertools.pairwise(times)), default=math.inf)


@pytest.mark.parametrize(("seed", "k", "dx", "dy"), [
    (21, 0, 2.0, 0.0), (22, 1, -1.2, 1.6), (23, 2, 0.0, -2.0), (24, 1, 1.4, 1.4),
])
def test_a_beacon_surveyed_2_m_off_costs_about_2_m_never_the_track(
        seed: int, k: int, dx: float, dy: float) -> None:
    # the tracker is told the beacon is 2 m from where it is
    r = run(LAWN, 700.0, seed=seed, lbl={"beacons": BEACONS},
            survey={"beacons": _moved(k, dx, dy)}, start_delay_s=30.0)
    acq = r.acquired_s
    assert acq is not None
    later = r.after(acq + 30.0)
    assert not any(s.track.lost for s in later if s.track is not None)
    updates = sorted({s.track.t0 for s in later if s.track is not None})
    assert _longest_gap(updates) <= 10.0
    errs = sorted(r.position_error(s) for s in later)
    assert errs[len(errs) // 2] <= 2.5
    assert errs[int(0.95 * len(errs))] <= 6.0
    assert r.tracker.counters().get("fix.innovation", 0) < 0.1 * r.tracker.fixes_accepted


def test_the_gates_widen_with_the_residuals_and_not_without_them() -> None:
    # 1.5 ms of detection jitter where 0.5 ms is configured: the innovations are
    # larger than their predicted spread and the measured scale says so
    noisy = run(LAWN, 500.0, seed=31, lbl={"jitter_s": 0.0015}, start_delay_s=30.0)
    assert 2.0 < noisy.tracker.noise.scale < 15.0
    refused = noisy.tracker.counters().get("fix.innovation", 0)
    assert refused < 0.05 * noisy.tracker.fixes_accepted
    clean = run(LAWN, 500.0, seed=31, start_delay_s=30.0)
    assert 1.0 <= clean.tracker.noise.scale < 1.6


def test_the_noise_scale_is_the_median_of_what_it_saw() -> None:
    ns = NoiseScale()
    # residuals four times as spread (in variance) as configured: each χ² is
    # computed with the scale then in force, as the tracker does
    for _ in range(40):
        ns.observe(0.4549 * 4.0 / ns.scale, 1)
    assert ns.scale == pytest.approx(4.0)
    for _ in range(14):
        ns.observe(1e6, 2)  # outliers, fewer than half of the window
    assert ns.scale == pytest.approx(4.0)
    for _ in range(40):
        ns.observe(0.01, 2)  # quieter than configured: never below 1
    assert ns.scale == 1.0


def _moved_filter(r: Run, dx: float, dy: float) -> tuple[int, list[tuple[float, float]]]:
    """Move the acquired filter of ``r`` by (dx, dy) m with a small covariance
    (sure of a wrong position), run the world 60 s on: the re-anchorings
    meanwhile and the filter's error (s since, m)."""
    kf = r.tracker.kf
    assert kf.initialised
    for m in getattr(kf, "models", [kf]):
        m.x[0] += dx
        m.x[1] += dy
        for i in range(len(m.P)):
            for j in range(len(m.P)):
                m.P[i][j] *= 0.01 if i == j else 0.0
    if hasattr(kf, "_combine"):
        kf._combine()
    before = r.tracker.counters().get("fix.reanchored", 0)
    t0 = r.samples[-1].t
    world, tracker = r.world, r.tracker
    errs = []
    t = t0
    while t < t0 + 60.0:
        t += 0.5
        for ev in world.events_exact_until(t):
            tracker.process(ev)
        tr = world.auv_truth(kf.t - world.epoch0_s)
        errs.append((t - t0, math.hypot(kf.x[0] - tr.x_m, kf.x[1] - tr.y_m)))
    return tracker.counters().get("fix.reanchored", 0) - before, errs


@pytest.mark.parametrize("seed", [41, 42, 43])
def test_a_filter_sure_of_a_wrong_position_re_anchors_instead_of_coasting(seed: int) -> None:
    # acquire, then move the filter 12 m off with a small covariance: every fix is
    # refused by its gate; a run of refused fixes the other beacons confirm
    # opens it up again and the track comes back within a few cycles
    r = run(LAWN, 120.0, seed=seed, start_delay_s=20.0)
    reanchored, errs = _moved_filter(r, 12.0, 0.0)
    assert reanchored > 0
    # back within 2 m of the truth within 20 s, and it stays there
    assert max(e for dt, e in errs if dt >= 20.0) < 2.0


@pytest.mark.parametrize("seed", [51, 52, 53])
def test_one_range_agreeing_does_not_stop_a_re_anchoring(seed: int) -> None:
    # two beacons: the listener's own cycles give one range, the other beacon's
    # a position.  Move the filter 10 m across the listener's line of sight
    # (its range barely changes) with a small covariance: the single ranges
    # still pass, the positions are refused.  The refused positions must add
    # up to a re-anchoring, not be reset by every single range in between
    # (manoeuvre detection off: it would open the filter too)
    two = BEACONS[:2]
    r = run(LAWN, 120.0, seed=seed, start_delay_s=20.0,
            lbl={"beacons": two, "turnaround_s": [0.1, 0.1]},
            trk={"maneuver_threshold": 1e4, "turn_cusum_threshold": 1e4,
                 "maneuver_on": 0.99, "maneuver_off": 0.98})
    kf = r.tracker.kf
    rx, ry = kf.x[0] - two[0][0], kf.x[1] - two[0][1]  # from the listener (beacon 0)
    n = math.hypot(rx, ry)
    reanchored, errs = _moved_filter(r, -ry / n * 10.0, rx / n * 10.0)
    assert reanchored > 0
    assert max(e for dt, e in errs if dt >= 30.0) < 3.5
