"""Ranges, motion bias, circle fix, mirror choice — on exact and simulated timing."""

from __future__ import annotations

import math

import pytest

from drivers.sim.acoustics import AcousticWorld, LblParams
from drivers.sim.auv import Auv, AuvParams
from zarco_core.auv_messages import AuvFix, AuvTrack
from zarco_core.lbl import LblNetworkParams
from zarco_runtime.tracking.cycles import Cycle
from zarco_runtime.tracking.fix import (
    circle_fix,
    cycle_ranges,
    motion_bias,
    range_variances,
)
from zarco_runtime.tracking.params import Network, TrackerParams
from zarco_runtime.tracking.tracker import AuvTracker

EPOCH = 1_780_308_000.0  # 2026-06-01T10:00:00Z: epoch-sized times throughout
EXACT = {"jitter_s": 0.0, "p_miss": 0.0, "p_false": 0.0, "p_multipath": 0.0}


def _run(waypoints: list[list[float]], duration_s: float, lbl: dict[str, object] | None = None,
         trk: dict[str, object] | None = None, seed: int = 1,
         depth_m: float = 10.0) -> tuple[AcousticWorld, AuvTracker, list[AuvFix], list[AuvTrack]]:
    """Simulate, feed the tracker the exact (unrounded) events, collect its output."""
    lp = LblParams(**(lbl or {}))  # type: ignore[arg-type]
    auv = Auv(AuvParams(waypoints=waypoints, depth_m=depth_m))
    world = AcousticWorld(lp, auv, seed, start_utc_epoch_s=EPOCH)
    tracker = AuvTracker(TrackerParams(network=lp.network(), auv_depth_m=depth_m,
                                       **(trk or {})))  # type: ignore[arg-type]
    fixes: list[AuvFix] = []
    tracks: list[AuvTrack] = []
    t = 0.0
    while t < duration_s:
        t += 0.5
        for ev in world.events_exact_until(t):
            for m in tracker.process(ev):
                if isinstance(m, AuvFix):
                    fixes.append(m)
                else:
                    tracks.append(m)
    assert tracker.dropped["internal"] == 0
    return world, tracker, fixes, tracks


def _err(world: AcousticWorld, fix: AuvFix) -> tuple[float, float]:
    tr = world.auv_truth(fix.emission_utc_s - EPOCH)
    return (math.hypot(fix.x_m - tr.x_m, fix.y_m - tr.y_m),
            math.hypot(fix.mirror_x_m - tr.x_m, fix.mirror_y_m - tr.y_m))


@pytest.mark.parametrize("pos", [[200.0, 150.0], [30.0, 250.0], [350.0, 300.0], [-80.0, -60.0]])
def test_static_auv_exact_timing_gives_its_position_to_a_millimetre(pos: list[float]) -> None:
    world, tracker, fixes, tracks = _run([pos], 60.0, EXACT)
    two_circle = [f for f in fixes if not f.range_only]
    assert len(two_circle) >= 30
    for f in two_circle[1:]:  # the first may precede the mirror vote
        assert f.accepted
        err, mirror_err = _err(world, f)
        assert err < 1e-3, (f, err)
        assert mirror_err > 1.0
        assert abs(f.bias_m) < 1e-4  # a still AUV has (almost) no motion bias
    last = tracks[-1]
    assert math.hypot(last.kf_x_m - pos[0], last.kf_y_m - pos[1]) < 1e-3
    assert not tracker.counters().get("fix.innovation")


def test_cycle_ranges_and_emission_time_exact() -> None:
    net = Network.from_params(LblNetworkParams(), 0.003)
    c = net.c
    auv = (180.0, 90.0, 10.0)
    lst = (net.north[0], net.east[0], net.depth[0])
    b = (net.north[2], net.east[2], net.depth[2])
    r_i, r_l = math.dist(auv, b), math.dist(auv, lst)
    t_emit = EPOCH + 5.0
    cyc = Cycle(0.0, 2, 3, t_emit + r_l / c, t_emit + r_i / c + net.tau[2] + net.d[2] / c,
                t_emit + 2 * r_i / c + net.tau[2] + net.delta + r_l / c, 1)
    rg = cycle_ranges(cyc, net)
    assert rg.r_i == pytest.approx(r_i, abs=1e-3)
    assert rg.r_l == pytest.approx(r_l, abs=1e-3)
    assert rg.emission_utc_s == pytest.approx(t_emit, abs=1e-6)
    cf = circle_fix(net, 2, rg.r_i, rg.r_l, 10.0)
    assert cf is not None and cf.gap_m == 0.0
    errs = sorted(math.hypot(x - auv[0], y - auv[1]) for x, y in ((cf.x1, cf.y1), (cf.x2, cf.y2)))
    assert errs[0] < 1e-3 < 1.0 < errs[1]


