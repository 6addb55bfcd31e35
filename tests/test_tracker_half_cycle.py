"""Half cycles: a missed interrogation costs two cycles, yet each still holds one
range combination — r_i − r_L without its closing ping, r_i + r_L without its
opening one — exact on the simulator's timing, and used by the tracker as
one-row updates."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tracker_rig import run

from drivers.sim.acoustics import AcousticWorld, LblParams
from drivers.sim.auv import Auv, AuvParams
from zarco_core.auv_messages import AcousticEvent, AuvFix, AuvTrack
from zarco_core.lbl import LblNetworkParams
from zarco_runtime.tracking.cycles import Cycle, CycleAssembler
from zarco_runtime.tracking.fix import half_cycle_measure
from zarco_runtime.tracking.params import Network, TrackerParams
from zarco_runtime.tracking.tracker import AuvTracker

EPOCH = 1_780_308_000.0  # 2026-06-01T10:00:00Z
DEPTH = 10.0
EXACT = {"jitter_s": 0.0, "p_miss": 0.0, "p_false": 0.0, "p_multipath": 0.0}


def _ev(utc: float, kind: str, beacon: int) -> AcousticEvent:
    return AcousticEvent(utc - EPOCH + 0.05, "buoy", utc, kind, beacon, 20.0)


def _times(net: Network, i: int, t_ping: float, auv: tuple[float, float, float]
           ) -> tuple[float, float, float]:
    """Listener UTC of the interrogation of beacon index ``i`` emitted at
    ``t_ping`` and of its reply, and the AUV's next ping (a still AUV)."""
    lst = (net.north[net.listener], net.east[net.listener], net.depth[net.listener])
    b = (net.north[i], net.east[i], net.depth[i])
    r_l, r_i = math.dist(auv, lst), math.dist(auv, b)
    return (t_ping + r_l / net.c, t_ping + r_i / net.c + net.tau[i] + net.d[i] / net.c,
            t_ping + 2.0 * r_i / net.c + net.tau[i] + net.delta)


def _ranges(net: Network, i: int, auv: tuple[float, float, float]) -> tuple[float, float]:
    lst = (net.north[net.listener], net.east[net.listener], net.depth[net.listener])
    return math.dist(auv, (net.north[i], net.east[i], net.depth[i])), math.dist(auv, lst)


def test_a_missed_interrogation_leaves_the_range_difference_and_the_range_sum() -> None:
    net = Network.from_params(LblNetworkParams(), 0.003)
    asm = CycleAssembler(net, DEPTH, 3000.0, sequence=[1, 2, 3])
    auv = (150.0, 120.0, DEPTH)
    t1, r1, n1 = _times(net, 1, EPOCH + 10.0, auv)   # beacon id 2, answered
    _, r2, n2 = _times(net, 2, n1, auv)               # beacon id 3: its I missed
    t0, _, _ = _times(net, 0, n2, auv)                # beacon id 1 (the listener's)
    asm.push(_ev(t1, "I", 2))
    asm.push(_ev(r1, "R", 2))
    asm.push(_ev(r2, "R", 3))
    assert asm.push(_ev(t0, "I", 1)) is None          # no whole cycle
    diff, total = asm.take_partial()
    assert asm.take_partial() == []                   # taken once
    assert asm.cycles_partial == 2 and asm.cycles_dropped["sequence"] == 1
    assert (diff.index, diff.t_i, diff.t_r) == (1, t1, r1) and math.isnan(diff.t_next)
    assert (total.index, total.t_r, total.t_next) == (2, r2, t0) and math.isnan(total.t_i)
    # exact but for epoch-sized float times (a 0.24 µs step: 0.4 mm)
    ri, rl = _ranges(net, 1, auv)
    assert abs(half_cycle_measure(diff, net) - (ri - rl)) < 1e-3
    ri, rl = _ranges(net, 2, auv)
    assert abs(half_cycle_measure(total, net) - (ri + rl)) < 1e-3


