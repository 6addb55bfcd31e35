"""Straight-line guidance: which line is active, and where the boat is on it.

Switching (paper III.C): by default the next line starts only once the boat
has crossed the end of the current one (along-track ≥ length), which causes
the corner overshoots of the paper's Fig. 4.  ``anticipate`` starts the
turn one turning radius (U / r_turn) before the end, which cuts them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_runtime.guidance.mission import Leg


@dataclass(frozen=True, slots=True)
class LineState:
    """Geometry of the boat relative to the active line."""

    leg: Leg
    along_m: float
    xtrack_m: float
    switched: bool
    complete: bool


class LineGuidance:
    """Tracks progress along a list of legs."""

    def __init__(self, legs: list[Leg], switching: str = "cross_end",
                 turn_rate_rps: float = math.radians(15.0)) -> None:
        if not legs:
            raise ValueError("no legs")
        self.legs = legs
        self.index = 0
        self.switching = switching
        self.turn_rate_rps = turn_rate_rps
        self.complete = False

    def _lead_m(self, leg: Leg) -> float:
        if self.switching != "anticipate" or leg.index + 1 >= len(self.legs):
            return 0.0
        nxt = self.legs[leg.index + 1]
        turn = abs(math.remainder(nxt.course_rad - leg.course_rad, math.tau))
        radius = leg.speed_mps / self.turn_rate_rps
        return radius * math.tan(min(turn, math.radians(120.0)) / 2.0)

    def update(self, x: float, y: float) -> LineState:
        """Advance the active leg if the boat passed its end; return the geometry."""
        switched = False
        leg = self.legs[self.index]
        along, d = leg.project(x, y)
        while not self.complete and along >= leg.length_m - self._lead_m(leg):
            if self.index + 1 >= len(self.legs):
                self.complete = True
                break
            self.index += 1
            switched = True
            leg = self.legs[self.index]
            along, d = leg.project(x, y)
        return LineState(leg, along, d, switched, self.complete)
