"""Figures of a follow-the-AUV run, measured on the simulator's truth.

The runtime's tracker and guidance live in another process; what the rig can
judge is where the boat went: the horizontal distance between the ASV and
the AUV, both true positions, sampled at ``scenario.record_hz``.  The run is
cut at the AUV's own plan (its hover, its turns):

* ``distance_start_m``: when the run starts;
* ``distance_hover_end_m``: when the AUV starts moving (the tracker has had the
  hover to acquire it);
* ``distance_leg_median_m`` / ``_p95_m`` / ``_max_m``: on the first straight
  leg, from ``LEG_SETTLE_S`` after the AUV starts moving until its first turn;
* ``turns``: per turn, the largest distance from the turn to the next one (or
  the end), and the median over the last ``FINAL_S`` of that span;
* ``distance_final_median_m``: over the last ``FINAL_S`` of the run;
* ``distance_max_m``: over the whole run; ``auv_travel_m`` / ``asv_travel_m``:
  how far each went (a boat that does not follow ends about ``auv_travel_m``
  away).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from drivers.sim.auv import Auv
from zarco_tools.sim_report import TrackLog

#: the first leg's distances are taken from this long after the AUV starts moving (s)
LEG_SETTLE_S = 25.0
#: the final distance is the median over this last part of a span (s)
FINAL_S = 10.0


def _r(v: float) -> float | None:
    return round(float(v), 3) if math.isfinite(v) else None


def _stats(d: np.ndarray, prefix: str) -> dict[str, float | None]:
    if not d.size:
        return {f"{prefix}_median_m": None, f"{prefix}_p95_m": None, f"{prefix}_max_m": None}
    return {f"{prefix}_median_m": _r(np.median(d)), f"{prefix}_p95_m": _r(np.percentile(d, 95)),
            f"{prefix}_max_m": _r(d.max())}


def _travel(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.hypot(np.diff(x), np.diff(y)).sum()) if x.size > 1 else 0.0


def follow_figures(log: TrackLog, auv_log: list[tuple[float, float, float, float]],
                   auv: Auv) -> dict[str, Any]:
    """Distance figures of a follow run (see the module docstring)."""
    n = min(len(log.t), len(auv_log))
    t = np.asarray(log.t[:n])
    x, y = np.asarray(log.x[:n]), np.asarray(log.y[:n])
    ax = np.array([a[1] for a in auv_log[:n]])
    ay = np.array([a[2] for a in auv_log[:n]])
    d = np.hypot(x - ax, y - ay)
    end = float(t[-1]) if n else 0.0
    move = float(auv.params.start_delay_s)
    turns = [tt for tt in auv.turn_times() if tt < end]

    def span(a: float, b: float) -> np.ndarray:
        out: np.ndarray = d[(t >= a) & (t < b)]
        return out

    def at(s: float) -> float | None:
        i = int(np.searchsorted(t, s))
        return _r(d[i]) if i < n else None

    first_turn = turns[0] if turns else end + 1.0
    turn_rows = []
    for i, ts in enumerate(turns):
        nxt = turns[i + 1] if i + 1 < len(turns) else end + 1.0
        after = span(ts, nxt)
        last = span(max(ts, min(nxt, end) - FINAL_S), nxt)
        turn_rows.append({"t_s": round(ts, 1),
                          "distance_max_m": _r(after.max()) if after.size else None,
                          "distance_final_median_m": _r(np.median(last)) if last.size
                          else None})
    final = span(end - FINAL_S, end + 1.0)
    return {
        "auv_moves_s": move,
        "auv_turns_s": [round(ts, 1) for ts in turns],
        "distance_start_m": at(0.0),
        "distance_hover_end_m": at(move),
        **_stats(span(move + LEG_SETTLE_S, first_turn), "distance_leg"),
        "turns": turn_rows,
        "distance_final_median_m": _r(np.median(final)) if final.size else None,
        "distance_max_m": _r(d.max()) if n else None,
        "auv_travel_m": round(_travel(ax, ay), 2),
        "asv_travel_m": round(_travel(x, y), 2),
        "samples": n,
    }