def test_circle_fix_mirror_geometry_and_tangent_cases() -> None:
    net = Network.from_params(LblNetworkParams(
        beacons=[[0.0, 0.0, 10.0], [100.0, 0.0, 10.0]], turnaround_s=[0.1, 0.1]), 0.003)
    # AUV at the beacons' depth: horizontal radii equal the ranges
    cf = circle_fix(net, 1, math.hypot(50.0, 30.0), math.hypot(50.0, 30.0), 10.0)
    assert cf is not None
    assert {(round(cf.x1, 9), round(cf.y1, 9)), (round(cf.x2, 9), round(cf.y2, 9))} == {
        (50.0, 30.0), (50.0, -30.0)}  # the mirror across the baseline (north axis)
    # circles 2 m apart: the point between them, both solutions equal
    cf = circle_fix(net, 1, 49.0, 49.0, 10.0)
    assert cf is not None and cf.gap_m == pytest.approx(2.0)
    assert (cf.x1, cf.y1) == (cf.x2, cf.y2) == (pytest.approx(50.0), pytest.approx(0.0))
    # nested: beyond beacon 1
    cf = circle_fix(net, 1, 10.0, 112.0, 10.0)
    assert cf is not None and cf.gap_m == pytest.approx(2.0) and cf.x1 == pytest.approx(111.0)
    # a range shorter than the depth offset is refused
    assert circle_fix(net, 1, 5.0, 50.0, 20.0) is None
    # the listener's own beacon has a single circle
    assert circle_fix(net, 0, 50.0, 50.0, 10.0) is None


def test_range_variances_match_the_timing_algebra() -> None:
    net = Network.from_params(LblNetworkParams(), 0.003)
    vi, vl = range_variances(net, 1, 0.001, 0.0)
    assert vi == pytest.approx(0.5 * 1.5**2)
    assert vl == pytest.approx(1.5 * 1.5**2)
    vi0, vl0 = range_variances(net, 0, 0.001, 0.5)
    assert vi0 == vl0 == pytest.approx(0.5 * 1.5**2 + 0.25)


def test_motion_bias_correction_on_a_moving_auv() -> None:
    """At 1 m/s the cycle's ranges are biased by ≈ v·P/2 (tens of cm); the
    correction with the filter's velocity removes it to the centimetre."""
    wps = [[100.0, 60.0], [100.0, 380.0]]  # eastwards, 320 m
    # the correction alone: the sound-speed estimate (its own tests) stays off
    world, _tr, fixes, _ = _run(wps, 250.0, EXACT, trk={"calibrate": False})

    def good_geometry_errors(w: AcousticWorld, fs: list[AuvFix]) -> list[float]:
        # near a baseline any residual range error is amplified across it (the
        # AUV crosses the listener–B3 baseline at t ≈ 208 s): judge the others
        out = []
        for f in fs[20:]:
            if f.accepted and not f.range_only:
                err, mirror_err = _err(w, f)
                if mirror_err > 60.0:
                    out.append(err)
        return out

    errs = good_geometry_errors(world, fixes)
    biases = [abs(f.bias_m) for f in fixes[20:] if not f.range_only]
    assert len(errs) > 80
    assert max(biases) > 0.2
    assert max(errs) < 0.02
    world2, _tr2, fixes2, _ = _run(wps, 250.0, EXACT, trk={"motion_correction": False,
                                                            "calibrate": False})
    errs2 = good_geometry_errors(world2, fixes2)
    assert sum(errs2) / len(errs2) > 0.25  # the uncorrected bias is real
    # and b matches its formula evaluated on the truth
    net = Network.from_params(LblParams().network(), 0.003)
    f = next(f for f in fixes[40:] if not f.range_only and f.beacon == 2)
    tr = world.auv_truth(f.emission_utc_s - EPOCH)
    b = motion_bias(net, 1, f.r_i_m, tr.x_m, tr.y_m, 10.0, tr.vx_mps, tr.vy_mps)
    assert f.bias_m == pytest.approx(b, abs=0.01)


def test_mirror_resolved_at_initialisation_against_a_misleading_prior() -> None:
    """The prior sits on the mirror of the true position across the listener–B2
    baseline; the vote of the two baselines still picks the truth."""
    pos = [250.0, 200.0]
    net = LblNetworkParams()
    # mirror of pos across the line B1(0,0) – B2(400,50)
    ux, uy = 400.0 / math.hypot(400, 50), 50.0 / math.hypot(400, 50)
    along = pos[0] * ux + pos[1] * uy
    mirror = [2 * along * ux - pos[0], 2 * along * uy - pos[1]]
    world, _tracker, fixes, tracks = _run([pos], 40.0, EXACT,
                                          trk={"prior_north_m": mirror[0],
                                               "prior_east_m": mirror[1]})
    assert net.beacons[1] == [400.0, 50.0, 30.0]
    accepted = [f for f in fixes if f.accepted and not f.range_only]
    assert accepted
    for f in accepted:
        err, mirror_err = _err(world, f)
        assert err < 0.01 and mirror_err > 100.0
    assert math.hypot(tracks[-1].kf_x_m - pos[0], tracks[-1].kf_y_m - pos[1]) < 0.01


