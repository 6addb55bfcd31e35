"""Follow-law geometry (paper VI), as pure functions.

Inputs: the AUV's line (x0, y0, vx, vy) from the RLS — NED metres and m/s,
(x0, y0) the AUV's position at the time origin t0 — and the ASV position
(x, y) in the same frame.  Times ``t`` are seconds *since t0*.

::

    ψ_AUV = atan2(vy, vx)                       course, clockwise from north
    v_AUV = √(vx² + vy²)
    h_AUV = (vy x0 − vx y0) / v_AUV             offset of the line from the origin
    s_AUV = (x0 vx + y0 vy) / v_AUV + v_AUV t   the AUV's along-line coordinate
    s     = (x vx + y vy) / v_AUV               the ASV's along-line coordinate
    d     = (vx y − vy x) / v_AUV + h_AUV       the ASV's cross-track offset

Sign of d.  The unit vector to the right (starboard) of a course ψ in NED is
(−sin ψ, cos ψ) = (−vy, vx)/v_AUV, so the signed distance of (x, y) from the
line through (x0, y0) is ((x − x0)(−vy) + (y − y0) vx)/v_AUV
= (vx y − vy x)/v_AUV + h_AUV: **d > 0 when the ASV is to starboard of the
AUV's track**, the convention of :meth:`zarco_runtime.guidance.mission.Leg.project`,
so ψ_ref = ψ_AUV − arctan(k_y d + k_l ∫d dt) turns the ASV back to port.
The paper prints d = (vx y + vy x)/v_AUV + h_AUV: that is a sign error —
with the AUV heading east (vx = 0, vy = v) it gives d = x + x0 instead of
x0 − x, which is not even zero on the line (x = x0), and for north/south
courses it flips the side.

s_AUV − s is the along-track lead of the AUV over the ASV (m): positive when the
ASV is behind and must speed up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: below this AUV speed (m/s) the course and the line are undefined
V_MIN_MPS = 0.05


def auv_course(vx: float, vy: float) -> float:
    """ψ_AUV = atan2(vy, vx) (rad, clockwise from north, in (−π, π])."""
    return math.atan2(vy, vx)


def auv_speed(vx: float, vy: float) -> float:
    """v_AUV = √(vx² + vy²) (m/s)."""
    return math.hypot(vx, vy)


def auv_offset(x0: float, y0: float, vx: float, vy: float) -> float:
    """h_AUV = (vy x0 − vx y0)/v_AUV (m): the cross-track offset of the origin of
    the frame from the AUV's line, positive when the origin is to starboard of it
    (NaN when v_AUV = 0)."""
    v = math.hypot(vx, vy)
    return (vy * x0 - vx * y0) / v if v > 0.0 else math.nan


def auv_along(x0: float, y0: float, vx: float, vy: float, t: float) -> float:
    """s_AUV = (x0 vx + y0 vy)/v_AUV + v_AUV t (m): the AUV's coordinate along its
    line ``t`` seconds after the time origin (NaN when v_AUV = 0)."""
    v = math.hypot(vx, vy)
    return (x0 * vx + y0 * vy) / v + v * t if v > 0.0 else math.nan


def along_track(x: float, y: float, vx: float, vy: float) -> float:
    """s = (x vx + y vy)/v_AUV (m): the ASV's coordinate along the AUV's line."""
    v = math.hypot(vx, vy)
    return (x * vx + y * vy) / v if v > 0.0 else math.nan


def cross_track(x: float, y: float, x0: float, y0: float, vx: float, vy: float) -> float:
    """d = (vx y − vy x)/v_AUV + h_AUV (m), > 0 with the ASV to starboard of the
    AUV's track (module docstring)."""
    v = math.hypot(vx, vy)
    if v <= 0.0:
        return math.nan
    return (vx * y - vy * x) / v + (vy * x0 - vx * y0) / v


@dataclass(slots=True)
class FollowGeometry:
    """Everything the follow law needs at one instant (m, m/s, rad)."""

    psi_auv_rad: float
    v_auv_mps: float
    h_auv_m: float
    s_auv_m: float
    s_m: float
    d_m: float

    @property
    def along_error_m(self) -> float:
        """s_AUV − s: how far the AUV is ahead of the ASV along its line."""
        return self.s_auv_m - self.s_m


def follow_geometry(x0: float, y0: float, vx: float, vy: float, x: float, y: float,
                    t: float, v_min: float = V_MIN_MPS) -> FollowGeometry | None:
    """ψ_AUV, v_AUV, h_AUV, s_AUV(t), s and d for an ASV at (x, y), ``t`` seconds
    after the line's time origin; None when the AUV is (nearly) still
    (v_AUV < ``v_min``): then there is no line to follow, hold station at
    (x0, y0) instead."""
    v = math.hypot(vx, vy)
    if not v >= v_min:  # also catches NaN
        return None
    h = (vy * x0 - vx * y0) / v
    return FollowGeometry(math.atan2(vy, vx), v, h, (x0 * vx + y0 * vy) / v + v * t,
                          (x * vx + y * vy) / v, (vx * y - vy * x) / v + h)


def drag_feedforward_n(v_mps: float, x_u: float, x_uu: float) -> float:
    """F_f(v): the surge force (N) that holds a steady speed ``v_mps`` through the
    water against the damping X = X_u u + X_|u|u |u| u (zarco_core/vessel.py; X_u, X_|u|u
    negative, N s/m and N s²/m²): F_f = −X_u v − X_|u|u |v| v."""
    return -x_u * v_mps - x_uu * abs(v_mps) * v_mps
