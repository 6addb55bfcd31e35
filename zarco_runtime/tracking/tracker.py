"""The passive AUV tracker: acoustic events in, AUV track out (paper IV–V).

:class:`AuvTracker` glues the chain, one event at a time::

    AcousticEvent ─▶ clock check ─▶ CycleAssembler ─▶ cycle_ranges ─▶ motion-bias
    correction ─▶ circle_fix (fix + mirror) ─▶ mirror choice ─▶ filter (an IMM
    of straight, manoeuvring and turning models, or one CV filter; gated)
    ─▶ LineRls (forgetting, re-centred, turn reset) ─▶ AuvTrack

* Cycles on beacon i ≠ listener give a two-circle fix; cycles on the listener's
  own beacon, and cycles whose reply was missed (two interrogations), give one
  range and are applied as a range-only update; a cycle whose ranges disagree
  with the other beacons' is tried on its interrogation-only range alone (the
  reply may be a multipath or false one: ``reply_refused``).  Updates are made
  in range space (the two ranges linearised at the chosen solution, or at the
  prediction when both solutions are plausible near a baseline or the circles
  miss each other), so a fix with poor geometry only informs the filter along
  the directions it constrains, and every range is used once.
* The published fix (:class:`AuvFix`) is the joint least-squares position of
  the cycle's ranges and the newest accepted range to every other beacon heard
  within ``ls_window_s`` (carried to the emission time along the filter's
  velocity), with its covariance: more beacons never make it worse.
* Initialisation resolves the mirror by a vote between fixes on different
  baselines (the true position is common to both, the mirrors are not); with a
  single baseline, by the configured prior.  Once the filter runs, the
  prediction resolves it (smaller Mahalanobis distance).
* Innovations beyond ``gate_chi2`` are refused (``innovation``), those beyond
  ``soft_gate_chi2`` down-weighted.  When ``reacquire_after`` fixes were
  refused within ``init_window_s``, all recent fixes vote; if the vote
  disagrees with the filter and a straight track through the voted solutions
  explains at least two more fixes than the filter's track, the filter
  re-initialises from the fixes (``reacquired``): this undoes a lock on the
  mirror track after crossing a baseline, or a turn the filter lost, while
  outliers never win.
* Manoeuvres: with the IMM, the probability that the AUV is not flying
  straight rising to ``maneuver_on`` declares a turn: the line restarts from
  the filter at every update until it falls to ``maneuver_off`` (TURNING set
  meanwhile and ``turning_flag_s`` after).  Besides, a two-sided CUSUM on the
  fixes' normalised cross-course innovation (a turn pushes them steadily to
  one side) opens up the filter's covariance (``maneuver``), and a CUSUM on the
  RLS residuals declares a turn and restarts the line from the filter's state
  (``turns``).
* Aging: no accepted update for ``stale_after_s`` sets STALE; for
  ``lost_after_s``, or a predicted position σ above ``lost_sigma_m``, the track
  is declared LOST (published once, then by :meth:`AuvTracker.tick`) and the
  filter re-initialises from the next fixes (REACQUIRED).

Clocks: event times ``utc_epoch_s`` (the buoy's GPS-disciplined UTC) drive all
the estimation; the runtime clock ``t`` of the events is only used to map UTC
onto it (a running minimum of t − utc, minus ``feed_latency_s``; or set
:meth:`AuvTracker.set_clock_offset` from the GPS time) for ``t0``, the track's
time origin on the runtime clock, and the aging.

Counters (:meth:`AuvTracker.counters`): ``event.<reason>`` for dropped events
(see :mod:`.cycles`, plus ``clock``), ``cycle.<reason>`` for lost cycles,
``fix.<reason>`` for cycles that gave no accepted update (``impossible_timing``,
``depth``, ``no_intersection``, ``innovation``, ``range_only_uninitialised``,
``init_pending``, ``inconsistent``: its ranges disagree with the other
beacons') and for tracker events (``maneuver``, ``reacquired``,
``clock_resync``, ``reply_refused``), ``internal`` for any unexpected exception
(never raised: the tests assert it stays absent).

Pure and deterministic: no I/O, no clock reads.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from typing import Any

from zarco_core.auv_messages import AuvFix, AuvTrack, BuoyStatus, TrackFlags
from zarco_runtime.tracking.cycles import Cycle, CycleAssembler
from zarco_runtime.tracking.fix import (
    CircleFix,
    circle_fix,
    cycle_ranges,
    horizontal_radius,
    ls_chi2,
    ls_fix,
    motion_bias,
    range_jacobian,
    range_variances,
)
from zarco_runtime.tracking.imm import Imm
from zarco_runtime.tracking.kalman import CvKalman
from zarco_runtime.tracking.params import Network, TrackerParams
from zarco_runtime.tracking.plan import PlanMatcher
from zarco_runtime.tracking.rls import LineRls

#: the runtime-minus-UTC estimate may rise by this much per second (s/s), so it
#: follows clock drift while sticking to the least-delayed events
CLOCK_LEAK = 1e-3
#: consecutive mutually consistent events that re-synchronise a jumped clock
CLOCK_RESYNC_N = 5
#: fixes remembered for the mirror vote at (re)initialisation
INIT_MEMORY = 16
#: χ² by which the other beacons' ranges must prefer one mirror solution
MIRROR_CHI2_MARGIN = 9.0
#: cycles dropped in a row after which the prediction no longer narrows the
#: closing window (see AuvTracker._predict_range)
WINDOW_OFF_DROPS = 6


class _InitEntry:
    """A fix remembered for the initialisation vote."""

    __slots__ = ("cf", "idx", "r_i", "r_l", "t")

    def __init__(self, t: float, idx: int, cf: CircleFix, r_i: float, r_l: float) -> None:
        self.t = t
        self.idx = idx
        self.cf = cf
        self.r_i = r_i
        self.r_l = r_l


class AuvTracker:
    """Passive LBL tracker of one AUV.  Feed :meth:`on_event` (or :meth:`process`)
    with every :class:`~zarco_core.auv_messages.AcousticEvent` in arrival
    order and call :meth:`tick` periodically; nothing here raises."""

    def __init__(self, params: TrackerParams) -> None:
        params.validate()
        self.p = params
        self.net: Network = Network.from_params(params.network, params.timing_tol_s)
        self.depth = params.auv_depth_m
        self.cycles = CycleAssembler(self.net, params.auv_depth_m, params.max_range_m,
                                     params.sequence, self._predict_range, 4.0,
                                     params.closing_margin_m)
        self.kf: CvKalman | Imm
        if params.motion_model == "imm":
            self.kf = Imm([("cv", params.accel_psd, 0.0),
                           ("cv", params.maneuver_accel_psd, 0.0),
                           ("ct", params.turn_accel_psd, params.turn_rate_psd)],
                          (params.straight_sojourn_s, params.maneuver_sojourn_s,
                           params.turn_sojourn_s), (0.5, 0.25, 0.25))
        else:
            self.kf = CvKalman(params.accel_psd)
        self._maneuvering = False
        self.rls = LineRls(params.rls_forgetting, params.turn_cusum_drift,
                           params.turn_cusum_threshold, params.turn_holdoff_s)
        self.dropped: Counter[str] = Counter()
        #: fixes accepted by the filter, and all two-circle fixes computed
        self.fixes_accepted = 0
        self.fixes = 0
        self.turns = 0
        self.last_fix: AuvFix | None = None
        self.last_track: AuvTrack | None = None
        self._init_buf: deque[_InitEntry] = deque(maxlen=INIT_MEMORY)
        # fixes the filter refused within the last init_window_s
        self._rejected: deque[_InitEntry] = deque(maxlen=INIT_MEMORY)
        self._prior = (params.prior_north_m, params.prior_east_m)
        self._offset: float | None = None  # runtime − UTC (s)
        self._offset_t = 0.0
        self._offset_fixed = False
        self._resync: list[float] = []
        self._last_update_utc = -math.inf
        self._lost = False
        self._ever_init = False
        self._reacquired_utc = -math.inf
        self._turn_utc = -math.inf
        self._bad_geometry = False
        self._cusum_pos = 0.0
        self._cusum_neg = 0.0
        self._line_restart = False
        self._last_range_only = False
        self._buoy_fault = False
        self._var = range_variances  # local alias for the hot path
        #: newest range to each beacon: (emission UTC s, range m, variance m²)
        self._ranges: dict[int, tuple[float, float, float]] = {}
        #: the AUV's a-priori plan: which leg it is on, its corners (:mod:`.plan`)
        self.plan = PlanMatcher(params.plan)

    # ------------------------------------------------------------ public API

    def on_event(self, ev: Any) -> AuvTrack | None:
        """Process one acoustic event; the AuvTrack it produced, if any."""
        track = None
        for m in self.process(ev):
            if isinstance(m, AuvTrack):
                track = m
        return track

    def process(self, ev: Any) -> list[AuvFix | AuvTrack]:
        """Process one acoustic event; every message it produced (an AuvFix per
        cycle that reached the fix stage, an AuvTrack per accepted update or
        lost declaration), in order."""
        out: list[AuvFix | AuvTrack] = []
        try:
            if not self._clock_ok(ev):
                return out
            before = self.cycles.accepted
            cycle = self.cycles.push(ev)
            if self.cycles.accepted != before:
                self._clock_update(ev.t, ev.t - ev.utc_epoch_s)
            if cycle is not None:
                self._on_cycle(cycle, out)
            self._check_lost(getattr(ev, "t", None), out)
        except Exception:  # the tracker must never take the runtime down
            self.dropped["internal"] += 1
        return out

    def on_status(self, st: BuoyStatus) -> None:
        """Record the buoy's status (a non-zero fault code sets BUOY_FAULT)."""
        self._buoy_fault = getattr(st, "fault_code", 0) != 0

    def tick(self, t: float) -> AuvTrack | None:
        """Age the track to runtime time ``t`` (declaring it lost when due); the
        current track (None before the first initialisation)."""
        out: list[AuvFix | AuvTrack] = []
        try:
            self._check_lost(t, out)
            if out:
                return out[-1]  # type: ignore[return-value]
            if self.last_track is None:
                return None
            return self._track(t, self.last_track)
        except Exception:
            self.dropped["internal"] += 1
            return None

    def set_clock_offset(self, runtime_minus_utc_s: float) -> None:
        """Fix the runtime-minus-UTC offset (e.g. from the GPS time) instead of
        estimating it from the feed."""
        self._offset = runtime_minus_utc_s
        self._offset_fixed = True

    @property
    def lost(self) -> bool:
        return self._lost

    def counters(self) -> dict[str, int]:
        """Every drop counter, prefixed ``event.``, ``cycle.`` or ``fix.``."""
        out = {f"event.{k}": v for k, v in self.cycles.dropped.items()}
        out.update({f"cycle.{k}": v for k, v in self.cycles.cycles_dropped.items()})
        out.update({(k if k == "internal" else f"fix.{k}"): v for k, v in self.dropped.items()})
        return out

    # ------------------------------------------------------------- clocks

    def _clock_ok(self, ev: Any) -> bool:
        """Refuse events whose runtime-minus-UTC offset jumped (``event.clock``),
        re-synchronising after CLOCK_RESYNC_N consistent ones."""
        t = getattr(ev, "t", None)
        u = getattr(ev, "utc_epoch_s", None)
        if (self._offset is None or not isinstance(t, (float, int))
                or not isinstance(u, (float, int))):
            return True  # garbage is the assembler's to count
        o = t - u
        if not math.isfinite(o):
            return True
        tol = self.p.clock_tol_s
        if abs(o - self._offset) <= tol + CLOCK_LEAK * max(t - self._offset_t, 0.0):
            self._resync.clear()
            return True
        rs = self._resync
        rs.append(o)
        if len(rs) >= CLOCK_RESYNC_N and max(rs[-CLOCK_RESYNC_N:]) - min(
                rs[-CLOCK_RESYNC_N:]) <= tol:
            self.dropped["clock_resync"] += 1
            self._offset = min(rs[-CLOCK_RESYNC_N:])
            self._offset_t = t
            self._offset_fixed = False
            rs.clear()
            self.cycles.reset(clock=True)
            self._ranges.clear()
            self.kf.reset()
            self.rls.initialised = False
            self._init_buf.clear()
            self._rejected.clear()
            return True
        self.cycles.dropped["clock"] += 1
        return False

    def _clock_update(self, t: float, o: float) -> None:
        if self._offset_fixed:
            return
        if self._offset is None:
            self._offset = o
        else:
            self._offset = min(self._offset + CLOCK_LEAK * max(t - self._offset_t, 0.0), o)
        self._offset_t = t

    def _rt_offset(self) -> float:
        """runtime − UTC offset for a detection time (s), latency removed."""
        return (self._offset or 0.0) - self.p.feed_latency_s

    # ------------------------------------------------------------- cycles

    def _predict_range(self, idx: int, t_i: float) -> tuple[float, float] | None:
        """Predicted 3-D range (m) from beacon ``idx`` to the AUV for an
        interrogation heard at UTC ``t_i``, and its 1σ (m); None when not
        tracking, or when ``WINDOW_OFF_DROPS`` cycles in a row were dropped since
        the last accepted update (the prediction may be what keeps the true
        cycles out: without it they are assembled again, refused by the
        filter, and the re-acquisition vote decides)."""
        kf = self.kf
        if not kf.initialised:
            return None
        drops = self.cycles.cycles_dropped
        if (drops["missed_ping"] + drops["superseded"] + drops["sequence"]
                - self._drops_at_update >= WINDOW_OFF_DROPS):
            return None
        net = self.net
        lst = net.listener
        x, y, _, _, _ = kf.predicted(t_i)
        dz = self.depth - net.depth[lst]
        r_l = math.sqrt((x - net.north[lst]) ** 2 + (y - net.east[lst]) ** 2 + dz * dz)
        x, y, pxx, _, pyy = kf.predicted(t_i - r_l / net.c)
        dz = self.depth - net.depth[idx]
        r = math.sqrt((x - net.north[idx]) ** 2 + (y - net.east[idx]) ** 2 + dz * dz)
        return r, math.sqrt(max(pxx, pyy, 0.0))

    def _on_cycle(self, cyc: Cycle, out: list[AuvFix | AuvTrack]) -> None:
        net = self.net
        p = self.p
        rg = cycle_ranges(cyc, net)
        r_i, r_l = rg.r_i, rg.r_l
        if math.isnan(r_l):  # no reply heard: the range to the beacon only
            r_l = r_i
        if not (0.0 <= r_i <= p.max_range_m and 0.0 <= r_l <= p.max_range_m + net.d[rg.index]):
            self.dropped["impossible_timing"] += 1
            return
        idx = rg.index
        kf = self.kf
        if idx == net.listener or math.isnan(cyc.t_r):
            self._range_only(cyc, idx, r_i, out)
            return
        depth = self.depth
        cf = circle_fix(net, idx, r_i, r_l, depth)
        if cf is None:
            self.dropped["depth"] += 1
            return
        bias = 0.0
        c = net.c
        if kf.initialised and p.motion_correction:
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
                self.dropped["depth"] += 1
                return
            cf = cf2
        t_em = cyc.t_i - r_l / c
        if cf.gap_m > p.max_gap_m:
            self.dropped["no_intersection"] += 1
            return
        self.fixes += 1
        self._bad_geometry = cf.gap_m > 0.0
        entry = _InitEntry(t_em, idx, cf, r_i, r_l)
        self._init_buf.append(entry)
        var_i, var_l = self._var(net, idx, p.timing_sigma_s, p.range_sigma_m)
        if not kf.initialised:
            chosen = self._try_init(self._init_buf)
            if chosen is None:
                self.dropped["init_pending"] += 1
                self._emit_fix(cyc, t_em, cf, cf.x1, cf.y1, r_i, r_l, bias, False, out)
                return
            fx, fy = chosen
            self._emit_fix(cyc, t_em, cf, fx, fy, r_i, r_l, bias, True, out)
            self._accepted(t_em, cyc.t, fx, fy, var_i + var_l, out)
            return
        self._plan_corners(t_em)
        # mirror: the candidate nearer the prediction in the Mahalanobis sense
        px, py, pxx, pxy, pyy = kf.predicted(t_em)
        e = var_i + var_l
        a, b, d = pxx + e, pxy, pyy + e
        det = a * d - b * b
        d1x, d1y, d2x, d2y = cf.x1 - px, cf.y1 - py, cf.x2 - px, cf.y2 - py
        m1 = d * d1x * d1x - 2.0 * b * d1x * d1y + a * d1y * d1y
        m2 = d * d2x * d2x - 2.0 * b * d2x * d2y + a * d2y * d2y
        if det > 0.0 and m2 < m1:
            fx, fy = cf.x2, cf.y2
        else:
            fx, fy = cf.x1, cf.y1
        # ... unless the other beacons' recent ranges tell the two apart (they do
        # not depend on the filter, which a turn or a mirror lock may have misled)
        by_ranges = self._mirror_by_ranges(idx, t_em, r_i, r_l, var_i, var_l, cf)
        if by_ranges is not None:
            fx, fy = by_ranges
        kf.predict(t_em)
        ambiguous = det > 0.0 and max(m1, m2) <= p.gate_chi2 * det
        if ambiguous or cf.gap_m > 0.0:
            # both solutions are plausible (near the baseline), or the circles
            # miss each other (the fix is only the point between them): do not
            # pick one, linearise the two ranges at the prediction (an EKF update)
            lx, ly = px, py
        else:
            lx, ly = fx, fy
        ji = range_jacobian(net, idx, lx, ly, depth)
        jl = range_jacobian(net, net.listener, lx, ly, depth)
        rows = [ji, jl]
        # the ranges linearised at (lx, ly): r ≈ r̂(l) + J (p − l)
        z = [r_i - self._range3(idx, lx, ly) + ji[0] * lx + ji[1] * ly,
             r_l - self._range3(net.listener, lx, ly) + jl[0] * lx + jl[1] * ly]
        mx, my = (cf.x2, cf.y2) if (fx, fy) == (cf.x1, cf.y1) else (cf.x1, cf.y1)
        ls, consistent = self._multi_fix(idx, t_em, r_i, r_l, var_i, var_l, fx, fy)
        if not consistent:
            # the cycle's ranges disagree with every other beacon's: a false or
            # late detection in it, whatever the filter says.  The reply may be
            # the bad part (a multipath or false one paired when the direct one
            # was missed): the range to the beacon comes from the two
            # interrogations alone, if the filter agrees with it well
            self._emit_fix(cyc, t_em, cf, fx, fy, r_i, r_l, bias, False, out)
            self._last_range_only = False
            if self._range_only(cyc, idx, rg.r_i, out, fallback=True):
                self.dropped["reply_refused"] += 1
            else:
                self.dropped["inconsistent"] += 1
            return
        lat = self._lateral(fx - px, fy - py, pxx, pxy, pyy, ji, jl, var_i, var_l)
        ok, _d2 = kf.update(rows, z, [var_i, var_l], p.gate_chi2,
                                p.soft_gate_chi2)
        if lat is not None and self._maneuver(lat) and not ok:
            ok, _d2 = kf.update(rows, z, [var_i, var_l], p.gate_chi2,
                                p.soft_gate_chi2)
        fix = AuvFix(cyc.t, t_em, cyc.beacon, ls[0], ls[1], mx, my, r_i, r_l, bias, ok,
                     False, ls[2], ls[3], ls[4])
        self.last_fix = fix
        out.append(fix)
        self.plan.fix(fix)  # the AUV's progress along its plan, whatever the filter made of it
        self._last_range_only = False
        if ok:
            # only ranges the filter accepted take part in later fixes
            self._ranges[idx] = (t_em, r_i, var_i)
            self._ranges[net.listener] = (t_em, r_l, var_l)
            self._accepted(t_em, cyc.t, fx, fy, e, out)
            return
        self.dropped["innovation"] += 1
        rej = self._rejected
        rej.append(entry)
        while rej and rej[0].t < t_em - p.init_window_s:
            rej.popleft()
        if len(rej) < p.reacquire_after:
            return
        # the filter refused several recent fixes: let every recent fix vote; if
        # the vote disagrees with the filter, the filter is wrong (locked on the
        # mirror track after crossing a baseline, or lost in a turn) — start again
        # from the fixes; if the vote agrees with the filter, or cannot decide,
        # the refused fixes were outliers
        rej.clear()
        voted = self._vote(self._init_buf, reinit=True)
        if voted is None:
            return
        chosen, recent = voted
        dx, dy = chosen[0] - px, chosen[1] - py
        if dx * dx + dy * dy <= (2.0 * p.init_agree_m) ** 2 or (
                det > 0.0 and (d * dx * dx - 2.0 * b * dx * dy + a * dy * dy) <= p.gate_chi2 * det):
            return
        # which explains more of the recent fixes: the filter's track, or a line
        # through the fixes consistent with the vote?  (one outlier never wins)
        x0, y0, vx, vy = kf.x
        h0 = self._explained(recent, x0, y0, vx, vy, t_em)
        line = self._line_through(recent, self._init_buf[-1], chosen)
        if line is None or self._explained(recent, *line, t_em) < h0 + 2:
            return
        self._prior = (px, py)
        self._init_from(recent, self._init_buf[-1], chosen, (kf.x[2], kf.x[3]))
        self.dropped["reacquired"] += 1
        self._accepted(t_em, cyc.t, chosen[0], chosen[1], e, out)

    def _explained(self, entries: list[_InitEntry], x: float, y: float, vx: float,
                   vy: float, t: float) -> int:
        """How many ``entries`` have a solution within ``init_agree_m`` of the
        straight track through (x, y) at UTC ``t`` with velocity (vx, vy)."""
        tol2 = self.p.init_agree_m ** 2
        n = 0
        for e in entries:
            ex = x + vx * (e.t - t)
            ey = y + vy * (e.t - t)
            cf = e.cf
            if min((cf.x1 - ex) ** 2 + (cf.y1 - ey) ** 2,
                   (cf.x2 - ex) ** 2 + (cf.y2 - ey) ** 2) <= tol2:
                n += 1
        return n

    def _line_through(self, entries: list[_InitEntry], last: _InitEntry,
                      chosen: tuple[float, float]
                      ) -> tuple[float, float, float, float] | None:
        """Least-squares straight track (x, y, vx, vy at ``last.t``) through the
        solutions of ``entries`` consistent with ``chosen`` (None if < 2)."""
        p = self.p
        pts = []
        for e in entries:
            allow = p.init_agree_m + p.max_speed_mps * abs(last.t - e.t)
            cf = e.cf
            d1 = math.dist((cf.x1, cf.y1), chosen)
            d2 = math.dist((cf.x2, cf.y2), chosen)
            q = (cf.x1, cf.y1) if d1 <= d2 else (cf.x2, cf.y2)
            if min(d1, d2) <= allow:
                pts.append((e.t - last.t, q[0], q[1]))
        n = len(pts)
        if n < 2:
            return None
        mt = sum(t for t, _, _ in pts) / n
        mx = sum(x for _, x, _ in pts) / n
        my = sum(y for _, _, y in pts) / n
        stt = sum((t - mt) ** 2 for t, _, _ in pts)
        if stt < 1e-6:
            return None
        vx = sum((t - mt) * (x - mx) for t, x, _ in pts) / stt
        vy = sum((t - mt) * (y - my) for t, _, y in pts) / stt
        return mx - vx * mt, my - vy * mt, vx, vy

    def _range3(self, idx: int, x: float, y: float) -> float:
        """3-D range (m) from beacon ``idx`` to the AUV at (x, y, depth)."""
        net = self.net
        dx = x - net.north[idx]
        dy = y - net.east[idx]
        dz = self.depth - net.depth[idx]
        return math.sqrt(dx * dx + dy * dy + dz * dz)

    def _range_only(self, cyc: Cycle, idx: int, r: float, out: list[AuvFix | AuvTrack],
                    fallback: bool = False) -> bool:
        """One range to beacon ``idx`` (a cycle on the listener's own beacon, a
        cycle whose reply was not heard, or with ``fallback`` one whose fix was
        refused): an EKF update at the emission time (the listener's range to
        it predicted when it is not measured).  True when accepted; with
        ``fallback`` a refusal is neither counted nor published."""
        kf = self.kf
        if not kf.initialised:
            if not fallback:
                self.dropped["range_only_uninitialised"] += 1
            return False
        net = self.net
        p = self.p
        lst = net.listener
        c = net.c
        depth = self.depth

        def emission(r_b: float) -> tuple[float, float]:
            """Emission time and the listener's range for a range r_b to idx."""
            if idx == lst:
                return cyc.t_i - r_b / c, r_b
            x, y, _, _, _ = kf.predicted(cyc.t_i)
            r_l = self._range3(lst, x, y)
            x, y, _, _, _ = kf.predicted(cyc.t_i - r_l / c)
            r_l = self._range3(lst, x, y)
            return cyc.t_i - r_l / c, r_l

        t_em, r_l = emission(r)
        if self._plan_corners(t_em):
            t_em, r_l = emission(r)
        px, py, _, _, _ = kf.predicted(t_em)
        bias = 0.0
        if p.motion_correction:
            bias = motion_bias(net, idx, r, px, py, depth, kf.x[2], kf.x[3])
            r -= bias
            t_em, r_l = emission(r)
            px, py, _, _, _ = kf.predicted(t_em)
        dz = depth - net.depth[idx]
        if horizontal_radius(r, dz) < -1.0:
            if not fallback:
                self.dropped["depth"] += 1
            return False
        kf.predict(t_em)
        dx, dy = px - net.north[idx], py - net.east[idx]
        r_hat = math.sqrt(dx * dx + dy * dy + dz * dz)
        j = range_jacobian(net, idx, px, py, depth)
        var_i, _ = self._var(net, idx, p.timing_sigma_s, p.range_sigma_m)
        z = [r - r_hat + j[0] * px + j[1] * py]
        # a fallback must agree well: it only replaces a reply, not the filter's doubt
        gate = p.soft_gate_chi2 if fallback else p.gate_chi2
        ok, _d2 = kf.update([j], z, [var_i], gate, p.soft_gate_chi2)
        # the point of the range circle nearest the prediction, for the record
        rho = max(horizontal_radius(r, dz), 0.0)
        hd = math.hypot(dx, dy)
        if hd > 1e-9:
            cx, cy = net.north[idx] + dx / hd * rho, net.east[idx] + dy / hd * rho
        else:
            cx, cy = px, py
        if not ok and fallback:
            return False
        if ok:
            self._ranges[idx] = (t_em, r, var_i)
        fix = AuvFix(cyc.t, t_em, cyc.beacon, cx, cy, cx, cy, r, r_l, bias, ok, True)
        self.last_fix = fix
        out.append(fix)
        if not ok:
            self.dropped["innovation"] += 1
            return False
        self._last_range_only = True
        self._accepted(t_em, cyc.t, cx, cy, var_i, out)
        return True

    def _other_ranges(self, idx: int, t_em: float, x: float, y: float
                      ) -> list[tuple[int, float, float]]:
        """The newest accepted range to every beacon but ``idx`` and the listener,
        heard within ``ls_window_s`` before ``t_em``, carried to ``t_em`` along
        the filter's velocity (directions taken at (x, y)), its variance grown
        by the velocity's uncertainty and the manoeuvring model's acceleration."""
        kf = self.kf
        if not kf.initialised:
            return []
        net = self.net
        p = self.p
        lst = net.listener
        vx, vy = kf.x[2], kf.x[3]
        P = kf.P
        out = []
        for k, (tk, rk, vk) in self._ranges.items():
            dt = t_em - tk
            if k in (idx, lst) or not 0.0 <= dt <= p.ls_window_s:
                continue
            jx, jy = range_jacobian(net, k, x, y, self.depth)
            pv = jx * jx * P[2][2] + 2.0 * jx * jy * P[2][3] + jy * jy * P[3][3]
            grow = dt * dt * pv + p.maneuver_accel_psd * dt ** 3 / 3.0
            out.append((k, rk + (jx * vx + jy * vy) * dt, vk + grow))
        return out

    def _mirror_by_ranges(self, idx: int, t_em: float, r_i: float, r_l: float,
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
        others = self._other_ranges(idx, t_em, mx, my)
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

    def _multi_fix(self, idx: int, t_em: float, r_i: float, r_l: float, var_i: float,
                   var_l: float, fx: float, fy: float
                   ) -> tuple[tuple[float, float, float, float, float], bool]:
        """The cycle's fix with every beacon heard within ``ls_window_s``: each
        older range brought to ``t_em`` along the filter's velocity (its
        variance grown by the velocity's uncertainty and the manoeuvring
        model's acceleration over the interval), then the joint least-squares
        position from the chosen two-circle solution (fx, fy).  Returns
        (x, y, Cxx, Cxy, Cyy); the two-circle solution (and its covariance) when
        no other beacon was heard or the ranges do not agree on one position
        (χ² of the residuals beyond ``gate_chi2`` + 2 per extra range), and
        whether they agree (True with no other beacon).  Only ranges of
        accepted cycles are remembered for later fixes."""
        net = self.net
        p = self.p
        depth = self.depth
        ranges = [(idx, r_i, var_i), (net.listener, r_l, var_l),
                  *self._other_ranges(idx, t_em, fx, fy)]
        two = ls_fix(net, ranges[:2], depth, fx, fy, 1)
        c2 = (two[2], two[3], two[4]) if two is not None else (math.nan,) * 3
        if len(ranges) > 2:
            # the joint solution, unless the ranges disagree (a false or late
            # detection in this cycle): then the cycle's own pair
            sol = ls_fix(net, ranges, depth, fx, fy)
            if sol is not None:
                if ls_chi2(net, ranges, depth, sol[0], sol[1]) <= (
                        p.gate_chi2 + 2.0 * (len(ranges) - 2)):
                    return sol, True
                return (fx, fy, *c2), False
        return (fx, fy, *c2), True

    def _lateral(self, ex: float, ey: float, pxx: float, pxy: float, pyy: float,
                 ji: tuple[float, float], jl: tuple[float, float], var_i: float,
                 var_l: float) -> float | None:
        """The fix's innovation (ex, ey) across the filter's course, normalised by
        its predicted 1σ (prediction + fix covariance J⁻¹ diag(var) J⁻ᵀ); None when
        the course or the fix geometry is undefined."""
        vx, vy = self.kf.x[2], self.kf.x[3]
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

    def _maneuver(self, lat: float) -> bool:
        """Two-sided CUSUM on the normalised cross-course innovation of the fixes
        (each clipped to ± ``maneuver_cap``): a turn pushes the fixes steadily to
        one side of the predicted course, outliers fall on either side.  When it
        fires, open up the filter's covariance and restart the line fit; True
        then."""
        p = self.p
        zc = max(-p.maneuver_cap, min(p.maneuver_cap, lat))
        k = p.maneuver_drift
        gp = max(0.0, self._cusum_pos + zc - k)
        gn = max(0.0, self._cusum_neg - zc - k)
        if gp <= p.maneuver_threshold and gn <= p.maneuver_threshold:
            self._cusum_pos, self._cusum_neg = gp, gn
            return False
        self._cusum_pos = self._cusum_neg = 0.0
        self._inflate(restart_line=p.maneuver_restarts_line)
        self.dropped["maneuver"] += 1
        return True

    def _inflate(self, restart_line: bool = True) -> None:
        """Add the turn covariance to the filter and (optionally) mark the line
        for a restart."""
        p = self.p
        self.kf.inflate(p.turn_pos_sigma_m ** 2, p.turn_vel_sigma_mps ** 2)
        if restart_line:
            self._line_restart = True

    def _emit_fix(self, cyc: Cycle, t_em: float, cf: CircleFix, fx: float, fy: float,
                  r_i: float, r_l: float, bias: float, ok: bool,
                  out: list[AuvFix | AuvTrack]) -> None:
        if fx == cf.x1 and fy == cf.y1:
            mx, my = cf.x2, cf.y2
        else:
            mx, my = cf.x1, cf.y1
        fix = AuvFix(cyc.t, t_em, cyc.beacon, fx, fy, mx, my, r_i, r_l, bias, ok)
        self.last_fix = fix
        out.append(fix)

    # ------------------------------------------------------- initialisation

    def _try_init(self, buf: deque[_InitEntry]) -> tuple[float, float] | None:
        """Vote on the latest fix of ``buf`` (:meth:`_vote`) and, if resolved,
        initialise the filter from every fix of ``buf`` consistent with it.
        Returns the chosen position of the latest fix, or None (wait)."""
        voted = self._vote(buf)
        if voted is None:
            return None
        chosen, recent = voted
        self._init_from(recent, buf[-1], chosen)
        return chosen

    def _vote(self, buf: deque[_InitEntry], reinit: bool = False
              ) -> tuple[tuple[float, float], list[_InitEntry]] | None:
        """Resolve the mirror of the latest fix of ``buf``: each recent fix on
        another baseline votes for the solution it has a candidate near (within
        ``init_agree_m`` + ``max_speed_mps`` × their time apart) when it is near
        only one of them; a solution needs more than twice the other's votes.
        With a single baseline the prior decides, and ``reacquire_after`` fixes
        must agree with the choice.
        Returns (chosen position, the recent fixes) or None (undecided)."""
        if not buf:
            return None
        p = self.p
        last = buf[-1]
        horizon = last.t - p.init_window_s
        recent = [e for e in buf if e.t >= horizon]
        c1 = (last.cf.x1, last.cf.y1)
        c2 = (last.cf.x2, last.cf.y2)
        baselines = self.net.n - 1
        chosen: tuple[float, float] | None = None
        if baselines <= 1:
            px, py = self._prior
            chosen = c1 if math.dist(c1, (px, py)) <= math.dist(c2, (px, py)) else c2
            # the prior only picks the side; ``reacquire_after`` fixes must agree
            # (a cycle mis-assembled from missed pings gives a fix far off)
            agree = sum(1 for e in recent if min(
                math.dist((e.cf.x1, e.cf.y1), chosen), math.dist((e.cf.x2, e.cf.y2), chosen))
                <= p.init_agree_m + p.max_speed_mps * abs(last.t - e.t))
            if agree < p.reacquire_after:
                return None
        else:
            v1 = v2 = 0
            near_any = False
            for e in recent:
                if e.idx == last.idx:
                    continue
                allow = p.init_agree_m + p.max_speed_mps * abs(last.t - e.t)
                e1 = (e.cf.x1, e.cf.y1)
                e2 = (e.cf.x2, e.cf.y2)
                ok1 = min(math.dist(c1, e1), math.dist(c1, e2)) <= allow
                ok2 = min(math.dist(c2, e1), math.dist(c2, e2)) <= allow
                near_any = near_any or ok1 or ok2
                if ok1 and not ok2:
                    v1 += 1
                elif ok2 and not ok1:
                    v2 += 1
            if v1 > 2 * v2:  # a clear majority (outliers may vote too)
                chosen = c1
            elif v2 > 2 * v1:
                chosen = c2
            elif near_any and math.dist(c1, c2) <= p.init_agree_m:
                chosen = c1  # near the baseline: both solutions agree anyway
        if chosen is None:
            return None
        return chosen, recent

    def _init_from(self, recent: list[_InitEntry], last: _InitEntry,
                   chosen: tuple[float, float],
                   velocity: tuple[float, float] = (0.0, 0.0)) -> None:
        """Initialise the filter on the remembered fixes consistent with ``chosen``,
        from ``velocity`` (m/s, 1σ ``init_vel_sigma_mps``)."""
        p = self.p
        net = self.net
        kf = self.kf
        first = True
        for e in recent:
            allow = p.init_agree_m + p.max_speed_mps * abs(last.t - e.t)
            cands = ((e.cf.x1, e.cf.y1), (e.cf.x2, e.cf.y2))
            q = min(cands, key=lambda c: math.dist(c, chosen))
            if e is not last and math.dist(q, chosen) > allow:
                continue
            if e is last:
                q = chosen
            if first:
                kf.init(e.t, q[0], q[1], velocity[0], velocity[1], p.init_pos_sigma_m ** 2,
                        p.init_vel_sigma_mps ** 2)
                first = False
                continue
            kf.predict(e.t)
            ji = range_jacobian(net, e.idx, q[0], q[1], self.depth)
            jl = range_jacobian(net, net.listener, q[0], q[1], self.depth)
            var_i, var_l = self._var(net, e.idx, p.timing_sigma_s, p.range_sigma_m)
            kf.update([ji, jl], [e.r_i - self._range3(e.idx, q[0], q[1]) + ji[0] * q[0]
                                 + ji[1] * q[1],
                                 e.r_l - self._range3(net.listener, q[0], q[1]) + jl[0] * q[0]
                                 + jl[1] * q[1]], [var_i, var_l])
        self._maneuvering = False
        if self._ever_init:
            self._reacquired_utc = last.t
        self._ever_init = True
        self._lost = False
        self.rls.initialised = False

    # ------------------------------------------------------------ updates

    def _accepted(self, t_em: float, t: float, fx: float, fy: float, fix_var: float,
                  out: list[AuvFix | AuvTrack]) -> None:
        """After an accepted filter update at emission time ``t_em``: RLS, track."""
        p = self.p
        kf = self.kf
        rls = self.rls
        self.fixes_accepted += 1
        self._last_update_utc = t_em
        drops = self.cycles.cycles_dropped
        self._drops_at_update = drops["missed_ping"] + drops["superseded"] + drops["sequence"]
        self._lost = False
        P = kf.P
        floor = p.rls_sigma_floor_m
        if not rls.initialised:
            rls.reset(t_em, kf.x[0], kf.x[1], kf.x[2], kf.x[3], 0.5 * (P[0][0] + P[1][1]),
                      0.5 * (P[2][2] + P[3][3]), 0.5 * (P[0][2] + P[1][3]),
                      max(kf.pos_sigma(), floor))
        else:
            if p.rls_input == "kf":
                x, y, sigma = kf.x[0], kf.x[1], max(kf.pos_sigma(), floor)
            else:
                if self._last_range_only:
                    x, y, sigma = kf.x[0], kf.x[1], max(kf.pos_sigma(), floor)
                else:
                    x, y, sigma = fx, fy, max(math.sqrt(0.5 * fix_var), floor)
            turn = rls.update(t_em, x, y, sigma)
            if turn:
                # a turn: open up the filter (it follows the new course faster)
                # and restart the line from the filter with that covariance
                self._inflate()
            # the IMM's manoeuvring model: restart the line from the filter at
            # every update while it dominates, and once more when it ends
            state = self._imm_state()
            if state or self._line_restart:
                if state == "enter" or not state:
                    self.turns += 1
                self._line_restart = False
                self._turn_utc = t_em
                P = kf.P
                rls.reset(t_em, kf.x[0], kf.x[1], kf.x[2], kf.x[3], 0.5 * (P[0][0] + P[1][1]),
                          0.5 * (P[2][2] + P[3][3]), 0.5 * (P[0][2] + P[1][3]),
                          max(kf.pos_sigma(), floor))
        self.plan.update(t_em, kf.x[0], kf.x[1], kf.x[2], kf.x[3], kf.pos_sigma())
        track = self._build(t)
        self.last_track = track
        out.append(track)

    def _plan_corners(self, t_em: float) -> bool:
        """Turn the filter onto the plan's next leg at each corner its prediction
        reaches by ``t_em`` (:meth:`.plan.PlanMatcher.corner`); True if it did."""
        kf = self.kf
        pp = self.p.plan
        turned = False
        while (c := self.plan.corner(kf.t, kf.x[0], kf.x[1], kf.x[2], kf.x[3], t_em)):
            kf.predict(c.t)
            kf.turn_to(c.course_rad)
            kf.inflate(pp.corner_pos_sigma_m ** 2, pp.corner_vel_sigma_mps ** 2)
            self._line_restart = turned = True
        return turned

    def _imm_state(self) -> str:
        """The IMM's manoeuvre state after an update: ``enter`` (the manoeuvring
        model's probability rose to ``maneuver_on``), ``during``, ``exit`` (it
        fell to ``maneuver_off``), or "" (straight, or a single-model filter)."""
        kf = self.kf
        if not isinstance(kf, Imm):
            return ""
        mu = kf.maneuver_probability
        p = self.p
        if not self._maneuvering:
            if mu >= p.maneuver_on:
                self._maneuvering = True
                return "enter"
            return ""
        if mu <= p.maneuver_off:
            self._maneuvering = False
            return "exit"
        return "during"

    def _flags(self, age: float) -> int:
        p = self.p
        f = TrackFlags.NONE
        if self.kf.initialised:
            f |= TrackFlags.INITIALISED
        if self.rls.initialised and self.rls.updates >= p.rls_min_updates:
            f |= TrackFlags.LINE_VALID
        t_em = self._last_update_utc
        if t_em - self._turn_utc <= p.turning_flag_s:
            f |= TrackFlags.TURNING
        if t_em - self._reacquired_utc <= p.stale_after_s:
            f |= TrackFlags.REACQUIRED
        if age > p.stale_after_s:
            f |= TrackFlags.STALE
        if self._lost:
            f |= TrackFlags.LOST
        if self._bad_geometry:
            f |= TrackFlags.BAD_GEOMETRY
        if self._buoy_fault:
            f |= TrackFlags.BUOY_FAULT
        if self._last_range_only:
            f |= TrackFlags.RANGE_ONLY
        return int(f)

    def _build(self, t: float) -> AuvTrack:
        rls = self.rls
        kf = self.kf
        off = self._rt_offset()
        x0, y0, vx, vy = rls.x0, rls.y0, rls.vx, rls.vy
        v = math.hypot(vx, vy)
        h = (vy * x0 - vx * y0) / v if v > 0.0 else math.nan
        age = t - (self._last_update_utc + off)
        kx = kf.x
        return AuvTrack(t, x0, y0, vx, vy, math.atan2(vy, vx), v, h, rls.covariance(),
                        rls.t0 + off, rls.t0, age, self._flags(age), self._lost,
                        kx[0], kx[1], kx[2], kx[3], kf.pos_sigma(),
                        *self.plan.track_fields(rls.t0))

    def _track(self, t: float, last: AuvTrack) -> AuvTrack:
        """``last`` re-stamped at ``t`` with its age and flags brought up to date."""
        age = t - (self._last_update_utc + self._rt_offset())
        return AuvTrack(t, last.x0_m, last.y0_m, last.vx_mps, last.vy_mps, last.psi_auv_rad,
                        last.v_auv_mps, last.h_auv_m, last.cov, last.t0, last.t0_utc_s, age,
                        self._flags(age), self._lost, last.kf_x_m, last.kf_y_m,
                        last.kf_vx_mps, last.kf_vy_mps, last.kf_pos_sigma_m,
                        *self.plan.track_fields(last.t0_utc_s))

    def _check_lost(self, t: float | None, out: list[AuvFix | AuvTrack]) -> None:
        """Declare the track lost when silent too long or too uncertain."""
        if self._lost or not self.kf.initialised or self.last_track is None:
            return
        if not isinstance(t, (float, int)) or not math.isfinite(t):
            return
        p = self.p
        off = self._rt_offset()
        age = t - (self._last_update_utc + off)
        _, _, pxx, _, pyy = self.kf.predicted(t - off)
        if age <= p.lost_after_s and 0.5 * (pxx + pyy) <= p.lost_sigma_m ** 2:
            return
        self._lost = True
        self.plan.leave()  # matched again once the track is back
        kx = self.kf.x
        self._prior = (kx[0], kx[1])
        self.kf.reset()
        self.rls.initialised = False
        self._init_buf.clear()
        self._rejected.clear()
        track = self._track(t, self.last_track)
        self.last_track = track
        out.append(track)
