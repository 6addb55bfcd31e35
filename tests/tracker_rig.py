"""A simulated AUV in its acoustic world feeding the tracker directly (no vessel):
the truth the simulator keeps next to what the tracker says, sampled in time.

The world's network (``lbl``) is the truth; the tracker is told ``survey`` —
the same network with some of its values replaced (the sound speed the
operator believes, beacons surveyed off, wrong turnarounds)."""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field
from typing import Any

from drivers.sim.acoustics import AcousticWorld, LblParams
from drivers.sim.auv import Auv, AuvParams, AuvTruth
from zarco_core.auv_messages import AuvTrack, TrackFlags
from zarco_core.lbl import LblNetworkParams
from zarco_runtime.tracking.params import TrackerParams
from zarco_runtime.tracking.tracker import AuvTracker

EPOCH = 1_780_308_000.0


@dataclass
class Sample:
    """What the tracker said at sim time ``t`` (its latest track) and the truth."""

    t: float
    track: AuvTrack | None
    truth: AuvTruth


@dataclass
class Run:
    world: AcousticWorld
    auv: Auv
    tracker: AuvTracker
    samples: list[Sample] = field(default_factory=list)

    @property
    def acquired_s(self) -> float | None:
        """Sim time of the first initialised track."""
        for s in self.samples:
            if s.track is not None and s.track.flags & TrackFlags.INITIALISED:
                return s.t
        return None

    def after(self, t: float) -> list[Sample]:
        return [s for s in self.samples if s.t >= t and s.track is not None]

    def position_error(self, s: Sample) -> float:
        """The filter's position carried to ``s.t`` along its velocity, against
        the truth (m)."""
        tr = s.track
        assert tr is not None
        dt = s.t - (tr.t0_utc_s - EPOCH)
        return math.hypot(tr.kf_x_m + tr.kf_vx_mps * dt - s.truth.x_m,
                          tr.kf_y_m + tr.kf_vy_mps * dt - s.truth.y_m)


def run(waypoints: list[list[float]], duration_s: float, *, seed: int = 1,
        lbl: dict[str, Any] | None = None, survey: dict[str, Any] | None = None,
        trk: dict[str, Any] | None = None, speed_mps: float = 1.0, depth_m: float = 10.0,
        start_delay_s: float = 0.0, at_end: str = "continue", dt: float = 0.5,
        arcs: list[list[float]] | None = None, turn_rate_dps: float = 10.0,
        plan: list[list[float]] | None = None) -> Run:
    """Simulate ``duration_s`` and sample the tracker every ``dt`` s (``arcs``,
    ``turn_rate_dps``: the simulated AUV's, :class:`~drivers.sim.auv.AuvParams`;
    ``plan``: the AUV's plan given to the tracker, NED m)."""
    lp = LblParams(**(lbl or {}))
    truth = lp.network()
    told = LblNetworkParams(**{**vars_of(truth), **(survey or {})})
    auv = Auv(AuvParams(waypoints=waypoints, speed_mps=speed_mps, depth_m=depth_m,
                        start_delay_s=start_delay_s, at_end=at_end, arcs=arcs or [],
                        turn_rate_dps=turn_rate_dps))
    world = AcousticWorld(lp, auv, seed, start_utc_epoch_s=EPOCH)
    opts = dict(trk or {})
    prior = opts.pop("prior", waypoints[0])
    tracker = AuvTracker(TrackerParams(network=told, auv_depth_m=depth_m,
                                       prior_north_m=prior[0], prior_east_m=prior[1], **opts))
    if plan:
        tracker.plan.set_plan([(n, e) for n, e in plan], "test")
    out = Run(world, auv, tracker)
    t = 0.0
    last: AuvTrack | None = None
    while t < duration_s:
        t += dt
        for ev in world.events_exact_until(t):
            for m in tracker.process(ev):
                if isinstance(m, AuvTrack):
                    last = m
        last = tracker.tick(t) or last
        out.samples.append(Sample(t, last, world.auv_truth(t)))
    assert tracker.dropped["internal"] == 0
    return out


def vars_of(p: LblNetworkParams) -> dict[str, Any]:
    return {"beacons": [list(b) for b in p.beacons], "beacon_ids": list(p.beacon_ids),
            "turnaround_s": list(p.turnaround_s), "auv_delay_s": p.auv_delay_s,
            "sound_speed_mps": p.sound_speed_mps, "listener_beacon": p.listener_beacon}


def uturn_course_errors(speed: float, rate: float, spacing: float, seed: int,
                        after_s: tuple[float, float], counter: str,
                        plan: bool = False, trk: dict[str, Any] | None = None
                        ) -> tuple[float, int]:
    """A lawnmower's U-turn (two 90° turns at ``rate`` deg/s, ``spacing`` m apart)
    flown at ``speed`` m/s (with its plan given to the tracker when ``plan``;
    ``trk``: tracker settings): the median error (deg) of the filter's course
    from ``after_s[0]`` to ``after_s[1]`` s after the U-turn ends, and the
    tracker's ``counter``."""
    wps = [[100.0, 150.0], [220.0, 150.0], [220.0, 150.0 + spacing], [100.0, 150.0 + spacing]]
    r = run(wps, 30.0 + (240.0 + spacing) / speed + 20.0, seed=seed, speed_mps=speed,
            turn_rate_dps=rate, start_delay_s=30.0, plan=wps if plan else None, trk=trk)
    t_end = r.auv.turn_times()[-1] + 90.0 / rate
    errs = [abs(math.degrees(math.remainder(
        math.atan2(s.track.kf_vy_mps, s.track.kf_vx_mps) - s.truth.psi_rad, math.tau)))
        for s in r.samples
        if t_end + after_s[0] <= s.t <= t_end + after_s[1] and s.track is not None]
    assert len(errs) >= 1.5 * (after_s[1] - after_s[0])  # sampled every 0.5 s
    return statistics.median(errs), r.tracker.counters().get(counter, 0)
