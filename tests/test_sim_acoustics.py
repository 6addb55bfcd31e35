"""Simulated AUV and LBL acoustics: determinism, physics, wire output, fix rate."""

from __future__ import annotations

import itertools
import math
import statistics

import pytest

from drivers.buoy_parser import parse_buoy
from drivers.nmea import NmeaFramer
from drivers.sim.acoustics import AcousticWorld, LblParams
from drivers.sim.auv import Auv, AuvParams
from zarco_core.auv_messages import AcousticEvent, AuvFix, BuoyStatus
from zarco_runtime.tracking.params import TrackerParams
from zarco_runtime.tracking.tracker import AuvTracker

EPOCH = 1_780_308_000.0
LINE = [[100.0, 100.0], [320.0, 100.0], [320.0, 380.0]]


def _bytes(seed: int, t_end: float = 120.0, **lbl: object) -> list[tuple[float, bytes]]:
    world = AcousticWorld(LblParams(**lbl), Auv(AuvParams(waypoints=LINE)),  # type: ignore[arg-type]
                          seed, start_utc_epoch_s=EPOCH)
    out: list[tuple[float, bytes]] = []
    t = 0.0
    while t < t_end:
        t += 0.1
        out += world.events_until(t)
    return out


def test_same_seed_same_bytes() -> None:
    a, b = _bytes(42), _bytes(42)
    assert a == b and len(a) > 200
    assert _bytes(43) != a


def test_output_is_time_ordered_and_every_line_parses() -> None:
    out = _bytes(5)
    times = [t for t, _ in out]
    assert times == sorted(times)
    framer = NmeaFramer()
    events, status = [], []
    for t, b in out:
        for line in framer.feed(b):
            for m in parse_buoy(line, t):
                (events if isinstance(m, AcousticEvent) else status).append(m)
    assert framer.bytes_discarded == 0
    assert len(status) == 121  # $PZBST at 1 Hz, t = 0..120 s
    st = status[-1]
    assert isinstance(st, BuoyStatus) and st.fault_code == 0 and 12.0 < st.battery_v < 12.7
    assert st.lat_deg == pytest.approx(41.185, abs=1e-6) and st.lon_deg == pytest.approx(
        -8.705, abs=1e-6)  # the listener beacon sits at the origin
    assert {e.kind for e in events} == {"I", "R"}
    assert {e.beacon for e in events} == {1, 2, 3}
    # the report comes latency_s after the detection it carries
    for e in events[:50]:
        assert e.t - (e.utc_epoch_s - EPOCH) == pytest.approx(0.05, abs=1e-5)


def test_streams_are_independent() -> None:
    """More false detections add events but never move the real ones."""
    def direct(p_false: float) -> list[tuple[float, str, int]]:
        world = AcousticWorld(LblParams(p_false=p_false), Auv(AuvParams(waypoints=LINE)), 9,
                              start_utc_epoch_s=EPOCH)
        world.events_exact_until(200.0)
        return [(d.t_s, d.kind, d.beacon) for d in world.detections if d.label == "direct"]

    assert direct(0.0) == direct(0.3)


def test_exact_propagation_for_a_still_auv() -> None:
    lp = LblParams(jitter_s=0.0, p_miss=0.0, p_false=0.0, p_multipath=0.0)
    pos = (150.0, 200.0, 10.0)
    world = AcousticWorld(lp, Auv(AuvParams(waypoints=[list(pos[:2])])), 1,
                          start_utc_epoch_s=EPOCH)
    evs = world.events_exact_until(30.0)
    c = lp.sound_speed_mps
    beacons = [tuple(b) for b in lp.beacons]
    lst = beacons[0]
    pings = world.pings
    assert [p.beacon for p in pings[:6]] == [1, 2, 3, 1, 2, 3]
    for k, ping in enumerate(pings[:-1]):
        i = ping.beacon - 1
        r_i = math.dist(pos, beacons[i])
        # the AUV pings again 2 r_i / c + τ_i + δ later
        assert pings[k + 1].t_s - ping.t_s == pytest.approx(
            2 * r_i / c + lp.turnaround_s[i] + lp.auv_delay_s, abs=1e-9)
    for ping in pings[:5]:
        i = ping.beacon - 1
        t_i = EPOCH + ping.t_s + math.dist(pos, lst) / c
        t_r = (EPOCH + ping.t_s + math.dist(pos, beacons[i]) / c + lp.turnaround_s[i]
               + math.dist(beacons[i], lst) / c)
        assert any(e.kind == "I" and e.beacon == ping.beacon and abs(e.utc_epoch_s - t_i) < 1e-6
                   for e in evs)
        assert any(e.kind == "R" and e.beacon == ping.beacon and abs(e.utc_epoch_s - t_r) < 1e-6
                   for e in evs)