def test_the_listeners_own_beacon_and_a_stray_reply_make_no_half_cycle() -> None:
    net = Network.from_params(LblNetworkParams(), 0.003)
    auv = (150.0, 120.0, DEPTH)
    # the listener's beacon (id 1) answered, the next I missed: r_i − r_L is 0 there
    asm = CycleAssembler(net, DEPTH, 3000.0, sequence=[1, 2, 3])
    t0, r0, n0 = _times(net, 0, EPOCH + 10.0, auv)
    _, _, n1 = _times(net, 1, n0, auv)
    t2, _, _ = _times(net, 2, n1, auv)
    asm.push(_ev(t0, "I", 1))
    asm.push(_ev(r0, "R", 1))
    asm.push(_ev(t2, "I", 3))
    assert asm.take_partial() == [] and asm.cycles_dropped["sequence"] == 1
    # a reply from a beacon that does not follow the last one interrogated
    # (id 2 was, id 3 follows it; id 1 replies) is not the reply to a missed ping
    asm = CycleAssembler(net, DEPTH, 3000.0, sequence=[1, 2, 3])
    t1, r1, n1 = _times(net, 1, EPOCH + 10.0, auv)
    t2, _, _ = _times(net, 2, n1, auv)
    asm.push(_ev(t1, "I", 2))
    asm.push(_ev(r1, "R", 2))
    asm.push(_ev(r1 + 0.2, "R", 1))
    cyc = asm.push(_ev(t2, "I", 3))
    assert cyc is not None and asm.dropped["gate"] == 1
    assert asm.take_partial() == []


def _every_fourth_interrogation_missed(world: AcousticWorld, until_s: float
                                       ) -> list[AcousticEvent]:
    """The world's exact events up to ``until_s`` (sim s), every fourth
    interrogation left out (the buoy missed it)."""
    out = []
    n_i = 0
    for ev in world.events_exact_until(until_s):
        if ev.kind == "I":
            n_i += 1
            if n_i % 4 == 0:
                continue
        out.append(ev)
    return out


def test_half_cycles_of_a_turning_auv_measure_its_true_ranges() -> None:
    """The simulator's exact timing, every fourth interrogation removed: each
    half cycle's measure equals the true combination — r_i − r_L from where the
    AUV pinged, r_i + r_L with r_i from where it heard the reply."""
    lp = LblParams(**EXACT)  # type: ignore[arg-type]
    auv = Auv(AuvParams(waypoints=[[100.0, 150.0], [200.0, 150.0], [200.0, 250.0]],
                        depth_m=DEPTH, speed_mps=1.4, turn_rate_dps=12.0))
    world = AcousticWorld(lp, auv, 3, start_utc_epoch_s=EPOCH)
    net = Network.from_params(lp.network(), 0.003)
    asm = CycleAssembler(net, DEPTH, 3000.0, sequence=list(net.ids))
    halves: list[Cycle] = []
    for ev in _every_fourth_interrogation_missed(world, 200.0):
        asm.push(ev)
        halves += asm.take_partial()
    kinds = [math.isnan(h.t_next) for h in halves]
    assert sum(kinds) >= 10 and len(kinds) - sum(kinds) >= 10
    pings = world.pings
    lst = (net.north[net.listener], net.east[net.listener], net.depth[net.listener])

    def heard(k: int) -> float:
        p = pings[k]
        return p.t_s + math.dist((p.x_m, p.y_m, p.depth_m), lst) / net.c + EPOCH

    arrivals = [heard(k) for k in range(len(pings))]
    for h in halves:
        if math.isnan(h.t_next):
            k = int(np.argmin([abs(a - h.t_i) for a in arrivals]))
            p = pings[k]
            pos = (p.x_m, p.y_m, p.depth_m)
            want = math.dist(pos, (net.north[h.index], net.east[h.index],
                                   net.depth[h.index])) - math.dist(pos, lst)
        else:
            k = int(np.argmin([abs(a - h.t_next) for a in arrivals]))
            p = pings[k]
            x, y, z = auv.position(p.t_s - net.delta)
            want = (math.dist((x, y, z), (net.north[h.index], net.east[h.index],
                                          net.depth[h.index]))
                    + math.dist((p.x_m, p.y_m, p.depth_m), lst))
        assert abs(half_cycle_measure(h, net) - want) < 1e-3, h


