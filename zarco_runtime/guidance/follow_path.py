"""What the follow guidance follows: the AUV now, and the path it is on.

The target is the AUV's position now (local NED, m) and velocity (m/s): the
tracker's filter position (which follows a turn within a fix or two) carried
forward from the track's time origin to now,

* without a plan, along a straight line with a velocity taken from the RLS
  line (the paper's estimate, smooth on straight legs) when it is valid, the
  tracker has not just declared a turn, and the line agrees with the filter
  (position and course), otherwise with the filter's own velocity
  (:func:`target_now`);
* with the AUV on its a-priori plan (the track's ``plan_leg``), along the
  plan: the tracker's estimate of its progress along the plan (path
  coordinate s, speed along the path, offset to starboard, the radius it
  rounds the corners with) carried forward along the legs, round their
  corners (:func:`plan_target`).

The path is where the AUV goes from there: a :class:`StraightPath` along its
course, or a :class:`PlanPath` along its plan (offset as the AUV is).  The
follow laws ask it where the boat is relative to the target (``locate``:
along-path a > 0 ahead of the target, cross c > 0 to starboard), for a point
some metres ahead on it (``point``, ``course``), and for the straight line
the AUV flies there (``line``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.auv_messages import AuvTrack, TrackFlags
from zarco_runtime.tracking.plan import Plan

#: a speed along the plan below minus this (m/s) is the AUV going backwards
BACKWARDS_MPS = 0.2
#: the RLS line is used only while its speed agrees with the filter's within
#: this (m/s): fitted over seconds of fixes, it lags an AUV setting off
LINE_SPEED_GATE_MPS = 0.4
#: the boat is located on a plan path within this of the target's path coordinate (m)
LOCATE_WINDOW_M = 30.0


@dataclass(frozen=True, slots=True)
class Target:
    """The AUV now: position (NED m), velocity (m/s), and where it came from
    (``line``, ``kf``, ``plan``)."""

    x: float
    y: float
    vx: float
    vy: float
    source: str


def target_now(track: AuvTrack, t: float, line_gate_m: float,
               line_course_gate_rad: float = math.inf) -> Target:
    """The AUV's position and velocity at runtime time ``t``: the Kalman
    filter's position, carried to ``t`` with the RLS line's velocity while the
    line is valid, settled (not just restarted by a turn) and consistent with
    the filter (positions within ``line_gate_m`` + 3σ, speeds within
    ``LINE_SPEED_GATE_MPS``, courses within ``line_course_gate_rad``), else
    with the filter's own velocity."""
    dt = t - track.t0
    kvx, kvy = track.kf_vx_mps, track.kf_vy_mps
    kf = Target(track.kf_x_m + kvx * dt, track.kf_y_m + kvy * dt, kvx, kvy, "kf")
    fl = track.flags
    if not fl & TrackFlags.LINE_VALID or fl & TrackFlags.TURNING:
        return kf
    lx = track.x0_m + track.vx_mps * dt
    ly = track.y0_m + track.vy_mps * dt
    if not (math.isfinite(lx) and math.isfinite(ly)):
        return kf
    sigma = track.kf_pos_sigma_m if math.isfinite(track.kf_pos_sigma_m) else 0.0
    if math.hypot(lx - kf.x, ly - kf.y) > line_gate_m + 3.0 * sigma:
        return kf
    if abs(math.hypot(kvx, kvy) - math.hypot(track.vx_mps, track.vy_mps)) > LINE_SPEED_GATE_MPS:
        return kf
    if math.hypot(kvx, kvy) > 0.05 and abs(math.remainder(
            math.atan2(kvy, kvx) - math.atan2(track.vy_mps, track.vx_mps), math.tau)
            ) > line_course_gate_rad:
        return kf
    return Target(track.kf_x_m + track.vx_mps * dt, track.kf_y_m + track.vy_mps * dt,
                  track.vx_mps, track.vy_mps, "line")