def test_moving_auv_hears_the_reply_where_it_has_moved_to() -> None:
    lp = LblParams(jitter_s=0.0, p_miss=0.0, p_false=0.0, p_multipath=0.0)
    auv = Auv(AuvParams(waypoints=[[100.0, 60.0], [100.0, 400.0]], speed_mps=2.0))
    world = AcousticWorld(lp, auv, 1, start_utc_epoch_s=EPOCH)
    world.events_exact_until(60.0)
    c = lp.sound_speed_mps
    for k, ping in enumerate(world.pings[5:20], start=5):
        b = lp.beacons[ping.beacon - 1]
        t_reply = ping.t_s + math.dist((ping.x_m, ping.y_m, ping.depth_m), b) / c + \
            lp.turnaround_s[ping.beacon - 1]
        t_heard = world.pings[k + 1].t_s - lp.auv_delay_s
        # the reply travelled from the beacon to where the AUV was when it heard it
        assert t_heard - t_reply == pytest.approx(math.dist(auv.position(t_heard), b) / c,
                                                  abs=1e-9)


def test_detection_statistics_follow_the_parameters() -> None:
    world = AcousticWorld(LblParams(p_miss=0.1, p_false=0.02, p_multipath=0.1),
                          Auv(AuvParams(waypoints=LINE)), 3, start_utc_epoch_s=EPOCH)
    world.events_exact_until(1200.0)
    arrivals = 2 * len(world.pings)
    labels = [d.label for d in world.detections]
    assert labels.count("direct") / arrivals == pytest.approx(0.9, abs=0.02)
    assert labels.count("false") / arrivals == pytest.approx(0.02, abs=0.007)
    assert labels.count("multipath") / arrivals == pytest.approx(0.09, abs=0.02)


def test_median_fix_interval_is_about_two_seconds() -> None:
    """Three beacons 400–430 m apart, listener at one of them, the default
    timing (τ = 0.1 s, δ = 0.5 s) and 10 % missed / 2 % false detections: a
    two-circle fix every ≈ 2 s (the listener's own cycle is range-only)."""
    lp = LblParams()
    world = AcousticWorld(lp, Auv(AuvParams(waypoints=LINE)), 1, start_utc_epoch_s=EPOCH)
    tracker = AuvTracker(TrackerParams(network=lp.network(), auv_depth_m=10.0))
    framer = NmeaFramer()
    fixes: list[AuvFix] = []
    t = 0.0
    while t < 600.0:
        t += 0.1
        for te, b in world.events_until(t):
            for line in framer.feed(b):
                for m in parse_buoy(line, te):
                    if isinstance(m, AcousticEvent):
                        fixes += [f for f in tracker.process(m) if isinstance(f, AuvFix)]
    emitted = [f.emission_utc_s for f in fixes if f.accepted and not f.range_only]
    gaps = [b - a for a, b in itertools.pairwise(emitted)]
    med = statistics.median(gaps)
    print(f"\nmedian fix interval {med:.2f} s over {len(gaps)} fixes")
    assert 1.6 <= med <= 2.4


# ------------------------------------------------------------------- the AUV


