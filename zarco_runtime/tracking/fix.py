"""Ranges, emission time, motion-bias correction and the depth-corrected fix.

Paper IV, with the listener at beacon L and a cycle (t^I_j, t^R_j, t^I_{j+1})
on beacon i (UTC seconds at the listener), turnaround τ_i, AUV delay δ, sound
speed c and d_i the 3-D distance from beacon i to the listener::

    P_j = t^I_{j+1} − t^I_j                       ping period (s)
    r_i = (c/2)(P_j − τ_i − δ)                    AUV range to beacon i (m)
    r_L = r_i + d_i − c (t^R_j − t^I_j − τ_i)     AUV range to the listener (m)
    T_j = t^I_j − r_L / c                         emission time (UTC s)

Motion bias.  With the AUV moving, P_j measures the outbound range at T_j and
the inbound range when the AUV hears the reply (Δt_h = 2 r_i/c + τ_i later),
plus the change of its range to the listener between its two pings
(Δt_P = Δt_h + δ later).  To first order both ranges come out biased by::

    b = ṙ_i Δt_h / 2 + ṙ_L Δt_P / 2               (≈ v P / 2, m)

where ṙ are the range rates.  :func:`motion_bias` computes b from a velocity
(the filter's), and the corrected ranges are r − b (both r_i and r_L carry the
same b: r_L − r_i only depends on t^R − t^I, which the motion does not bias).

Fix.  With the AUV depth z known, each 3-D range becomes a horizontal radius
ρ = √(r² − (z − z_b)²), and the two horizontal circles about beacon i and the
listener meet in a fix and its mirror across the baseline.  When noise keeps
them apart (or nested) by less than ``max_gap_m``, the least-squares point on
the baseline is returned (tangent case, both solutions equal).

All functions are pure; positions are local NED (x north, y east, metres).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_runtime.tracking.cycles import Cycle
from zarco_runtime.tracking.params import Network


@dataclass(slots=True)
class CycleRanges:
    """Ranges of one cycle (m), emission time (UTC s) and ping period (s)."""

    index: int
    r_i: float
    r_l: float
    emission_utc_s: float
    period_s: float


@dataclass(slots=True)
class CircleFix:
    """The two intersections of the horizontal circles (NED m) and the gap (m).

    ``gap_m`` is 0 when the circles intersect; otherwise by how much they miss
    (both solutions are then the least-squares point on the baseline).
    ``rho_i_m``/``rho_l_m`` are the horizontal radii used.
    """

    x1: float
    y1: float
    x2: float
    y2: float
    gap_m: float
    rho_i_m: float
    rho_l_m: float


def cycle_ranges(cycle: Cycle, net: Network) -> CycleRanges:
    """Uncorrected ranges r_i, r_L, emission time T_j and period P_j of ``cycle``.

    For a cycle on the listener's own beacon r_L = r_i by construction
    (t^R − t^I − τ_L is then pure noise and is ignored).
    """
    i = cycle.index
    c = net.c
    p = cycle.t_next - cycle.t_i
    r_i = 0.5 * c * (p - net.tau[i] - net.delta)
    # on the listener's own beacon t^R − t^I − τ_L is pure noise: r_L = r_i
    path_diff = 0.0 if i == net.listener else net.d[i] - c * (cycle.t_r - cycle.t_i - net.tau[i])
    r_l = r_i + path_diff
    return CycleRanges(i, r_i, r_l, cycle.t_i - r_l / c, p)


def half_cycle_measure(cycle: Cycle, net: Network) -> float:
    """The range combination (m) a half cycle (:mod:`.cycles`) measures.

    Without its closing ping (``t_next`` NaN), from the emission point at T:
    r_i − r_L = c(t^R − t^I − τ_i) − d_i (exact for a moving AUV: both ranges
    are from where it pinged).  Without its opening ping (``t_i`` NaN):
    r_i′ + r_L′ = c(t^I_{j+1} − t^R − δ) + d_i, r_i′ the range from beacon i to
    where the AUV heard the reply (at T′ − δ), r_L′ the listener's range at
    the next emission T′ (the turnaround cancels)."""
    i = cycle.index
    c = net.c
    if math.isnan(cycle.t_next):
        return c * (cycle.t_r - cycle.t_i - net.tau[i]) - net.d[i]
    return c * (cycle.t_next - cycle.t_r - net.delta) + net.d[i]


def range_rate(net: Network, index: int, x: float, y: float, z: float, vx: float,
               vy: float) -> float:
    """d/dt of the 3-D range from beacon ``index`` to an AUV at (x, y, z) moving
    horizontally at (vx, vy) m/s (m/s; 0 at the beacon itself)."""
    dx = x - net.north[index]
    dy = y - net.east[index]
    dz = z - net.depth[index]
    r = math.sqrt(dx * dx + dy * dy + dz * dz)
    return 0.0 if r < 1e-9 else (dx * vx + dy * vy) / r


def motion_bias(net: Network, index: int, r_i: float, x: float, y: float, z: float,
                vx: float, vy: float) -> float:
    """First-order range bias b (m) of a cycle on beacon ``index`` for an AUV at
    (x, y, z) moving at (vx, vy): b = ṙ_i Δt_h/2 + ṙ_L Δt_P/2 (module docstring).
    Subtract it from both r_i and r_L."""
    dt_h = 2.0 * r_i / net.c + net.tau[index]
    dt_p = dt_h + net.delta
    rd_i = range_rate(net, index, x, y, z, vx, vy)
    rd_l = range_rate(net, net.listener, x, y, z, vx, vy)
    return 0.5 * (rd_i * dt_h + rd_l * dt_p)


def horizontal_radius(r: float, dz: float) -> float:
    """√(r² − dz²), or a negative number −√(dz² − r²) when the range is shorter
    than the depth offset (callers decide how much of that they tolerate)."""
    q = r * r - dz * dz
    return math.sqrt(q) if q >= 0.0 else -math.sqrt(-q)


def circle_fix(net: Network, index: int, r_i: float, r_l: float,
               depth_m: float) -> CircleFix | None:
    """Depth-corrected two-circle fix from ranges to beacon ``index`` and to the
    listener; None when a range is shorter than its depth offset (by more than
    1 m) or the beacon is the listener (a single circle)."""
    lst = net.listener
    if index == lst:
        return None
    rho_i = horizontal_radius(r_i, depth_m - net.depth[index])
    rho_l = horizontal_radius(r_l, depth_m - net.depth[lst])
    if rho_i < -1.0 or rho_l < -1.0:
        return None
    rho_i = max(rho_i, 0.0)
    rho_l = max(rho_l, 0.0)
    xl, yl = net.north[lst], net.east[lst]
    bx, by = net.north[index] - xl, net.east[index] - yl
    dist = math.hypot(bx, by)
    if dist < 1e-6:  # beacons vertically above each other: no baseline
        return None
    ux, uy = bx / dist, by / dist
    a = (rho_l * rho_l - rho_i * rho_i + dist * dist) / (2.0 * dist)
    h2 = rho_l * rho_l - a * a
    if h2 >= 0.0:
        h = math.sqrt(h2)
        gap = 0.0
    else:
        h = 0.0
        if dist >= rho_l + rho_i:  # apart: the point midway between the circles
            gap = dist - rho_l - rho_i
            a = 0.5 * (rho_l + dist - rho_i)
        elif rho_l >= dist + rho_i:  # beacon i's circle inside, beyond beacon i
            gap = rho_l - dist - rho_i
            a = 0.5 * (rho_l + dist + rho_i)
        else:  # listener's circle inside, beyond the listener
            gap = rho_i - dist - rho_l
            a = 0.5 * (dist - rho_l - rho_i)
    mx, my = xl + a * ux, yl + a * uy
    # (−uy, ux) is the baseline direction turned 90° to the right (starboard) in NED
    return CircleFix(mx - h * uy, my + h * ux, mx + h * uy, my - h * ux, gap, rho_i, rho_l)


def range3(net: Network, index: int, x: float, y: float, depth_m: float) -> float:
    """3-D range (m) from beacon ``index`` to the AUV at (x, y, depth) (NED m)."""
    dx = x - net.north[index]
    dy = y - net.east[index]
    dz = depth_m - net.depth[index]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


def range_jacobian(net: Network, index: int, x: float, y: float,
                   depth_m: float) -> tuple[float, float]:
    """∂r/∂(x, y) of the 3-D range from beacon ``index`` to (x, y, depth) — the
    horizontal offset over the 3-D range (0, 0 at the beacon)."""
    dx = x - net.north[index]
    dy = y - net.east[index]
    dz = depth_m - net.depth[index]
    r = math.sqrt(dx * dx + dy * dy + dz * dz)
    if r < 1e-9:
        return 0.0, 0.0
    return dx / r, dy / r


def range_variances(net: Network, index: int, timing_sigma_s: float,
                    range_sigma_m: float) -> tuple[float, float]:
    """Variances (m²) of r_i and r_L from independent detection jitter σ_t on the
    three times plus a range error σ_r on each.

    r_i = (c/2)(t^I_{j+1} − t^I_j) + const and
    r_L = (c/2)(t^I_{j+1} + t^I_j) − c t^R + const, so Var r_i = c²σ_t²/2,
    Var r_L = 3c²σ_t²/2 and their covariance is 0 (the t^I_j terms cancel).
    """
    ct2 = (net.c * timing_sigma_s) ** 2
    rr = range_sigma_m * range_sigma_m
    var_i = 0.5 * ct2 + rr
    var_l = var_i if index == net.listener else 1.5 * ct2 + rr
    return var_i, var_l


def ls_fix(net: Network, ranges: list[tuple[int, float, float]], depth_m: float, x0: float,
           y0: float, iterations: int = 4) -> tuple[float, float, float, float, float] | None:
    """Weighted least-squares position from 3-D ranges to several beacons.

    ``ranges``: (beacon index, range m, variance m²) at one instant; Gauss–Newton
    from (x0, y0) (NED m) on Σ (r_k − ρ_k(p))² / var_k, ρ_k the 3-D range to the
    AUV at ``depth_m``.  Returns (x, y, Cxx, Cxy, Cyy): the position and its
    covariance (JᵀWJ)⁻¹ at the solution (m, m²); None when the ranges leave the
    position undetermined (fewer than two independent directions).
    """
    x, y = x0, y0
    cxx = cxy = cyy = math.inf
    for _ in range(iterations):
        x, y, cxx, cxy, cyy, done = _gauss_newton_step(net, ranges, depth_m, x, y)
        if math.isnan(cxx):
            return None
        if done:
            break
    return x, y, cxx, cxy, cyy


def ls_chi2(net: Network, ranges: list[tuple[int, float, float]], depth_m: float, x: float,
            y: float) -> float:
    """Σ (r_k − ρ_k(x, y))² / var_k: how well a position explains the ranges."""
    out = 0.0
    for k, r, var in ranges:
        rho = math.sqrt((x - net.north[k]) ** 2 + (y - net.east[k]) ** 2
                        + (depth_m - net.depth[k]) ** 2)
        out += (r - rho) ** 2 / var if var > 0.0 else 0.0
    return out


def _gauss_newton_step(net: Network, ranges: list[tuple[int, float, float]], depth_m: float,
                       x: float, y: float
                       ) -> tuple[float, float, float, float, float, bool]:
    """One Gauss–Newton step of :func:`ls_fix`: (x, y, Cxx, Cxy, Cyy, converged);
    NaN covariance when undetermined."""
    a00 = a01 = a11 = b0 = b1 = 0.0
    for k, r, var in ranges:
        dx = x - net.north[k]
        dy = y - net.east[k]
        dz = depth_m - net.depth[k]
        rho = math.sqrt(dx * dx + dy * dy + dz * dz)
        if rho < 1e-9 or var <= 0.0:
            continue
        jx, jy = dx / rho, dy / rho
        w = 1.0 / var
        res = r - rho
        a00 += w * jx * jx
        a01 += w * jx * jy
        a11 += w * jy * jy
        b0 += w * jx * res
        b1 += w * jy * res
    det = a00 * a11 - a01 * a01
    if not det > 1e-9 * max(a00 * a11, 1e-300):
        return x, y, math.nan, math.nan, math.nan, True
    cxx, cxy, cyy = a11 / det, -a01 / det, a00 / det
    sx = cxx * b0 + cxy * b1
    sy = cxy * b0 + cyy * b1
    return x + sx, y + sy, cxx, cxy, cyy, sx * sx + sy * sy < 1e-6