def test_one_event_publishes_one_track_whatever_updates_it_made() -> None:
    """An interrogation after a missed one closes two half cycles and may
    close a cycle too: three updates, one track (the last state), every
    fix published."""
    lp = LblParams(**EXACT)  # type: ignore[arg-type]
    auv = Auv(AuvParams(waypoints=[[100.0, 150.0], [250.0, 150.0]], depth_m=DEPTH))
    world = AcousticWorld(lp, auv, 5, start_utc_epoch_s=EPOCH)
    tracker = AuvTracker(TrackerParams(network=lp.network(), auv_depth_m=DEPTH,
                                       prior_north_m=100.0, prior_east_m=150.0))
    fixes = 0
    updates = 0
    for ev in _every_fourth_interrogation_missed(world, 150.0):
        before = tracker.fixes_accepted
        out = tracker.process(ev)
        fixes += sum(isinstance(m, AuvFix) for m in out)
        updates += tracker.fixes_accepted - before
        tracks = [m for m in out if isinstance(m, AuvTrack)]
        assert len(tracks) <= 1
        if tracker.fixes_accepted > before:
            assert tracks and tracks[-1].t0_utc_s == pytest.approx(tracker.kf.t)
    assert tracker.cycles.cycles_partial >= 20 and updates > fixes // 2


def _uturn_errors(seed: int, half: bool) -> tuple[float, int]:
    """A lawnmower U-turn heard with a fifth of the arrivals missed: the RMS of
    the track's position error (m) from the AUV's start to the end, and the
    filter updates accepted."""
    wps = [[100.0, 150.0], [220.0, 150.0], [220.0, 170.0], [100.0, 170.0]]
    r = run(wps, 30.0 + 260.0 / 1.2 + 20.0, seed=seed, speed_mps=1.2, turn_rate_dps=10.0,
            start_delay_s=30.0, lbl={"p_miss": 0.2}, trk={"half_cycles": half})
    errs = [r.position_error(s) for s in r.samples if s.t >= 30.0 and s.track is not None]
    return float(np.sqrt(np.mean(np.square(errs)))), r.tracker.fixes_accepted


def test_half_cycles_follow_a_uturn_more_closely_when_pings_are_missed() -> None:
    with_half = [_uturn_errors(seed, True) for seed in (1, 2, 3, 4)]
    without = [_uturn_errors(seed, False) for seed in (1, 2, 3, 4)]
    # a fifth of the arrivals missed loses about a third of the cycles: the
    # half cycles give back updates
    for (_, n_h), (_, n_w) in zip(with_half, without, strict=True):
        assert n_h >= 1.2 * n_w
    # and a track nearer the AUV on the whole
    assert np.mean([e for e, _ in with_half]) < np.mean([e for e, _ in without])


def _turn_peak(speed: float, rate: float, angle: float, seed: int, half: bool) -> float:
    """The track's largest position error (m) through a sharp turn and the
    40 s after it (the rig of :mod:`test_tracker_turns`)."""
    a = math.radians(angle)
    wps = [[100.0, 150.0], [250.0, 150.0],
           [250.0 + 150.0 * math.cos(a), 150.0 + 150.0 * math.sin(a)]]
    r = run(wps, 30.0 + 300.0 / speed + 30.0, seed=seed, speed_mps=speed,
            turn_rate_dps=rate, start_delay_s=30.0, trk={"half_cycles": half})
    (t_turn,) = r.auv.turn_times()
    return max(r.position_error(s) for s in r.samples if t_turn <= s.t <= t_turn + 40.0)


def test_half_cycles_keep_the_track_nearer_through_sharp_turns_on_the_whole() -> None:
    """One case may go either way (a gate decided on a few centimetres), the
    ten together not."""
    cases = [(speed, rate, angle, seed + k) for speed, rate, angle, seed in (
        (0.5, 6.0, 90.0, 11), (1.0, 10.0, -90.0, 12), (1.4, 15.0, 90.0, 13),
        (1.2, 8.0, 120.0, 14), (1.0, 10.0, -150.0, 15)) for k in (0, 100)]
    with_half = [_turn_peak(*c, half=True) for c in cases]
    without = [_turn_peak(*c, half=False) for c in cases]
    assert np.mean(with_half) < np.mean(without)
