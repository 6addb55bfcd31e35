"""Follow the AUV (paper VI): guidance from the AUV's estimated track.

The target is the AUV now, and the path it is on (:mod:`.follow_path`): the
tracker's filter position carried forward along a straight line, or along
the AUV's a-priori plan while the tracker has the AUV on it.  With a plan the
path turns where the plan's legs turn, so the boat turns with the AUV at a
corner instead of after the track has seen the turn (on a plan the tracker
guessed, :mod:`~zarco_runtime.tracking.plan_infer`, once the filter has the
AUV turning there: the survey may have ended, and only while the plan's
target stays within ``PLAN_GATE_M`` of the filter's position; approaching
such a corner the boat drops back ``TRAIL_M`` behind the track's target:
that much less to overshoot if the AUV turns, that much to close again if
it flies on).

Two laws (``follow.law``):

``los``, line of sight.  The ASV steers along a virtual leg from its own
position to an aim point on the AUV's path: with (a, c) the ASV's offset from
the target along and across the path (a > 0 ahead, c > 0 to starboard), the
aim point lies ``lookahead_m`` ahead of the target when the ASV is behind it,
and ``lookahead_m`` ahead of the ASV's projection on the path when it is
ahead::

    aim = path(max(a, 0) + Δ)        path(a): the point a metres along the path

so the ASV converges onto the AUV's track at atan(c/Δ) when alongside, heads
for the AUV itself when far behind, and, on a plan, starts its turn Δ before
the AUV reaches a corner (it cuts the corner as the AUV does).  The ASV is on
its own virtual leg (cross-track 0); the line controller's heading law steers
its course over ground along it.  Speed: the paper's surge law X = F_f(v_AUV)
+ k_v(v_AUV − v) + k_s(s_AUV − s) + k_i∫(s_AUV − s) dt, with the catch-up
moved into the speed reference::

    v_ref = clamp(v_AUV − a / τ_c, v_min, v_max) / max(cos θ, 0.5)

θ the angle between the leg and the direction from the target to the aim
point (the part of the ASV's speed along it is what closes the gap), v_min
enough to steer across a current.  The line controller's speed loop then adds
the feedforward F_f(v_ref) that catching up needs; k_s and k_i (on
``along_error_m``, the lead when the AUV is ahead, 0 when the boat is) only
trim what is left.

``paper``, the paper's law as printed (:mod:`.follow_paper`): the leg is the
AUV's line — through the target along its course, or the plan's leg the path
is on ``lookahead_m`` ahead of the target — tracked by the line controller at
the AUV's speed, the surge force adding ``paper_k_s``·(s_AUV − s) +
``paper_k_i``·∫(s_AUV − s) dt, either sign.

Before the AUV is first heard, with its a-priori plan, the boat goes to the
plan's start (``ABOVE_STATION_M`` ahead of it on the first leg, facing that
leg) and holds there: the AUV waits for its mission at its start, and the
boat is then above it when its first fixes come instead of setting off only
then (tens of metres at under 2 m/s).  A plan whose start is further than
``PLAN_START_MAX_M`` is not gone to (more likely a plan in the wrong place
than a launch that far).  Without a plan the boat waits where it is: the
tracker's prior only resolves mirror fixes, and its default (0, 0) says
nothing of where the AUV is.

When the track is lost (no fix for the configured time, a covariance too
large, or the tracker says so) the boat slows down and holds the position
where it lost it, and resumes following when the track is back.  Above a
still AUV it keeps within ``hold_radius_m`` of the filter's position once the
track has settled, going back there (faster the further it is) when it
drifts off or the AUV starts to move; without a plan it faces the way the
filter has the AUV creeping (``FACE_COURSE_MPS``), which is the way it sets
off when it does, and takes it to move once the boat has held above it and
the filter's speed alone passes 0.5 m/s (:mod:`.follow_motion`: the RLS
line, fitted over seconds of fixes, lags a start), pivoting straight after
it.  A slow AUV (below ``SLOW_AUV_MPS``) further than ``APPROACH_FAR_M``
is gone to the same way, whatever course its track says: at the start a
still AUV's track can creep along a course that is noise, and the
line-of-sight law would have the boat wait "ahead" of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.auv_messages import AuvPlan, AuvTrack, TrackFlags
from zarco_runtime.guidance.follow_motion import AuvMotion
from zarco_runtime.guidance.follow_paper import follow_geometry
from zarco_runtime.guidance.follow_path import (
    PlanPath,
    StraightPath,
    Target,
    plan_target,
    target_now,
)
from zarco_runtime.guidance.follow_settings import FollowSettings
from zarco_runtime.guidance.mission import Leg
from zarco_runtime.tracking.plan import INFERRED_SOURCE, Plan
from zarco_runtime.tracking.plan_geometry import PlanLeg

__all__ = ["FollowGuidance", "FollowSettings", "FollowState", "Target", "target_now"]

#: below this AUV speed (m/s) the course is undefined: hold above it
V_MIN_MPS = 0.05
#: the look-ahead shrinks by the along-track lag down to this fraction of it
MIN_LOOKAHEAD_FRACTION = 0.1
#: a target that jumps further than this (m) is followed at once (re-acquired)
TARGET_RESET_M = 8.0
#: the boat's course over ground is taken over this long (s), above this speed (m/s)
COG_WINDOW_S = 0.5
COG_MIN_MPS = 0.25
#: the virtual leg leads the boat's course over ground by at most this (rad)
MAX_LEAD_RAD = math.radians(90.0)
#: a change of the leg's course larger than this (rad) is a reversal: it turns
#: the way the AUV's path turns (with a plan), not the shorter way
REVERSAL_RAD = math.radians(120.0)
#: a plan's corner turning this much or more (rad) may be turned either way round
AMBIGUOUS_TURN_RAD = math.radians(178.0)
#: on a plan the tracker guessed, the AUV is taken to turn at a corner once the
#: filter's course is this far (deg) off the course before it
TENTATIVE_TURN_DEG = 11.0
#: a guessed plan's target is followed only within this (m, plus 3σ of the
#: filter's position) of the filter's position carried to now
PLAN_GATE_M = 8.0
#: on a plan the tracker guessed, while the track's target is within this
#: (m) before a corner the AUV has not yet been seen to turn, the boat's speed
#: reference drops it back this far (m) behind the target: if the AUV turns,
#: the boat has that much less to overshoot; if it flies on (the survey's
#: end), that much to close again, under 4 m
TRAIL_BEFORE_M = 12.0
TRAIL_M = 2.5
#: a still AUV further than this many position σ (and 1 m) is closed in on
#: before its track has settled
APPROACH_SIGMAS = 4.0
#: the plan's target is followed from this (or 1.2 turning radii, m) and the
#: look-ahead before a corner to this long after it (s of the AUV's progress,
#: at least the same distance), and as long after the plan's start; along its
#: legs, the track's
PLAN_CORNER_ZONE_M = 12.0
PLAN_AFTER_CORNER_S = 20.0
#: … and on, up to this long after it (s of the AUV's progress), while the
#: filter has not settled on the new leg (:func:`_settling`): its course
#: further than ``PLAN_SETTLE_DEG`` off the leg's, its position within
#: ``PLAN_SETTLE_GATE_M`` of the plan's target, and not going further off the
#: leg once more than ``PLAN_SETTLE_CROSS_M`` (m) off it (an AUV leaving its
#: plan)
PLAN_SETTLE_MAX_S = 60.0
PLAN_SETTLE_DEG = 10.0
PLAN_SETTLE_GATE_M = 4.0
PLAN_SETTLE_CROSS_M = 1.5
#: above an AUV waiting on its plan, the boat's station is this far (m) ahead
#: of it on its first leg; there, facing the leg, the boat holds it forward or
#: astern while it stays within these bounds (m: to the side of the leg, behind
#: and ahead of the AUV along it; :meth:`FollowGuidance._above`)
ABOVE_STATION_M = 1.75
ABOVE_SIDE_M = 2.5
ABOVE_BEHIND_M = 2.5
ABOVE_AHEAD_M = 4.0
#: the station is held while the guidance keeps finding the boat there (s
#: between two control ticks at most)
STATION_GAP_S = 0.5
#: holding it, the boat's heading turns up to this far off the course (rad),
#: in full from this far off the station (m), and keeps the station ahead (or
#: astern) until it is this far past abeam (rad)
STATION_TILT_RAD = math.radians(45.0)
STATION_TILT_M = 3.0
STATION_SWAP_RAD = math.radians(20.0)
#: before the AUV is first heard, a plan's start within this (m) of the boat
#: is gone to
PLAN_START_MAX_M = 200.0
#: above a still AUV, its plan's course is kept this long (s) after its track
#: was last on the plan
PLAN_COURSE_HOLD_S = 10.0
#: an AUV slower than this (m/s) further than this (m) is gone to as a still
#: one is, whatever course its track says
SLOW_AUV_MPS = 0.45
APPROACH_FAR_M = 10.0
#: above a still AUV without a plan, the boat faces the filter's course once
#: its speed passes this (m/s).  Facing a course that is noise costs nothing
#: (whatever way the boat faces, the AUV sets off in a direction it does not
#: know), facing the way the AUV sets off saves a pivot
FACE_COURSE_MPS = 0.2
#: for this long (s) after an AUV the boat held above sets off, the virtual
#: leg is not held within MAX_LEAD_RAD of the boat's course over ground
SET_OFF_S = 10.0
#: length of the virtual leg laid past the aim point (m)
LEG_PAST_AIM_M = 100.0
#: the paper law's leg starts this far behind the AUV and ends this far ahead (m)
PAPER_LEG_BEHIND_M = 50.0
PAPER_LEG_AHEAD_M = 200.0


def _low_pass(sm: tuple[float, float, float] | None, tg: Target, t: float, tau_s: float,
              max_gap_s: float = math.inf) -> tuple[tuple[float, float, float], Target]:
    """``tg``'s position low-passed over ``tau_s`` (s) about its own motion from
    the state ``sm`` (t, x, y; None, or older than ``max_gap_s``: start at
    ``tg``); a jump beyond ``TARGET_RESET_M`` is taken at once.  Returns the
    new state and target."""
    if (sm is None or t <= sm[0] or t - sm[0] > max_gap_s
            or math.hypot(tg.x - sm[1], tg.y - sm[2]) > TARGET_RESET_M):
        return (t, tg.x, tg.y), tg
    dt = t - sm[0]
    x = sm[1] + tg.vx * dt
    y = sm[2] + tg.vy * dt
    a = min(1.0, dt / tau_s)
    x += a * (tg.x - x)
    y += a * (tg.y - y)
    return (t, x, y), Target(x, y, tg.vx, tg.vy, tg.source)


@dataclass(slots=True)
class FollowState:
    """What the follow guidance decided at one instant.

    ``d_m``: the ASV's cross-track offset from the AUV's track (m, > 0 to
    starboard); ``along_error_m``: how far the AUV is ahead of the ASV along
    its course (m); ``target``: which estimate was followed (``line``, ``kf``,
    ``plan``); ``k_s`` (N/m), ``k_i`` (N/(m s)): the surge gains on
    ``along_error_m`` of the law in use; ``heading_rad``: without a leg, the
    heading to keep (NaN: the present one) — above an AUV waiting on its plan,
    the course it will leave on; without a plan, the filter's course once it
    has the AUV creeping; ``station``: without a leg, the point (NED, m) the
    boat holds forward or astern along its heading with the surge law of
    station keeping (``[hold]`` gains; None: it drifts).
    """

    mode: str  # "follow", "hold" (track lost), "wait" (no track yet)
    leg: Leg | None
    d_m: float
    along_error_m: float
    speed_ref_mps: float
    reason: str = ""
    target: str = ""
    k_s: float = 0.0
    k_i: float = 0.0
    heading_rad: float = math.nan
    station: tuple[float, float] | None = None


class FollowGuidance:
    """AuvTrack → virtual leg, cross-track and along-track errors, speed reference."""

    def __init__(self, cfg: FollowSettings) -> None:
        self.cfg = cfg
        self.leg_id = 0
        self._psi_leg: float | None = None
        self.hold: tuple[float, float] | None = None
        self.mode = "wait"
        self.target: Target | None = None
        #: whether the AUV is taken to be moving (:mod:`.follow_motion`)
        self.motion = AuvMotion(cfg.still_speed_mps)
        self._psi_ref: float | None = None
        self._t_ref: float | None = None
        self._t_now = 0.0
        self._last_pos: tuple[float, float, float] | None = None
        self._cog: float | None = None
        self._sm: tuple[float, float, float] | None = None
        self._was_above = False
        #: runtime time (s) the boat last held its station above a still AUV
        #: on its plan (None: not holding it)
        self._station_t: float | None = None
        #: … with the station ahead of the boat (else astern)
        self._station_ahead = True
        #: above a still AUV on its plan, its track's target low-passed (t, x, y)
        self._sm_still: tuple[float, float, float] | None = None
        #: the AUV's plan (set_plan) and the target's smoothed (t, s, cross) on it
        self.plan: Plan | None = None
        self._plan_msg: AuvPlan | None = None
        self._sm_plan: tuple[float, float, float] | None = None
        self._plan_leg_id = -1
        #: when (s) the AUV was last followed on its plan, and the plan's course there
        self._plan_course: tuple[float, float] | None = None
        #: how far (m) the boat drops back behind the target before a guessed
        #: corner (``TRAIL_M``, set by :meth:`_on_plan`), else 0
        self._trail_m = 0.0

    @property
    def moving(self) -> bool:
        """Whether the AUV is taken to be moving (:class:`.follow_motion.AuvMotion`)."""
        return self.motion.moving

    def _lost_reason(self, track: AuvTrack | None, t: float) -> str:
        if track is None:
            return "no AUV track yet"
        if track.lost:
            return "tracker declared the track lost"
        age = track.fix_age_s + (t - track.t)
        if age > self.cfg.lost_after_s:
            return f"no AUV fix for {age:.0f} s"
        if track.kf_pos_sigma_m > self.cfg.max_pos_sigma_m:
            return f"AUV position σ {track.kf_pos_sigma_m:.1f} m"
        if not (math.isfinite(track.kf_vx_mps) and math.isfinite(track.kf_vy_mps)
                and math.isfinite(track.kf_x_m) and math.isfinite(track.kf_y_m)):
            return "AUV state not estimated"
        return ""

    def update(self, track: AuvTrack | None, t: float, x: float, y: float) -> FollowState:
        """Guidance at runtime time ``t`` for the ASV at (x, y) (NED, m)."""
        cfg = self.cfg
        self._t_now = t
        self._track_cog(t, x, y)
        reason = self._lost_reason(track, t)
        if reason or track is None:
            self.target = None
            self.motion.track_lost()
            if track is None:
                start = self._to_plan_start(t, x, y)
                if start is not None:
                    return start
            return self._hold(x, y, reason or "no AUV track yet")
        raw = target_now(track, t, cfg.line_gate_m, math.radians(cfg.line_course_gate_deg))
        tg = raw
        on_plan = self._on_plan(track, t)
        path: StraightPath | PlanPath
        if on_plan is not None:
            tg, path = on_plan
            self._plan_course = (t, path.course_at(0.0))
        else:
            tg = self._smooth(tg, t)
            path = StraightPath(tg)
        self.target = tg
        v = math.hypot(tg.vx, tg.vy)
        self.motion.update(track, t, v if on_plan is not None else None)
        # a slow AUV far off (at the start, its track's course mostly noise): go to
        # it, not "ahead" of it on that course to wait for it
        gap = math.hypot(tg.x - x, tg.y - y)  # the boat's distance to the target (m)
        approach = on_plan is None and v < SLOW_AUV_MPS and gap > APPROACH_FAR_M
        if not (self.moving and v >= V_MIN_MPS) or approach:
            if on_plan is not None:
                # above a still AUV, where its track has it, not its plan's
                # target: the tracker's progress along the plan and its speed
                # there are noise of a hovering AUV (metres ahead of it)
                self._sm_still, tg = _low_pass(self._sm_still, raw, t, cfg.target_tau_s,
                                               max_gap_s=1.0)
                self.target = tg
            # AUV still: keep above it once its track has settled (going to where
            # the filter has it, so a start is followed before it is declared),
            # else hold where we are
            # (the filter alone: a start restarts the line, which is not a reason
            # to stop going where the AUV is)
            # Far from it, a track still settling is good enough to close in on:
            # metres of uncertainty do not matter tens of metres away
            sigma = track.kf_pos_sigma_m
            far = gap >= APPROACH_SIGMAS * max(sigma, 1.0)
            # Once above it, an AUV starting off (its filter's σ grows while the
            # track restarts) is gone after at once, not waited for
            settled = bool(track.flags & TrackFlags.INITIALISED) and (
                (sigma <= cfg.hold_above_sigma_m
                 and (self._was_above or bool(track.flags & TrackFlags.LINE_VALID)))
                or ((far or self._was_above) and sigma <= cfg.max_pos_sigma_m))
            if not settled:
                return self._hold(x, y, "AUV (nearly) still, track settling")
            # on its plan, the course it will leave on — also for a moment after
            # the tracker's match of a hovering AUV to its plan flickers off
            pc = self._plan_course
            course = (path.course_at(0.0) if on_plan is not None
                      else pc[1] if self.plan is not None and pc is not None
                      and t - pc[0] <= PLAN_COURSE_HOLD_S else math.nan)
            # without it, the filter's course once its speed passes
            # FACE_COURSE_MPS: the AUV may be setting off that way, and a boat
            # facing it sets off after it without a pivot (to face only: on a
            # course that may be noise, the boat does not wait ahead of it)
            face = (math.atan2(track.kf_vy_mps, track.kf_vx_mps)
                    if math.hypot(track.kf_vx_mps, track.kf_vy_mps) >= FACE_COURSE_MPS
                    else math.nan)
            return self._above(tg, t, x, y, course,
                               "closing in on a slow AUV" if self.moving else "", face)
        self.hold = None
        self.mode = "follow"
        if cfg.law == "paper":
            return self._paper(tg, path, x, y)
        return self._los(tg, path, t, x, y)

    def _los(self, tg: Target, path: StraightPath | PlanPath, t: float, x: float,
             y: float) -> FollowState:
        """The line-of-sight law (module docstring)."""
        cfg = self.cfg
        v = math.hypot(tg.vx, tg.vy)
        a, c = path.locate(x, y)  # a > 0: the ASV is ahead; c > 0: to starboard
        # far behind, aim nearer the AUV itself: its course (the noisiest part of
        # the estimate) then swings the aim less
        look = max(cfg.lookahead_m - max(-a, 0.0), MIN_LOOKAHEAD_FRACTION * cfg.lookahead_m)
        ahead = max(a, 0.0) + look
        ax, ay = path.point(ahead)
        # just after the AUV set off from under the boat, the boat's course over
        # ground is its drift and its first surge before it has pivoted: no lead
        psi = self._steer(math.atan2(ay - y, ax - x), t,
                          lead_cog=t - self.motion.set_off_t > SET_OFF_S,
                          turn_sign=_path_turn_sign(path, ahead))
        self._new_leg(psi)
        if isinstance(path, PlanPath):
            # be at the aim point when the AUV is: its straight distance from the
            # boat over the time the AUV takes along its path to get there (a
            # chord across a turn is shorter than the AUV's arc)
            v_ref = v * math.hypot(ax - x, ay - y) / ahead
            v_ref = max(cfg.min_speed_mps, min(cfg.max_speed_mps, v_ref))
        else:
            theta = math.remainder(psi - math.atan2(ay - tg.y, ax - tg.x), math.tau)
            v_ref = max(cfg.min_speed_mps, min(cfg.max_speed_mps,
                                               v - (a + self._trail_m) / cfg.catchup_tau_s))
            v_ref = min(cfg.max_speed_mps, v_ref / max(math.cos(theta), 0.5))
        dist = math.hypot(tg.x - x, tg.y - y)
        if a <= 0.5 * dist:
            # far off and not mostly ahead (a slow AUV's course, the sign of a,
            # is mostly noise): close in on it whatever its course says
            v_ref = max(v_ref, min(cfg.max_speed_mps, (dist - cfg.lookahead_m)
                                   / cfg.catchup_tau_s))
        cp, sp = math.cos(psi), math.sin(psi)
        # from the ASV towards the aim point (along the rate-limited course), and on
        reach = math.hypot(ax - x, ay - y) + LEG_PAST_AIM_M
        leg = Leg(self.leg_id, x, y, x + reach * cp, y + reach * sp, v_ref)
        # the along-track trim only pushes forward: ahead of the AUV the speed
        # reference slows the boat, and a reverse thrust would drive it the wrong
        # way while it still faces away from the AUV's course
        return FollowState("follow", leg, c, max(-a - self._trail_m, 0.0), v_ref, "",
                           tg.source, cfg.k_s, cfg.k_i)

    def _paper(self, tg: Target, path: StraightPath | PlanPath, x: float,
               y: float) -> FollowState:
        """The paper's law (module docstring): the AUV's line — its plan's leg
        ``lookahead_m`` ahead of it on a plan — at the AUV's speed."""
        cfg = self.cfg
        v = math.hypot(tg.vx, tg.vy)
        lx, ly, course, ident = path.line(cfg.lookahead_m)
        cp, sp = math.cos(course), math.sin(course)
        g = follow_geometry(lx, ly, v * cp, v * sp, x, y, 0.0)
        if g is None:  # not reached: the caller holds above a still AUV
            return FollowState("follow", None, 0.0, 0.0, 0.0, "AUV (nearly) still", tg.source)
        if ident >= 0:  # a plan leg: a new leg exactly when the plan's leg changes
            if ident != self._plan_leg_id:
                self._plan_leg_id = ident
                self.leg_id += 1
                self._psi_leg = course
        else:
            self._plan_leg_id = -1
            self._new_leg(course)
        leg = Leg(self.leg_id, lx - PAPER_LEG_BEHIND_M * cp, ly - PAPER_LEG_BEHIND_M * sp,
                  lx + PAPER_LEG_AHEAD_M * cp, ly + PAPER_LEG_AHEAD_M * sp, v)
        return FollowState("follow", leg, g.d_m, g.along_error_m, v, "", tg.source,
                           cfg.paper_k_s, cfg.paper_k_i)

    def _new_leg(self, psi: float) -> None:
        """A new virtual leg (the line controller resets its cross-track states)
        when the course ``psi`` (rad) moved more than ``new_line_deg`` from the
        leg's."""
        if (self._psi_leg is None
                or abs(math.remainder(psi - self._psi_leg, math.tau))
                > math.radians(self.cfg.new_line_deg)):
            self.leg_id += 1
            self._psi_leg = psi

    # ------------------------------------------------------------ the plan

    def set_plan(self, msg: AuvPlan | None) -> None:
        """The AUV's plan (:class:`AuvPlan`; None or empty: none); the tracker's
        ``plan_leg`` says when the AUV is on it.  A message already taken is
        ignored."""
        if msg is self._plan_msg:
            return
        self._plan_msg = msg
        self._sm_plan = None
        self._plan_course = None
        self.plan = None
        if msg is not None and msg.points:
            try:
                self.plan = Plan(msg.points)
            except ValueError:  # the tracker refused it too and says so
                self.plan = None

    def _on_plan(self, track: AuvTrack, t: float) -> tuple[Target, PlanPath] | None:
        """The target carried along the plan, its position low-passed over
        ``target_tau_s`` along the path (path coordinate and offset); None
        without a plan, with the AUV off it, or a track older than the plan.
        Only about a corner — from ``PLAN_CORNER_ZONE_M`` (or 1.2 turning radii)
        and the look-ahead before it to ``PLAN_AFTER_CORNER_S`` of the AUV's
        progress after it, or on while the filter has yet to settle on the new
        leg (:func:`_settling`, up to ``PLAN_SETTLE_MAX_S``) — and after the
        plan's start: there the plan's target turns with the AUV where the
        filter's lags, and is on the next line while the filter settles on it;
        along a leg the track alone is as good, and follows at once an AUV that
        turns off its plan mid-leg, before the tracker has made sure it left.
        Within ``TRAIL_BEFORE_M`` before a guessed corner that the AUV has not
        yet turned: None, with :attr:`_trail_m` set to ``TRAIL_M`` (the boat
        drops back that far)."""
        self._trail_m = 0.0
        plan, msg = self.plan, self._plan_msg
        if plan is None or msg is None or track.t < msg.t or track.plan_leg < 0:
            self._sm_plan = None
            return None
        got = plan_target(track, plan, t)
        if got is None:
            self._sm_plan = None
            return None
        tg, path = got
        # the progress along a guessed plan is carried forward on its own: where
        # it has run away from the filter (an AUV that left the plan, not yet
        # noticed), the filter is followed.  (On a plan given, the filter is
        # as often the one off: a survey error, two beacons.)
        dt = t - track.t0
        kf_now = (track.kf_x_m + track.kf_vx_mps * dt, track.kf_y_m + track.kf_vy_mps * dt)
        sigma = track.kf_pos_sigma_m if math.isfinite(track.kf_pos_sigma_m) else 0.0
        if (msg.source == INFERRED_SOURCE
                and math.dist((tg.x, tg.y), kf_now) > PLAN_GATE_M + 3.0 * sigma):
            self._sm_plan = None
            return None
        zone = max(PLAN_CORNER_ZONE_M, 1.2 * path.radius)
        leg = plan.leg_at(path.s)
        since = path.s - leg.s0_m  # since the last corner, or the plan's start
        to = leg.s0_m + leg.length_m - path.s if leg.index + 1 < len(plan.legs) else math.inf
        v = math.hypot(tg.vx, tg.vy)
        after = since <= max(zone, v * PLAN_AFTER_CORNER_S) or (
            since <= v * PLAN_SETTLE_MAX_S and (_settling(track, kf_now, tg, path, leg)
                                                or _rounding(plan, leg, path, tg, kf_now)))
        if to > zone + self.cfg.lookahead_m and not after:
            self._sm_plan = None
            return None
        if msg.source == INFERRED_SOURCE:
            # a guessed corner is taken once the AUV turns there: the filter's
            # course off the course before the corner by TENTATIVE_TURN_DEG
            before = plan.legs[leg.index - 1] if after and leg.index > 0 else leg
            kc = math.atan2(track.kf_vy_mps, track.kf_vx_mps)
            if abs(math.remainder(kc - before.course_rad, math.tau)) < math.radians(
                    TENTATIVE_TURN_DEG):
                self._sm_plan = None
                if not after and to <= TRAIL_BEFORE_M:
                    # it may turn there or fly on: hedge, a little behind it
                    self._trail_m = TRAIL_M
                return None
        r = path.radius
        sm = self._sm_plan
        if sm is None and self._sm is not None and t - self._sm[0] <= 1.0:
            # on the plan from plan-free following: start from where the boat was aiming
            s0, c0 = plan.nearest(self._sm[1], self._sm[2], path.s - TARGET_RESET_M,
                                  path.s + TARGET_RESET_M, r)
            sm = (self._sm[0], s0, c0)
        if sm is not None and t > sm[0]:
            s_pred = plan.advance(sm[1], v * (t - sm[0]), r)
            if abs(path.s - s_pred) <= TARGET_RESET_M:
                k = min(1.0, (t - sm[0]) / self.cfg.target_tau_s)
                s = s_pred + k * (path.s - s_pred)
                cross = sm[2] + k * (path.cross - sm[2])
                x, y, course = plan.point_at(s, cross, r)
                tg = Target(x, y, v * math.cos(course), v * math.sin(course), "plan")
                path = PlanPath(plan, s, cross, r)
        self._sm_plan = (t, path.s, path.cross)
        self._sm = (t, tg.x, tg.y)  # plan-free following continues from here
        return tg, path

    def _to_plan_start(self, t: float, x: float, y: float) -> FollowState | None:
        """Before the AUV is first heard: go to its plan's start and hold there
        (module docstring), the station ``ABOVE_STATION_M`` ahead on the first
        leg, facing it; None without a (given) plan, or with its start further
        than ``PLAN_START_MAX_M``."""
        plan, msg = self.plan, self._plan_msg
        if plan is None or msg is None or msg.source == INFERRED_SOURCE:
            return None
        sx, sy, course = plan.point_at(0.0)
        gx, gy = _station_ahead(sx, sy, course)
        dx, dy = gx - x, gy - y
        dist = math.hypot(dx, dy)
        if dist > PLAN_START_MAX_M:
            return None
        self.mode = "wait"
        why = "going to the AUV plan's start"
        if dist <= self.cfg.hold_radius_m:
            self._psi_ref = None
            return FollowState("wait", None, 0.0, 0.0, 0.0, why, "plan",
                               heading_rad=self._station_heading(course, dx, dy),
                               station=(gx, gy))
        v_ref = self._closing_speed(dist)
        return FollowState("wait", self._leg_to(gx, gy, t, x, y, v_ref), 0.0, 0.0, v_ref,
                           why, "plan")

    def _smooth(self, tg: Target, t: float) -> Target:
        """The target's position low-passed over ``target_tau_s`` about its own
        motion (no lag at constant velocity): a new fix moves it smoothly, not
        in a step the boat would steer at.  A jump beyond ``TARGET_RESET_M``
        (re-acquisition) is taken at once."""
        self._sm, tg = _low_pass(self._sm, tg, t, self.cfg.target_tau_s)
        return tg

    def _above(self, tg: Target, t: float, x: float, y: float,
               course: float = math.nan, reason: str = "",
               face: float = math.nan) -> FollowState:
        """Keep above a still AUV: drift within ``hold_radius_m`` of the filter's
        position, else go there at the speed the AUV moves away (its
        estimate's, while it is not yet taken to move) plus the gap over
        ``catchup_tau_s``.  With ``course`` (rad: on its plan, the AUV will
        leave along it) the boat's station is ``ABOVE_STATION_M`` ahead of the
        AUV on that course: once within ``hold_radius_m`` of it the boat faces
        the course and holds the station forward or astern (a drift along the
        course is not a pivot and a run back), until it is further than
        ``ABOVE_SIDE_M`` to the side of the course or outside
        ``ABOVE_BEHIND_M`` behind to ``ABOVE_AHEAD_M`` ahead of the AUV; it
        then goes back to the station.  ``reason``: what the state says when
        the AUV is not still (a slow AUV far off); ``face``: without
        ``course``, the heading (rad) to keep above it (NaN: the present
        one)."""
        cfg = self.cfg
        self._was_above = True
        self.hold = None
        self.mode = "follow"
        gx, gy = tg.x, tg.y
        if math.isfinite(course):
            cc, sc = math.cos(course), math.sin(course)
            dx, dy = tg.x - x, tg.y - y
            lead, side = -(dx * cc + dy * sc), -dx * sc + dy * cc
            gx, gy = _station_ahead(tg.x, tg.y, course)
            held = self._station_t is not None and 0.0 <= t - self._station_t <= STATION_GAP_S
            if (math.hypot(gx - x, gy - y) <= cfg.hold_radius_m
                    or (held and -ABOVE_BEHIND_M <= lead <= ABOVE_AHEAD_M
                        and abs(side) <= ABOVE_SIDE_M)):
                self._station_t = t
                self.motion.hovered_above()
                self._psi_ref = None
                return FollowState("follow", None, 0.0, -lead, 0.0, "above a still AUV",
                                   tg.source, heading_rad=self._station_heading(
                                       course, gx - x, gy - y), station=(gx, gy))
        self._station_t = None
        dx, dy = gx - x, gy - y
        dist = math.hypot(dx, dy)
        if dist <= cfg.hold_radius_m:
            self.motion.hovered_above()
            self._psi_ref = None
            return FollowState("follow", None, 0.0, 0.0, 0.0, "above a still AUV", tg.source,
                               heading_rad=face)
        v_ref = self._closing_speed(dist, max(0.0, (tg.vx * dx + tg.vy * dy) / dist))
        return FollowState("follow", self._leg_to(gx, gy, t, x, y, v_ref), 0.0, 0.0, v_ref,
                           reason or "above a still AUV", tg.source)

    def _closing_speed(self, dist: float, away: float = 0.0) -> float:
        """The speed (m/s) to go to a point ``dist`` metres off that moves away
        at ``away`` m/s: that speed plus the gap over ``catchup_tau_s``, between
        ``hold_speed_mps`` and ``max_speed_mps``."""
        cfg = self.cfg
        return min(cfg.max_speed_mps, max(cfg.hold_speed_mps, away + dist / cfg.catchup_tau_s))

    def _leg_to(self, gx: float, gy: float, t: float, x: float, y: float,
                v_ref: float) -> Leg:
        """A virtual leg from the boat at (``x``, ``y``) to (``gx``, ``gy``) (NED
        m) at ``v_ref`` (m/s): its course rate-limited, not held near the boat's
        course over ground (:meth:`_steer`), a new leg when it moved further than
        ``new_line_deg``."""
        dist = math.hypot(gx - x, gy - y)
        psi = self._steer(math.atan2(gy - y, gx - x), t, lead_cog=False)
        self._new_leg(psi)
        c, s = math.cos(psi), math.sin(psi)
        return Leg(self.leg_id, x, y, x + dist * c, y + dist * s, v_ref)

    def _station_heading(self, course: float, ex: float, ey: float) -> float:
        """The heading (rad) to hold a station (``ex``, ``ey``: NED m from the
        boat) with the course ``course`` (rad) it will leave on: the course,
        turned up to ``STATION_TILT_RAD`` (in full from ``STATION_TILT_M`` off)
        to bring the station ahead or astern — the surge law then closes a
        sideways offset too (the hull cannot be pushed sideways).  Ahead or
        astern is kept until the station is ``STATION_SWAP_RAD`` past abeam."""
        d = math.hypot(ex, ey)
        if d < 1e-6:
            return course
        off = math.remainder(math.atan2(ey, ex) - course, math.tau)
        edge = 0.5 * math.pi + (STATION_SWAP_RAD if self._station_ahead else -STATION_SWAP_RAD)
        self._station_ahead = abs(off) <= edge
        if not self._station_ahead:
            off = math.remainder(off + math.pi, math.tau)  # the stern towards it
        tilt = max(-STATION_TILT_RAD, min(STATION_TILT_RAD, off)) * min(1.0, d / STATION_TILT_M)
        return course + tilt

    def _track_cog(self, t: float, x: float, y: float) -> None:
        """The boat's course over ground (rad) from its positions at least
        ``COG_WINDOW_S`` apart; None while it moves slower than ``COG_MIN_MPS``."""
        if self._last_pos is None or t < self._last_pos[0]:
            self._last_pos = (t, x, y)
            return
        t0, x0, y0 = self._last_pos
        if t - t0 < COG_WINDOW_S:
            return
        dx, dy = x - x0, y - y0
        self._cog = (math.atan2(dy, dx) if math.hypot(dx, dy) >= COG_MIN_MPS * (t - t0)
                     else None)
        self._last_pos = (t, x, y)

    def _steer(self, psi: float, t: float, lead_cog: bool = True,
               turn_sign: float = 0.0) -> float:
        """The virtual leg's course towards ``psi`` (rad): turning no faster than
        ``max_turn_rate_dps``, and, with ``lead_cog``, never more than
        ``MAX_LEAD_RAD`` off the boat's course over ground while it moves (a
        reversal behind a moving AUV is taken as a turn the boat can follow,
        not as a heading error of 180°).  Going to a still AUV (or a slow one
        far off, :meth:`_above`) the leg points at it whatever the boat's
        course over ground: that course is then a drift (current, backing
        off, a pivot), and holding the leg within 90° of it sent the boat
        round the long way (a full turn before it set off).  ``turn_sign``
        (+1 starboard, −1 port, 0 unknown): the way the AUV's plan turns back
        here; a change of more than ``REVERSAL_RAD`` the other way is turned
        this way round (a few metres of offset at a reversal make the other
        way the shorter, and take the boat away from the AUV's turn)."""
        ref = self._psi_ref
        if ref is not None and self._t_ref is not None and t > self._t_ref:
            step = math.radians(self.cfg.max_turn_rate_dps) * (t - self._t_ref)
            dpsi = math.remainder(psi - ref, math.tau)
            if turn_sign * dpsi < 0.0 and abs(dpsi) > REVERSAL_RAD:
                # a reversal: turn the way the AUV's path turns, not the way a
                # few metres of offset make the shorter
                dpsi += math.copysign(math.tau, turn_sign)
            psi = ref + max(-step, min(step, dpsi))
        if lead_cog and self._cog is not None:
            off = math.remainder(psi - self._cog, math.tau)
            psi = self._cog + max(-MAX_LEAD_RAD, min(MAX_LEAD_RAD, off))
        self._psi_ref, self._t_ref = psi, t
        return psi

    def _hold(self, x: float, y: float, reason: str,
              above: tuple[float, float] | None = None) -> FollowState:
        if above is not None and all(math.isfinite(v) for v in above):
            self.hold = above
        elif self.hold is None and self.mode == "follow":
            self.hold = (x, y)  # the track was lost here
        self.mode = "hold" if self._psi_leg is not None else "wait"
        if self.hold is None:  # nothing to hold to yet: no leg
            self._psi_ref = None
            return FollowState(self.mode, None, 0.0, 0.0, 0.0, reason)
        hx, hy = self.hold
        dist = math.hypot(hx - x, hy - y)
        if dist <= self.cfg.hold_radius_m:
            self._psi_ref = None
            return FollowState(self.mode, None, 0.0, 0.0, 0.0, reason)
        # head back to the hold point along a virtual leg from here
        psi = self._steer(math.atan2(hy - y, hx - x), self._t_now)
        c, s = math.cos(psi), math.sin(psi)
        leg = Leg(-1, x - c, y - s, x + dist * c, y + dist * s, self.cfg.hold_speed_mps)
        return FollowState(self.mode, leg, 0.0, 0.0, self.cfg.hold_speed_mps, reason)


