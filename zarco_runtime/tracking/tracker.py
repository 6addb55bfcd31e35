"""The passive AUV tracker: acoustic events in, AUV track out (paper IV–V).

:class:`AuvTracker` glues the chain, one event at a time::

    AcousticEvent ─▶ clock check (.timemap) ─▶ CycleAssembler (.cycles) ─▶
    cycle_ranges at the estimated sound speed and beacon positions, less the
    estimated range bias
    (.fix, .calibration) ─▶ fix assembly (.assembly: motion-bias correction,
    circle fix, mirror choice, joint fix, range-only) ─▶ filter (an IMM of a
    quiet coordinated turn, manoeuvring and turning models, or one CV filter;
    gated at the measured noise, .gates) ─▶ manoeuvre detection (.maneuver)
    ─▶ LineRls (forgetting, re-centred, turn reset) ─▶ AuvTrack
                         └─▶ calibration (.calibration): sound speed, biases

and keeps what ties them together: acquisition and re-acquisition
(:mod:`.acquire`), re-anchoring, the track's flags, its aging and the lost
declaration.

* Cycles on beacon i ≠ listener give a two-circle fix; cycles on the listener's
  own beacon, and cycles whose reply was missed (two interrogations), give one
  range and are applied as a range-only update; a cycle whose ranges disagree
  with the other beacons' is tried on its interrogation-only range alone (the
  reply may be a multipath or false one: ``reply_refused``).  A missed
  interrogation leaves two half cycles (:mod:`.cycles`), each one range
  combination applied as a one-row update (``half_cycles``; not fed to the
  calibration).  Updates are made
  in range space (the two ranges linearised at the chosen solution, or at the
  prediction when both solutions are plausible near a baseline or the circles
  miss each other), so a fix with poor geometry only informs the filter along
  the directions it constrains, and every range is used once.
* The published fix (:class:`AuvFix`) is the joint least-squares position of
  the cycle's ranges and the newest accepted range to every other beacon heard
  within ``ls_window_s`` (carried to the emission time along the filter's
  velocity), with its covariance: more beacons never make it worse.
* Initialisation resolves the mirror by a vote between fixes on different
  baselines; with a single baseline, by the configured prior.  Once the
  filter runs, the prediction resolves it (smaller Mahalanobis distance),
  unless the other beacons' recent ranges tell the two apart.
* Innovations beyond ``gate_chi2`` are refused (``innovation``), those beyond
  ``soft_gate_chi2`` down-weighted, the range variances scaled by the noise
  the joint fixes measure (:mod:`.gates`).  ``reanchor_after`` consistent
  fixes refused in a row open the filter up until the fix passes
  (``reanchored``).  When ``reacquire_after`` fixes were
  refused within ``init_window_s``, all recent fixes vote; if the vote
  disagrees with the filter and a straight track through the voted solutions
  explains at least two more fixes than the filter's track, the filter
  re-initialises from the fixes (``reacquired``): this undoes a lock on the
  mirror track after crossing a baseline, or a turn the filter lost, while
  outliers never win.
* Manoeuvres (:mod:`.maneuver`): the IMM's probability of not flying straight,
  a CUSUM on the fixes' cross-course innovation and a CUSUM on the RLS
  residuals declare turns; the line restarts from the filter while a turn
  lasts (TURNING set meanwhile and ``turning_flag_s`` after).  An arc (the
  quiet model's averaged turn rate) sets TURNING without restarting the
  line; while turning, :meth:`AuvTracker.tick` brings the filter's state
  forward along its turn rate.  A turn rate the path does not bear out (what
  a sharp turn leaves in the quiet model) is set back to 0 (``spin``); so
  is one left on the straight part of a leg of the AUV's plan, which says
  the AUV flies straight there (``plan_straight``, once per leg).
* Every accepted range also feeds the sound-speed estimate
  (:mod:`.calibration`); the network the ranges are computed with follows it.
* Aging: no accepted update for ``stale_after_s`` sets STALE; for
  ``lost_after_s``, or a predicted position σ above ``lost_sigma_m``, the track
  is declared LOST (published once, then by :meth:`AuvTracker.tick`) and the
  filter re-initialises from the next fixes (REACQUIRED).

Clocks: event times ``utc_epoch_s`` (the buoy's GPS-disciplined UTC) drive all
the estimation; the runtime clock ``t`` of the events is only used to map UTC
onto it (:mod:`.timemap`) for ``t0``, the track's time origin on the runtime
clock, and the aging.

Counters (:meth:`AuvTracker.counters`): ``event.<reason>`` for dropped events
(see :mod:`.cycles`, plus ``clock``), ``cycle.<reason>`` for lost cycles,
``fix.<reason>`` for cycles that gave no accepted update (``impossible_timing``,
``depth``, ``no_intersection``, ``innovation``, ``range_only_uninitialised``,
``init_pending``, ``inconsistent``: its ranges disagree with the other
beacons'; ``half_cycle_refused``, ``half_cycle_uninitialised``,
``half_cycle_geometry``: a half cycle whose combination barely depends on the
position) and for tracker events (``maneuver``, ``reacquired``, ``reanchored``,
``clock_resync``, ``reply_refused``, ``spin``, ``plan_straight``, ``mirror_prior``:
the prior resolved the mirror of beacons in a line, :mod:`.acquire`;
``calibration_restarted``: a sound-speed hypothesis strayed from the filter and
was restarted from it, :mod:`.calibration`), ``internal``
for any unexpected exception (never raised: the tests assert it stays absent).

Pure and deterministic: no I/O, no clock reads.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

from zarco_core.auv_messages import AuvFix, AuvTrack, BuoyStatus, TrackFlags
from zarco_runtime.tracking.acquire import Acquisition, InitEntry
from zarco_runtime.tracking.assembly import FixAssembly, Prediction, RangeOnly
from zarco_runtime.tracking.calibration import SoundSpeedEstimator
from zarco_runtime.tracking.cycles import Cycle, CycleAssembler
from zarco_runtime.tracking.fix import CircleFix, CycleRanges, cycle_ranges, range_variances
from zarco_runtime.tracking.gates import NoiseScale
from zarco_runtime.tracking.imm import Imm, ModelSpec, turn_step
from zarco_runtime.tracking.kalman import CvKalman
from zarco_runtime.tracking.maneuver import ManeuverDetector
from zarco_runtime.tracking.params import Network, TrackerParams
from zarco_runtime.tracking.plan import INFERRED_SOURCE, PlanMatcher
from zarco_runtime.tracking.plan_infer import LawnmowerInference
from zarco_runtime.tracking.rls import LineRls
from zarco_runtime.tracking.timemap import ClockCheck, TimeMap

#: the ranges are recomputed at a new sound speed once the estimate moved this far (m/s)
SOUND_SPEED_STEP_MPS = 0.01
#: the beacons' positions move with the survey estimate once it moved this far (m)
SURVEY_STEP_M = 0.05
#: 1σ (deg/s) of the turn rate the two fixed-rate turning models start a turn with
TURN_RATE_SIGMA_DPS = 2.0
#: the measured noise scale learns from updates while the IMM's probability of a
#: manoeuvre is at most this
STRAIGHT_NOISE_PROBABILITY = 0.2
#: cycles dropped in a row after which the prediction no longer narrows the
#: closing window (see AuvTracker._predict_range)
WINDOW_OFF_DROPS = 6
#: on its plan, the AUV is on a leg's straight part this far (m) past the arc of
#: the corner before it (and short of the next): the turn rate is checked once there
PLAN_STRAIGHT_MARGIN_M = 3.0

Out = list[AuvFix | AuvTrack]


def imm_bank(params: TrackerParams) -> Imm:
    """The IMM the tracker runs with ``motion_model = "imm"``: the quiet model
    (a straight line or a slow arc), the manoeuvring constant-velocity one, a
    coordinated turn at any rate, and two at ``turn_rate_dps`` (to starboard,
    to port), with the parameters' densities and sojourn times."""
    w0 = math.radians(params.turn_rate_dps)
    w_max = math.radians(params.max_turn_rate_dps)
    w_var = math.radians(TURN_RATE_SIGMA_DPS) ** 2
    turn = ModelSpec("ct", params.turn_accel_psd, params.turn_rate_psd, omega_max=w_max)
    return Imm([ModelSpec("ct", params.accel_psd, params.arc_rate_psd, omega_max=w_max),
                ModelSpec("cv", params.maneuver_accel_psd), turn,
                turn._replace(q_omega=w_var / params.turn_sojourn_s, omega0=w0,
                              omega0_var=w_var),
                turn._replace(q_omega=w_var / params.turn_sojourn_s, omega0=-w0,
                              omega0_var=w_var)],
               (params.straight_sojourn_s, params.maneuver_sojourn_s,
                params.turn_sojourn_s, params.turn_sojourn_s, params.turn_sojourn_s),
               (0.6, 0.1, 0.1, 0.1, 0.1))


