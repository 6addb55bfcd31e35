"""Tracking on the bus: AcousticEvent / BuoyStatus / AuvPlan → AuvFix, AuvTrack.

The tracker folds each acoustic event in as the buoy driver publishes it (a
bus listener: a median of ~15 µs per event) and publishes the fixes and track
updates it produced; a 1 Hz task ages the track so that a silent feed makes
it stale and then lost.  The AUV's plan (:class:`AuvPlan`, from the
supervisor) goes to the tracker's plan matcher, whose news (the AUV on its
plan, off it, back on it) goes out as ``mission`` events; a lawnmower the
tracker inferred without a plan given goes out as an :class:`AuvPlan` of
source ``tracker`` (:mod:`.plan_infer`).  Beacons nearly on one line
(:mod:`.layout`) are told as a ``mission`` event when tracking starts.
"""

from __future__ import annotations

import asyncio

from zarco_core.auv_messages import AcousticEvent, AuvPlan, BuoyStatus
from zarco_core.bus import Bus, Listen
from zarco_core.clock import Clock
from zarco_core.messages import Event
from zarco_runtime.tracking.layout import line_warning
from zarco_runtime.tracking.params import TrackerParams
from zarco_runtime.tracking.plan import INFERRED_SOURCE
from zarco_runtime.tracking.tracker import AuvTracker

#: how often the track is aged without events (s)
TICK_S = 1.0


class Tracking:
    def __init__(self, params: TrackerParams, bus: Bus, clock: Clock,
                 listen: Listen | None = None) -> None:
        self.tracker = AuvTracker(params)
        self.bus = bus
        self.clock = clock
        on = listen or bus.listen
        on(AcousticEvent, self._on_event)
        on(BuoyStatus, self.tracker.on_status)
        on(AuvPlan, self._on_plan)
        self.fixes = 0
        self.tracks = 0

    def _on_event(self, ev: AcousticEvent) -> None:
        publish = self.bus.publish
        for m in self.tracker.process(ev):
            publish(m)
        self._inferred(ev.t)
        if self.tracker.plan.events:
            self._plan_events(ev.t)

    def _on_plan(self, plan: AuvPlan) -> None:
        # an inferred plan serving again is published with the next event, not
        # from inside this delivery (the plan being delivered would reach the
        # listeners after it, and stand as the latest)
        self.tracker.set_plan(plan.points, plan.source)
        self._plan_events(plan.t)

    def _inferred(self, t: float) -> None:
        """Publish the plans the tracker inferred (the guidance follows the AUV
        along them as along a plan given)."""
        got, self.tracker.inferred = self.tracker.inferred, []
        for points in got:
            self.bus.publish(AuvPlan(t, points, INFERRED_SOURCE))

    def _plan_events(self, t: float) -> None:
        events = self.tracker.plan.events
        for text in events:
            self.bus.publish(Event(t, "mission", text, "tracker"))
        events.clear()

    async def run(self) -> None:
        """Tell the operator when the beacons lie nearly on one line
        (:mod:`.layout`), then age the track once a second (publishes it,
        lost or not)."""
        net = self.tracker.net0
        warning = line_warning(net.north, net.east)
        if warning is not None:
            self.bus.publish(Event(self.clock.now(), "mission", warning, "tracker"))
        while True:
            await asyncio.sleep(TICK_S)
            tr = self.tracker.tick(self.clock.now())
            if tr is not None:
                self.bus.publish(tr)