def _station_ahead(x: float, y: float, course: float) -> tuple[float, float]:
    """The station above an AUV at (``x``, ``y``) (NED m) that will leave on
    ``course`` (rad): ``ABOVE_STATION_M`` ahead of it on that course."""
    return x + ABOVE_STATION_M * math.cos(course), y + ABOVE_STATION_M * math.sin(course)


def _settling(track: AuvTrack, kf_now: tuple[float, float], tg: Target, path: PlanPath,
              leg: PlanLeg) -> bool:
    """Whether the filter has yet to settle on ``leg``, the plan's leg the
    target ``tg`` is on (``path``): after a corner, or the start, the filter's
    course takes tens of seconds to come onto the new leg's (swinging up to
    30° about it after a U-turn) while the plan's target is already on it.
    Settling: the filter's course more than ``PLAN_SETTLE_DEG`` off the leg's,
    its position (``kf_now``, NED m, carried to now) within ``PLAN_SETTLE_GATE_M`` of
    the target, and, once more than ``PLAN_SETTLE_CROSS_M`` off the leg (from
    the target's offset), heading back towards it: going further off it is
    an AUV leaving its plan, which the tracker takes seconds to declare."""
    off = math.remainder(math.atan2(track.kf_vy_mps, track.kf_vx_mps) - leg.course_rad,
                         math.tau)
    if abs(off) <= math.radians(PLAN_SETTLE_DEG):
        return False
    if math.dist((tg.x, tg.y), kf_now) > PLAN_SETTLE_GATE_M:
        return False
    c_rel = leg.project(*kf_now)[1] - path.cross  # m, > 0 to starboard of the target
    return abs(c_rel) <= PLAN_SETTLE_CROSS_M or c_rel * math.sin(off) <= 0.0


