"""Whether the followed AUV moves, and when it sets off from under the boat.

The follow guidance holds above a still AUV and follows a moving one; this
decides which, with hysteresis, from the AUV's track:

* on its a-priori plan, the tracker's speed along the plan: moving above
  ``still_speed_mps`` (a still AUV waiting at its plan's start is seen moving
  off along its first leg within a fix or two) with the filter's speed above
  ``PLAN_KF_MOVING_MPS`` (a hovering AUV's speed along its plan flickers to
  0.3–0.5 m/s for seconds while its filter's stays below 0.2 m/s: the boat
  ran metres along the plan after a target that was not moving), still again
  below half of ``still_speed_mps``;
* otherwise the RLS line's speed (re-seeded from the filter at every
  manoeuvre, a start included) above ``still_speed_mps`` and
  ``MOVING_SIGMAS`` of its uncertainty; or, once the boat has held above the
  AUV (:meth:`AuvMotion.hovered_above`), the filter's speed alone above
  ``KF_MOVING_MPS`` — the line, fitted over seconds of fixes, lags an AUV
  setting off, and the first velocities of a new track are noise, so the
  filter alone is trusted only for a start from under the boat.  Still again
  only when both speeds are surely small (a turn's uncertainty is not a
  stop).

A track just acquired (or acquired again after a loss while the AUV was
taken to be still: one taken to move keeps moving through a loss) is not
taken to move for ``FRESH_S``, unless its filter has gone ``FRESH_ESCAPE_M`` from where it
was first seen: its first fixes come while the self-calibration (sound speed,
range biases) settles and while the boat, closing in, changes the geometry
that maps those errors into position, and they drift by metres over tens of
seconds — a still AUV seen going at 0.4–1 m/s, its line's σ (white fix
errors) far too small to tell.  Meanwhile the boat goes to the filter's
position at the speed it draws away (the guidance's "above" case), which
also follows an AUV that was moving when acquired.

The moment an AUV the boat held above is taken to move is :attr:`set_off_t`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.auv_messages import AuvTrack

#: the AUV moves when its line's speed exceeds this many standard deviations
MOVING_SIGMAS = 3.0
#: the filter alone takes the AUV to be moving above this speed (m/s), once the
#: boat has held above it
KF_MOVING_MPS = 0.5
#: on its plan, an AUV is taken to move only once its filter's speed is above
#: this too (m/s)
PLAN_KF_MOVING_MPS = 0.2
#: for this long (s) after the track is first seen (or seen again after a
#: loss) a still AUV is not taken to move, unless its filter has gone this
#: far (m) from where it was first seen
FRESH_S = 30.0
FRESH_ESCAPE_M = 12.0


@dataclass(slots=True)
class AuvMotion:
    """Moving or still, with hysteresis (module docstring).  ``still_speed_mps``
    (m/s): ``follow.still_speed_mps``."""

    still_speed_mps: float
    #: whether the AUV is taken to be moving
    moving: bool = False
    #: the boat has drifted within the hold radius above a still AUV since the
    #: AUV was last taken to move
    hovered: bool = False
    #: runtime time (s) an AUV the boat held above was last taken to set off
    set_off_t: float = -math.inf
    #: runtime time (s) and filter position (NED m) the track was first seen
    #: since the last loss (NaN: not yet)
    seen: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    def hovered_above(self) -> None:
        """The boat holds above a still AUV (within the hold radius)."""
        self.hovered = True

    def track_lost(self) -> None:
        """The track is lost: the one that comes back starts with velocities
        that are noise, not a set-off from under the boat."""
        self.hovered = False
        self.seen = (math.nan, math.nan, math.nan)

    def update(self, track: AuvTrack, t: float, plan_speed_mps: float | None) -> bool:
        """Moving at runtime time ``t`` (s)?  ``plan_speed_mps``: the AUV's
        speed along its plan (m/s) while the tracker has it on the plan, else
        None."""
        still = self.still_speed_mps
        if not math.isfinite(self.seen[0]):
            self.seen = (t, track.kf_x_m, track.kf_y_m)
        t0, x0, y0 = self.seen
        if (not self.moving and t - t0 < FRESH_S
                and math.hypot(track.kf_x_m - x0, track.kf_y_m - y0) < FRESH_ESCAPE_M):
            return False
        v_kf = math.hypot(track.kf_vx_mps, track.kf_vy_mps)
        if plan_speed_mps is not None:
            if self.moving:
                self.moving = plan_speed_mps >= 0.5 * still
            else:
                self.moving = plan_speed_mps >= still and v_kf >= PLAN_KF_MOVING_MPS
            return self.moving
        cov = track.cov
        sv = math.sqrt(max(0.5 * (cov[10] + cov[15]), 0.0)) if len(cov) == 16 else 0.0
        v_line = math.hypot(track.vx_mps, track.vy_mps)
        if not self.moving:
            self.moving = (v_line >= max(still, MOVING_SIGMAS * sv)
                           or (self.hovered and v_kf >= max(still, KF_MOVING_MPS)))
            if self.moving and self.hovered:
                self.hovered = False
                self.set_off_t = t
        elif v_line + 2.0 * sv < still and v_kf < still:
            self.moving = False
        return self.moving
