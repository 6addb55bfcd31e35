"""The AUV's progress along its plan, and how tightly it turns its corners.

:class:`AlongPlan` is a Kalman filter of the path coordinate ``s`` (m, the
sharp plan's: :mod:`.plan_geometry`) and the speed along the path ``u`` (m/s)
at time ``t``.  The AUV flies its plan at a steady speed, so its progress is
a quiet one-dimensional motion however the legs turn: each fix, placed on the
path (the point of the path nearest it, within ``window`` of the
prediction), follows a corner as soon as the AUV turns it, where a filter of
the motion in the plane sees the turn only once several fixes disagree with
a straight line.  ``cross`` is the AUV's offset from the path (m, > 0 to
starboard) and ``cross_rate`` its rate (m/s), a second filter: on a straight
leg a steady offset (its own navigation error, and the tracker's: a beacon
surveyed off), averaged over many fixes; about a corner, where an AUV that
cannot turn as tightly as the plan swings out and back, a quickly changing
one (``CROSS_ACCEL_CORNER``), damped back to steady over ``CROSS_DAMP_S``.

The path is the plan rounded with the AUV's turning radius, chosen among
``RADII_M`` by how well each explains the fixes about the corners (the sum
of their squared offsets from each rounded path, normalised, with a slow
forgetting), starting from the configured radius: after its first corner
the path is the one the AUV flies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from zarco_core.auv_messages import AuvFix
from zarco_runtime.tracking.plan_geometry import Plan

#: the turning radii (m) the AUV's path is chosen from
RADII_M = (0.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0,
           12.5, 14.0, 16.0, 18.0)
#: gate of a fix's path coordinate (χ², 1 degree of freedom)
ALONG_GATE_CHI2 = 16.0
#: fixes refused in a row after which the progress restarts from the fix
ALONG_REANCHOR = 3
#: an innovation beyond this (χ²) opens up the speed's variance by
#: SPEED_CHANGE_SIGMA_MPS (m/s) for what follows
SPEED_CHANGE_CHI2 = 4.0
SPEED_CHANGE_SIGMA_MPS = 0.3
#: below this speed along the path (m/s) the AUV is still and may start off:
#: its speed's white-acceleration density is then at least START_ACCEL_PSD (m²/s³)
STILL_MPS = 0.3
START_ACCEL_PSD = 0.25
#: white-acceleration density of the offset from the path on a straight leg and
#: about a corner (m²/s³)
CROSS_ACCEL_STRAIGHT = 0.002
CROSS_ACCEL_CORNER = 0.03
#: the offset's rate decays with this time constant (s)
CROSS_DAMP_S = 8.0
#: gate of a fix's offset from the path (χ², 1 degree of freedom)
CROSS_GATE_CHI2 = 9.0
#: the CUSUM of the fixes' offsets from the path: each normalised offset clipped
#: to ± OFF_CAP, less OFF_DRIFT; the AUV has left the path at OFF_LEVEL
OFF_CAP = 2.5
OFF_DRIFT = 1.0
OFF_LEVEL = 4.0
#: a leg's straight part (between its corners' arcs) is one from this long (m)
STRAIGHT_MIN_M = 10.0
#: a fix adds at most this (χ²) to a radius's score
SCORE_CAP_CHI2 = 9.0
#: "about a corner": within the widest rounding's tangent length plus this (m)
CORNER_MARGIN_M = 10.0
#: each fix about a corner keeps this much of the radii's scores
RADIUS_MEMORY = 0.97
#: a radius replaces the one in use when its score is this much lower (χ²)
RADIUS_MARGIN = 4.0
#: weight of the configured radius in the scores before any corner (χ² per
#: step of RADII_M away from it)
RADIUS_PRIOR = 1.0
#: the variance of a fix across the path is at least this (m²)
CROSS_VAR_FLOOR_M2 = 0.25


@dataclass(slots=True)
class AlongPlan:
    """Progress along ``plan`` (module docstring): ``s`` (m), ``u`` (m/s) at time
    ``t`` (s), covariance ``P`` of (s, u), offset ``cross`` (m), the turning
    radius in use ``radius`` (m)."""

    plan: Plan
    t: float
    s: float
    u: float
    P: list[list[float]]
    cross: float
    radius: float
    #: consecutive fixes refused by the gate
    refused: int = 0
    scores: list[float] = field(default_factory=list)
    cross_rate: float = 0.0
    #: the CUSUM of the fixes' offsets from the path (to starboard, to port), and
    #: the last fix's offset (m)
    off_pos: float = 0.0
    off_neg: float = 0.0
    last_offset: float = 0.0
    #: the offset from the path on the last straight stretch (m): what the
    #: radii's paths are scored against about a corner, where ``cross`` follows
    #: the path in use wherever the AUV is
    steady_cross: float = 0.0
    #: … as a displacement (north, east, m: a bias of the fixes — a beacon
    #: surveyed off, a turnaround — is one in the plane, whichever way the leg
    #: runs) and its variance (m²)
    steady_ne: tuple[float, float] = (0.0, 0.0)
    steady_var: float = 4.0

    def predicted(self, floor: float) -> tuple[float, float, float, float, float]:
        """Where the AUV flying its plan would be now: (x, y) (m, NED) at the
        path coordinate, displaced as the fixes were on the last straight
        stretch (not by the offset that follows the fixes about a corner,
        which would follow an AUV not turning there too), and the covariance
        (xx, xy, yy, m²) of the variances along the path and across it there
        (each plus ``floor``², m: the AUV rounds the corners)."""
        x, y, course = self.plan.point_at(self.s, 0.0, self.radius)
        x, y = x + self.steady_ne[0], y + self.steady_ne[1]
        ux, uy = math.cos(course), math.sin(course)
        va = self.P[0][0] + floor * floor
        vc = self.steady_var + floor * floor
        return (x, y, va * ux * ux + vc * uy * uy, (va - vc) * ux * uy,
                va * uy * uy + vc * ux * ux)

    @property
    def off_path(self) -> bool:
        """Whether the fixes have drifted off the path (the CUSUM's level)."""
        return max(self.off_pos, self.off_neg) >= OFF_LEVEL
    #: covariance of (cross, cross_rate)
    Pc: list[list[float]] = field(default_factory=lambda: [[4.0, 0.0], [0.0, 0.01]])

    @classmethod
    def start(cls, plan: Plan, t: float, s: float, u: float, s_var: float, cross: float,
              radius: float) -> AlongPlan:
        """From path coordinate ``s`` (variance ``s_var``, m²), speed ``u``, offset
        ``cross``, and the configured turning ``radius`` (m)."""
        near = min(range(len(RADII_M)), key=lambda i: abs(RADII_M[i] - radius))
        scores = [RADIUS_PRIOR * abs(i - near) for i in range(len(RADII_M))]
        _, _, course = plan.point_at(s, 0.0, RADII_M[near])
        return cls(plan, t, s, u, [[s_var, 0.0], [0.0, 0.2 ** 2]], cross, RADII_M[near],
                   0, scores, steady_cross=cross,
                   steady_ne=(-cross * math.sin(course), cross * math.cos(course)))

    def predict(self, t: float, q: float) -> None:
        """To time ``t`` (s), with ``q`` the white-acceleration density of the
        speed along the path (m²/s³)."""
        dt = t - self.t
        if dt <= 0.0:
            return
        if abs(self.u) < STILL_MPS:
            q = max(q, START_ACCEL_PSD)  # a still AUV may start at any moment
        (a, b), (_, d) = self.P
        a += 2.0 * dt * b + dt * dt * d + q * dt ** 3 / 3.0
        b += dt * d + q * dt * dt / 2.0
        d += q * dt
        self.P = [[a, b], [b, d]]
        self.s = self.plan.advance(self.s, self.u * dt, self.radius)
        self.t = t
        qc = CROSS_ACCEL_CORNER if self.near_corner() else CROSS_ACCEL_STRAIGHT
        f = math.exp(-dt / CROSS_DAMP_S)
        (a, b), (_, d) = self.Pc
        # x' = [[1, dt], [0, f]] x: the rate decays
        a += 2.0 * dt * b + dt * dt * d + qc * dt ** 3 / 3.0
        b = f * (b + dt * d) + qc * dt * dt / 2.0
        d = f * f * d + qc * dt
        self.Pc = [[a, b], [b, d]]
        self.cross += self.cross_rate * dt
        self.cross_rate *= f

    def near_corner(self) -> bool:
        """Whether the progress is about a corner (where the AUV turns)."""
        plan = self.plan
        k = plan.leg_at(self.s).index
        for j in (k - 1, k):
            if 0 <= j < len(plan.legs) - 1:
                lo, hi = plan.span(j, RADII_M[-1])
                if lo - CORNER_MARGIN_M <= self.s <= hi + CORNER_MARGIN_M:
                    return True
        return False

    def on_straight(self, margin: float) -> int:
        """The leg (index) whose straight part the progress is on — past the
        rounding (at the AUV's own turning radius) of the corner before it and
        short of the next one, by ``margin`` (m) — else −1."""
        plan = self.plan
        leg = plan.leg_at(self.s)
        k = leg.index
        lo = (plan.span(k - 1, self.radius)[1] if k > 0 else leg.s0_m) + margin
        hi = (plan.span(k, self.radius)[0] - margin if k + 1 < len(plan.legs)
              else leg.s0_m + leg.length_m)
        if hi - lo < STRAIGHT_MIN_M:
            return -1  # no straight part worth the name: a leg of a curve drawn as a polyline
        if not lo <= self.s <= hi:
            return -1
        return k

    def fix(self, fix: AuvFix, window: float, floor: float) -> bool:
        """Place a fix on the path and update; True if it was taken.  Fixes
        about a corner also score the turning radii."""
        plan = self.plan
        x, y = fix.x_m, fix.y_m
        if not (math.isfinite(x) and math.isfinite(y)):
            return False
        cxx, cxy, cyy = fix.cov_xx_m2, fix.cov_xy_m2, fix.cov_yy_m2
        cov_ok = all(math.isfinite(v) for v in (cxx, cxy, cyy))
        lo, hi = self.s - window, self.s + window
        s_m, c = plan.nearest(x, y, lo, hi, self.radius)
        _, _, course = plan.point_at(s_m, 0.0, self.radius)
        ux, uy = math.cos(course), math.sin(course)
        if cov_ok:
            var = max(ux * ux * cxx + 2.0 * ux * uy * cxy + uy * uy * cyy, 0.0)
            var_c = max(uy * uy * cxx - 2.0 * ux * uy * cxy + ux * ux * cyy, 0.0)
        else:
            var = var_c = 4.0
        var_c += floor * floor
        var += floor * floor
        # a fix far off the path where the AUV is (a wrong mirror, a late
        # detection) is an outlier, not a sudden offset
        e = c - self.cross
        self.last_offset = c
        # a two-sided CUSUM of the fixes' normalised offsets from the path (each
        # clipped: one outlier is not a departure, fixes drifting to one side are)
        z = max(-OFF_CAP, min(OFF_CAP, e / math.sqrt(self.Pc[0][0] + var_c)))
        self.off_pos = max(0.0, self.off_pos + z - OFF_DRIFT)
        self.off_neg = max(0.0, self.off_neg - z - OFF_DRIFT)
        if e * e <= CROSS_GATE_CHI2 * (self.Pc[0][0] + var_c):
            self._score(x, y, lo, hi, var_c)
            if self._update(s_m, var):
                self._cross_update(c, var_c)
                if not self.near_corner():
                    # (the fix's course on the path: the same leg, off the corners)
                    self.steady_cross, self.steady_var = self.cross, self.Pc[0][0]
                    self.steady_ne = (-self.cross * uy, self.cross * ux)
                return True
        else:
            self.refused += 1
        if self.refused >= ALONG_REANCHOR:
            # the fixes keep disagreeing with the progress (the AUV slowed, or the
            # progress ran ahead of it, or it flies off the path): start again
            # from this one
            self.s, self.cross, self.cross_rate = s_m, c, 0.0
            self.P = [[var, 0.0], [0.0, max(self.P[1][1], 0.2 ** 2)]]
            self.Pc = [[var_c, 0.0], [0.0, 0.01]]
            self.refused = 0
            self.off_pos = self.off_neg = 0.0
        return False

    def _update(self, s: float, var: float) -> bool:
        (a, b), (_, d) = self.P
        sv = a + var
        nu = s - self.s
        if nu * nu > ALONG_GATE_CHI2 * sv:
            self.refused += 1
            return False
        self.refused = 0
        if nu * nu > SPEED_CHANGE_CHI2 * sv:
            # a surprise: the AUV may have changed speed (started, stopped):
            # its speed is less certain from now on
            d += SPEED_CHANGE_SIGMA_MPS ** 2
        ka, kb = a / sv, b / sv
        self.s += ka * nu
        self.u += kb * nu
        self.P = [[a - ka * a, b - ka * b], [b - ka * b, d - kb * b]]
        return True

    def _cross_update(self, c: float, var: float) -> None:
        (a, b), (_, d) = self.Pc
        sv = a + var
        nu = c - self.cross
        ka, kb = a / sv, b / sv
        self.cross += ka * nu
        self.cross_rate += kb * nu
        self.Pc = [[a - ka * a, b - ka * b], [b - ka * b, d - kb * b]]

    def _score(self, x: float, y: float, lo: float, hi: float, var_c: float) -> None:
        """Score every radius by the fix's offset from its path, if the fix is
        about a corner (elsewhere the paths are one); switch to the best."""
        plan = self.plan
        if not self.near_corner():
            return
        sc = self.scores
        for i, r in enumerate(RADII_M):
            _, c = plan.nearest(x, y, lo, hi, r)
            e = c - self.steady_cross
            sc[i] = RADIUS_MEMORY * sc[i] + min(e * e / var_c, SCORE_CAP_CHI2)
        best = min(range(len(RADII_M)), key=sc.__getitem__)
        cur = RADII_M.index(self.radius)
        if sc[best] + RADIUS_MARGIN < sc[cur]:
            self.radius = RADII_M[best]