def test_auv_flies_lines_at_constant_speed_and_depth_with_bounded_turns() -> None:
    auv = Auv(AuvParams(waypoints=LINE, speed_mps=1.0, depth_m=12.0, turn_rate_dps=10.0))
    prev = auv.truth(0.0)
    max_rate = 0.0
    for k in range(1, 5000):
        tr = auv.truth(k * 0.1)
        assert tr.depth_m == 12.0
        if k * 0.1 < 440:
            assert tr.speed_mps == pytest.approx(1.0, abs=1e-6)
        dpsi = math.atan2(math.sin(tr.psi_rad - prev.psi_rad), math.cos(tr.psi_rad - prev.psi_rad))
        max_rate = max(max_rate, abs(dpsi) / 0.1)
        prev = tr
    assert math.degrees(max_rate) <= 10.0 + 1e-6
    (switch,) = auv.turn_times()
    assert 205.0 < switch < 220.0  # 220 m at 1 m/s, the turn anticipated
    # on the first leg, well before the turn: exactly on the line x: 100 → 320, y = 100
    mid = auv.truth(100.0)
    assert mid.y_m == pytest.approx(100.0, abs=1e-6) and mid.psi_rad == pytest.approx(0.0)
    after = auv.truth(switch + 40.0)
    assert after.x_m == pytest.approx(320.0, abs=0.3)  # settled on the second line
    assert after.psi_rad == pytest.approx(math.pi / 2, abs=math.radians(1.0))
    end = auv.truth(520.0)  # hovering at the last waypoint
    assert end.speed_mps == 0.0
    assert math.hypot(end.x_m - 320.0, end.y_m - 380.0) < 1.0


def test_auv_lines_on_the_fly() -> None:
    auv = Auv(AuvParams(waypoints=[[0.0, 0.0], [50.0, 0.0]], speed_mps=1.0))
    assert auv.truth(80.0).speed_mps == 0.0  # reached the end and stopped
    auv.append_waypoint(50.0, 60.0)
    tr = auv.truth(120.0)
    assert tr.speed_mps == pytest.approx(1.0) and tr.y_m > 30.0
    assert auv.truth(150.0).speed_mps == 0.0  # at (50, 60) again
    assert auv.truth(150.0).y_m == pytest.approx(60.0, abs=0.1)
    auv.set_waypoints([[0.0, 60.0]])
    tr2 = auv.truth(200.0)
    assert math.cos(tr2.psi_rad) == pytest.approx(-1.0, abs=1e-3)  # heading back south
    hover = Auv(AuvParams(waypoints=[[5.0, 6.0]]))
    assert hover.position(100.0) == (5.0, 6.0, 10.0)


def test_parameters_are_a_config_schema() -> None:
    """AuvParams, LblParams and TrackerParams load from scenario tables, and a bad
    value names the file and the dotted key."""
    from zarco_core.config import ConfigError, build

    lbl = build(LblParams, {"p_miss": 0.2, "sequence": [1, 3, 2],
                            "beacons": [[0, 0, 30], [400, 50, 30], [150, 400, 30]]},
                "s.toml", "world.lbl")
    assert lbl.sequence == [1, 3, 2] and lbl.beacons[1] == [400.0, 50.0, 30.0]
    auv = build(AuvParams, {"waypoints": [[0, 0], [100, 0]], "speed_mps": 1.5}, "s.toml",
                "world.auv")
    assert auv.speed_mps == 1.5
    trk = build(TrackerParams, {"network": {"turnaround_s": [0.1, 0.2, 0.3]}}, "s.toml",
                "runtime.tracker")
    assert trk.network.turnaround_s == [0.1, 0.2, 0.3]
    for cls, data, key in [
        (LblParams, {"turnaround_s": [0.1]}, "world.lbl.turnaround_s"),
        (LblParams, {"p_miss": 1.5}, "world.lbl.p_miss"),
        (AuvParams, {"waypoints": [[0, 0, 1]]}, "world.auv.waypoints"),
        (TrackerParams, {"sequence": [7]}, "runtime.tracker.sequence"),
        (TrackerParams, {"rls_input": "raw"}, "runtime.tracker.rls_input"),
    ]:
        prefix = key.rsplit(".", 1)[0]
        with pytest.raises(ConfigError) as ei:
            build(cls, data, "s.toml", prefix)  # type: ignore[arg-type]
        assert ei.value.key == key and ei.value.file == "s.toml"
