"""Figures of station keeping (``hold``, and ``return`` once home), measured on the
simulator's true position against the point the supervisor told the boat to hold.

Each hold is measured from ``settle_s`` after it began (the boat arrives and
turns into the current first) until the next directive.  Thrust use is the
mean of (|U1| + |U2|)/2 (% of full scale) and the RMS change of the commands
between samples.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from zarco_runtime.guidance.directive import Directive
from zarco_tools.sim_report import TrackLog

#: time after a hold begins before it is measured (s)
SETTLE_S = 30.0


def hold_figures(log: TrackLog, directives: list[Directive],
                 settle_s: float = SETTLE_S) -> dict[str, Any]:
    t = np.asarray(log.t)
    x, y = np.asarray(log.x), np.asarray(log.y)
    u1, u2 = np.asarray(log.u1), np.asarray(log.u2)
    holds: list[dict[str, Any]] = []
    all_d: list[np.ndarray] = []
    all_u: list[np.ndarray] = []
    steps: list[np.ndarray] = []
    for i, d in enumerate(directives):
        if d.mode.value != "hold" or d.point is None:
            continue
        t1 = directives[i + 1].t if i + 1 < len(directives) else math.inf
        sel = (t >= d.t + settle_s) & (t < t1)
        if sel.sum() < 2:
            continue
        dist = np.hypot(x[sel] - d.point[0], y[sel] - d.point[1])
        use = (np.abs(u1[sel]) + np.abs(u2[sel])) / 2.0
        all_d.append(dist)
        all_u.append(use)
        steps.append(np.concatenate([np.diff(u1[sel]), np.diff(u2[sel])]))
        holds.append({"t_s": round(d.t, 2), "duration_s": round(float(t[sel][-1] - d.t), 1),
                      "reason": d.reason,
                      "distance_p50_m": round(float(np.percentile(dist, 50)), 3),
                      "distance_p95_m": round(float(np.percentile(dist, 95)), 3),
                      "distance_max_m": round(float(dist.max()), 3),
                      "thrust_mean_pct": round(float(use.mean()), 2)})
    if not holds:
        return {"holds": []}
    dd, uu, ss = np.concatenate(all_d), np.concatenate(all_u), np.concatenate(steps)
    return {
        "hold_distance_p50_m": round(float(np.percentile(dd, 50)), 3),
        "hold_distance_p95_m": round(float(np.percentile(dd, 95)), 3),
        "hold_distance_max_m": round(float(dd.max()), 3),
        "hold_seconds": round(float(dd.size / max(1e-9, 1.0 / np.median(np.diff(t)))), 1),
        "hold_thrust_mean_pct": round(float(uu.mean()), 2),
        "hold_command_step_rms": round(float(np.sqrt(np.mean(ss * ss))), 3),
        "holds": holds,
    }
