"""The tracker never raises: bad events, fuzzing, clock jumps, silence, speed."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from drivers.sim.acoustics import AcousticWorld, LblParams
from drivers.sim.auv import Auv, AuvParams
from zarco_core.auv_messages import AcousticEvent, AuvTrack, TrackFlags
from zarco_runtime.tracking.params import TrackerParams
from zarco_runtime.tracking.tracker import AuvTracker

EPOCH = 1_780_308_000.0
LINE = [[100.0, 100.0], [320.0, 100.0], [320.0, 380.0]]


def _world(seed: int = 1, **lbl: object) -> tuple[AcousticWorld, TrackerParams]:
    lp = LblParams(**lbl)  # type: ignore[arg-type]
    world = AcousticWorld(lp, Auv(AuvParams(waypoints=LINE)), seed, start_utc_epoch_s=EPOCH)
    return world, TrackerParams(network=lp.network(), auv_depth_m=10.0)


def _events(world: AcousticWorld, t_end: float, t_start: float = 0.0) -> list[AcousticEvent]:
    out: list[AcousticEvent] = []
    t = t_start
    while t < t_end:
        t += 0.5
        out.extend(world.events_exact_until(t))
    return out


def _kf_error(world: AcousticWorld, track: AuvTrack) -> float:
    tr = world.auv_truth(track.t0_utc_s - EPOCH)
    return math.hypot(track.kf_x_m - tr.x_m, track.kf_y_m - tr.y_m)


def test_bad_events_are_counted_and_dropped() -> None:
    world, params = _world()
    tracker = AuvTracker(params)
    good = _events(world, 120.0)
    bad = [
        AcousticEvent(1.0, "b", EPOCH + 1.0, "I", 7, 10.0),        # unknown beacon
        AcousticEvent(1.0, "b", math.nan, "I", 1, 10.0),          # garbage time
        AcousticEvent(1.0, "b", EPOCH + 1.0, "Z", 1, 10.0),       # garbage kind
        AcousticEvent(1.0, "b", EPOCH + 1.0, "I", None, 10.0),    # type: ignore[arg-type]
    ]
    stream: list[object] = []
    for k, ev in enumerate(good):
        stream.append(ev)
        if k % 50 == 10:
            stream.append(ev)  # duplicated
        if k % 50 == 20:
            stream.append(AcousticEvent(ev.t, ev.source, ev.utc_epoch_s - 1.0, "R", 2, 9.0))
        if k % 50 == 30:
            stream.extend(bad)
    tracks = [m for ev in stream for m in tracker.process(ev) if isinstance(m, AuvTrack)]
    c = tracker.counters()
    n = len(good) // 50 + 1
    assert c["event.duplicate"] >= n - 1
    assert c["event.out_of_order"] >= n - 1
    assert c["event.unknown_beacon"] >= n - 1
    assert c["event.garbage"] >= 3 * (n - 1)
    assert "internal" not in c
    assert tracks and _kf_error(world, tracks[-1]) < 3.0


def _random_event(rng: np.random.Generator, t: float) -> object:
    r = rng.random()
    if r < 0.02:
        return rng.choice([None, 3, "PZBAE", object()])
    kind = rng.choice(["I", "R", "I", "R", "X", ""])
    beacon = rng.choice([1, 2, 3, 1, 2, 3, 0, 4, -1])
    utc = EPOCH + t + float(rng.normal(0.0, 0.2) if rng.random() < 0.1 else 0.0)
    if rng.random() < 0.01:
        utc = rng.choice([math.nan, math.inf, -math.inf, 0.0, 1e300])
    tt = t + 0.05 if rng.random() > 0.01 else rng.choice([math.nan, -1e9, 1e12])
    return AcousticEvent(tt, "fuzz", utc, str(kind), int(beacon), float(rng.normal(15, 5)))


@pytest.mark.parametrize("seed", range(8))
def test_fuzz_random_streams_never_raise(seed: int) -> None:
    rng = np.random.default_rng(seed)
    tracker = AuvTracker(TrackerParams())
    t = 0.0
    for _ in range(3000):
        t += float(rng.exponential(0.3))
        tracker.process(_random_event(rng, t))
        if rng.random() < 0.05:
            tracker.tick(t)
    assert "internal" not in tracker.counters()


@pytest.mark.parametrize("seed", range(4))
def test_fuzz_mangled_real_streams_still_track(seed: int) -> None:
    """A real stream with neighbours swapped, events duplicated, dropped and
    shifted, and random junk inserted: no exception, and the track survives."""
    rng = np.random.default_rng(100 + seed)
    world, params = _world(seed)
    events = _events(world, 300.0)
    stream: list[object] = []
    for ev in events:
        r = rng.random()
        if r < 0.05:
            continue  # dropped
        if r < 0.08 and stream:
            stream.insert(len(stream) - 1, ev)  # swapped with its predecessor
            continue
        if r < 0.10:
            ev = AcousticEvent(ev.t, ev.source, ev.utc_epoch_s + float(rng.normal(0, 0.05)),
                               ev.kind, ev.beacon, ev.snr_db)
        stream.append(ev)
        if r > 0.97:
            stream.append(ev)
        if r > 0.99:
            stream.append(_random_event(rng, ev.t))
    tracker = AuvTracker(params)
    tracks = [m for ev in stream for m in tracker.process(ev) if isinstance(m, AuvTrack)]
    assert "internal" not in tracker.counters()
    errs = [_kf_error(world, tk) for tk in tracks[len(tracks) // 2:]]
    assert statistics.median(errs) < 3.0


def test_silence_ages_then_loses_then_reacquires() -> None:
    world, params = _world()
    tracker = AuvTracker(params)
    for ev in _events(world, 100.0):
        tracker.process(ev)
    last = tracker.tick(100.0)
    assert last is not None and not last.lost and last.fix_age_s < 5.0
    _events(world, 160.0, 100.0)  # the feed goes silent for 60 s (events lost)
    stale = tracker.tick(100.0 + params.stale_after_s + 1.0)
    assert stale is not None and stale.flags & TrackFlags.STALE and not stale.lost
    lost = tracker.tick(100.0 + params.lost_after_s + 1.0)
    assert lost is not None and lost.lost and lost.flags & TrackFlags.LOST
    assert tracker.tick(150.0).lost  # type: ignore[union-attr]
    tracks = [m for ev in _events(world, 220.0, 160.0) for m in tracker.process(ev)
              if isinstance(m, AuvTrack)]
    assert tracks and not tracks[-1].lost
    assert any(tk.flags & TrackFlags.REACQUIRED for tk in tracks)
    assert _kf_error(world, tracks[-1]) < 3.0
    assert tracks[-1].fix_age_s < 5.0


def test_runtime_clock_jump_resynchronises() -> None:
    world, params = _world()
    tracker = AuvTracker(params)
    for ev in _events(world, 100.0):
        tracker.process(ev)
    tracks = []
    for ev in _events(world, 200.0, 100.0):
        jumped = AcousticEvent(ev.t + 5000.0, ev.source, ev.utc_epoch_s, ev.kind, ev.beacon,
                               ev.snr_db)
        tracks += [m for m in tracker.process(jumped) if isinstance(m, AuvTrack)]
    c = tracker.counters()
    assert c["event.clock"] == 4 and c["fix.clock_resync"] == 1
    assert tracks and _kf_error(world, tracks[-1]) < 3.0
    # t0 is on the (new) runtime clock: t0 − t0_utc is the new offset
    assert tracks[-1].t0 - tracks[-1].t0_utc_s == pytest.approx(5000.0 - EPOCH, abs=0.2)


def test_track_time_origin_on_the_runtime_clock() -> None:
    world, params = _world(latency_s=0.2)
    params.feed_latency_s = 0.2
    tracker = AuvTracker(params)
    tracks = [m for ev in _events(world, 60.0) for m in tracker.process(ev)
              if isinstance(m, AuvTrack)]
    tk = tracks[-1]
    # runtime clock = sim time here: t0 is the emission time of the last fix
    assert tk.t0 == pytest.approx(tk.t0_utc_s - EPOCH, abs=1e-6)
    assert 0.0 < tk.t - tk.t0 < 2.0
    assert len(tk.cov) == 16
