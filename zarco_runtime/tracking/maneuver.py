"""Manoeuvre detection: when the AUV leaves its straight line.

Three detectors feed one decision, :meth:`ManeuverDetector.declare`, which
opens up the filter's covariance (``turn_pos_sigma_m``, ``turn_vel_sigma_mps``:
it follows the new course faster) and, optionally, marks the RLS line for a
restart from the filter:

* the IMM (:meth:`ManeuverDetector.imm_state`): the probability that the AUV
  is not flying straight rising to ``maneuver_on`` declares a turn — the line
  restarts from the filter at every update until it falls to
  ``maneuver_off``, and once more then;
* a two-sided CUSUM on the fixes' normalised cross-course innovation
  (:meth:`ManeuverDetector.lateral`, :meth:`ManeuverDetector.cusum`): a turn
  pushes the fixes steadily to one side of the predicted course, outliers fall
  on either side;
* the RLS line's own residual CUSUM (in :class:`~zarco_runtime.tracking.rls.LineRls`),
  which the tracker passes on to :meth:`ManeuverDetector.declare`.

Any other source that knows the AUV turns — an a-priori plan saying where its
legs turn and to which course — declares the turn the same way, through
:meth:`ManeuverDetector.declare`.

``turn_utc``: UTC (s) of the last line restart (the TURNING flag holds
``turning_flag_s`` after it).
"""

from __future__ import annotations

import math

from zarco_runtime.tracking.imm import Imm
from zarco_runtime.tracking.kalman import CvKalman
from zarco_runtime.tracking.params import TrackerParams

#: the quiet model's turn rate is averaged over this long (s) to tell an arc
ARC_TAU_S = 10.0
#: 1σ (deg/s) of the quiet model's turn rate once a sharp turn is over
QUIET_RATE_SIGMA_DPS = 0.5


class ManeuverDetector:
    """The CUSUM's state, the IMM's manoeuvre state and the pending line restart."""

    __slots__ = ("arc_rate", "arc_t", "arcing", "cusum_neg", "cusum_pos", "line_restart",
                 "maneuvering", "p", "turn_utc")

    def __init__(self, params: TrackerParams) -> None:
        self.p = params
        self.cusum_pos = 0.0
        self.cusum_neg = 0.0
        #: the IMM's manoeuvring model dominates
        self.maneuvering = False
        #: the AUV flies an arc; the quiet turn rate's average (rad/s) and its time
        self.arcing = False
        self.arc_rate = 0.0
        self.arc_t = math.nan
        #: a turn was declared: restart the line at the next update
        self.line_restart = False
        self.turn_utc = -math.inf

    def reset(self) -> None:
        """A (re)initialised filter starts straight."""
        self.maneuvering = False
        self.arcing = False
        self.arc_rate = 0.0
        self.arc_t = math.nan

    def _arc(self, kf: Imm) -> bool:
        """Whether the AUV flies an arc (:meth:`imm_state`)."""
        w, _ = kf.quiet_turn_rate
        t = kf.t
        if not math.isfinite(self.arc_t) or t <= self.arc_t:
            self.arc_rate = w if not math.isfinite(self.arc_t) else self.arc_rate
        else:
            a = min(1.0, (t - self.arc_t) / ARC_TAU_S)
            self.arc_rate += a * (w - self.arc_rate)
        self.arc_t = t
        lim = math.radians(self.p.arc_rate_dps)
        self.arcing = abs(self.arc_rate) >= (0.5 * lim if self.arcing else lim)
        return self.arcing

    def declare(self, kf: CvKalman | Imm, restart_line: bool = True) -> None:
        """A turn: add the turn covariance to the filter and (optionally) mark
        the line for a restart."""
        p = self.p
        kf.inflate(p.turn_pos_sigma_m ** 2, p.turn_vel_sigma_mps ** 2)
        if restart_line:
            self.line_restart = True

    def lateral(self, kf: CvKalman | Imm, ex: float, ey: float, pxx: float, pxy: float,
                pyy: float, ji: tuple[float, float], jl: tuple[float, float], var_i: float,
                var_l: float) -> float | None:
        """The fix's innovation (ex, ey) across the filter's course, normalised by
        its predicted 1σ (prediction + fix covariance J⁻¹ diag(var) J⁻ᵀ); None when
        the course or the fix geometry is undefined."""
        vx, vy = kf.x[2], kf.x[3]
        v = math.hypot(vx, vy)
        det = ji[0] * jl[1] - ji[1] * jl[0]
        if v < 0.2 or abs(det) < 1e-3:
            return None
        nx, ny = -vy / v, vx / v  # starboard normal of the course
        # n·J⁻¹ = (a, b): J⁻¹ = [[jl1, −ji1], [−jl0, ji0]] / det
        a = (nx * jl[1] - ny * jl[0]) / det
        b = (-nx * ji[1] + ny * ji[0]) / det
        var = nx * nx * pxx + 2.0 * nx * ny * pxy + ny * ny * pyy + a * a * var_i + b * b * var_l
        if var <= 0.0:
            return None
        return (ex * nx + ey * ny) / math.sqrt(var)

    def cusum(self, kf: CvKalman | Imm, lat: float) -> bool:
        """Two-sided CUSUM on the normalised cross-course innovation ``lat`` (each
        clipped to ± ``maneuver_cap``).  When it fires, declare a turn (the
        line restarts only with ``maneuver_restarts_line``); True then."""
        p = self.p
        zc = max(-p.maneuver_cap, min(p.maneuver_cap, lat))
        k = p.maneuver_drift
        gp = max(0.0, self.cusum_pos + zc - k)
        gn = max(0.0, self.cusum_neg - zc - k)
        if gp <= p.maneuver_threshold and gn <= p.maneuver_threshold:
            self.cusum_pos, self.cusum_neg = gp, gn
            return False
        self.cusum_pos = self.cusum_neg = 0.0
        self.declare(kf, restart_line=p.maneuver_restarts_line)
        return True

    def imm_state(self, kf: CvKalman | Imm) -> str:
        """The IMM's manoeuvre state after an update: ``enter`` (the manoeuvring
        models' probability rose to ``maneuver_on``), ``during``, ``exit`` (it
        fell to ``maneuver_off``), or "" (straight, or a single-model filter).
        Updates :attr:`arcing` besides: the quiet model's turn rate, averaged
        over ``ARC_TAU_S``, at least ``arc_rate_dps`` (and until it falls below
        half that) — a steady turn the straight line would lag."""
        if not isinstance(kf, Imm):
            return ""
        mu = kf.maneuver_probability
        p = self.p
        arc = self._arc(kf)
        if not self.maneuvering:
            if mu >= p.maneuver_on:
                self.maneuvering = True
                return "enter"
            return ""
        if mu <= p.maneuver_off:
            self.maneuvering = False
            if not arc:
                # a sharp turn is over: what the quiet model learnt of it is no arc
                kf.reset_quiet_turn_rate(math.radians(QUIET_RATE_SIGMA_DPS) ** 2)
                self.arc_rate = 0.0
            return "exit"
        return "during"
