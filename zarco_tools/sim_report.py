"""Figures of a simulated mission, measured on the simulator's *true* position.

Cross-track error of a leg is measured from 15 m after the leg starts (along
the line) to its end (when the next leg becomes active); a leg's overshoot is
its largest cross-track error within its first 15 m (``overshoot_m``: how
far the boat swings past the new line while turning onto it);
``overshoot_outside_m`` keeps only the part on the
outside of the turn, which is what an anticipating turn removes (it starts
the new line a little inside it instead).  Percentiles use the
nearest-rank-interpolated definition of numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from zarco_runtime.guidance.mission import Leg

#: distance after a leg's start excluded from its cross-track figures (m): the turn onto
#: the leg, measured separately as its overshoot
SETTLE_M = 15.0


@dataclass(slots=True)
class TrackLog:
    """True trajectory samples with the active leg and the commands."""

    t: list[float] = field(default_factory=list)
    x: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    psi: list[float] = field(default_factory=list)
    leg: list[int] = field(default_factory=list)
    u1: list[float] = field(default_factory=list)
    u2: list[float] = field(default_factory=list)

    def add(self, t: float, x: float, y: float, psi: float, leg: int, u1: float,
            u2: float) -> None:
        self.t.append(t)
        self.x.append(x)
        self.y.append(y)
        self.psi.append(psi)
        self.leg.append(leg)
        self.u1.append(u1)
        self.u2.append(u2)


def _stats(d: np.ndarray) -> dict[str, float]:
    if d.size == 0:
        return {"xtrack_rms_m": math.nan, "xtrack_p95_m": math.nan, "xtrack_max_m": math.nan}
    a = np.abs(d)
    return {
        "xtrack_rms_m": float(np.sqrt(np.mean(d * d))),
        "xtrack_p95_m": float(np.percentile(a, 95)),
        "xtrack_max_m": float(a.max()),
    }


def xtrack_series(log: TrackLog, legs: list[Leg]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(along, d, leg) for every sample, relative to the leg active then."""
    along = np.empty(len(log.t))
    d = np.empty(len(log.t))
    for i, (x, y, k) in enumerate(zip(log.x, log.y, log.leg, strict=True)):
        if 0 <= k < len(legs):
            along[i], d[i] = legs[k].project(x, y)
        else:
            along[i] = d[i] = math.nan
    return along, d, np.asarray(log.leg)


def line_figures(log: TrackLog, legs: list[Leg]) -> dict[str, Any]:
    """Whole-run and per-leg cross-track figures (the keys of ``zarco sim --report``)."""
    along, d, leg_idx = xtrack_series(log, legs)
    per_leg = []
    settled_all = []
    overshoots = []
    outsides: list[float] = []
    for leg in legs:
        sel = leg_idx == leg.index
        if not sel.any():
            continue
        a, dd = along[sel], d[sel]
        settled = dd[a >= SETTLE_M]
        early = dd[a < SETTLE_M]
        ov = float(np.abs(early).max()) if early.size else 0.0
        # the part of it on the outside of the turn into this leg (a left turn
        # overshoots to starboard of the new line, a right turn to port)
        outside = 0.0
        if leg.index > 0 and early.size:
            turn = math.remainder(leg.course_rad - legs[leg.index - 1].course_rad, math.tau)
            side = early if turn < 0 else -early
            outside = max(0.0, float(side.max()))
        per_leg.append({"leg": leg.index, "speed_mps": leg.speed_mps, **_stats(settled),
                        "overshoot_m": ov, "overshoot_outside_m": outside,
                        "samples": int(settled.size)})
        settled_all.append(settled)
        if leg.index > 0:
            overshoots.append(ov)
            outsides.append(outside)
    allv = np.concatenate(settled_all) if settled_all else np.empty(0)
    return {**_stats(allv), "corner_overshoot_max_m": max(overshoots) if overshoots else 0.0,
            "corner_overshoot_outside_max_m": max(outsides) if outsides else 0.0,
            "legs": per_leg}
