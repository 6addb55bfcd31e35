"""Least-squares velocity through timed positions (the manoeuvre detector's
path check, the lawnmower inference's legs)."""

from __future__ import annotations

import math
from collections.abc import Sequence


def ls_velocity(points: Sequence[Sequence[float]]
                ) -> tuple[float, float, float, float, float, float] | None:
    """The least-squares velocity through positions (time s, north m, east m,
    ...; any one clock and local NED): (mean north m, mean east m, north
    velocity m/s, east velocity m/s, speed m/s, Σ(t − t̄)² s²); None without
    points, when their times do not spread, or without motion."""
    n = len(points)
    if n == 0:
        return None
    tb = sum(p[0] for p in points) / n
    xb = sum(p[1] for p in points) / n
    yb = sum(p[2] for p in points) / n
    stt = sum((p[0] - tb) ** 2 for p in points)
    if stt <= 0.0:
        return None
    vx = sum((p[0] - tb) * (p[1] - xb) for p in points) / stt
    vy = sum((p[0] - tb) * (p[2] - yb) for p in points) / stt
    v = math.hypot(vx, vy)
    if v <= 0.0:
        return None
    return xb, yb, vx, vy, v, stt