class StraightPath:
    """The AUV's path without a plan: the line through the target along its course."""

    __slots__ = ("course", "ux", "uy", "x", "y")

    def __init__(self, tg: Target) -> None:
        v = math.hypot(tg.vx, tg.vy)
        self.x, self.y = tg.x, tg.y
        self.ux, self.uy = (tg.vx / v, tg.vy / v) if v > 0.0 else (1.0, 0.0)
        self.course = math.atan2(self.uy, self.ux)

    def locate(self, x: float, y: float) -> tuple[float, float]:
        """(a, c): the point (x, y) along the path from the target (m, > 0
        ahead) and across it (m, > 0 to starboard)."""
        ex, ey = x - self.x, y - self.y
        return ex * self.ux + ey * self.uy, -ex * self.uy + ey * self.ux

    def point(self, a: float) -> tuple[float, float]:
        """The point ``a`` metres along the path from the target."""
        return self.x + a * self.ux, self.y + a * self.uy

    def course_at(self, a: float) -> float:
        """The path's course ``a`` metres from the target (rad)."""
        return self.course

    def line(self, a: float) -> tuple[float, float, float, int]:
        """The straight line the AUV flies ``a`` metres from the target: a point
        of it level with the target (m), its course (rad), and an identity (-1:
        the AUV's own course, no plan leg)."""
        return self.x, self.y, self.course, -1


class PlanPath:
    """The AUV's path on its plan: the plan's legs, rounded with the AUV's
    turning radius ``radius`` (m), from the target's path coordinate ``s``
    (m), offset ``cross`` metres to starboard as the AUV is."""

    __slots__ = ("cross", "plan", "radius", "s")

    def __init__(self, plan: Plan, s: float, cross: float, radius: float) -> None:
        self.plan = plan
        self.s = s
        self.cross = cross
        self.radius = radius

    def _at(self, a: float) -> float:
        return self.plan.advance(self.s, a, self.radius)

    def locate(self, x: float, y: float) -> tuple[float, float]:
        """(a, c) as :meth:`StraightPath.locate`, along the path: the nearest point
        of the path within ``LOCATE_WINDOW_M`` of the target (a U-turn's other
        leg, a few metres away, is not where the boat is following).  Inside a
        corner that point is on the next leg, ahead of the target, while the
        boat is level with it: ``a`` is at most the boat's lead along the
        target's own course."""
        sb, c = self.plan.nearest(x, y, self._at(-LOCATE_WINDOW_M), self._at(LOCATE_WINDOW_M),
                                  self.radius)
        tx, ty, course = self.plan.point_at(self.s, self.cross, self.radius)
        lead = (x - tx) * math.cos(course) + (y - ty) * math.sin(course)
        return min(sb - self.s, lead), c - self.cross

    def point(self, a: float) -> tuple[float, float]:
        x, y, _ = self.plan.point_at(self._at(a), self.cross, self.radius)
        return x, y

    def course_at(self, a: float) -> float:
        return self.plan.point_at(self._at(a), 0.0, self.radius)[2]

    def turns(self, a: float) -> tuple[float, ...]:
        """The turns (rad, + to starboard) of the plan's corners within ``a``
        metres of the target along the path, before or after it, in order."""
        k0 = self.plan.leg_at(self._at(-a)).index
        k1 = self.plan.leg_at(self._at(a)).index
        return tuple(self.plan.turn_rad(k) for k in range(k0, k1))

    def line(self, a: float) -> tuple[float, float, float, int]:
        """The (offset) plan leg ``a`` metres from the target: the point of it
        level with the target, its course, its index."""
        leg = self.plan.leg_at(self._at(a))
        tx, ty = self.point(0.0)
        x, y = leg.point(leg.project(tx, ty)[0], self.cross)
        return x, y, leg.course_rad, leg.index


def plan_target(track: AuvTrack, plan: Plan, t: float) -> tuple[Target, PlanPath] | None:
    """The AUV at runtime time ``t`` on its plan: the tracker's progress along
    it (``plan_s_m`` at the track's time origin, ``plan_speed_mps``) carried
    forward, offset ``plan_cross_m`` as the AUV is; and its path.  None when
    the track does not put the AUV on a leg of ``plan`` (or going backwards
    faster than ``BACKWARDS_MPS``: a still AUV's speed along the plan is
    noise of either sign, taken as 0)."""
    s0, u, cross = track.plan_s_m, track.plan_speed_mps, track.plan_cross_m
    radius = track.plan_turn_radius_m
    if not (0 <= track.plan_leg < len(plan.legs) and math.isfinite(s0) and math.isfinite(u)
            and math.isfinite(cross) and u >= -BACKWARDS_MPS):
        return None
    u = max(u, 0.0)
    radius = radius if math.isfinite(radius) and radius > 0.0 else 0.0
    s = plan.advance(s0, u * max(t - track.t0, 0.0), radius)
    x, y, course = plan.point_at(s, cross, radius)
    tg = Target(x, y, u * math.cos(course), u * math.sin(course), "plan")
    return tg, PlanPath(plan, s, cross, radius)
