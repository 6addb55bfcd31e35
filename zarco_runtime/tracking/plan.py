"""The AUV's a-priori plan in the tracker: which leg the AUV is on, its
progress along the plan, and whether it still flies it (paper V: the AUV
describes a sequence of straight lines "according to an a priori mission
plan, or defined on-the-fly in adaptive sampling missions").

The geometry (legs, corners, the plan rounded with the AUV's turning radius)
is :mod:`.plan_geometry`; the progress along the plan (a filter of the path
coordinate and speed, fed with the fixes) is :mod:`.plan_progress`.

:class:`PlanMatcher` is fed by the tracker with every two-circle fix
(:meth:`PlanMatcher.fix`: the progress) and with its filtered state after
every accepted update (:meth:`PlanMatcher.update`: the matching):

* ``none``: no plan;
* ``search``: a plan, the AUV not on it.  A leg fits when the position is
  within ``cross_gate_m`` + 2σ of it and between its ends, and the AUV's
  course (moving faster than ``min_speed_mps``) is within ``course_gate_deg``
  of the leg's; an AUV hovering at the plan's first point fits its first leg.
  One leg fitting for ``join_after_s`` puts the AUV on it (event ``AUV on
  its plan``) and starts its progress there;
* ``on`` leg k: the leg follows the progress along the plan (never back), or
  the filter's state fitting the next leg near the corner.  The AUV must fit
  its leg: within ``cross_gate_m`` + 2σ of it (plus half its turning radius
  about a corner, which it rounds), on its course outside the zones of
  ``corner_zone_m`` (or 1.2 turning radii) about its corners (where it
  turns), not past the corner's zone without turning.  Misfitting for
  ``leave_after_s`` — off its leg, on another course (an early turn, a leg
  the plan does not have), a late turn, a skipped corner — it has left the
  plan: event ``AUV left its plan`` with the reason, and the matcher searches
  again; re-joining any leg later puts it back on (``AUV back on its plan``).
  Sooner, at a corner: each fix is weighed between the progress along the
  plan and the tracker's filter (:meth:`PlanMatcher._weigh`); fixes that
  keep following the filter rather than the plan (an AUV running on past a
  corner, or turning the other way) have left it.

The tracker's :class:`~zarco_core.auv_messages.AuvTrack` carries the leg,
the progress and the offset from the plan (:meth:`PlanMatcher.track_fields`);
the follow guidance follows the AUV along its plan from there, round its
corners as the AUV turns them.

Pure and deterministic: no I/O, no clocks; times are any one clock (s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from zarco_core.auv_messages import AuvFix, AuvTrack
from zarco_core.config import spec
from zarco_runtime.tracking.gates import mahalanobis2
from zarco_runtime.tracking.plan_geometry import (
    MAX_POINTS,
    Plan,
    PlanError,
    PlanLeg,
    check_points,
    geodetic_plan,
)
from zarco_runtime.tracking.plan_progress import AlongPlan

__all__ = ["INFERRED_SOURCE", "MAX_POINTS", "AlongPlan", "Plan", "PlanError", "PlanLeg",
           "PlanMatcher", "PlanParams", "check_points", "geodetic_plan"]

#: the source of a plan the tracker inferred (:mod:`.plan_infer`): a tentative one
INFERRED_SOURCE = "tracker"
#: on a tentative plan, an AUV further past a corner than this many seconds of
#: its speed (and this many metres), still within this of the leg's course
#: (deg), has not turned there
TENTATIVE_PAST_S = 5.0
TENTATIVE_PAST_M = 4.0
TENTATIVE_STRAIGHT_DEG = 15.0


#: the fixes weighed between the tracker's filter and the progress along a plan
#: given (:meth:`PlanMatcher._weigh`): each prediction's share of a fix (half
#: its Mahalanobis distance²) capped at this — a fix far from both (a false
#: detection, a wrong mirror) tells neither —
TRACK_HALF_D2_CAP = 4.5
#: … the fix's evidence for the filter (the plan's share less the filter's)
#: clipped to ± this, less this drift, summed; the AUV has left the plan at
#: this level
TRACK_LLR_CAP = 3.0
TRACK_LLR_DRIFT = 0.5
TRACK_LLR_LEVEL = 6.0
#: a fix the tracker's filter refused, further than this (Mahalanobis distance²,
#: 2 degrees of freedom) from where the AUV flying its plan would be, is an
#: outlier (a late or false detection paired into a cycle): it tells neither the
#: progress nor the weighing anything
PLAN_OUTLIER_D2 = 9.0

#: a prediction: (x, y) (m) and its covariance (xx, xy, yy, m²)
Predicted = tuple[float, float, float, float, float]


def _half_d2(dx: float, dy: float, a: float, b: float, d: float) -> float | None:
    """Half the Mahalanobis distance² of an offset (dx, dy) (m) under the
    covariance (a, b; b, d) (m²); None if singular."""
    m2 = mahalanobis2(dx, dy, a, b, d)
    return None if m2 is None else 0.5 * m2


def _half_range_d2(x: float, y: float, a: float, b: float, d: float, bx: float, by: float,
                   rho: float, var: float) -> float | None:
    """Half the squared normalised residual of a range: the point (x, y) (m)
    of covariance (a, b; b, d) (m²) against the circle of horizontal radius
    ``rho`` (m) about (``bx``, ``by``), ``var`` (m²) the range's variance;
    None at the circle's centre."""
    dx, dy = x - bx, y - by
    h = math.hypot(dx, dy)
    if h < 1e-6:
        return None
    ux, uy = dx / h, dy / h
    s = var + ux * ux * a + 2.0 * ux * uy * b + uy * uy * d
    return 0.5 * (h - rho) ** 2 / s if s > 0.0 else None


