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

When the IMM's manoeuvre ends, the turn rate the quiet model picked up
meanwhile is set back to 0 unless the AUV flew an arc (the quiet rate's
average above ``arc_rate_dps``) since at least ``ARC_TAU_S`` before the
manoeuvre began: an arc that tightened for a moment goes on, the rate a
U-turn taught the quiet model (its average is an arc by then) goes.

A sharp turn the quiet model followed in part leaves it a turn rate once the
AUV flies straight again, which noisy fixes correct only slowly: between
fixes the track curves off the new leg, the boat with it, and the track says
arcing.  :meth:`ManeuverDetector.spin` checks the rate against the path: over
the last ``SPIN_WINDOW_S`` it compares the course of the filter's positions
(a least-squares velocity through those of each half of the window: positions
follow the fixes, a course carried between fixes by a wrong rate does not)
in the second half with the first, and the quiet model's turn rate averaged
over the window times half its length.  When the rate says at least
``SPIN_MIN_DEG`` and the path turned less than ``SPIN_STRAIGHT_DEG`` and half
of it (or the other way), by ``SPIN_SIGMAS`` of the path's turn (from the
filter's position σ), on ``SPIN_CHECKS`` updates in a row, the rate is
spurious and set back to 0.  On a true arc the path turns as the rate says.
The tracker runs the check after every update while the IMM says straight.
On the AUV's plan the tracker knows sooner: once the AUV is on the straight
part of a leg, :meth:`ManeuverDetector.plan_straight` sets a leftover rate
back to 0 at once (every model's, while the IMM still says manoeuvring).

``turn_utc``: UTC (s) of the last line restart (the TURNING flag holds
``turning_flag_s`` after it).
"""

from __future__ import annotations

import math
from collections import deque

from zarco_runtime.tracking.imm import Imm
from zarco_runtime.tracking.kalman import CvKalman
from zarco_runtime.tracking.ls_fit import ls_velocity
from zarco_runtime.tracking.params import TrackerParams

#: the quiet model's turn rate is averaged over this long (s) to tell an arc
ARC_TAU_S = 10.0
#: below this speed (m/s) nothing is taken for an arc
ARC_MIN_SPEED_MPS = 0.2
#: 1σ (deg/s) of the quiet model's turn rate once a sharp turn is over
QUIET_RATE_SIGMA_DPS = 0.5
#: the quiet model's turn rate is checked against the path the filter's
#: positions trace over this long (s), when it says a turn of at least this (deg)
SPIN_WINDOW_S = 24.0
SPIN_MIN_DEG = 20.0
#: ... and reset when the path turned less than this (deg) and half that, and
#: less by this many σ of the path's turn, on this many updates in a row
SPIN_STRAIGHT_DEG = 8.0
SPIN_SIGMAS = 3.0
SPIN_CHECKS = 4


def _course(entries: list[tuple[float, float, float, float]], sigma_m: float
            ) -> tuple[float, float] | None:
    """The course (rad) of the least-squares velocity through the positions of
    ``entries`` (time s, north m, east m, ...) and its 1σ (rad) for positions
    of ``sigma_m`` 1σ each; None with fewer than 3 or no speed."""
    if len(entries) < 3:
        return None
    f = ls_velocity(entries)
    if f is None:
        return None
    _, _, vx, vy, v, stt = f
    return math.atan2(vy, vx), sigma_m / (v * math.sqrt(stt))


class ManeuverDetector:
    """The CUSUM's state, the IMM's manoeuvre state and the pending line restart."""

    __slots__ = ("arc_rate", "arc_since", "arc_t", "arcing", "cusum_neg", "cusum_pos",
                 "enter_t", "history", "line_restart", "maneuvering", "p", "spin_run", "spins",
                 "turn_utc")

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
        #: since when (filter time s) the AUV is taken to fly an arc (NaN: it is not),
        #: and when the IMM's manoeuvre began
        self.arc_since = math.nan
        self.enter_t = math.nan
        #: a turn was declared: restart the line at the next update
        self.line_restart = False
        self.turn_utc = -math.inf
        #: (filter time s, north m, east m, quiet turn rate rad/s) after recent updates
        self.history: deque[tuple[float, float, float, float]] = deque()
        #: spurious quiet turn rates set back to 0 (:meth:`spin`), and checks in
        #: a row that found the rate spurious
        self.spins = 0
        self.spin_run = 0

    def reset(self) -> None:
        """A (re)initialised filter starts straight."""
        self.maneuvering = False
        self.arcing = False
        self.arc_rate = 0.0
        self.arc_t = math.nan
        self.history.clear()
        self.spin_run = 0

    def plan_straight(self, kf: Imm) -> bool:
        """The AUV's plan says it flies a straight line now: a turn rate left
        in the quiet model (a sharp corner it followed as an arc) is set back
        to 0; True if there was one.  While the IMM still takes the AUV to
        manoeuvre (after a U-turn every model has the turn's rate, and none
        predicting better, the manoeuvre lingers), the turning models are set
        back to the rates they expect as well."""
        w, _ = kf.quiet_turn_rate
        if self.maneuvering:
            kf.reset_turn_rates()
        if abs(w) < math.radians(QUIET_RATE_SIGMA_DPS):
            return False
        self._straight(kf)
        return True

    def _straight(self, kf: Imm) -> None:
        """The AUV flies straight: the quiet model's turn rate back to 0 (1σ
        ``QUIET_RATE_SIGMA_DPS``), no arc, the path check's history restarted."""
        kf.reset_quiet_turn_rate(math.radians(QUIET_RATE_SIGMA_DPS) ** 2)
        self.arc_rate = 0.0
        self.arcing = False
        self.arc_since = math.nan
        self.history.clear()

    def spin(self, kf: Imm) -> bool:
        """After an update (filter time s, NED m): check the quiet model's turn
        rate against the path over the last ``SPIN_WINDOW_S`` (module
        docstring); when the path did not turn as the rate says, set the rate
        back to 0 (counted in :attr:`spins`) and return True."""
        vx, vy = kf.x[2], kf.x[3]
        h = self.history
        if math.hypot(vx, vy) < ARC_MIN_SPEED_MPS:
            h.clear()
            return False
        w, _ = kf.quiet_turn_rate
        h.append((kf.t, kf.x[0], kf.x[1], w))
        while len(h) > 2 and kf.t - h[1][0] >= SPIN_WINDOW_S:
            h.popleft()
        t0 = h[0][0]
        if kf.t - t0 < SPIN_WINDOW_S:
            return False
        tm = 0.5 * (t0 + kf.t)
        first = [e for e in h if e[0] <= tm]
        second = [e for e in h if e[0] >= tm]
        sigma = kf.pos_sigma()
        k1, k2 = _course(first, sigma), _course(second, sigma)
        if k1 is None or k2 is None:
            return False
        turned = math.remainder(k2[0] - k1[0], math.tau)
        # between the halves' middles: half the window
        said = sum(e[3] for e in h) / len(h) * 0.5 * (kf.t - t0)
        sign = math.copysign(1.0, said)
        if (abs(said) < math.radians(SPIN_MIN_DEG)
                or turned * sign >= min(0.5 * abs(said), math.radians(SPIN_STRAIGHT_DEG))
                or abs(said) - turned * sign < SPIN_SIGMAS * math.hypot(k1[1], k2[1])):
            self.spin_run = 0
            return False
        self.spin_run += 1
        if self.spin_run < SPIN_CHECKS:
            return False
        self.spin_run = 0
        self._straight(kf)
        self.spins += 1
        return True

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
        # the same turn-rate noise is a smaller sideways acceleration at low speed:
        # below 1 m/s the rate that makes an arc grows as 1/speed
        v = math.hypot(kf.x[2], kf.x[3])
        lim = math.radians(self.p.arc_rate_dps) / min(1.0, max(v, ARC_MIN_SPEED_MPS))
        was = self.arcing
        self.arcing = abs(self.arc_rate) >= (0.5 * lim if self.arcing else lim)
        if self.arcing and not was:
            self.arc_since = t
        elif not self.arcing:
            self.arc_since = math.nan
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
        over ``ARC_TAU_S``, at least ``arc_rate_dps`` (divided by the speed in
        m/s below 1 m/s; and until it falls below half that) — a steady turn the
        straight line would lag."""
        if not isinstance(kf, Imm):
            return ""
        mu = kf.maneuver_probability
        p = self.p
        arc = self._arc(kf)
        if not self.maneuvering:
            if mu >= p.maneuver_on:
                self.maneuvering = True
                self.enter_t = kf.t
                return "enter"
            return ""
        if mu <= p.maneuver_off:
            self.maneuvering = False
            # an arc only if the AUV flew it before the manoeuvre began: a rate the
            # quiet model picked up during a sharp turn is that turn's
            genuine = arc and self.arc_since <= self.enter_t - ARC_TAU_S
            if not genuine:
                # a sharp turn is over: what the quiet model learnt of it is no arc
                kf.reset_quiet_turn_rate(math.radians(QUIET_RATE_SIGMA_DPS) ** 2)
                self.arc_rate = 0.0
            return "exit"
        return "during"