def test_single_baseline_network_uses_the_prior() -> None:
    lbl = dict(EXACT, beacons=[[0.0, 0.0, 30.0], [400.0, 0.0, 30.0]], turnaround_s=[0.1, 0.1])
    pos = [200.0, 120.0]
    for prior, want_true in [((200.0, 100.0), True), ((200.0, -100.0), False)]:
        world, _tr, fixes, _tracks = _run([pos], 30.0, lbl,
                                          trk={"prior_north_m": prior[0],
                                               "prior_east_m": prior[1]})
        f = next(f for f in fixes if f.accepted and not f.range_only)
        err, mirror_err = _err(world, f)
        assert (err < 0.01) == want_true and (mirror_err < 0.01) == (not want_true)


def test_mirror_choice_follows_the_prediction_while_tracking() -> None:
    """A moving AUV crossing the middle of the network: every accepted fix is
    the true solution, though the mirrors come as close as a few metres when
    the AUV crosses a baseline."""
    world, tracker, fixes, _ = _run([[30.0, 300.0], [300.0, 40.0]], 360.0, EXACT)
    accepted = [f for f in fixes if f.accepted and not f.range_only][10:]  # after convergence
    assert len(accepted) > 150
    near_baseline = 0
    for f in accepted:
        err, mirror_err = _err(world, f)
        assert err <= mirror_err and err < 2.0, f  # near a baseline the fix is poorer
        near_baseline += mirror_err < 20.0
    assert near_baseline >= 2  # the test does exercise close mirrors
    assert tracker.counters().get("fix.reacquired", 0) == 0


FOUR = LblNetworkParams(beacons=[[0.0, 0.0, 30.0], [400.0, 50.0, 30.0], [150.0, 400.0, 30.0],
                                 [420.0, 380.0, 30.0]], turnaround_s=[0.1] * 4)


def _ranges(net: Network, p: tuple[float, float], idx: list[int], noise: list[float],
            var: float) -> list[tuple[int, float, float]]:
    return [(i, math.dist((p[0], p[1], 10.0), (net.north[i], net.east[i], net.depth[i])) + n,
             var) for i, n in zip(idx, noise, strict=True)]


def test_least_squares_fix_is_exact_with_exact_ranges() -> None:
    from zarco_runtime.tracking.fix import ls_fix

    net = Network.from_params(FOUR)
    p = (180.0, 230.0)
    sol = ls_fix(net, _ranges(net, p, [0, 1, 2, 3], [0.0] * 4, 1.0), 10.0, p[0] + 7.0,
                 p[1] - 5.0)
    assert sol is not None
    assert (sol[0], sol[1]) == pytest.approx(p, abs=1e-6)
    assert sol[2] > 0.0 and sol[4] > 0.0 and sol[2] * sol[4] > sol[3] ** 2


def test_a_fourth_beacon_never_makes_the_fix_worse_and_its_covariance_is_honest() -> None:
    import numpy as np

    from zarco_runtime.tracking.fix import ls_fix

    net = Network.from_params(FOUR)
    rng = np.random.default_rng(11)
    # along the listener–beacon-4 diagonal: the pair (0, 3) alone is poor there
    pts = [(120.0 + 5.0 * k, 110.0 + 4.5 * k) for k in range(40)]
    e3, e4, nees = [], [], []
    for p in pts:
        n = rng.normal(0.0, 0.7, 4)
        s3 = ls_fix(net, _ranges(net, p, [0, 1, 2], list(n[:3]), 0.49), 10.0, p[0], p[1])
        s4 = ls_fix(net, _ranges(net, p, [0, 1, 2, 3], list(n), 0.49), 10.0, p[0], p[1])
        assert s3 is not None and s4 is not None
        e3.append(math.hypot(s3[0] - p[0], s3[1] - p[1]))
        ex, ey = s4[0] - p[0], s4[1] - p[1]
        e4.append(math.hypot(ex, ey))
        det = s4[2] * s4[4] - s4[3] ** 2
        nees.append((s4[4] * ex * ex - 2 * s4[3] * ex * ey + s4[2] * ey * ey) / det)
    rms3 = math.sqrt(sum(e * e for e in e3) / len(e3))
    rms4 = math.sqrt(sum(e * e for e in e4) / len(e4))
    assert rms4 <= rms3
    # normalised error squared: 2 on average for an honest 2-D covariance
    assert 1.0 < sum(nees) / len(nees) < 3.5


def test_tracker_fixes_with_four_beacons_no_worse_than_with_three() -> None:
    def fix_rms(lbl: dict[str, object]) -> float:
        world, _, fixes, _ = _run([[120.0, 110.0], [300.0, 270.0]], 300.0, lbl)
        errs = [_err(world, f)[0] for f in fixes if f.accepted and not f.range_only]
        return math.sqrt(sum(e * e for e in errs) / len(errs))

    three = fix_rms({})
    four = fix_rms({"beacons": FOUR.beacons, "turnaround_s": FOUR.turnaround_s})
    assert four <= 1.1 * three