def _rounding(plan: Plan, leg: PlanLeg, path: PlanPath, tg: Target,
              kf_now: tuple[float, float]) -> bool:
    """Whether the target ``tg`` (on ``path``) is still where the AUV comes
    round the corner before ``leg`` (a reversal's swing and the way back onto
    the line take tens of metres of its guidance: :mod:`~zarco_runtime.tracking.plan_flown`),
    within ``PLAN_SETTLE_GATE_M`` of the filter's position ``kf_now`` (NED, m)."""
    return (leg.index > 0 and path.s < plan.span(leg.index - 1, path.radius)[1]
            and math.dist((tg.x, tg.y), kf_now) <= PLAN_SETTLE_GATE_M)


def _path_turn_sign(path: StraightPath | PlanPath, ahead: float) -> float:
    """+1 (to starboard) or −1 (to port) when the corners of the AUV's plan
    within ``ahead`` metres of the target, before or after it, turn it back
    by more than ``REVERSAL_RAD`` together (a target just past a sharp corner
    has the boat still before it; two 90° corners of a lawnmower make one
    U-turn); 0 without a plan, without such a turn, or with a corner of
    ``AMBIGUOUS_TURN_RAD`` or more (its way round is the AUV's choice)."""
    if not isinstance(path, PlanPath) or ahead <= 0.0:
        return 0.0
    turns = path.turns(ahead)
    if any(abs(w) >= AMBIGUOUS_TURN_RAD for w in turns):
        return 0.0
    total = sum(turns)
    return math.copysign(1.0, total) if abs(total) > REVERSAL_RAD else 0.0