@dataclass(slots=True)
class PlanParams:
    """``[tracker.plan]``: matching the AUV to its a-priori plan."""

    cross_gate_m: float = spec(5.0, "m", "the AUV is on a leg while the filter's position is "
                               "within this (plus 2σ) of it", min=0.5, max=1000.0)
    course_gate_deg: float = spec(30.0, "deg", "… and its course within this of the leg's "
                                  "(outside the corner zones)", min=1.0, max=90.0)
    corner_zone_m: float = spec(12.0, "m", "within this of a corner the AUV may be on any "
                                "course (it turns there): about its turning radius plus "
                                "the track's error", min=0.0, max=1000.0)
    min_speed_mps: float = spec(0.2, "m/s", "below this speed the AUV's course is not "
                                "judged (hovering)", min=0.0, max=5.0)
    join_after_s: float = spec(6.0, "s", "a leg must fit this long before the AUV is taken "
                               "to be on it", min=0.0, max=600.0)
    leave_after_s: float = spec(4.0, "s", "the AUV must misfit its leg this long before it "
                                "is taken to have left the plan", min=0.0, max=600.0)
    along_accel_psd: float = spec(0.01, "m²/s³", "the AUV's progress along its plan: white "
                                  "acceleration density of its speed along the path",
                                  min=1e-6, max=10.0)
    along_floor_m: float = spec(1.0, "m", "1σ added to every fix's position along the plan "
                                "(the AUV rounds the plan's corners)", min=0.0, max=100.0)
    along_window_m: float = spec(15.0, "m", "a fix is placed on the plan within this of the "
                                 "predicted path coordinate", min=1.0, max=1000.0)
    turn_radius_m: float = spec(6.0, "m", "the AUV's turning radius until its first corners "
                                "show it (the plan's corners are rounded with it)",
                                min=0.0, max=18.0)
    infer: bool = spec(True, "", "without a plan given, infer a lawnmower survey's from the "
                       "legs the AUV flies (a long leg, the spacing, the start of the leg "
                       "back) and match the AUV to it as to a given one")


