"""Beacons nearly on one line: measured, and told to the operator when
tracking starts (an AUV near the line can be tracked on its mirror side)."""

from __future__ import annotations

import asyncio
import contextlib
import math

import pytest

from zarco_core.bus import Bus
from zarco_core.clock import Clock, run_virtual
from zarco_core.lbl import LblNetworkParams
from zarco_core.messages import Event
from zarco_runtime.tracking.layout import line_spread, line_warning
from zarco_runtime.tracking.params import TrackerParams
from zarco_runtime.tracking.task import Tracking

# a layout drawn by the follow campaign on which a mission with nothing off
# was tracked on its mirror side: the listener 3.2 m off the line through the
# other two, 265 m apart
NEAR_LINE = [[-181.3, 83.4, 34.6], [77.3, 26.0, 47.4], [-46.7, 50.2, 57.0]]
TRIANGLE = [[0.0, 0.0, 30.0], [400.0, 50.0, 30.0], [150.0, 400.0, 30.0]]


def test_the_spread_is_the_distance_from_the_best_line_and_the_extent_along_it() -> None:
    # symmetric about north = 100: the best line is east = 1 (the mean), the
    # outer two 1 m below it and the middle one 2 m above
    width, span = line_spread([0.0, 100.0, 200.0], [0.0, 3.0, 0.0])
    assert width == pytest.approx(2.0)
    assert span == pytest.approx(200.0)
    # the same turned by 30° and moved: a line is a line whichever way it runs
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    pts = [(0.0, 0.0), (100.0, 3.0), (200.0, 0.0)]
    north = [500.0 + c * x - s * y for x, y in pts]
    east = [-70.0 + s * x + c * y for x, y in pts]
    assert line_spread(north, east) == pytest.approx((2.0, 200.0))


def test_only_three_beacons_or_more_near_a_line_are_warned_of() -> None:
    north, east = [b[0] for b in NEAR_LINE], [b[1] for b in NEAR_LINE]
    text = line_warning(north, east)
    assert text is not None and "one line" in text and "265 m" in text
    assert line_warning([b[0] for b in TRIANGLE], [b[1] for b in TRIANGLE]) is None
    assert line_warning([0.0, 300.0], [0.0, 0.0]) is None  # two beacons: always a line


@pytest.mark.parametrize("beacons,warned", [(NEAR_LINE, True), (TRIANGLE, False)])
def test_tracking_tells_the_operator_once_when_it_starts(beacons: list[list[float]],
                                                         warned: bool) -> None:
    params = TrackerParams(network=LblNetworkParams(beacons=beacons,
                                                    turnaround_s=[0.1] * len(beacons)),
                           auv_depth_m=10.0)
    bus = Bus()
    events: list[Event] = []
    bus.listen(Event, events.append)
    tracking = Tracking(params, bus, Clock(utc_offset_s=0.0))

    async def main() -> None:
        task = asyncio.create_task(tracking.run())
        await asyncio.sleep(5.5)  # five ticks of the track's aging
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task

    run_virtual(main())
    told = [e for e in events if e.source == "tracker" and "one line" in e.text]
    assert len(told) == (1 if warned else 0)
    if warned:
        assert told[0].kind == "mission"