class AuvTracker:
    """Passive LBL tracker of one AUV.  Feed :meth:`on_event` (or :meth:`process`)
    with every :class:`~zarco_core.auv_messages.AcousticEvent` in arrival
    order and call :meth:`tick` periodically; nothing here raises."""

    def __init__(self, params: TrackerParams) -> None:
        params.validate()
        self.p = params
        #: the network as configured (the prior sound speed c₀)
        self.net0: Network = Network.from_params(params.network, params.timing_tol_s)
        #: the network at the estimated sound speed (what the ranges are computed with)
        self.net: Network = self.net0
        self.cal: SoundSpeedEstimator | None = (SoundSpeedEstimator(params, self.net0)
                                                if params.calibrate else None)
        self._cal_restart = True
        #: the survey corrections the network's positions carry (north, east, m)
        self._offsets: list[tuple[float, float]] = [(0.0, 0.0)] * self.net0.n
        self.depth = params.auv_depth_m
        self.cycles = CycleAssembler(self.net, params.auv_depth_m, params.max_range_m,
                                     params.sequence, self._predict_range, 4.0,
                                     params.closing_margin_m)
        self.kf: CvKalman | Imm = (imm_bank(params) if params.motion_model == "imm"
                                   else CvKalman(params.accel_psd))
        self.rls = LineRls(params.rls_forgetting, params.turn_cusum_drift,
                           params.turn_cusum_threshold, params.turn_holdoff_s)
        self.clock = TimeMap(params.clock_tol_s, params.feed_latency_s)
        self.acq = Acquisition(params, self.net)
        self.asm = FixAssembly(params, self.net)
        self.man = ManeuverDetector(params)
        self.noise = NoiseScale()
        #: consistent fixes refused in a row (re-anchoring)
        self._refused_run = 0
        self.dropped: Counter[str] = Counter()
        #: fixes accepted by the filter, and all two-circle fixes computed
        self.fixes_accepted = 0
        self.fixes = 0
        self.turns = 0
        self.last_fix: AuvFix | None = None
        self.last_track: AuvTrack | None = None
        self._last_update_utc = -math.inf
        self._drops_at_update = 0
        self._lost = False
        self._ever_init = False
        self._reacquired_utc = -math.inf
        self._bad_geometry = False
        self._last_range_only = False
        self._buoy_fault = False
        #: the AUV's a-priori plan: which leg it is on, its progress (:mod:`.plan`)
        self.plan = PlanMatcher(params.plan)
        #: without a plan given, the lawnmower its legs make (:mod:`.plan_infer`);
        #: the plans inferred and not yet published (points; empty: cleared)
        self.infer = LawnmowerInference()
        self.inferred: list[tuple[tuple[float, float], ...]] = []
        self._given_plan = False
        #: the plan leg whose straight part the turn rate was last checked on
        self._straight_leg = -1

    # ------------------------------------------------------------ public API

    def set_plan(self, points: tuple[tuple[float, float], ...] | list[tuple[float, float]],
                 source: str = "") -> None:
        """The AUV's plan (NED points, m; empty: none) from ``source``.  A plan
        given stops the inference; none given lets it run, and a lawnmower
        already inferred serves again (queued in :attr:`inferred` to be
        published).  The tracker's own inferred plans coming back are ignored."""
        if source == INFERRED_SOURCE:
            return
        self._given_plan = bool(points)
        got = self.infer.plan
        if not points and got and self.p.plan.infer:
            self.plan.set_plan(got, INFERRED_SOURCE, tentative=True)
            self.inferred.append(got)
            return
        self.plan.set_plan(points, source)

    def on_event(self, ev: Any) -> AuvTrack | None:
        """Process one acoustic event; the AuvTrack it produced, if any."""
        track = None
        for m in self.process(ev):
            if isinstance(m, AuvTrack):
                track = m
        return track

    def process(self, ev: Any) -> Out:
        """Process one acoustic event; every message it produced (an AuvFix per
        cycle or half cycle that reached the fix stage, then the AuvTrack of
        the event's last accepted update or its lost declaration), in order:
        one track per event at most, whatever updates it made."""
        out: Out = []
        try:
            if not self._clock_ok(ev):
                return out
            before = self.cycles.accepted
            cycle = self.cycles.push(ev)
            if self.cycles.accepted != before:
                self.clock.update(ev.t, ev.t - ev.utc_epoch_s)
            for half in self.cycles.take_partial():
                self._on_half_cycle(half, out)
            if cycle is not None:
                self._on_cycle(cycle, out)
            self._check_lost(getattr(ev, "t", None), out)
        except Exception:  # the tracker must never take the runtime down
            self.dropped["internal"] += 1
        tracks = [m for m in out if isinstance(m, AuvTrack)]
        if len(tracks) > 1:
            # a missed interrogation's half cycles and the cycle the same event
            # closes: the last state stands for the event
            out = [m for m in out if not isinstance(m, AuvTrack) or m is tracks[-1]]
        return out

    def on_status(self, st: BuoyStatus) -> None:
        """Record the buoy's status (a non-zero fault code sets BUOY_FAULT)."""
        self._buoy_fault = getattr(st, "fault_code", 0) != 0

    def tick(self, t: float) -> AuvTrack | None:
        """Age the track to runtime time ``t`` (declaring it lost when due); the
        current track (None before the first initialisation)."""
        out: Out = []
        try:
            self._check_lost(t, out)
            if out:
                return out[-1]  # type: ignore[return-value]
            if self.last_track is None:
                return None
            if (self.kf.initialised and not self._lost
                    and (self.man.maneuvering or self.man.arcing)):
                return self._predicted(t, self.last_track)
            return self._track(t, self.last_track)
        except Exception:
            self.dropped["internal"] += 1
            return None

    def set_clock_offset(self, runtime_minus_utc_s: float) -> None:
        """Fix the runtime-minus-UTC offset (e.g. from the GPS time) instead of
        estimating it from the feed."""
        self.clock.set_fixed(runtime_minus_utc_s)

    @property
    def lost(self) -> bool:
        return self._lost

    def counters(self) -> dict[str, int]:
        """Every drop counter, prefixed ``event.``, ``cycle.`` or ``fix.``."""
        out = {f"event.{k}": v for k, v in self.cycles.dropped.items()}
        out.update({f"cycle.{k}": v for k, v in self.cycles.cycles_dropped.items()})
        out.update({(k if k == "internal" else f"fix.{k}"): v for k, v in self.dropped.items()})
        if self.acq.mirror_prior:
            out["fix.mirror_prior"] = self.acq.mirror_prior
        if self.plan.outliers:
            out["fix.plan_outlier"] = self.plan.outliers
        return out

    # ------------------------------------------------------------- clocks

    def _clock_ok(self, ev: Any) -> bool:
        """Refuse events whose runtime-minus-UTC offset jumped (``event.clock``);
        after a jump (:class:`~.timemap.TimeMap`) forget every pending cycle and
        the filter."""
        check = self.clock.check(ev)
        if check is ClockCheck.OK:
            return True
        if check is ClockCheck.RESYNC:
            self.dropped["clock_resync"] += 1
            self.cycles.reset(clock=True)
            self.asm.clear()
            self.kf.reset()
            self.rls.initialised = False
            self.acq.clear()
            return True
        self.cycles.dropped["clock"] += 1
        return False

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

    def _on_cycle(self, cyc: Cycle, out: Out) -> None:
        net = self.net
        p = self.p
        rg = self._ranges(cyc)
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
        corrected = self.asm.circle(kf, rg)
        if corrected is None:
            self.dropped["depth"] += 1
            return
        cf, r_i, r_l, bias = corrected
        t_em = cyc.t_i - r_l / net.c
        if cf.gap_m > p.max_gap_m:
            self.dropped["no_intersection"] += 1
            return
        self.fixes += 1
        self._bad_geometry = cf.gap_m > 0.0
        entry = InitEntry(t_em, idx, cf, r_i, r_l)
        self.acq.buf.append(entry)
        var0 = range_variances(net, idx, p.timing_sigma_s, p.range_sigma_m)
        scale = self.noise.scale
        var_i, var_l = var0[0] * scale, var0[1] * scale
        if not kf.initialised:
            voted = self.acq.vote()
            if voted is None:
                self.dropped["init_pending"] += 1
                self._emit_fix(cyc, t_em, cf, cf.x1, cf.y1, r_i, r_l, bias, False, out)
                return
            chosen, recent = voted
            self._init_from(recent, entry, chosen)
            fx, fy = chosen
            self._emit_fix(cyc, t_em, cf, fx, fy, r_i, r_l, bias, True, out)
            self._accepted(t_em, cyc.t, fx, fy, var_i + var_l, out)
            return
        self._track_cycle(cyc, rg.r_i, t_em, cf, entry, r_i, r_l, bias, var_i, var_l, var0,
                          out)

    def _ranges(self, cyc: Cycle) -> CycleRanges:
        """The cycle's ranges at the estimated sound speed, corrected for the
        estimated range bias of its beacon (:mod:`.calibration`)."""
        net = self.net
        rg = cycle_ranges(cyc, net)
        if self.cal is not None:
            b = self.cal.bias(rg.index)
            if b != 0.0:
                rg.r_i -= b
                if rg.index != net.listener:
                    rg.r_l += b
                    rg.emission_utc_s = cyc.t_i - rg.r_l / net.c
        return rg

    def _calibrate(self, cyc: Cycle, t_em: float, idx: int, bias: float, reply: bool,
                   var_i: float, var_l: float) -> None:
        """Fold an accepted cycle's ranges into the calibration (``reply``: its
        listener range too) and move the network to the new sound speed and,
        when the survey hypothesis is the reported one, the beacons to their
        corrected positions (the sound speed it estimates goes with them)."""
        cal = self.cal
        if cal is None:
            return
        kf = self.kf
        if self._cal_restart or not cal.initialised:
            # the motion filter's state already holds this cycle: start from it
            cal.start(kf.t, kf.x[0], kf.x[1], kf.x[2], kf.x[3], kf.P)
            self._cal_restart = False
            return
        cal.predict(t_em)
        # the filter's time is not always the cycle's emission (up to 0.7 s
        # apart when another update came in between): carried to it
        dt = t_em - kf.t
        if cal.anchor(kf.x[0] + kf.x[2] * dt, kf.x[1] + kf.x[3] * dt, kf.x[2], kf.x[3], kf.P):
            self.dropped["calibration_restarted"] += 1
        rg0 = cycle_ranges(cyc, self.net0)
        cal.beacon_range(idx, rg0.r_i - bias, var_i)
        if reply and idx != self.net0.listener:
            cal.listener_range(idx, rg0.r_l - bias, var_l)
        c = cal.sound_speed_mps
        offs = cal.offsets()
        if abs(c - self.net.c) > SOUND_SPEED_STEP_MPS or max(
                (abs(a[0] - b[0]) + abs(a[1] - b[1]) for a, b in zip(offs, self._offsets,
                                                                    strict=True)),
                default=0.0) > SURVEY_STEP_M:
            self._offsets = offs
            self._set_network(self.net0.corrected(c, offs))

    def _set_network(self, net: Network) -> None:
        self.net = net
        self.cycles.net = net
        self.acq.net = net
        self.asm.net = net

    def _track_cycle(self, cyc: Cycle, r_raw: float, t_em: float, cf: CircleFix,
                     entry: InitEntry, r_i: float, r_l: float, bias: float, var_i: float,
                     var_l: float, var0: tuple[float, float], out: Out) -> None:
        """A two-circle cycle while the filter runs: mirror choice, consistency
        with the other beacons, filter update, manoeuvre detection, re-anchoring
        after a run of refused consistent fixes, and the re-acquisition test
        after a run of refusals.  ``var_i``, ``var_l``: the ranges' variances
        at the measured noise scale (m²), ``var0`` as configured."""
        p = self.p
        kf = self.kf
        asm = self.asm
        idx = entry.idx
        e = var_i + var_l
        # mirror: the candidate nearer the prediction in the Mahalanobis sense ...
        pr = asm.by_prediction(kf, cf, t_em, e)
        fx, fy = pr.fx, pr.fy
        # ... unless the other beacons' recent ranges tell the two apart (they do
        # not depend on the filter, which a turn or a mirror lock may have misled)
        by_ranges = asm.mirror_by_ranges(kf, idx, t_em, r_i, r_l, var_i, var_l, cf)
        if by_ranges is not None:
            fx, fy = by_ranges
        kf.predict(t_em)
        det = pr.det
        ambiguous = det > 0.0 and max(pr.m1, pr.m2) <= p.gate_chi2 * det
        if ambiguous or cf.gap_m > 0.0:
            # both solutions are plausible (near the baseline), or the circles
            # miss each other (the fix is only the point between them): do not
            # pick one, linearise the two ranges at the prediction (an EKF update)
            lx, ly = pr.px, pr.py
        else:
            lx, ly = fx, fy
        rows, z = asm.linearised(idx, r_i, r_l, lx, ly)
        mx, my = (cf.x2, cf.y2) if (fx, fy) == (cf.x1, cf.y1) else (cf.x1, cf.y1)
        ls, consistent = asm.multi_fix(kf, idx, t_em, r_i, r_l, var_i, var_l, fx, fy)
        if not consistent:
            # the cycle's ranges disagree with every other beacon's: a false or
            # late detection in it, whatever the filter says.  The reply may be
            # the bad part (a multipath or false one paired when the direct one
            # was missed): the range to the beacon comes from the two
            # interrogations alone, if the filter agrees with it well
            self._emit_fix(cyc, t_em, cf, fx, fy, r_i, r_l, bias, False, out)
            self._last_range_only = False
            if self._range_only(cyc, idx, r_raw, out, fallback=True):
                self.dropped["reply_refused"] += 1
            else:
                self.dropped["inconsistent"] += 1
            return
        lat = self.man.lateral(kf, fx - pr.px, fy - pr.py, pr.pxx, pr.pxy, pr.pyy, rows[0],
                               rows[1], var_i, var_l)
        ok, d2 = kf.update(rows, z, [var_i, var_l], p.gate_chi2, p.soft_gate_chi2)
        if lat is not None and self._maneuver(lat) and not ok:
            ok, d2 = kf.update(rows, z, [var_i, var_l], p.gate_chi2, p.soft_gate_chi2)
        if not ok:
            self._refused_run += 1
            if self._refused_run >= p.reanchor_after and math.isfinite(d2):
                # the other beacons confirm the fix: the filter is off, not the
                # fix — open its covariance until the fix passes, and take it
                s_row = 0.5 * (pr.pxx + pr.pyy) + 0.5 * e
                kf.inflate(NoiseScale.reanchor_variance(d2, p.gate_chi2, s_row),
                           p.turn_vel_sigma_mps ** 2)
                ok, d2 = kf.update(rows, z, [var_i, var_l], p.gate_chi2, p.soft_gate_chi2)
                if ok:
                    self.dropped["reanchored"] += 1
        fix = AuvFix(cyc.t, t_em, cyc.beacon, ls[0], ls[1], mx, my, r_i, r_l, bias, ok,
                     False, ls[2], ls[3], ls[4])
        self.last_fix = fix
        out.append(fix)
        # the AUV's progress along its plan, whatever the filter made of it (and
        # the fix weighed between the plan and the filter's prediction)
        self.plan.fix(fix, (pr.px, pr.py, pr.pxx, pr.pxy, pr.pyy))
        self._last_range_only = False
        if ok:
            # only ranges the filter accepted take part in later fixes
            asm.remember(idx, t_em, r_i, var_i)
            asm.remember(self.net.listener, t_em, r_l, var_l)
            if self.net.n >= 3:
                chi2, dof = asm.last_chi2
                self.noise.observe(chi2, dof)
            else:
                self._observe_noise(d2, 2)
            self._accepted(t_em, cyc.t, fx, fy, e, out)
            self._calibrate(cyc, t_em, idx, bias, True, var0[0], var0[1])
            return
        self.dropped["innovation"] += 1
        if self.acq.refused(entry):
            self._reacquire(cyc, t_em, pr, e, out)

    def _reacquire(self, cyc: Cycle, t_em: float, pr: Prediction, e: float, out: Out) -> None:
        """The filter refused several recent fixes: let every recent fix vote; if
        the vote disagrees with the filter, the filter is wrong (locked on the
        mirror track after crossing a baseline, or lost in a turn) — start
        again from the fixes; if the vote agrees with the filter, or cannot
        decide, the refused fixes were outliers."""
        p = self.p
        kf = self.kf
        acq = self.acq
        voted = acq.vote()
        if voted is None:
            return
        chosen, recent = voted
        px, py, det = pr.px, pr.py, pr.det
        dx, dy = chosen[0] - px, chosen[1] - py
        if dx * dx + dy * dy <= (2.0 * p.init_agree_m) ** 2 or (
                det > 0.0 and pr.chi2_det(dx, dy) <= p.gate_chi2 * det):
            return
        # which explains more of the recent fixes: the filter's track, or a line
        # through the fixes consistent with the vote?  (one outlier never wins)
        x0, y0, vx, vy = kf.x
        h0 = acq.explained(recent, x0, y0, vx, vy, t_em)
        line = acq.line_through(recent, acq.buf[-1], chosen)
        if line is None or acq.explained(recent, *line, t_em) < h0 + 2:
            return
        acq.prior = (px, py)
        self._init_from(recent, acq.buf[-1], chosen, (kf.x[2], kf.x[3]))
        self.dropped["reacquired"] += 1
        self._accepted(t_em, cyc.t, chosen[0], chosen[1], e, out)

    def _maneuver(self, lat: float) -> bool:
        """The cross-course CUSUM (:meth:`.maneuver.ManeuverDetector.cusum`),
        counted as ``fix.maneuver`` when it fires."""
        if not self.man.cusum(self.kf, lat):
            return False
        self.dropped["maneuver"] += 1
        return True

    def _emit_fix(self, cyc: Cycle, t_em: float, cf: CircleFix, fx: float, fy: float,
                  r_i: float, r_l: float, bias: float, ok: bool, out: Out) -> None:
        if fx == cf.x1 and fy == cf.y1:
            mx, my = cf.x2, cf.y2
        else:
            mx, my = cf.x1, cf.y1
        fix = AuvFix(cyc.t, t_em, cyc.beacon, fx, fy, mx, my, r_i, r_l, bias, ok)
        self.last_fix = fix
        out.append(fix)

    def _range_only(self, cyc: Cycle, idx: int, r: float, out: Out,
                    fallback: bool = False) -> bool:
        """One range to beacon ``idx`` (:meth:`.assembly.FixAssembly.range_only`),
        published as a range-only fix.  True when accepted; with ``fallback`` a
        refusal is neither counted nor published."""
        self.asm.var_scale = self.noise.scale
        res = self.asm.range_only(self.kf, cyc, idx, r, fallback)
        if res.status in ("uninitialised", "depth"):
            if not fallback:
                self.dropped["range_only_uninitialised" if res.status == "uninitialised"
                             else "depth"] += 1
            return False
        if res.status != "ok" and fallback:
            return False
        if res.pred is not None:
            # weighed between the plan and the filter's prediction as a fix is,
            # refused or not (a range the filter refuses at a corner it has not
            # seen yet is the plan's evidence)
            self.plan.range_fix(res.t_em, self.net.north[idx], self.net.east[idx], res.rho,
                                res.var, res.pred)
        if not self._one_row_fix(cyc, res, "innovation", out):
            return False
        if self.net.n < 3:
            self._observe_noise(res.d2, 1)
        self._accepted(res.t_em, cyc.t, res.cx, res.cy, res.var, out, position=False)
        var0 = res.var / self.noise.scale
        self._calibrate(cyc, res.t_em, idx, res.bias, False, var0, var0)
        return True

    def _one_row_fix(self, cyc: Cycle, res: RangeOnly, refused: str, out: Out) -> bool:
        """Publish a one-row update (a range, a half cycle) as a range-only fix;
        True when the filter accepted it, else counted as ``refused``."""
        ok = res.status == "ok"
        fix = AuvFix(cyc.t, res.t_em, cyc.beacon, res.cx, res.cy, res.cx, res.cy, res.r,
                     res.r_l, res.bias, ok, True)
        self.last_fix = fix
        out.append(fix)
        if not ok:
            self.dropped[refused] += 1
            return False
        self._last_range_only = True
        return True

    def _on_half_cycle(self, cyc: Cycle, out: Out) -> None:
        """A cycle that lost one of its interrogations (:mod:`.cycles`): its
        range sum or difference as a one-row update
        (:meth:`.assembly.FixAssembly.half_cycle`), published as a range-only
        fix; not used for the calibration."""
        if not self.p.half_cycles:
            return
        self.asm.var_scale = self.noise.scale
        bias = self.cal.bias(cyc.index) if self.cal is not None else 0.0
        res = self.asm.half_cycle(self.kf, cyc, bias)
        if res.status in ("uninitialised", "geometry"):
            self.dropped[f"half_cycle_{res.status}"] += 1
            return
        if self._one_row_fix(cyc, res, "half_cycle_refused", out):
            self._accepted(res.t_em, cyc.t, res.cx, res.cy, res.var, out, position=False)

    def _observe_noise(self, d2: float, rows: int) -> None:
        """With two beacons (no joint fix to measure the noise by), an accepted
        update's d² feeds the measured noise scale while the AUV flies straight
        (:mod:`.gates`)."""
        kf = self.kf
        if self.man.maneuvering or (isinstance(kf, Imm) and kf.maneuver_probability
                                    > STRAIGHT_NOISE_PROBABILITY):
            return
        self.noise.observe(d2, rows)

    # ------------------------------------------------------- initialisation

    def _init_from(self, recent: list[InitEntry], last: InitEntry,
                   chosen: tuple[float, float],
                   velocity: tuple[float, float] = (0.0, 0.0)) -> None:
        """Initialise the filter on the remembered fixes consistent with
        ``chosen`` (:meth:`.acquire.Acquisition.init_filter`)."""
        self.acq.init_filter(self.kf, recent, last, chosen, velocity)
        self.man.reset()
        self._cal_restart = True
        if self._ever_init:
            self._reacquired_utc = last.t
        self._ever_init = True
        self._lost = False
        self.rls.initialised = False

    # ------------------------------------------------------------ updates

    def _accepted(self, t_em: float, t: float, fx: float, fy: float, fix_var: float,
                  out: Out, position: bool = True) -> None:
        """After an accepted filter update at emission time ``t_em``: RLS, track.
        ``position``: the update fixed the position (two ranges or more), which
        ends a run of refused fixes; one range alone agrees with a filter gone
        off along it, and does not."""
        p = self.p
        kf = self.kf
        rls = self.rls
        man = self.man
        self.fixes_accepted += 1
        if position:
            self._refused_run = 0
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
                man.declare(kf)
            # the IMM's manoeuvring model: restart the line from the filter at
            # every update while it dominates, and once more when it ends
            if isinstance(kf, Imm) and not man.maneuvering and man.spin(kf):
                self.dropped["spin"] += 1
            state = man.imm_state(kf)
            if state or man.line_restart:
                if state == "enter" or not state:
                    self.turns += 1
                man.line_restart = False
                man.turn_utc = t_em
                P = kf.P
                rls.reset(t_em, kf.x[0], kf.x[1], kf.x[2], kf.x[3], 0.5 * (P[0][0] + P[1][1]),
                          0.5 * (P[2][2] + P[3][3]), 0.5 * (P[0][2] + P[1][3]),
                          max(kf.pos_sigma(), floor))
            elif man.arcing:
                # an arc: the track says turning (the filter, whose turn rate
                # follows it, leads), the line is left to its fit
                man.turn_utc = t_em
        self.plan.update(t_em, kf.x[0], kf.x[1], kf.x[2], kf.x[3], kf.pos_sigma(),
                         math.sqrt(max(0.5 * (kf.P[2][2] + kf.P[3][3]), 0.0)))
        if p.plan.infer and not self._given_plan:
            got = self.infer.update(t_em, kf.x[0], kf.x[1], kf.x[2], kf.x[3])
            if got is not None:
                self.plan.set_plan(got, INFERRED_SOURCE, tentative=True)
                self.inferred.append(got)
        self._plan_straight()
        track = self._build(t)
        self.last_track = track
        out.append(track)

    def _plan_straight(self) -> None:
        """On the straight part of a leg of the AUV's plan (and on the leg), once
        per leg: the plan says the AUV flies straight there, so a turn rate the
        corner left in the IMM is set back (:meth:`.maneuver.ManeuverDetector.plan_straight`:
        whether or not the IMM still says manoeuvring)."""
        al, kf = self.plan.along, self.kf
        if al is None or self.plan.leg < 0 or not isinstance(kf, Imm):
            self._straight_leg = -1  # off the plan: every leg counts again
            return
        k = al.on_straight(PLAN_STRAIGHT_MARGIN_M)
        if k < 0 or k == self._straight_leg or abs(al.cross) > self.p.plan.cross_gate_m:
            return
        self._straight_leg = k
        if self.man.plan_straight(kf):
            self.dropped["plan_straight"] += 1

    # ------------------------------------------------------------ the track

    def _flags(self, age: float) -> int:
        p = self.p
        f = TrackFlags.NONE
        if self.kf.initialised:
            f |= TrackFlags.INITIALISED
        if self.rls.initialised and self.rls.updates >= p.rls_min_updates:
            f |= TrackFlags.LINE_VALID
        t_em = self._last_update_utc
        if t_em - self.man.turn_utc <= p.turning_flag_s:
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
        off = self.clock.rt_offset()
        x0, y0, vx, vy = rls.x0, rls.y0, rls.vx, rls.vy
        v = math.hypot(vx, vy)
        h = (vy * x0 - vx * y0) / v if v > 0.0 else math.nan
        age = t - (self._last_update_utc + off)
        kx = kf.x
        return self.plan.stamp(AuvTrack(
            t, x0, y0, vx, vy, math.atan2(vy, vx), v, h, rls.covariance(), rls.t0 + off,
            rls.t0, age, self._flags(age), self._lost, kx[0], kx[1], kx[2], kx[3],
            kf.pos_sigma(), *self._sound_speed()))

    def _sound_speed(self) -> tuple[float, float, bool]:
        """(sound speed m/s, its 1σ m/s, converged) for the track."""
        cal = self.cal
        if cal is None:
            return self.net.c, 0.0, False
        return cal.sound_speed_mps, cal.sound_speed_sigma_mps, cal.converged

    def _track(self, t: float, last: AuvTrack) -> AuvTrack:
        """``last`` re-stamped at ``t`` with its age and flags brought up to date."""
        age = t - (self._last_update_utc + self.clock.rt_offset())
        return self.plan.stamp(AuvTrack(
            t, last.x0_m, last.y0_m, last.vx_mps, last.vy_mps, last.psi_auv_rad,
            last.v_auv_mps, last.h_auv_m, last.cov, last.t0, last.t0_utc_s, age,
            self._flags(age), self._lost, last.kf_x_m, last.kf_y_m, last.kf_vx_mps,
            last.kf_vy_mps, last.kf_pos_sigma_m, *self._sound_speed()))

    def _predicted(self, t: float, last: AuvTrack) -> AuvTrack:
        """The track brought forward to runtime ``t`` while the AUV turns: the
        filter's state predicted along its turn rate (a coordinated turn: the
        course keeps turning between fixes) and the line's origin moved to
        ``t``.  (On a straight leg a tick only re-stamps the track: the guidance
        carries the filter's position along the line's smoother velocity.)"""
        off = self.clock.rt_offset()
        t_utc = t - off
        kf = self.kf
        if t_utc <= kf.t:
            return self._track(t, last)
        w = kf.omega if isinstance(kf, Imm) else 0.0
        x, y, vx, vy = turn_step(kf.x[0], kf.x[1], kf.x[2], kf.x[3], w, t_utc - kf.t)
        _, _, pxx, _, pyy = kf.predicted(t_utc)
        rls = self.rls
        lx, ly = rls.position(t_utc)
        lvx, lvy = rls.vx, rls.vy
        v = math.hypot(lvx, lvy)
        h = (lvy * lx - lvx * ly) / v if v > 0.0 else math.nan
        age = t - (self._last_update_utc + off)
        return self.plan.stamp(AuvTrack(
            t, lx, ly, lvx, lvy, math.atan2(lvy, lvx), v, h, rls.covariance_at(t_utc), t,
            t_utc, age, self._flags(age), self._lost, x, y, vx, vy,
            math.sqrt(max(0.5 * (pxx + pyy), 0.0)), *self._sound_speed()))

    def _check_lost(self, t: float | None, out: Out) -> None:
        """Declare the track lost when silent too long or too uncertain."""
        if self._lost or not self.kf.initialised or self.last_track is None:
            return
        if not isinstance(t, (float, int)) or not math.isfinite(t):
            return
        p = self.p
        off = self.clock.rt_offset()
        age = t - (self._last_update_utc + off)
        _, _, pxx, _, pyy = self.kf.predicted(t - off)
        if age <= p.lost_after_s and 0.5 * (pxx + pyy) <= p.lost_sigma_m ** 2:
            return
        self._lost = True
        self.plan.leave()  # matched again once the track is back
        kx = self.kf.x
        self.acq.prior = (kx[0], kx[1])
        self.kf.reset()
        self.rls.initialised = False
        self.acq.clear()
        track = self._track(t, self.last_track)
        self.last_track = track
        out.append(track)
