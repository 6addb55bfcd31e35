"""Thrust allocation: X_act, N_act → F1, F2 → U1, U2 (paper section III.A).

With N_act = b(F1 − F2) and X_act = F1 + F2 (thrusters at ±b), the consistent
split is F1 = X/2 + N/(2b), F2 = X/2 − N/(2b) (the paper prints N/b, which
doubles the moment actually produced; checked in tests/test_thruster_map_allocation.py).
Port thruster 1 sits at y = −b: F1 > F2 yaws the boat clockwise (to starboard).

Saturation: yaw authority is what keeps the boat on its line, so the
differential thrust is honoured first (up to what the two thrusters can give
together) and the common-mode (surge) thrust gives way, down but not up: a
differential never drives the boat ahead of its surge demand (see
:func:`allocate`).  The result says which demand was cut and in which
direction, so the controllers stop integrating that way (anti-windup).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.thruster_map import ThrusterMap


@dataclass(frozen=True, slots=True)
class Allocation:
    """Allocated thrusts and commands.

    ``x_n``/``n_nm`` are what the allocation actually asks of the thrusters;
    ``sat_x``/``sat_n`` are +1 (demand cut from above), −1 (from below) or 0.
    """

    x_n: float
    n_nm: float
    f1_n: float
    f2_n: float
    u1: float
    u2: float
    sat_x: int
    sat_n: int
    fault: str = ""

    @property
    def saturated(self) -> bool:
        return self.sat_x != 0 or self.sat_n != 0


ZERO = Allocation(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0)


def allocate(x_des: float, n_des: float, b_m: float, port: ThrusterMap,
             starboard: ThrusterMap, surge_raise_max_n: float = 0.0) -> Allocation:
    """Allocate surge force ``x_des`` (N) and yaw moment ``n_des`` (N m).

    The differential may push the common-mode thrust at most
    ``surge_raise_max_n`` (N, of X) above the demand: reverse thrust is weaker
    than forward, so a large differential at a small surge demand would
    otherwise drive the boat ahead exactly when it is turning hardest.  At low
    speed through the water that surge kick multiplies the steering gain and
    the line tracking cycles; the yaw moment is cut instead (``sat_n``).
    ``math.inf`` gives the yaw moment absolute priority.

    Non-finite demands give zero thrust and a fault string.
    """
    if not (math.isfinite(x_des) and math.isfinite(n_des)):
        return Allocation(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0,
                          fault=f"non-finite demand X={x_des} N={n_des}")
    lo1, hi1 = port.f_min, port.f_max
    lo2, hi2 = starboard.f_min, starboard.f_max
    # half differential thrust, limited to what the pair can produce
    d = n_des / (2.0 * b_m)
    d_lo, d_hi = (lo1 - hi2) / 2.0, (hi1 - lo2) / 2.0
    if surge_raise_max_n < math.inf:
        h0 = max(x_des / 2.0, 0.0)
        g = surge_raise_max_n / 2.0
        d_hi = min(d_hi, max(0.0, h0 + g - lo2))
        d_lo = max(d_lo, -max(0.0, h0 + g - lo1))
    sat_n = 0
    if d > d_hi:
        d, sat_n = d_hi, 1
    elif d < d_lo:
        d, sat_n = d_lo, -1
    # common-mode thrust, within what is left
    h = x_des / 2.0
    h_lo = max(lo1 - d, lo2 + d)
    h_hi = min(hi1 - d, hi2 + d)
    sat_x = 0
    if h > h_hi:
        h, sat_x = h_hi, 1
    elif h < h_lo:
        h, sat_x = h_lo, -1
    f1, f2 = h + d, h - d
    u1 = max(-100.0, min(100.0, port.inverse(f1)))
    u2 = max(-100.0, min(100.0, starboard.inverse(f2)))
    return Allocation(2.0 * h, 2.0 * b_m * d, f1, f2, u1, u2, sat_x, sat_n)
