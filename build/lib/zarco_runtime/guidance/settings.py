"""Settings of the line guidance (``[guidance]``)."""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec


@dataclass(slots=True)
class Guidance:
    switching: str = spec("cross_end", "", "when the next line starts: 'cross_end' (paper: "
                          "after crossing the end of the line) or 'anticipate' (turn early "
                          "by the turning radius)", choices=["cross_end", "anticipate"])
    turn_rate_dps: float = spec(50.0, "deg/s", "turn rate assumed by 'anticipate' (its lead "
                                "is U/r·tan(turn/2); 50 minimises the corner error here)",
                                min=1.0, max=90.0)


@dataclass(slots=True)
class HoldSettings:
    """Station keeping (``hold``, and ``return`` once home).

    Far from the point the boat transits to it along a straight leg, slowing
    as it gets near; within ``station_radius_m`` it holds: bow into the
    estimated water current (a line through the point along the current,
    kept by the line-tracking steering law), position along that line by a
    PI on the along-track distance to the point (surge forward or astern).
    With less current than ``current_min_mps`` there is nothing to point
    into: the boat keeps its heading and its along-line position until it has
    drifted ``still_relay_m`` from the point, then faces the point and closes in.
    """

    station_radius_m: float = spec(4.0, "m", "closer than this to the point: station "
                                   "keeping; further: transit to it", min=0.5, max=1000.0)
    transit_speed_mps: float = spec(1.0, "m/s", "speed of the transit to the point",
                                    min=0.1, max=3.0)
    approach_gain: float = spec(0.2, "1/s", "transit speed reference = this × distance, "
                                "at most transit_speed_mps (slows down near the point)",
                                min=0.01, max=10.0)
    current_min_mps: float = spec(0.08, "m/s", "estimated current below this: keep the "
                                  "arrival heading instead of pointing into the current",
                                  min=0.0, max=2.0)
    still_relay_m: float = spec(1.0, "m", "in still water, drifted this far from the point: "
                                "turn to face it and close in", min=0.1, max=100.0)
    realign_deg: float = spec(20.0, "deg", "re-lay the station line when the current's "
                              "direction moves by more than this", min=1.0, max=180.0)
    k_s: float = spec(20.0, "N/m", "surge force per metre the point is ahead", min=0.0,
                      max=1e4)
    k_i: float = spec(1.0, "N/(m s)", "integral of the along-line distance to the point",
                      min=0.0, max=1e4)
    along_clamp_m: float = spec(4.0, "m", "along-line distance used at most by the surge law",
                                min=0.1, max=1e3)
