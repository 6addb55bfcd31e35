"""Follow the AUV (paper VI): guidance from the AUV's estimated track.

The target is the AUV's position now: the tracker's filter position (which
follows a turn within a fix or two) carried forward to now with a velocity
taken from

* the RLS line (vx, vy: the paper's estimate, smooth on straight legs) when it
  is valid, the tracker has not just declared a turn, and the line agrees with
  the filter (position and course);
* otherwise the filter's own velocity, which follows a turn several seconds
  before a new line is fitted.

The ASV steers along a virtual leg from its own position to an aim point on
the AUV's track (line of sight): with (a, c) the ASV's offset from the
target along and across the AUV's course (a > 0 ahead, c > 0 to starboard),
the aim point lies ``lookahead_m`` ahead of the target when the ASV is
behind it, and ``lookahead_m`` ahead of the ASV's projection on the track
when it is ahead::

    aim = p_AUV + (max(a, 0) + Δ) u        u the unit vector of the AUV's course

so the ASV converges onto the AUV's track at atan(c/Δ) when alongside, and
heads for the AUV itself when far behind (through turns, and while a new
line is being fitted).  The ASV is on its own virtual leg (cross-track 0);
the line controller's heading law steers its course over ground along it.

Speed: the paper's surge law X = F_f(v_AUV) + k_v(v_AUV − v) + k_s(s_AUV − s)
+ k_i∫(s_AUV − s) dt, with the catch-up moved into the speed reference::

    v_ref = clamp(v_AUV − a / τ_c, v_min, v_max) / max(cos θ, 0.5)

θ the angle between the leg and the AUV's course (the along-track part of the
ASV's speed is what closes the gap), v_min enough to steer across a current.
The line controller's speed loop then adds the feedforward F_f(v_ref) that
catching up needs; k_s and k_i (on ``along_error_m``, the lead when the AUV is
ahead, 0 when the boat is) only trim what is left.

When the track is lost (no fix for the configured time, a covariance too
large, or the tracker says so) the boat slows down and holds the position
where it lost it, and resumes following when the track is back.  Above a
still AUV it keeps within ``hold_radius_m`` of the filter's position once the
track has settled, going back there (faster the further it is) when it
drifts off or the AUV starts to move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.auv_messages import AuvTrack, TrackFlags
from zarco_core.config import spec
from zarco_runtime.guidance.mission import Leg

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
#: the AUV moves when its line's speed exceeds this many standard deviations
MOVING_SIGMAS = 1.5
#: length of the virtual leg laid past the aim point (m)
LEG_PAST_AIM_M = 100.0


@dataclass(slots=True)
class FollowSettings:
    """``[follow]`` table of the runtime configuration."""

    k_s: float = spec(5.0, "N/m", "surge force per metre the AUV is ahead along its track "
                      "(the speed reference already closes the gap)", min=0.0, max=1e4)
    k_i: float = spec(0.0, "N/(m s)", "integral of the along-track lead (the speed loop's "
                      "integral already removes a steady lag)", min=0.0, max=1e4)
    along_clamp_m: float = spec(8.0, "m", "along-track lead used at most by the surge law",
                                min=0.1, max=1e4)
    min_speed_mps: float = spec(0.3, "m/s", "slowest speed reference while following (ahead "
                                "of the AUV): enough to steer across a current",
                                min=0.0, max=3.0)
    max_speed_mps: float = spec(1.5, "m/s", "fastest speed reference while catching up",
                                min=0.1, max=3.0)
    lookahead_m: float = spec(5.0, "m", "line-of-sight look-ahead Δ: the ASV converges "
                              "onto the AUV's track at atan(offset/Δ)", min=0.5, max=100.0)
    max_turn_rate_dps: float = spec(25.0, "deg/s", "the virtual leg's course turns no "
                                    "faster than this (the estimate's jitter is not "
                                    "steered)", min=1.0, max=360.0)
    catchup_tau_s: float = spec(5.0, "s", "time constant of closing an along-track gap "
                                "(speed reference v_AUV + gap/τ)", min=0.5, max=600.0)
    target_tau_s: float = spec(1.5, "s", "the AUV's position is low-passed over this about "
                               "its velocity (fixes move the aim smoothly)", min=0.01,
                               max=60.0)
    line_gate_m: float = spec(3.0, "m", "the RLS line is used only while its position "
                              "agrees with the Kalman filter's within this plus 3σ",
                              min=0.1, max=1000.0)
    line_course_gate_deg: float = spec(20.0, "deg", "… and while its course agrees with the "
                                       "Kalman filter's within this", min=1.0, max=180.0)
    lost_after_s: float = spec(20.0, "s", "no accepted fix for this long → track lost",
                               min=1.0, max=3600.0)
    max_pos_sigma_m: float = spec(15.0, "m", "track position σ above this → track lost",
                                  min=0.1, max=1e4)
    new_line_deg: float = spec(20.0, "deg", "course change that starts a new virtual leg "
                               "(the line controller resets its cross-track states)",
                               min=1.0, max=180.0)
    hold_radius_m: float = spec(1.5, "m", "while holding, drift freely within this radius",
                                min=0.5, max=1000.0)
    hold_above_sigma_m: float = spec(2.0, "m", "hold above a still AUV only once its "
                                     "position σ is below this", min=0.1, max=100.0)
    still_speed_mps: float = spec(0.3, "m/s", "a still AUV starts moving when its speed "
                                  "exceeds this (and 1.5σ); a moving one stops when its "
                                  "speed plus 2σ is below it", min=0.01, max=2.0)
    hold_speed_mps: float = spec(0.5, "m/s", "speed back to the hold point", min=0.05,
                                 max=2.0)


@dataclass(slots=True)
class FollowState:
    """What the follow guidance decided at one instant.

    ``d_m``: the ASV's cross-track offset from the AUV's track (m, > 0 to
    starboard); ``along_error_m``: how far the AUV is ahead of the ASV along
    its course (m); ``target``: which estimate was followed (``line``, ``kf``).
    """

    mode: str  # "follow", "hold" (track lost), "wait" (no track yet)
    leg: Leg | None
    d_m: float
    along_error_m: float
    speed_ref_mps: float
    reason: str = ""
    target: str = ""


@dataclass(frozen=True, slots=True)
class Target:
    """The AUV now: position (NED m), velocity (m/s), and where it came from."""

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
    the filter (positions within ``line_gate_m`` + 3σ, courses within
    ``line_course_gate_rad``), else with the filter's own velocity."""
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
    if math.hypot(kvx, kvy) > V_MIN_MPS and abs(math.remainder(
            math.atan2(kvy, kvx) - math.atan2(track.vy_mps, track.vx_mps), math.tau)
            ) > line_course_gate_rad:
        return kf
    return Target(track.kf_x_m + track.vx_mps * dt, track.kf_y_m + track.vy_mps * dt,
                  track.vx_mps, track.vy_mps, "line")


