"""Fix assembly: from a cycle's ranges to what the filter is updated with.

* :meth:`FixAssembly.circle` — the two-circle fix of a cycle, its ranges
  corrected for the AUV's motion during the cycle with the filter's velocity
  (the solution nearer the prediction gives the directions);
* :meth:`FixAssembly.by_prediction` — the mirror nearer the prediction in the
  Mahalanobis sense, and whether both solutions are plausible;
* :meth:`FixAssembly.mirror_by_ranges` — the mirror the other beacons' recent
  ranges choose (they do not depend on the filter, which a turn or a mirror
  lock may have misled);
* :meth:`FixAssembly.multi_fix` — the published fix: the joint least squares
  of the cycle's ranges and the newest accepted range to every other beacon
  heard within ``ls_window_s``, carried to the emission time along the
  filter's velocity, and whether they agree;
* :meth:`FixAssembly.linearised` — the two ranges as measurement rows
  linearised at a point (an extended Kalman update in range space);
* :meth:`FixAssembly.half_cycle` — a half cycle's sum or difference of the
  ranges to its beacon and to the listener (:mod:`.cycles`) as a one-row EKF
  update linearised at the prediction;
* :meth:`FixAssembly.range_only` — one range (a cycle on the listener's own
  beacon, a cycle whose reply was not heard, or a fallback when a reply is
  doubted) as a one-row update at its emission time.

Only ranges the filter accepted are remembered (:meth:`FixAssembly.remember`)
for later fixes.  Positions NED (m), times UTC (s), ranges 3-D (m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_runtime.tracking.cycles import Cycle
from zarco_runtime.tracking.fix import (
    CircleFix,
    CycleRanges,
    circle_fix,
    half_cycle_measure,
    horizontal_radius,
    ls_chi2,
    ls_fix,
    motion_bias,
    range3,
    range_jacobian,
    range_variances,
)
from zarco_runtime.tracking.imm import Imm
from zarco_runtime.tracking.kalman import CvKalman
from zarco_runtime.tracking.params import Network, TrackerParams

#: a half cycle whose range combination changes less than this (m per m of
#: the AUV's horizontal position) is not used: the beacon and the listener
#: in line with the AUV (a difference) or on either side of it (a sum)
HALF_CYCLE_MIN_GRADIENT = 0.2
#: χ² by which the other beacons' ranges must prefer one mirror solution
MIRROR_CHI2_MARGIN = 9.0

Filter = CvKalman | Imm
Rows = list[tuple[float, float]]


@dataclass(slots=True)
class Prediction:
    """The filter's prediction at a fix's emission time and the mirror it prefers.

    (px, py): predicted position (m); pxx, pxy, pyy its covariance (m²);
    (a, b; b, d) the prediction's covariance plus the fix's (m²), ``det`` its
    determinant; ``m1``, ``m2`` the two solutions' Mahalanobis distances²
    times ``det``; (fx, fy) the solution nearer the prediction.
    """

    px: float
    py: float
    pxx: float
    pxy: float
    pyy: float
    a: float
    b: float
    d: float
    det: float
    m1: float
    m2: float
    fx: float
    fy: float

    def chi2_det(self, dx: float, dy: float) -> float:
        """Mahalanobis distance² × ``det`` of an offset (dx, dy) from the prediction."""
        return self.d * dx * dx - 2.0 * self.b * dx * dy + self.a * dy * dy


@dataclass(slots=True)
class RangeOnly:
    """Outcome of a range-only update.  ``status``: ``ok`` (accepted),
    ``refused`` (gated), ``uninitialised`` or ``depth`` (nothing done); then
    the emission time (UTC s), the point (cx, cy) of the range circle nearest
    the prediction (m), the corrected range and the listener's (m), the
    motion bias removed (m), the range's variance (m²) and the update's d²;
    for a range to one beacon, the range circle's horizontal radius ``rho``
    (m) and the filter's prediction ``pred`` at the emission time before the
    update — (x, y) (m) and its covariance (xx, xy, yy, m²)."""

    status: str
    t_em: float = math.nan
    cx: float = math.nan
    cy: float = math.nan
    r: float = math.nan
    r_l: float = math.nan
    bias: float = 0.0
    var: float = math.nan
    d2: float = math.nan
    rho: float = math.nan
    pred: tuple[float, float, float, float, float] | None = None


class FixAssembly:
    """The fix stage of the tracker and its memory of accepted ranges."""

    __slots__ = ("depth", "last_chi2", "net", "p", "ranges", "var_scale")

    def __init__(self, params: TrackerParams, net: Network) -> None:
        self.p = params
        self.net = net
        self.depth = params.auv_depth_m
        #: newest accepted range to each beacon: (emission UTC s, range m, variance m²)
        self.ranges: dict[int, tuple[float, float, float]] = {}
        #: the measured noise scale applied to the configured range variance
        self.var_scale = 1.0
        #: the last joint fix's residual χ² and its degrees of freedom (0: none)
        self.last_chi2: tuple[float, int] = (math.nan, 0)

    def clear(self) -> None:
        self.ranges.clear()

    def remember(self, idx: int, t_em: float, r: float, var: float) -> None:
        """Keep an accepted range to beacon ``idx`` for later fixes."""
        self.ranges[idx] = (t_em, r, var)

    # ------------------------------------------------------------ two circles

    def circle(self, kf: Filter, rg: CycleRanges
               ) -> tuple[CircleFix, float, float, float] | None:
        """The cycle's two-circle fix with its ranges corrected for the AUV's
        motion (when the filter runs and ``motion_correction`` is on): (fix,
        r_i, r_L, the bias removed); None when a range is shorter than its
        depth offset."""
        net = self.net
        depth = self.depth
        idx = rg.index
        r_i, r_l = rg.r_i, rg.r_l
        cf = circle_fix(net, idx, r_i, r_l, depth)
        if cf is None:
            return None
        bias = 0.0
        if kf.initialised and self.p.motion_correction:
            px, py, _, _, _ = kf.predicted(rg.emission_utc_s)
            if (cf.x1 - px) ** 2 + (cf.y1 - py) ** 2 <= (cf.x2 - px) ** 2 + (cf.y2 - py) ** 2:
                fx, fy = cf.x1, cf.y1
            else:
                fx, fy = cf.x2, cf.y2
            bias = motion_bias(net, idx, r_i, fx, fy, depth, kf.x[2], kf.x[3])
            r_i -= bias
            r_l -= bias
            cf2 = circle_fix(net, idx, r_i, r_l, depth)
            if cf2 is None:
                return None
            cf = cf2
        return cf, r_i, r_l, bias

    def by_prediction(self, kf: Filter, cf: CircleFix, t_em: float,
                      fix_var: float) -> Prediction:
        """The filter's prediction at ``t_em`` and the solution of ``cf`` nearer
        it in the Mahalanobis sense (``fix_var``: the fix's variance per axis, m²)."""
        px, py, pxx, pxy, pyy = kf.predicted(t_em)
        e = fix_var
        a, b, d = pxx + e, pxy, pyy + e
        det = a * d - b * b
        d1x, d1y, d2x, d2y = cf.x1 - px, cf.y1 - py, cf.x2 - px, cf.y2 - py
        m1 = d * d1x * d1x - 2.0 * b * d1x * d1y + a * d1y * d1y
        m2 = d * d2x * d2x - 2.0 * b * d2x * d2y + a * d2y * d2y
        if det > 0.0 and m2 < m1:
            fx, fy = cf.x2, cf.y2
        else:
            fx, fy = cf.x1, cf.y1
        return Prediction(px, py, pxx, pxy, pyy, a, b, d, det, m1, m2, fx, fy)

    def linearised(self, idx: int, r_i: float, r_l: float, lx: float, ly: float
                   ) -> tuple[Rows, list[float]]:
        """Measurement rows and values of the ranges to beacon ``idx`` and to
        the listener linearised at (lx, ly): r ≈ r̂(l) + J (p − l)."""
        net = self.net
        depth = self.depth
        ji = range_jacobian(net, idx, lx, ly, depth)
        jl = range_jacobian(net, net.listener, lx, ly, depth)
        z = [r_i - range3(net, idx, lx, ly, depth) + ji[0] * lx + ji[1] * ly,
             r_l - range3(net, net.listener, lx, ly, depth) + jl[0] * lx + jl[1] * ly]
        return [ji, jl], z

    # ------------------------------------------------------------ other beacons

    def other_ranges(self, kf: Filter, idx: int, t_em: float, x: float, y: float
                     ) -> list[tuple[int, float, float]]:
        """The newest accepted range to every beacon but ``idx`` and the listener,
        heard within ``ls_window_s`` before ``t_em``, carried to ``t_em`` along
        the filter's velocity (directions taken at (x, y)), its variance grown
        by the velocity's uncertainty and the manoeuvring model's acceleration."""
        if not kf.initialised:
            return []
        net = self.net
        p = self.p
        lst = net.listener
        vx, vy = kf.x[2], kf.x[3]
        P = kf.P
        out = []
        for k, (tk, rk, vk) in self.ranges.items():
            dt = t_em - tk
            if k in (idx, lst) or not 0.0 <= dt <= p.ls_window_s:
                continue
            jx, jy = range_jacobian(net, k, x, y, self.depth)
            pv = jx * jx * P[2][2] + 2.0 * jx * jy * P[2][3] + jy * jy * P[3][3]
            grow = dt * dt * pv + p.maneuver_accel_psd * dt ** 3 / 3.0
            out.append((k, rk + (jx * vx + jy * vy) * dt, vk + grow))
        return out

    def mirror_by_ranges(self, kf: Filter, idx: int, t_em: float, r_i: float, r_l: float,
                         var_i: float, var_l: float, cf: CircleFix
                         ) -> tuple[float, float] | None:
        """The two-circle solution the other beacons' ranges choose: the joint
        least squares started from each solution, the one that explains all
        ranges (χ² within ``gate_chi2`` + 2 per extra range) clearly better than
        the other (by ``MIRROR_CHI2_MARGIN``) or both converging to one point;
        None when they cannot tell (no other beacon, or both fit)."""
        if math.hypot(cf.x1 - cf.x2, cf.y1 - cf.y2) < 1.0:
            return None
        net = self.net
        mx, my = 0.5 * (cf.x1 + cf.x2), 0.5 * (cf.y1 + cf.y2)
        others = self.other_ranges(kf, idx, t_em, mx, my)
        if not others:
            return None
        ranges = [(idx, r_i, var_i), (net.listener, r_l, var_l), *others]
        depth = self.depth
        fits = []
        for cx, cy in ((cf.x1, cf.y1), (cf.x2, cf.y2)):
            sol = ls_fix(net, ranges, depth, cx, cy)
            if sol is None:
                return None
            fits.append((ls_chi2(net, ranges, depth, sol[0], sol[1]), sol[0], sol[1]))
        (c1, x1, y1), (c2, x2, y2) = fits
        best = fits[0] if c1 <= c2 else fits[1]
        if best[0] > self.p.gate_chi2 + 2.0 * len(others):
            return None
        if abs(c1 - c2) < MIRROR_CHI2_MARGIN and math.hypot(x1 - x2, y1 - y2) > 1.0:
            return None
        bx, by = best[1], best[2]
        if (cf.x1 - bx) ** 2 + (cf.y1 - by) ** 2 <= (cf.x2 - bx) ** 2 + (cf.y2 - by) ** 2:
            return cf.x1, cf.y1
        return cf.x2, cf.y2

    def multi_fix(self, kf: Filter, idx: int, t_em: float, r_i: float, r_l: float,
                  var_i: float, var_l: float, fx: float, fy: float
                  ) -> tuple[tuple[float, float, float, float, float], bool]:
        """The cycle's fix with every beacon heard within ``ls_window_s``: each
        older range brought to ``t_em`` (:meth:`other_ranges`), then the joint
        least-squares position from the chosen two-circle solution (fx, fy).
        Returns (x, y, Cxx, Cxy, Cyy); the two-circle solution (and its
        covariance) when no other beacon was heard or the ranges do not agree
        on one position (χ² of the residuals beyond ``gate_chi2`` + 2 per extra
        range), and whether they agree (True with no other beacon)."""
        net = self.net
        p = self.p
        depth = self.depth
        ranges = [(idx, r_i, var_i), (net.listener, r_l, var_l),
                  *self.other_ranges(kf, idx, t_em, fx, fy)]
        two = ls_fix(net, ranges[:2], depth, fx, fy, 1)
        c2 = (two[2], two[3], two[4]) if two is not None else (math.nan,) * 3
        self.last_chi2 = (math.nan, 0)
        if len(ranges) > 2:
            # the joint solution, unless the ranges disagree (a false or late
            # detection in this cycle): then the cycle's own pair
            sol = ls_fix(net, ranges, depth, fx, fy)
            if sol is not None:
                chi2 = ls_chi2(net, ranges, depth, sol[0], sol[1])
                self.last_chi2 = (chi2, len(ranges) - 2)
                if chi2 <= p.gate_chi2 + 2.0 * (len(ranges) - 2):
                    return sol, True
                return (fx, fy, *c2), False
        return (fx, fy, *c2), True

    def _heard(self, kf: Filter, t_heard: float) -> tuple[float, float]:
        """The emission time (UTC s) of an interrogation the listener heard at
        ``t_heard`` and the listener's range (m) then, from the filter's
        prediction (T = t − r_L(T)/c, two passes)."""
        net, lst, c = self.net, self.net.listener, self.net.c
        x, y, _, _, _ = kf.predicted(t_heard)
        r_l = range3(net, lst, x, y, self.depth)
        x, y, _, _, _ = kf.predicted(t_heard - r_l / c)
        r_l = range3(net, lst, x, y, self.depth)
        return t_heard - r_l / c, r_l

    # ------------------------------------------------------------ one range

    def range_only(self, kf: Filter, cyc: Cycle, idx: int, r: float,
                   fallback: bool = False) -> RangeOnly:
        """One range to beacon ``idx`` as an EKF update at its emission time (the
        listener's range to it predicted when it is not measured).  With
        ``fallback`` (a cycle whose fix was refused, tried on its
        interrogation-only range) the range must agree well: the gate is
        ``soft_gate_chi2``.  An accepted range is remembered."""
        if not kf.initialised:
            return RangeOnly("uninitialised")
        net = self.net
        p = self.p
        lst = net.listener
        c = net.c
        depth = self.depth

        def emission(r_b: float) -> tuple[float, float]:
            """Emission time and the listener's range for a range r_b to idx."""
            if idx == lst:
                return cyc.t_i - r_b / c, r_b
            return self._heard(kf, cyc.t_i)

        t_em, r_l = emission(r)
        pred = kf.predicted(t_em)
        px, py = pred[0], pred[1]
        bias = 0.0
        if p.motion_correction:
            bias = motion_bias(net, idx, r, px, py, depth, kf.x[2], kf.x[3])
            r -= bias
            t_em, r_l = emission(r)
            pred = kf.predicted(t_em)
            px, py = pred[0], pred[1]
        dz = depth - net.depth[idx]
        if horizontal_radius(r, dz) < -1.0:
            return RangeOnly("depth")
        kf.predict(t_em)
        dx, dy = px - net.north[idx], py - net.east[idx]
        r_hat = math.sqrt(dx * dx + dy * dy + dz * dz)
        j = range_jacobian(net, idx, px, py, depth)
        var_i = range_variances(net, idx, p.timing_sigma_s, p.range_sigma_m)[0] * self.var_scale
        z = [r - r_hat + j[0] * px + j[1] * py]
        # a fallback must agree well: it only replaces a reply, not the filter's doubt
        gate = p.soft_gate_chi2 if fallback else p.gate_chi2
        ok, d2 = kf.update([j], z, [var_i], gate, p.soft_gate_chi2)
        # the point of the range circle nearest the prediction, for the record
        rho = max(horizontal_radius(r, dz), 0.0)
        hd = math.hypot(dx, dy)
        if hd > 1e-9:
            cx, cy = net.north[idx] + dx / hd * rho, net.east[idx] + dy / hd * rho
        else:
            cx, cy = px, py
        if ok:
            self.remember(idx, t_em, r, var_i)
        return RangeOnly("ok" if ok else "refused", t_em, cx, cy, r, r_l, bias, var_i, d2, rho,
                         pred)

    # ------------------------------------------------------------ half cycles

    def half_cycle(self, kf: Filter, cyc: Cycle, bias: float) -> RangeOnly:
        """A half cycle (:mod:`.cycles`) on beacon ``cyc.index`` as a one-row EKF
        update of :func:`~.fix.half_cycle_measure`: without its closing ping,
        r_i − r_L at the emission time T (less twice the beacon's range
        ``bias``, m: a turnaround error enters it twice,
        :mod:`.calibration`); without its opening ping, r_i at T′ − δ (where
        the AUV heard the reply) plus r_L at the next emission T′ — the
        update at T′ − δ, the AUV's motion over δ from the filter.  It must
        agree well (gated at ``soft_gate_chi2``, like a fallback range): one
        interrogation of it was taken as missed, and a false reply would make
        one up.  Returned as a :class:`RangeOnly` whose ``r``/``r_l`` are the
        filter's ranges after the update and (cx, cy) its position."""
        if not kf.initialised:
            return RangeOnly("uninitialised")
        net, p, depth = self.net, self.p, self.depth
        idx, lst, c = cyc.index, net.listener, net.c
        m = half_cycle_measure(cyc, net)
        if math.isnan(cyc.t_next):
            t_em = self._heard(kf, cyc.t_i)[0]
            px, py, _, _, _ = kf.predicted(t_em)
            qx, qy = px, py
            m -= 2.0 * bias
            sign = -1.0
        else:
            t_next = self._heard(kf, cyc.t_next)[0]
            qx, qy, _, _, _ = kf.predicted(t_next)
            t_em = t_next - net.delta
            px, py, _, _, _ = kf.predicted(t_em)
            sign = 1.0
        ji = range_jacobian(net, idx, px, py, depth)
        jl = range_jacobian(net, lst, qx, qy, depth)
        # the listener's range moves with the same position error as the beacon's
        row = (ji[0] + sign * jl[0], ji[1] + sign * jl[1])
        if math.hypot(*row) < HALF_CYCLE_MIN_GRADIENT:
            return RangeOnly("geometry")
        h = range3(net, idx, px, py, depth) + sign * range3(net, lst, qx, qy, depth)
        # two detections' jitter and a range error on each range
        var = 2.0 * ((c * p.timing_sigma_s) ** 2 + p.range_sigma_m ** 2) * self.var_scale
        kf.predict(t_em)
        ok, d2 = kf.update([row], [m - h + row[0] * px + row[1] * py], [var],
                           p.soft_gate_chi2, p.soft_gate_chi2)
        fx, fy = kf.x[0], kf.x[1]
        return RangeOnly("ok" if ok else "refused", t_em, fx, fy,
                         range3(net, idx, fx, fy, depth), range3(net, lst, fx, fy, depth),
                         bias, var, d2)