@dataclass(slots=True)
class _Fit:
    """How the AUV's state fits one leg."""

    along: float
    cross: float
    pos_ok: bool
    course_ok: bool


@dataclass(slots=True)
class PlanMatcher:
    """Which leg of its plan the AUV is on, and when it leaves it (module
    docstring).  :attr:`events` collects what an operator should read
    (drained by whoever publishes them)."""

    params: PlanParams
    plan: Plan | None = None
    #: the leg the AUV is on, −1 when off the plan (or without one)
    leg: int = -1
    events: list[str] = field(default_factory=list)
    #: how many times the AUV left the plan, and joined it
    left: int = 0
    joined: int = 0
    #: fixes left out as outliers of the plan (:meth:`_outlier`)
    outliers: int = 0
    _cand: int = -1
    _cand_since: float = math.nan
    _bad_since: float = math.nan
    _bad_reason: str = ""
    _last_t: float = -math.inf
    _vel_sigma: float = 0.0
    #: the AUV's progress along the plan while it is on it
    along: AlongPlan | None = None
    #: the plan is a guess (:meth:`set_plan`)
    tentative: bool = False
    #: the CUSUM of the fixes' evidence for the filter against the plan (:meth:`_weigh`)
    _track_llr: float = 0.0

    @property
    def state(self) -> str:
        """``none`` (no plan), ``search`` or ``on``."""
        if self.plan is None:
            return "none"
        return "on" if self.leg >= 0 else "search"

    def set_plan(self, points: tuple[tuple[float, float], ...] | list[tuple[float, float]],
                 source: str = "", tentative: bool = False) -> None:
        """Take a new plan (NED points, m; empty clears it) and match from scratch.
        Points that are not a plan clear it, with an event saying why.
        ``tentative``: a plan guessed (:mod:`.plan_infer`), not given — an AUV
        going straight on past one of its corners has left it at once
        (:meth:`_straight_on`), not only past the corner's zone."""
        self.tentative = tentative
        had = self.plan is not None
        self.plan = None
        self.leg = -1
        self.along = None
        self._reset_search()
        self._bad_since = math.nan
        if not points:
            if had:
                self.events.append("AUV plan cleared; tracking without it")
            return
        try:
            self.plan = Plan(list(points))
        except ValueError as exc:
            self.events.append(f"AUV plan refused ({exc}); tracking without it")
            return
        n = len(self.plan.legs)
        self.events.append(f"AUV plan of {n} leg{'s' if n != 1 else ''} "
                           f"({self.plan.length_m:.0f} m)" + (f" from {source}" if source else "")
                           + "; waiting for the AUV on it")

    def _reset_search(self) -> None:
        self._cand = -1
        self._cand_since = math.nan

    # ------------------------------------------------------------ matching

    def _fit(self, leg: PlanLeg, x: float, y: float, vx: float, vy: float,
             sigma: float) -> _Fit:
        p = self.params
        along, cross = leg.project(x, y)
        gate = p.cross_gate_m + 2.0 * sigma
        pos_ok = abs(cross) <= gate and -gate <= along <= leg.length_m + gate
        return _Fit(along, cross, pos_ok, self._course_ok(leg.course_rad, vx, vy))

    def _course_ok(self, course: float, vx: float, vy: float) -> bool:
        """Whether the velocity (m/s) runs along ``course`` (rad) within
        ``course_gate_deg`` beyond its own uncertainty (2σ of the velocity's
        direction: a filter just started or re-anchored does not know it), or
        is too slow to say."""
        p = self.params
        v = math.hypot(vx, vy)
        tol = math.radians(p.course_gate_deg) + math.atan2(self._vel_sigma, max(v, 1e-6))
        return v < p.min_speed_mps or abs(math.remainder(
            math.atan2(vy, vx) - course, math.tau)) <= tol

    def update(self, t: float, x: float, y: float, vx: float, vy: float,
               sigma: float = 0.0, vel_sigma: float = 0.0) -> None:
        """Match the AUV's filtered state at time ``t`` (s): position (m),
        velocity (m/s), position σ (m), velocity σ (m/s)."""
        plan = self.plan
        if plan is None or not all(math.isfinite(v) for v in (t, x, y, vx, vy)):
            return
        if not math.isfinite(sigma):
            sigma = 0.0
        self._vel_sigma = vel_sigma if math.isfinite(vel_sigma) and vel_sigma > 0.0 else 0.0
        self._last_t = t
        if self.leg < 0:
            self._search(t, x, y, vx, vy, sigma)
            if self.leg >= 0:
                self._start_along(t, x, y, vx, vy, sigma)
        else:
            self._progress(t)
            self._follow_on(t, x, y, vx, vy, sigma)
        if self.leg < 0:
            self.along = None

    def fix(self, fix: AuvFix, track: Predicted | None = None) -> None:
        """A position fix (its emission time ``emission_utc_s`` on this matcher's
        clock), accepted by the tracker's filter or not: it moves the AUV's
        progress along the plan (which has its own gate) — unless the filter
        refused it and it is far from the plan's prediction too: an outlier
        (:meth:`_outlier`), counted and left out.  ``track``: the
        tracker's filter predicted to the fix — (x, y) (m) and its covariance
        (xx, xy, yy, m²) — which the fix is weighed between (:meth:`_weigh`)."""
        al, p = self.along, self.params
        if al is None or self.leg < 0 or not fix.emission_utc_s >= al.t:
            return
        al.predict(fix.emission_utc_s, p.along_accel_psd)
        # where the AUV flying its plan would be, and its covariance
        plan_pred = al.predicted(p.along_floor_m)
        if not fix.accepted and self._outlier(fix, plan_pred):
            self.outliers += 1
            return
        gap = (self._weigh(fix, plan_pred, track) if track is not None and not self.tentative
               else None)
        if gap is not None:
            self._leave(f"fixes {gap:.0f} m from its path follow the track")
            return
        al.fix(fix, p.along_window_m, p.along_floor_m)
        if al.off_path and not al.near_corner():
            # fixes drifting off a straight leg, beyond what the AUV's offset from
            # it explains: it has turned off (the fixes know before the filter's
            # course does)
            off = al.last_offset
            self._leave(f"fixes {abs(off):.0f} m {'starboard' if off > 0 else 'port'} of "
                        f"leg {self.leg + 1}")
            return
        self._advance()

    def stamp(self, track: AuvTrack) -> AuvTrack:
        """``track`` (before it is published) with what it says of the plan at
        its time origin ``t0_utc_s``: the leg, the path coordinate (m), the speed
        along the path (m/s), the offset from the plan (m), the AUV's turning
        radius (m); −1 and NaN off the plan."""
        al = self.along
        if self.leg < 0 or al is None or self.plan is None:
            return track
        dt = track.t0_utc_s - al.t
        track.plan_leg = self.leg
        track.plan_s_m = self.plan.advance(al.s, al.u * dt, al.radius) if dt else al.s
        track.plan_speed_mps = al.u
        track.plan_cross_m = al.cross + al.cross_rate * dt
        track.plan_turn_radius_m = al.radius
        return track

    def leave(self) -> None:
        """The track is lost: match again once it is back (no event: the loss
        has its own)."""
        self.leg = -1
        self.along = None
        self._reset_search()

    # ------------------------------------------------------------ progress

    def _start_along(self, t: float, x: float, y: float, vx: float, vy: float,
                     sigma: float) -> None:
        assert self.plan is not None
        self._track_llr = 0.0
        leg = self.plan.legs[self.leg]
        along, cross = leg.project(x, y)
        u = vx * leg.ux + vy * leg.uy
        self.along = AlongPlan.start(self.plan, t, leg.s0_m + along, u,
                                     sigma * sigma + self.params.along_floor_m ** 2, cross,
                                     self.params.turn_radius_m)

    def _progress(self, t: float) -> None:
        """Predict the progress to ``t``."""
        al = self.along
        if al is not None:
            al.predict(t, self.params.along_accel_psd)
            self._advance()

    def _advance(self) -> None:
        """On to the leg the progress is on (never back)."""
        al, plan = self.along, self.plan
        if al is None or plan is None:
            return
        k = plan.leg_at(al.s).index
        if k > self.leg:
            self.leg = k
            self._bad_since = math.nan

    def _search(self, t: float, x: float, y: float, vx: float, vy: float,
                sigma: float) -> None:
        plan = self.plan
        assert plan is not None
        best = -1
        if math.hypot(vx, vy) < self.params.min_speed_mps:
            # hovering: its course says nothing yet, but an AUV waiting at its
            # plan's first point is about to fly its first leg
            first = plan.legs[0]
            if math.hypot(x - first.n0, y - first.e0) <= self.params.cross_gate_m + 2.0 * sigma:
                best = 0
        else:
            best = self._best_leg(x, y, vx, vy, sigma)
        if best < 0:
            self._reset_search()
            return
        if best != self._cand:
            self._cand, self._cand_since = best, t
        if t - self._cand_since < self.params.join_after_s:
            return
        self.leg = best
        self._reset_search()
        self._bad_since = math.nan
        self.joined += 1
        n = len(plan.legs)
        self.events.append(("AUV back on its plan" if self.left else "AUV on its plan")
                           + f", leg {best + 1} of {n}")

    def _best_leg(self, x: float, y: float, vx: float, vy: float, sigma: float) -> int:
        """The leg the moving AUV fits best (nearest), or −1."""
        assert self.plan is not None
        best, best_c = -1, math.inf
        for leg in self.plan.legs:
            f = self._fit(leg, x, y, vx, vy, sigma)
            if f.pos_ok and f.course_ok and 0.0 <= f.along <= leg.length_m \
                    and abs(f.cross) < best_c:
                best, best_c = leg.index, abs(f.cross)
        return best

    def _follow_on(self, t: float, x: float, y: float, vx: float, vy: float,
                   sigma: float) -> None:
        plan = self.plan
        assert plan is not None
        p = self.params
        legs = plan.legs
        # the AUV rounds the corners: about them it is off the legs by up to
        # about half its turning radius, on any course, over its tangent length
        radius = self.along.radius if self.along is not None else 0.0
        zone = max(p.corner_zone_m, 1.2 * radius)
        # on to the next leg(s) once near the corner and fitting them
        while self.leg + 1 < len(legs):
            k = self.leg
            cur = self._fit(legs[k], x, y, vx, vy, sigma)
            if cur.along < legs[k].length_m - zone:
                break
            nxt = self._fit(legs[k + 1], x, y, vx, vy, sigma)
            if nxt.pos_ok and nxt.course_ok:
                self.leg = k + 1
                continue
            # past a leg shorter than the zone (a lawnmower's crossing): the one after
            if k + 2 < len(legs) and legs[k + 1].length_m <= 2.0 * zone:
                nn = self._fit(legs[k + 2], x, y, vx, vy, sigma)
                if nn.pos_ok and nn.course_ok:
                    self.leg = k + 2
                    continue
            break
        k = self.leg
        leg = legs[k]
        f = self._fit(leg, x, y, vx, vy, sigma)
        near_end = k + 1 < len(legs) and f.along >= leg.length_m - zone
        near_start = k > 0 and f.along <= zone
        gate = p.cross_gate_m + 2.0 * sigma + (0.5 * radius if near_end or near_start else 0.0)
        cross, course_ok = f.cross, f.course_ok
        al = self.along
        if al is not None and radius > 0.0:
            # off the path the AUV flies, not the sharp leg: past a reversal it
            # swings out up to its turning circle and comes back over tens of
            # metres, off the leg's line and course all that while
            s_m, cross = plan.nearest(x, y, al.s - p.along_window_m, al.s + p.along_window_m,
                                      radius)
            course_ok = self._course_ok(plan.point_at(s_m, 0.0, radius)[2], vx, vy)
        reason = ""
        if abs(cross) > gate:
            reason = f"{abs(cross):.0f} m {'starboard' if cross > 0 else 'port'} of leg {k + 1}"
        elif k + 1 < len(legs) and f.along > leg.length_m + zone:
            reason = f"past the end of leg {k + 1} without turning"
        elif self.tentative and (passed := self._straight_on(k, x, y, vx, vy)) >= 0:
            # a guessed corner the AUV flew straight past: no such corner
            self._leave(f"straight on past the end of leg {passed + 1}")
            return
        elif not course_ok and not (near_end or near_start):
            course = math.degrees(math.atan2(vy, vx)) % 360.0
            reason = (f"course {course:.0f}° where leg {k + 1} runs "
                      f"{math.degrees(leg.course_rad) % 360.0:.0f}°")
        if not reason:
            self._bad_since = math.nan
            return
        if not math.isfinite(self._bad_since):
            self._bad_since, self._bad_reason = t, reason
        if t - self._bad_since < p.leave_after_s:
            return
        self._leave(reason)

    def _straight_on(self, k: int, x: float, y: float, vx: float, vy: float) -> int:
        """On leg ``k`` or just past it onto ``k`` + 1: the leg (index; −1: none)
        the AUV is further along than its end plus ``TENTATIVE_PAST_S`` of its
        speed (and ``TENTATIVE_PAST_M``), still on its course (within
        ``TENTATIVE_STRAIGHT_DEG``): a guessed corner is where the AUV began
        its turns, and by then it would have turned more than that."""
        assert self.plan is not None
        legs = self.plan.legs
        c = math.atan2(vy, vx)
        for j in (k - 1, k):
            if j < 0 or j + 1 >= len(legs):
                continue
            leg = legs[j]
            along, _ = leg.project(x, y)
            past = max(TENTATIVE_PAST_M, TENTATIVE_PAST_S * math.hypot(vx, vy))
            if along > leg.length_m + past and abs(math.remainder(
                    c - leg.course_rad, math.tau)) < math.radians(TENTATIVE_STRAIGHT_DEG):
                return j
        return -1

    def _outlier(self, fix: AuvFix, plan_pred: Predicted) -> bool:
        """Whether ``fix`` is further than ``PLAN_OUTLIER_D2`` from the plan's
        prediction ``plan_pred`` (with the fix's covariance, or
        ``along_floor_m``² a side for a fix without one).  Projected on the
        path, such a fix about a corner can land within the path's gates on
        the other leg and throw the progress and its speed off for tens of
        seconds."""
        x, y = fix.x_m, fix.y_m
        if not (math.isfinite(x) and math.isfinite(y)):
            return False
        fl = self.params.along_floor_m ** 2
        cxx, cxy, cyy = fix.cov_xx_m2, fix.cov_xy_m2, fix.cov_yy_m2
        if not all(math.isfinite(v) for v in (cxx, cxy, cyy)):
            cxx, cxy, cyy = fl, 0.0, fl
        px, py, pxx, pxy, pyy = plan_pred
        m2 = mahalanobis2(x - px, y - py, pxx + cxx, pxy + cxy, pyy + cyy)
        return m2 is not None and m2 > PLAN_OUTLIER_D2

    def _weigh(self, fix: AuvFix, plan_pred: Predicted, track: Predicted) -> float | None:
        """The fix's distance from the plan's prediction ``plan_pred`` (m) if
        the fixes have been explained better by the tracker's filter than by
        the progress along the plan for long enough that the AUV has left it,
        else None: a CUSUM of each fix's evidence for the filter — half the
        difference of its squared Mahalanobis distances from the two
        predictions (each capped at TRACK_HALF_D2_CAP), clipped to
        ± TRACK_LLR_CAP, less TRACK_LLR_DRIFT — at TRACK_LLR_LEVEL.  (Without
        the covariances' determinants: the filter is not preferred for being
        the tighter of the two.)  At a corner the AUV does not turn (or turns
        another way) the filter, which goes straight until the fixes turn it,
        explains them first; where the AUV turns as planned the plan does,
        however late the filter sees the turn; on a straight leg the two
        agree.  On a guessed plan the corners are only taken once the AUV
        turns there (the guidance), so this is for plans given."""
        x, y = fix.x_m, fix.y_m
        cxx, cxy, cyy = fix.cov_xx_m2, fix.cov_xy_m2, fix.cov_yy_m2
        if not all(math.isfinite(v) for v in (x, y, cxx, cxy, cyy, *track)):
            return None
        px, py, pxx, pxy, pyy = plan_pred
        tx, ty, txx, txy, tyy = track
        d_plan = _half_d2(x - px, y - py, pxx + cxx, pxy + cxy, pyy + cyy)
        d_track = _half_d2(x - tx, y - ty, txx + cxx, txy + cxy, tyy + cyy)
        if d_plan is None or d_track is None:
            return None
        return math.hypot(x - px, y - py) if self._accumulate(d_plan, d_track) else None

    def _accumulate(self, d_plan: float, d_track: float) -> bool:
        """One measurement's evidence for the filter against the plan (half
        its Mahalanobis distances² from the two predictions) into the CUSUM
        of :meth:`_weigh`; True once it is at ``TRACK_LLR_LEVEL``."""
        z = max(-TRACK_LLR_CAP, min(TRACK_LLR_CAP, min(d_plan, TRACK_HALF_D2_CAP)
                                     - min(d_track, TRACK_HALF_D2_CAP)))
        self._track_llr = max(0.0, self._track_llr + z - TRACK_LLR_DRIFT)
        return self._track_llr >= TRACK_LLR_LEVEL

    def range_fix(self, t_em: float, bx: float, by: float, rho: float, var: float,
                  track: Predicted) -> None:
        """A range on its own (no position: a cycle on the listener's beacon, a
        reply refused), accepted by the tracker's filter or not, at emission time
        ``t_em`` (this matcher's clock): the AUV on the circle of horizontal
        radius ``rho`` (m) about the beacon at (``bx``, ``by``) (NED, m), the
        range's variance ``var`` (m²).  It does not move the progress (one
        range does not place the AUV along the path), but it is weighed
        between the plan's prediction and the filter's ``track`` as a fix is
        (:meth:`_weigh`): with two beacons every other cycle is such a range,
        and an AUV turning off its plan at a corner was left to the fixes of
        the other half, seconds apart."""
        al = self.along
        if (al is None or self.leg < 0 or self.tentative or not t_em >= al.t
                or not all(math.isfinite(v) for v in (bx, by, rho, var, *track))):
            return
        al.predict(t_em, self.params.along_accel_psd)
        px, py, pxx, pxy, pyy = al.predicted(self.params.along_floor_m)
        d_plan = _half_range_d2(px, py, pxx, pxy, pyy, bx, by, rho, var)
        d_track = _half_range_d2(*track, bx, by, rho, var)
        if d_plan is None or d_track is None:
            return
        if self._accumulate(d_plan, d_track):
            off = abs(math.hypot(px - bx, py - by) - rho)
            self._leave(f"ranges {off:.0f} m from its path follow the track")

    def _leave(self, reason: str) -> None:
        self.leg = -1
        self.along = None
        self.left += 1
        self._bad_since = math.nan
        self._reset_search()
        self.events.append(f"AUV left its plan ({reason}); tracking without it")
