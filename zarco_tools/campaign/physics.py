"""What physics allows a following boat: its top speed through the water and
the speed it has left to close on the AUV.

A mission whose closing speed is ≤ 0 somewhere on its route cannot be
followed there whatever the software does: the campaign's tables say so with
the figure instead of counting a miss.
"""

from __future__ import annotations

import math


def top_speed(x_u: float, x_uu: float, thrust_n: float) -> float:
    """Steady speed through the water (m/s) where the damping −X_u u − X_|u|u u²
    (``x_u`` N·s/m, ``x_uu`` N·s²/m², both negative) equals ``thrust_n`` (N,
    both thrusters at full forward)."""
    a, b = -x_uu, -x_u
    if a <= 0.0:
        return thrust_n / b if b > 0.0 else math.inf
    return (-b + math.sqrt(b * b + 4.0 * a * thrust_n)) / (2.0 * a)


def straight_thrust(fwd_max_n: float, mismatch: float, phi1_deg: float,
                    phi2_deg: float) -> float:
    """The most surge force (N) two thrusters of nominal full thrust
    ``fwd_max_n`` give while the boat goes straight: with the mismatch
    f1 = (1 + Δ) f, f2 = (1 − Δ) f the stronger is held back to the weaker's
    thrust (the yaw moment must be zero), and each thrust points ``phi_deg``
    off the boat's axis."""
    per = fwd_max_n * (1.0 - abs(mismatch))
    return per * (math.cos(math.radians(phi1_deg)) + math.cos(math.radians(phi2_deg)))


def closing_speed(u_max: float, course_rad: float, current_mps: float,
                  current_to_rad: float, v_auv: float) -> float:
    """The boat's top ground speed along ``course_rad`` in a current
    (``current_mps`` towards ``current_to_rad``), crabbing to cancel its cross
    component, minus the AUV's speed (m/s)."""
    along = current_mps * math.cos(current_to_rad - course_rad)
    cross = current_mps * math.sin(current_to_rad - course_rad)
    if abs(cross) >= u_max:
        return -v_auv
    return along + math.sqrt(u_max * u_max - cross * cross) - v_auv


def least_closing_speed(u_max: float, courses_rad: list[float], current_mps: float,
                        current_to_rad: float, v_auv: float) -> float:
    """The least closing speed (m/s) over the route's courses."""
    return min(closing_speed(u_max, c, current_mps, current_to_rad, v_auv)
               for c in courses_rad)


def survey_scale_pct(true_ne: list[tuple[float, float]],
                     surveyed_ne: list[tuple[float, float]]) -> float:
    """How much larger (%) the surveyed network is than the true one: the
    scale of the least-squares similarity (rotation, translation, scale) taking
    the true beacons' horizontal positions (north, east, m) onto the surveyed
    ones.  Acoustic timings cannot tell a network s times larger with sound s
    times faster: a tracker that trusts the survey can know the sound speed
    no better than this."""
    n = len(true_ne)
    if n < 2 or len(surveyed_ne) != n:
        return 0.0
    an = sum(p[0] for p in true_ne) / n
    ae = sum(p[1] for p in true_ne) / n
    bn = sum(p[0] for p in surveyed_ne) / n
    be = sum(p[1] for p in surveyed_ne) / n
    # with complex numbers a, b about their centroids: b ≈ z a, |z| the scale
    num = 0j
    den = 0.0
    for (tn, te), (sn, se) in zip(true_ne, surveyed_ne, strict=True):
        a = complex(tn - an, te - ae)
        b = complex(sn - bn, se - be)
        num += b * a.conjugate()
        den += abs(a) ** 2
    return (abs(num) / den - 1.0) * 100.0 if den > 0.0 else 0.0
