"""The paper's follow law (paper VI, ``follow.law = "paper"``): its geometry.

The ASV tracks the AUV's line with the line controller (the paper's N_act:
k_ψ(ψ_AUV − arctan(k_y d + k_l∫d dt) − ψ) − k_r r) at the AUV's speed, its
surge force adding k_s(s_AUV − s) + k_i∫(s_AUV − s) dt to the feedforward
F_f(v_AUV) and the speed loop k_v(v_AUV − v) (the paper's X_act).

Inputs: the AUV's line (x0, y0, vx, vy) — NED metres and m/s, (x0, y0) the
AUV's position at the time origin t0 — and the ASV position (x, y) in the
same frame.  Times ``t`` are seconds *since t0*.  The follow guidance gives
the line through the AUV's position now (t = 0) along its course, or along
its plan's leg when it is on its plan.

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
