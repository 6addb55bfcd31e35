"""Follow the AUV (paper VI, DESIGN.md §5): guidance from the AUV's estimated line.

The AUV's current straight line (x0, y0, vx, vy from the tracker's RLS) is
turned into a virtual leg for the line-tracking controller — the steering law
N_act = k_ψ(ψ_AUV − arctan(k_y d + k_l ∫d) − ψ) − k_r r is exactly the line
law on that leg — plus the along-track term of the surge law:

    X_act = F_f(v_AUV) + k_v (v_AUV − v) + k_s (s_AUV − s) + k_i ∫(s_AUV − s) dt

When the track is lost (no fix for the configured time, a covariance too
large, or the tracker says so) the boat slows down and holds the position
where it lost it, and resumes following when the track is back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.auv_messages import AuvTrack, TrackFlags
from zarco_core.config import spec
from zarco_runtime.guidance.mission import Leg
from zarco_runtime.tracking.follow import follow_geometry

#: half-length of the virtual leg laid along the AUV's line (m)
VIRTUAL_HALF_LENGTH_M = 10_000.0


@dataclass(slots=True)
class FollowSettings:
    """``[follow]`` table of the runtime configuration."""

    k_s: float = spec(20.0, "N/m", "surge force per metre the AUV is ahead along its line",
                      min=0.0, max=1e4)
    k_i: float = spec(1.0, "N/(m s)", "integral of the along-track lead", min=0.0, max=1e4)
    along_clamp_m: float = spec(8.0, "m", "along-track lead used at most by the surge law",
                                min=0.1, max=1e4)
    max_speed_mps: float = spec(1.5, "m/s", "fastest speed reference while catching up",
                                min=0.1, max=3.0)
    lost_after_s: float = spec(20.0, "s", "no accepted fix for this long → track lost",
                               min=1.0, max=3600.0)
    max_pos_sigma_m: float = spec(15.0, "m", "track position σ above this → track lost",
                                  min=0.1, max=1e4)
    new_line_deg: float = spec(20.0, "deg", "course change that starts a new virtual leg "
                               "(resets the cross-track integral)", min=1.0, max=180.0)
    hold_radius_m: float = spec(1.5, "m", "while holding, drift freely within this radius",
                                min=0.5, max=1000.0)
    hold_above_sigma_m: float = spec(2.0, "m", "hold above a still AUV only once its "
                                     "position σ is below this", min=0.1, max=100.0)
    hold_speed_mps: float = spec(0.5, "m/s", "speed back to the hold point", min=0.05,
                                 max=2.0)


@dataclass(slots=True)
class FollowState:
    """What the follow guidance decided at one instant."""

    mode: str  # "follow", "hold" (track lost), "wait" (no track yet)
    leg: Leg | None
    d_m: float
    along_error_m: float
    speed_ref_mps: float
    reason: str = ""


class FollowGuidance:
    """AuvTrack → virtual leg, cross-track and along-track errors."""

    def __init__(self, cfg: FollowSettings) -> None:
        self.cfg = cfg
        self.leg_id = 0
        self._psi_leg: float | None = None
        self.hold: tuple[float, float] | None = None
        self.mode = "wait"

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
        if not (math.isfinite(track.vx_mps) and math.isfinite(track.vy_mps)):
            return "AUV line not estimated"
        return ""

    def update(self, track: AuvTrack | None, t: float, x: float, y: float) -> FollowState:
        """Guidance at runtime time ``t`` for the ASV at (x, y) (NED, m)."""
        reason = self._lost_reason(track, t)
        geo = None
        if not reason and track is not None:
            geo = follow_geometry(track.x0_m, track.y0_m, track.vx_mps, track.vy_mps, x, y,
                                  t - track.t0)
            if geo is None:
                reason = ""
        if reason or geo is None or track is None:
            # AUV still but tracked: hold above it; track lost: hold where we are
            settled = (track is not None and geo is None and not reason
                       and track.kf_pos_sigma_m <= self.cfg.hold_above_sigma_m
                       and bool(track.flags & TrackFlags.LINE_VALID))
            above = (track.kf_x_m, track.kf_y_m) if settled and track is not None else None
            return self._hold(x, y, reason or "AUV (nearly) still", above)
        self.hold = None
        self.mode = "follow"
        psi = geo.psi_auv_rad
        if (self._psi_leg is None
                or abs(math.remainder(psi - self._psi_leg, math.tau))
                > math.radians(self.cfg.new_line_deg)):
            self.leg_id += 1
            self._psi_leg = psi
        c, s = math.cos(psi), math.sin(psi)
        # the AUV's position now, on its line
        ax = track.x0_m + track.vx_mps * (t - track.t0)
        ay = track.y0_m + track.vy_mps * (t - track.t0)
        half = VIRTUAL_HALF_LENGTH_M
        leg = Leg(self.leg_id, ax - half * c, ay - half * s, ax + half * c, ay + half * s,
                  geo.v_auv_mps)
        lead = geo.along_error_m
        return FollowState("follow", leg, geo.d_m, lead,
                           min(self.cfg.max_speed_mps, geo.v_auv_mps))

    def _hold(self, x: float, y: float, reason: str,
              above: tuple[float, float] | None = None) -> FollowState:
        if above is not None and all(math.isfinite(v) for v in above):
            self.hold = above
        elif self.hold is None:
            self.hold = (x, y)
        self.mode = "hold" if self._psi_leg is not None else "wait"
        hx, hy = self.hold
        dist = math.hypot(hx - x, hy - y)
        if dist <= self.cfg.hold_radius_m:
            return FollowState(self.mode, None, 0.0, 0.0, 0.0, reason)
        # head back to the hold point along a virtual leg from here
        psi = math.atan2(hy - y, hx - x)
        c, s = math.cos(psi), math.sin(psi)
        leg = Leg(-1, x - c, y - s, hx, hy, self.cfg.hold_speed_mps)
        return FollowState(self.mode, leg, 0.0, 0.0, self.cfg.hold_speed_mps, reason)