class FollowGuidance:
    """AuvTrack → virtual leg, cross-track and along-track errors, speed reference."""

    def __init__(self, cfg: FollowSettings) -> None:
        self.cfg = cfg
        self.leg_id = 0
        self._psi_leg: float | None = None
        self.hold: tuple[float, float] | None = None
        self.mode = "wait"
        self.target: Target | None = None
        #: whether the AUV is taken to be moving (hysteresis, see update)
        self.moving = False
        self._psi_ref: float | None = None
        self._t_ref: float | None = None
        self._t_now = 0.0
        self._last_pos: tuple[float, float, float] | None = None
        self._cog: float | None = None
        self._sm: tuple[float, float, float] | None = None
        self._was_above = False

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
            return self._hold(x, y, reason or "no AUV track yet")
        tg = self._smooth(target_now(track, t, cfg.line_gate_m,
                                     math.radians(cfg.line_course_gate_deg)), t)
        self.target = tg
        v = math.hypot(tg.vx, tg.vy)
        # moving: the line's speed (re-seeded from the filter at every manoeuvre,
        # a start included) above ``still_speed_mps`` and its uncertainty; still
        # again only when the speed is surely small (a turn's uncertainty is
        # not a stop)
        cov = track.cov
        sv = math.sqrt(max(0.5 * (cov[10] + cov[15]), 0.0)) if len(cov) == 16 else 0.0
        v_line = math.hypot(track.vx_mps, track.vy_mps)
        if not self.moving:
            self.moving = v_line >= max(cfg.still_speed_mps, MOVING_SIGMAS * sv)
        elif v_line + 2.0 * sv < cfg.still_speed_mps:
            self.moving = False
        if not (self.moving and v >= V_MIN_MPS):
            # AUV still: keep above it once its track has settled (going to where
            # the filter has it, so a start is followed before it is declared),
            # else hold where we are
            # (the filter alone: a start restarts the line, which is not a reason
            # to stop going where the AUV is)
            settled = (track.kf_pos_sigma_m <= cfg.hold_above_sigma_m
                       and bool(track.flags & TrackFlags.INITIALISED)
                       and (self._was_above or bool(track.flags & TrackFlags.LINE_VALID)))
            if not settled:
                return self._hold(x, y, "AUV (nearly) still, track settling")
            return self._above(tg, t, x, y)
        self.hold = None
        self.mode = "follow"
        ux, uy = tg.vx / v, tg.vy / v
        ex, ey = x - tg.x, y - tg.y
        a = ex * ux + ey * uy  # > 0: the ASV is ahead of the AUV
        c = -ex * uy + ey * ux  # > 0: the ASV is to starboard of its track
        # far behind, aim nearer the AUV itself: its course (the noisiest part of
        # the estimate) then swings the aim less
        look = max(cfg.lookahead_m - max(-a, 0.0), MIN_LOOKAHEAD_FRACTION * cfg.lookahead_m)
        ahead = max(a, 0.0) + look
        ax, ay = tg.x + ahead * ux, tg.y + ahead * uy
        psi = self._steer(math.atan2(ay - y, ax - x), t)
        if (self._psi_leg is None
                or abs(math.remainder(psi - self._psi_leg, math.tau))
                > math.radians(cfg.new_line_deg)):
            self.leg_id += 1
            self._psi_leg = psi
        theta = math.remainder(psi - math.atan2(uy, ux), math.tau)
        v_ref = max(cfg.min_speed_mps, min(cfg.max_speed_mps, v - a / cfg.catchup_tau_s))
        v_ref = min(cfg.max_speed_mps, v_ref / max(math.cos(theta), 0.5))
        cp, sp = math.cos(psi), math.sin(psi)
        # from the ASV towards the aim point (along the rate-limited course), and on
        reach = math.hypot(ax - x, ay - y) + LEG_PAST_AIM_M
        leg = Leg(self.leg_id, x, y, x + reach * cp, y + reach * sp, v_ref)
        # the along-track trim only pushes forward: ahead of the AUV the speed
        # reference slows the boat, and a reverse thrust would drive it the wrong
        # way while it still faces away from the AUV's course
        return FollowState("follow", leg, c, max(-a, 0.0), v_ref, "", tg.source)

    def _smooth(self, tg: Target, t: float) -> Target:
        """The target's position low-passed over ``target_tau_s`` about its own
        motion (no lag at constant velocity): a new fix moves it smoothly, not
        in a step the boat would steer at.  A jump beyond ``TARGET_RESET_M``
        (re-acquisition) is taken at once."""
        sm = self._sm
        if sm is None or t <= sm[0] or math.hypot(tg.x - sm[1], tg.y - sm[2]) > TARGET_RESET_M:
            self._sm = (t, tg.x, tg.y)
            return tg
        dt = t - sm[0]
        x = sm[1] + tg.vx * dt
        y = sm[2] + tg.vy * dt
        a = min(1.0, dt / self.cfg.target_tau_s)
        x += a * (tg.x - x)
        y += a * (tg.y - y)
        self._sm = (t, x, y)
        return Target(x, y, tg.vx, tg.vy, tg.source)

    def _above(self, tg: Target, t: float, x: float, y: float) -> FollowState:
        """Keep above a still AUV: drift within ``hold_radius_m`` of the filter's
        position, else go there (faster the further it is)."""
        cfg = self.cfg
        self._was_above = True
        self.hold = None
        self.mode = "follow"
        dist = math.hypot(tg.x - x, tg.y - y)
        if dist <= cfg.hold_radius_m:
            self._psi_ref = None
            return FollowState("follow", None, 0.0, 0.0, 0.0, "above a still AUV", tg.source)
        psi = self._steer(math.atan2(tg.y - y, tg.x - x), t)
        if self._psi_leg is None or abs(math.remainder(psi - self._psi_leg, math.tau)) > \
                math.radians(cfg.new_line_deg):
            self.leg_id += 1
            self._psi_leg = psi
        v_ref = min(cfg.max_speed_mps, max(cfg.hold_speed_mps, dist / cfg.catchup_tau_s))
        c, s = math.cos(psi), math.sin(psi)
        leg = Leg(self.leg_id, x, y, x + dist * c, y + dist * s, v_ref)
        return FollowState("follow", leg, 0.0, 0.0, v_ref, "above a still AUV", tg.source)

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

    def _steer(self, psi: float, t: float) -> float:
        """The virtual leg's course towards ``psi`` (rad): turning no faster than
        ``max_turn_rate_dps``, and never more than ``MAX_LEAD_RAD`` off the
        boat's course over ground while it moves (a reversal is taken as a
        turn the boat can follow, not as a heading error of 180°)."""
        ref = self._psi_ref
        if ref is not None and self._t_ref is not None and t > self._t_ref:
            step = math.radians(self.cfg.max_turn_rate_dps) * (t - self._t_ref)
            dpsi = math.remainder(psi - ref, math.tau)
            psi = ref + max(-step, min(step, dpsi))
        if self._cog is not None:
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
