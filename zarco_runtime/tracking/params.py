"""Tracker configuration (the ``[runtime.tracker]`` schema) and the derived network.

Conventions of :mod:`zarco_core.config`: ``@dataclass(slots=True)``, every
field built with :func:`~zarco_core.config.spec` (default, unit, doc, range),
cross-field checks in ``validate()`` raising ``ValueError("key: reason")``.

Frames: beacon positions are local NED ``[north, east, depth]``
metres about the configured origin, depth positive down.  Times in seconds.

:class:`Network` is the immutable, precomputed form of
:class:`LblNetworkParams` that the hot path uses (index lookups, listener
distances d_i, physical reply windows).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

from zarco_core.config import spec
from zarco_core.lbl import LblNetworkParams
from zarco_runtime.tracking.plan import PlanParams

#: inputs the RLS line fit may take
RLS_INPUTS = ("kf", "fix")
#: motion models of the AUV filter
MOTION_MODELS = ("imm", "cv")


@dataclass(slots=True)
class TrackerParams:
    """Passive AUV tracker: cycle gates, fix, Kalman filter, RLS, track loss."""

    network: LblNetworkParams = spec(LblNetworkParams, "", "the LBL network")
    plan: PlanParams = spec(PlanParams, "", "matching the AUV to its a-priori plan")
    auv_depth_m: float = spec(10.0, "m", "the AUV's (known, constant) depth, positive down",
                              min=0.0, max=6000.0)
    sequence: list[int] = spec([], "", "beacon ids in the AUV's interrogation order, "
                               "cyclic; a cycle whose next interrogation is not the "
                               "successor is dropped (empty: any order)", min=0, max=9999)
    timing_tol_s: float = spec(0.003, "s", "margin added to every physical timing window "
                               "(several detection-jitter σ)", min=0.0, max=1.0)
    max_range_m: float = spec(3000.0, "m", "largest AUV–beacon range accepted",
                              min=10.0, max=20000.0)
    closing_margin_m: float = spec(15.0, "m", "once tracking, the AUV's next interrogation "
                                   "must come within ±2(4σ + this)/c of the period the "
                                   "predicted range implies", min=0.0, max=10000.0)
    max_speed_mps: float = spec(3.0, "m/s", "largest plausible AUV speed (initialisation)",
                                min=0.1, max=20.0)
    timing_sigma_s: float = spec(0.0005, "s", "1σ detection-time jitter assumed for the "
                                 "measurement covariance", min=0.0, max=0.1)
    range_sigma_m: float = spec(0.5, "m", "1σ range error added to the timing part "
                                "(sound speed, residual motion bias)", min=0.0, max=100.0)
    motion_correction: bool = spec(True, "", "correct the v·P/2 motion bias of the ranges "
                                   "with the filter's velocity")
    half_cycles: bool = spec(True, "", "a cycle that lost one of its interrogations still "
                             "updates the filter with its range sum or difference (one row)")
    ls_window_s: float = spec(8.0, "s", "a fix combines the ranges to every beacon heard "
                              "within this long (brought to its emission time along the "
                              "filter's velocity)", min=0.0, max=120.0)
    max_gap_m: float = spec(8.0, "m", "circles further apart than this give no fix "
                            "(closer: the tangent point, flagged bad geometry)",
                            min=0.0, max=1000.0)
    accel_psd: float = spec(0.004, "m²/s³", "constant-velocity model: white-acceleration "
                            "spectral density q (the quiet model of the IMM)",
                            min=1e-8, max=100.0)
    arc_rate_psd: float = spec(3e-6, "rad²/s³", "IMM: turn-rate random walk of the quiet "
                               "model (a straight line, or an arc it follows without lag)",
                               min=0.0, max=1.0)
    arc_rate_dps: float = spec(0.4, "deg/s", "IMM: an estimated turn rate at least this "
                               "is a turn (an arc: the track says turning while it "
                               "lasts); at speeds below 1 m/s, this divided by the speed",
                               min=0.0, max=90.0)
    motion_model: str = spec("imm", "", "the AUV filter: 'imm' (models side by side: "
                             "straight, manoeuvring, coordinated turn) or 'cv' (one "
                             "constant-velocity model)", choices=list(MOTION_MODELS))
    maneuver_accel_psd: float = spec(0.2, "m²/s³", "IMM: white-acceleration density of the "
                                     "manoeuvring constant-velocity model",
                                     min=1e-6, max=100.0)
    turn_accel_psd: float = spec(0.01, "m²/s³", "IMM: white-acceleration density of the "
                                 "coordinated-turn model", min=1e-8, max=100.0)
    turn_rate_psd: float = spec(0.003, "rad²/s³", "IMM: turn-rate random walk of the "
                                "coordinated-turn model", min=1e-8, max=10.0)
    turn_rate_dps: float = spec(10.0, "deg/s", "IMM: the AUV's usual turn rate; two "
                                "coordinated-turn models (to port, to starboard) expect "
                                "turns at it (a third estimates any rate: arcs)",
                                min=0.0, max=90.0)
    max_turn_rate_dps: float = spec(20.0, "deg/s", "IMM: the AUV never turns faster than "
                                    "this", min=0.1, max=180.0)
    straight_sojourn_s: float = spec(60.0, "s", "IMM: mean time the AUV keeps a straight "
                                     "line (sets the switching probability)",
                                     min=1.0, max=1e5)
    maneuver_sojourn_s: float = spec(10.0, "s", "IMM: mean time in the manoeuvring model",
                                     min=0.5, max=1e4)
    turn_sojourn_s: float = spec(20.0, "s", "IMM: mean duration of a turn", min=0.5, max=1e4)
    maneuver_on: float = spec(0.6, "", "IMM: probability of not flying straight that "
                              "declares a turn (the line restarts from the filter while it "
                              "lasts)", min=0.01, max=0.99)
    maneuver_off: float = spec(0.3, "", "IMM: probability under which the turn is over "
                               "(the line restarts once more and is fitted on)",
                               min=0.01, max=0.99)
    init_pos_sigma_m: float = spec(5.0, "m", "1σ position uncertainty at initialisation",
                                   min=0.01, max=1e4)
    init_vel_sigma_mps: float = spec(1.0, "m/s", "1σ velocity uncertainty at initialisation",
                                     min=0.01, max=20.0)
    gate_chi2: float = spec(16.0, "", "innovation gate on the Mahalanobis distance² of a "
                            "fix (2 dof; 13.8 is 99.9 %)", min=1.0, max=1e6)
    soft_gate_chi2: float = spec(4.0, "", "innovations with a Mahalanobis distance² above "
                                 "this (and under gate_chi2) have their measurement "
                                 "variance scaled by d²/this (robust down-weighting)",
                                 min=1.0, max=1e6)
    reacquire_after: int = spec(3, "", "gated fixes within init_window_s that make the "
                                "tracker test whether the fixes, not the filter, are right "
                                "(and re-initialise from them if so)", min=1, max=1000)
    reanchor_after: int = spec(3, "", "consistent fixes (the other beacons agree) refused "
                               "in a row after which the filter's covariance is opened "
                               "until the fix passes (re-anchoring, not coasting)",
                               min=1, max=1000)
    init_window_s: float = spec(30.0, "s", "fixes this recent vote for the mirror choice at "
                                "(re)initialisation", min=1.0, max=600.0)
    init_agree_m: float = spec(10.0, "m", "candidates from two baselines agree within this "
                                "distance (plus max_speed × their time apart)",
                               min=0.1, max=1000.0)
    prior_north_m: float = spec(0.0, "m", "prior AUV position (north), resolves the mirror "
                                "when only one baseline exists", min=-1e6, max=1e6)
    prior_east_m: float = spec(0.0, "m", "prior AUV position (east)", min=-1e6, max=1e6)
    rls_forgetting: float = spec(0.97, "1/s", "RLS forgetting factor per second (λ^Δt for "
                                 "fixes Δt apart)", min=0.5, max=1.0)
    rls_input: str = spec("kf", "", "what the RLS fits: Kalman-filtered positions or the "
                          "raw fixes", choices=list(RLS_INPUTS))
    rls_sigma_floor_m: float = spec(0.3, "m", "floor of the residual 1σ used to normalise "
                                    "the RLS residuals", min=0.001, max=100.0)
    rls_min_updates: int = spec(5, "", "updates after a reset before the line is flagged "
                                "valid", min=1, max=1000)
    turn_cusum_drift: float = spec(2.0, "", "CUSUM drift on the normalised squared residual "
                                   "(mean 1 on a straight line)", min=0.0, max=100.0)
    turn_cusum_threshold: float = spec(8.0, "", "CUSUM level that declares a turn and "
                                       "resets the RLS covariance", min=0.1, max=1e4)
    turn_vel_sigma_mps: float = spec(0.5, "m/s", "velocity 1σ added to the Kalman filter "
                                     "when a turn is declared (the RLS restarts from it)",
                                     min=0.0, max=10.0)
    turn_pos_sigma_m: float = spec(1.0, "m", "position 1σ added to the Kalman filter when "
                                   "a turn is declared", min=0.0, max=100.0)
    maneuver_drift: float = spec(1.0, "", "CUSUM drift on the fixes' normalised "
                                 "cross-course innovation (σ units)", min=0.0, max=100.0)
    maneuver_threshold: float = spec(3.0, "", "that CUSUM's level declaring a manoeuvre "
                                     "(a turn)", min=0.1, max=1e4)
    maneuver_cap: float = spec(4.0, "", "each innovation is clipped to ± this (σ) in that "
                                "CUSUM, so one outlier alone never declares a turn",
                               min=0.1, max=1e4)
    maneuver_restarts_line: bool = spec(False, "", "a manoeuvre declared by the filter "
                                        "also restarts the RLS line (otherwise only the "
                                        "RLS residual CUSUM does)")
    turn_holdoff_s: float = spec(4.0, "s", "no second turn declaration this soon after one",
                                 min=0.0, max=600.0)
    turning_flag_s: float = spec(8.0, "s", "TURNING flag stays set this long after a line "
                                 "restart or the last update of an arc (the follow guidance "
                                 "then takes the filter's velocity, not the line's)",
                                 min=0.0, max=600.0)
    stale_after_s: float = spec(10.0, "s", "no accepted fix for this long: STALE",
                                min=0.1, max=3600.0)
    lost_after_s: float = spec(30.0, "s", "no accepted fix for this long: LOST",
                               min=0.1, max=3600.0)
    lost_sigma_m: float = spec(30.0, "m", "predicted position 1σ above this: LOST",
                               min=0.1, max=1e5)
    calibrate: bool = spec(True, "", "estimate the sound speed (and per-beacon range "
                           "biases) online from the redundancy of the ranges; off: the "
                           "configured network is taken as exact")
    sound_speed_sigma_mps: float = spec(10.0, "m/s", "1σ uncertainty of the configured "
                                        "sound speed (a CTD cast: 5–10 m/s)",
                                        min=0.01, max=100.0)
    sound_speed_walk_mps: float = spec(0.01, "m/s/√s", "random walk of the sound speed "
                                       "(how fast the water may change it)",
                                       min=0.0, max=10.0)
    sound_speed_converged_mps: float = spec(1.5, "m/s", "the estimate has converged when "
                                            "its 1σ is at most this", min=0.01, max=100.0)
    range_bias_sigma_m: float = spec(1.0, "m", "1σ prior of each beacon's range bias (a "
                                     "turnaround error of 1 ms is 0.75 m; 0: no bias "
                                     "estimated)", min=0.0, max=100.0)
    survey_sigma_m: float = spec(1.0, "m", "1σ (each horizontal axis) of every beacon's "
                                 "surveyed position: a third explanation of the ranges, the "
                                 "beacons a little off their survey (0: the survey is taken "
                                 "as exact)", min=0.0, max=100.0)
    clock_tol_s: float = spec(2.0, "s", "an event whose runtime-minus-UTC time differs "
                              "from the running estimate by more than this is refused "
                              "(`clock`), unless 5 in a row agree (the clock jumped)",
                              min=0.01, max=3600.0)
    feed_latency_s: float = spec(0.0, "s", "smallest delay from detection at the buoy to "
                                 "reception by the runtime (maps the acoustic UTC clock "
                                 "onto the runtime clock)", min=0.0, max=60.0)

    def validate(self) -> None:
        ids = self.network.ids()
        for b in self.sequence:
            if b not in ids:
                raise ValueError(f"sequence: beacon id {b} is not in the network {ids}")
        if self.lost_after_s < self.stale_after_s:
            raise ValueError("lost_after_s: must be ≥ stale_after_s")
        if self.maneuver_off >= self.maneuver_on:
            raise ValueError("maneuver_off: must be below maneuver_on")


@dataclass(frozen=True, slots=True)
class Network:
    """Precomputed network: positions, ids, τ, listener distances and reply windows.

    ``d[i]``: 3-D distance from beacon i to the listener (m); ``reply_lo[i]`` /
    ``reply_hi[i]``: the physical window τ_i ≤ t^R − t^I ≤ τ_i + 2 d_i / c,
    widened by the timing tolerance (s).
    """

    north: tuple[float, ...]
    east: tuple[float, ...]
    depth: tuple[float, ...]
    ids: tuple[int, ...]
    index: dict[int, int]
    tau: tuple[float, ...]
    d: tuple[float, ...]
    reply_lo: tuple[float, ...]
    reply_hi: tuple[float, ...]
    delta: float
    c: float
    listener: int
    tol: float

    @classmethod
    def from_params(cls, p: LblNetworkParams, timing_tol_s: float = 0.003) -> Network:
        p.validate()
        ids = tuple(p.ids())
        north = tuple(float(b[0]) for b in p.beacons)
        east = tuple(float(b[1]) for b in p.beacons)
        depth = tuple(float(b[2]) for b in p.beacons)
        k = p.listener_beacon
        d = tuple(math.dist((north[i], east[i], depth[i]), (north[k], east[k], depth[k]))
                  for i in range(len(ids)))
        c = p.sound_speed_mps
        tau = tuple(float(x) for x in p.turnaround_s)
        return cls(north, east, depth, ids, {b: i for i, b in enumerate(ids)}, tau, d,
                   tuple(tau[i] - timing_tol_s for i in range(len(ids))),
                   tuple(tau[i] + 2.0 * d[i] / c + timing_tol_s for i in range(len(ids))),
                   p.auv_delay_s, c, k, timing_tol_s)

    def with_sound_speed(self, c: float) -> Network:
        """The same network with sound speed ``c`` (m/s) and its reply windows."""
        tol = self.tol
        return replace(self, c=c, reply_hi=tuple(
            self.tau[i] + 2.0 * self.d[i] / c + tol for i in range(len(self.ids))))

    def corrected(self, c: float, offsets: Sequence[tuple[float, float]]) -> Network:
        """The network with sound speed ``c`` (m/s) and each beacon moved by
        its (north, east) offset (m) from the configured position: the
        listener distances and reply windows recomputed."""
        north = tuple(n + o[0] for n, o in zip(self.north, offsets, strict=True))
        east = tuple(e + o[1] for e, o in zip(self.east, offsets, strict=True))
        k = self.listener
        d = tuple(math.dist((north[i], east[i], self.depth[i]),
                            (north[k], east[k], self.depth[k])) for i in range(len(self.ids)))
        tol = self.tol
        return replace(self, north=north, east=east, d=d, c=c, reply_hi=tuple(
            self.tau[i] + 2.0 * d[i] / c + tol for i in range(len(self.ids))))

    @property
    def n(self) -> int:
        return len(self.ids)

    @property
    def max_reply_s(self) -> float:
        """Longest physical reply delay of any beacon (s), tolerance included."""
        return max(self.reply_hi)
