"""Simulated long-baseline acoustics and the listening buoy (its ``$PZBAE``/``$PZBST`` feed).

The LBL cycle, on the simulation clock (s since the start of the run):

1. the AUV (a :class:`drivers.sim.auv.Auv`) interrogates beacon i at T from
   p(T);
2. beacon i hears it at T + |p(T) − b_i|/c and replies τ_i later;
3. the AUV hears the reply at t_h, solving t_h = t_reply + |p(t_h) − b_i|/c
   (the AUV keeps moving; fixed-point iteration), and interrogates the next
   beacon of its sequence δ after that: T' = t_h + δ.  With probability
   ``auv_p_miss`` it misses the reply and interrogates the next beacon
   ``auv_timeout_s`` after T instead (a cycle the tracker must drop);
4. the listener at beacon k hears every interrogation at T + |p(T) − b_k|/c
   and every reply at t_reply + d_ik/c (straight-line 3-D paths, constant c).

Each arrival at the listener is detected with probability 1 − ``p_miss``,
timestamped with Gaussian jitter ``jitter_s``; with probability ``p_multipath``
a late copy (extra delay uniform in [``multipath_delay_min_s``,
``multipath_delay_max_s``], SNR lower by ``multipath_loss_db``) is also
detected (with its own miss chance); with probability ``p_false`` a false
detection of a random kind and beacon appears uniformly within
``false_window_s`` after it.  SNR = ``snr_db`` − 20 log10(range / 100 m) +
N(0, ``snr_sigma_db``).

The buoy reports each detection as ``$PZBAE`` (UTC, µs) ``latency_s`` after
it, and ``$PZBST`` (position of the listener beacon, battery, fault code) at
``status_rate_hz``.  :meth:`AcousticWorld.events_until` hands out
``(t_emit_s, bytes)`` in time order.

Seeding as :mod:`drivers.sim.world`: ``SeedSequence(seed).spawn`` gives one
child stream per component of :data:`STREAMS` (append only); every arrival
draws the same number of variates from each stream whatever happens, so one
seed gives bit-identical bytes and changing a probability never shifts the
draws of another component.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from drivers.buoy_parser import encode_pzbae, encode_pzbst
from drivers.sim.auv import Auv, AuvTruth
from drivers.sim.disturbance import BLOCK, NormalStream
from drivers.sim.sensors import NedToGeodetic
from zarco_core.auv_messages import AcousticEvent
from zarco_core.config import spec
from zarco_core.lbl import LblNetworkParams

#: child random streams, by index: never reorder, only append
STREAMS = ("detect", "jitter", "multipath", "false_detection", "snr", "auv_miss", "status")
#: fixed-point iterations for the moving AUV's reception time (v/c ≈ 1e-3 per pass)
RECEIVE_ITERATIONS = 4


@dataclass(slots=True)
class LblParams:
    """The LBL network, its acoustics and the listening buoy (``[world.lbl]``)."""

    beacons: list[list[float]] = spec(
        [[0.0, 0.0, 30.0], [400.0, 50.0, 30.0], [150.0, 400.0, 30.0]], "m",
        "beacon positions [north, east, depth] in the local NED frame")
    beacon_ids: list[int] = spec([], "", "wire ids of the beacons (empty: 1..N)",
                                 min=0, max=9999)
    turnaround_s: list[float] = spec([0.1, 0.1, 0.1], "s", "turnaround τ_i of each beacon",
                                     min=0.0, max=10.0)
    auv_delay_s: float = spec(0.5, "s", "the AUV's fixed delay δ after hearing a reply",
                              min=0.0, max=30.0)
    sound_speed_mps: float = spec(1500.0, "m/s", "sound speed c", min=1400.0, max=1600.0)
    listener_beacon: int = spec(0, "", "index (0-based) of the beacon the buoy listens at",
                                min=0, max=63)
    sequence: list[int] = spec([], "", "beacon ids in the AUV's interrogation order, "
                               "cyclic (empty: every beacon in order)", min=0, max=9999)
    start_s: float = spec(1.0, "s", "time of the AUV's first interrogation",
                          min=0.0, max=1e6)
    jitter_s: float = spec(0.0005, "s", "1σ detection-time jitter at the listener",
                           min=0.0, max=0.1)
    p_miss: float = spec(0.10, "", "probability that the listener misses an arrival",
                         min=0.0, max=1.0)
    p_false: float = spec(0.02, "", "probability of a false detection per arrival",
                          min=0.0, max=1.0)
    false_window_s: float = spec(2.0, "s", "a false detection falls uniformly within this "
                                 "after the arrival that spawned it", min=0.0, max=60.0)
    p_multipath: float = spec(0.10, "", "probability of a late multipath copy per arrival",
                              min=0.0, max=1.0)
    multipath_delay_min_s: float = spec(0.002, "s", "least extra delay of a multipath copy",
                                        min=0.0, max=1.0)
    multipath_delay_max_s: float = spec(0.030, "s", "largest extra delay of a multipath "
                                        "copy", min=0.0, max=1.0)
    multipath_loss_db: float = spec(6.0, "dB", "SNR loss of a multipath copy",
                                    min=0.0, max=100.0)
    snr_db: float = spec(25.0, "dB", "detection SNR at 100 m", min=-20.0, max=100.0)
    snr_sigma_db: float = spec(2.0, "dB", "1σ SNR scatter", min=0.0, max=50.0)
    auv_p_miss: float = spec(0.0, "", "probability that the AUV misses a reply (it then "
                             "interrogates the next beacon after auv_timeout_s)",
                             min=0.0, max=1.0)
    auv_timeout_s: float = spec(3.0, "s", "the AUV's reply timeout", min=0.01, max=60.0)
    latency_s: float = spec(0.05, "s", "delay from detection to the buoy's report",
                            min=0.0, max=10.0)
    status_rate_hz: float = spec(1.0, "Hz", "$PZBST rate (0 disables)", min=0.0, max=50.0)
    battery_v: float = spec(12.6, "V", "battery voltage at the start", min=0.0, max=100.0)
    battery_drain_v_per_h: float = spec(0.05, "V/h", "battery voltage drop per hour",
                                        min=0.0, max=100.0)
    fault_code: int = spec(0, "", "fault code the buoy reports (0 ok)", min=0, max=9999)

    def network(self) -> LblNetworkParams:
        """The network as a tracker would be configured with it (the truth)."""
        return LblNetworkParams(beacons=[list(b) for b in self.beacons],
                                beacon_ids=list(self.beacon_ids),
                                turnaround_s=list(self.turnaround_s),
                                auv_delay_s=self.auv_delay_s,
                                sound_speed_mps=self.sound_speed_mps,
                                listener_beacon=self.listener_beacon)

    def validate(self) -> None:
        self.network().validate()
        ids = self.network().ids()
        for b in self.sequence:
            if b not in ids:
                raise ValueError(f"sequence: beacon id {b} is not in the network {ids}")
        if self.multipath_delay_max_s < self.multipath_delay_min_s:
            raise ValueError("multipath_delay_max_s: must be ≥ multipath_delay_min_s")


class _Uniforms:
    """U[0, 1) variates from ``rng``, drawn a block at a time (as NormalStream)."""

    __slots__ = ("_buf", "_i", "_rng")

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._buf: list[float] = []
        self._i = 0

    def next(self) -> float:
        i = self._i
        if i >= len(self._buf):
            self._buf = self._rng.random(BLOCK).tolist()
            i = 0
        self._i = i + 1
        return self._buf[i]


@dataclass(frozen=True, slots=True)
class Detection:
    """One detection at the listener (sim time s), for tests and reports:
    ``label`` is ``direct``, ``multipath`` or ``false``."""

    t_s: float
    kind: str
    beacon: int
    snr_db: float
    label: str


@dataclass(frozen=True, slots=True)
class Ping:
    """One true interrogation: emission time (sim s), beacon id, AUV position (m)."""

    t_s: float
    beacon: int
    x_m: float
    y_m: float
    depth_m: float


class AcousticWorld:
    """The LBL network around ``auv`` and the buoy at the listener beacon."""

    def __init__(self, params: LblParams, auv: Auv, seed: int,
                 start_utc_epoch_s: float = 1_780_308_000.0,
                 origin: tuple[float, float] = (41.185, -8.705)) -> None:
        params.validate()
        self.params = params
        self.auv = auv
        self.epoch0_s = start_utc_epoch_s
        net = params.network()
        self.ids = net.ids()
        self.pos = [(float(b[0]), float(b[1]), float(b[2])) for b in params.beacons]
        self.c = params.sound_speed_mps
        k = params.listener_beacon
        self.listener = self.pos[k]
        self.d = [math.dist(b, self.listener) for b in self.pos]
        self.sequence = ([self.ids.index(b) for b in params.sequence] if params.sequence
                         else list(range(len(self.ids))))
        children = np.random.SeedSequence(seed).spawn(len(STREAMS))
        rng = {name: np.random.default_rng(ss)
               for name, ss in zip(STREAMS, children, strict=True)}
        self._u_detect = _Uniforms(rng["detect"])
        self._n_jitter = NormalStream(rng["jitter"])
        self._u_multipath = _Uniforms(rng["multipath"])
        self._u_false = _Uniforms(rng["false_detection"])
        self._n_snr = NormalStream(rng["snr"])
        self._u_auv = _Uniforms(rng["auv_miss"])
        self._n_status = NormalStream(rng["status"])
        lat0, lon0 = origin
        self._geo = NedToGeodetic(lat0, lon0)
        self._buoy_latlon = self._geo(self.listener[0], self.listener[1], 0.0)[:2]
        self._heap: list[tuple[float, int, str, int, float, str]] = []
        self._n = 0
        self._t_next = params.start_s
        self._seq_pos = 0
        self._status_k = 0
        #: every detection made so far and every true interrogation (for tests/reports)
        self.detections: list[Detection] = []
        self.pings: list[Ping] = []

    # --------------------------------------------------------------- physics

    def _range(self, p: tuple[float, float, float], b: tuple[float, float, float]) -> float:
        return math.dist(p, b)

    def _ping(self) -> None:
        """Simulate the interrogation at ``self._t_next`` and schedule the next."""
        prm = self.params
        c = self.c
        t = self._t_next
        i = self.sequence[self._seq_pos % len(self.sequence)]
        self._seq_pos += 1
        bid = self.ids[i]
        p = self.auv.position(t)
        self.pings.append(Ping(t, bid, p[0], p[1], p[2]))
        b = self.pos[i]
        r_l = self._range(p, self.listener)
        self._arrival("I", bid, t + r_l / c, r_l)
        t_reply = t + self._range(p, b) / c + prm.turnaround_s[i]
        self._arrival("R", bid, t_reply + self.d[i] / c, self.d[i])
        t_h = t_reply + self._range(p, b) / c
        for _ in range(RECEIVE_ITERATIONS):
            t_h = t_reply + self._range(self.auv.position(t_h), b) / c
        missed = self._u_auv.next() < prm.auv_p_miss
        self._t_next = t + prm.auv_timeout_s if missed else t_h + prm.auv_delay_s

    def _snr(self, dist: float) -> float:
        prm = self.params
        return (prm.snr_db - 20.0 * math.log10(max(dist, 1.0) / 100.0)
                + prm.snr_sigma_db * self._n_snr.next())

    def _arrival(self, kind: str, bid: int, t_arr: float, dist: float) -> None:
        """One arrival at the listener: direct detection, multipath copy, false
        detection — a fixed number of draws from each stream."""
        prm = self.params
        miss_direct = self._u_detect.next() < prm.p_miss
        miss_copy = self._u_detect.next() < prm.p_miss
        jit_direct = prm.jitter_s * self._n_jitter.next()
        jit_copy = prm.jitter_s * self._n_jitter.next()
        has_copy = self._u_multipath.next() < prm.p_multipath
        extra = prm.multipath_delay_min_s + self._u_multipath.next() * (
            prm.multipath_delay_max_s - prm.multipath_delay_min_s)
        has_false = self._u_false.next() < prm.p_false
        false_dt = self._u_false.next() * prm.false_window_s
        false_kind = "I" if self._u_false.next() < 0.5 else "R"
        false_beacon = self.ids[min(int(self._u_false.next() * len(self.ids)),
                                    len(self.ids) - 1)]
        snr_direct = self._snr(dist)
        snr_copy = self._snr(dist) - prm.multipath_loss_db
        snr_false = prm.snr_db - 12.0 + prm.snr_sigma_db * self._n_snr.next()
        if not miss_direct:
            self._push(t_arr + jit_direct, kind, bid, snr_direct, "direct")
        if has_copy and not miss_copy:
            self._push(t_arr + extra + jit_copy, kind, bid, snr_copy, "multipath")
        if has_false:
            self._push(t_arr + false_dt, false_kind, false_beacon, snr_false, "false")

    def _push(self, t: float, kind: str, bid: int, snr: float, label: str) -> None:
        heapq.heappush(self._heap, (t, self._n, kind, bid, snr, label))
        self._n += 1

    # ----------------------------------------------------------------- output

    def events_until(self, t_s: float) -> list[tuple[float, bytes]]:
        """Every buoy sentence emitted up to ``t_s`` (sim s) not handed out yet,
        as (emission time s, bytes), in time order."""
        prm = self.params
        lat = prm.latency_s
        out = [(d.t_s + lat, encode_pzbae(self.epoch0_s + d.t_s, d.kind, d.beacon, d.snr_db))
               for d in self._pop_detections(t_s)]
        if prm.status_rate_hz > 0.0:
            status: list[tuple[float, bytes]] = []
            while (self._status_k / prm.status_rate_hz) <= t_s:
                ts = self._status_k / prm.status_rate_hz
                self._status_k += 1
                volts = (prm.battery_v - prm.battery_drain_v_per_h * ts / 3600.0
                         + 0.01 * self._n_status.next())
                status.append((ts, encode_pzbst(self.epoch0_s + ts, self._buoy_latlon[0],
                                                self._buoy_latlon[1], max(volts, 0.0),
                                                prm.fault_code)))
            if status:
                out = list(heapq.merge(out, status, key=lambda e: e[0]))
        return out

    def _pop_detections(self, t_s: float) -> list[Detection]:
        """Simulate as far as needed and hand out the detections reported by ``t_s``."""
        prm = self.params
        margin = 0.01 + 10.0 * prm.jitter_s
        while self._t_next - margin <= t_s:
            self._ping()
        heap = self._heap
        lat = prm.latency_s
        out: list[Detection] = []
        while heap and heap[0][0] + lat <= t_s:
            t, _n, kind, bid, snr, label = heapq.heappop(heap)
            d = Detection(t, kind, bid, snr, label)
            self.detections.append(d)
            out.append(d)
        return out

    def events_exact_until(self, t_s: float, source: str = "buoy") -> list[AcousticEvent]:
        """The detections reported by ``t_s`` as AcousticEvent messages directly,
        without the wire's µs rounding (``t`` = report time on the sim clock,
        ``utc_epoch_s`` = epoch0 + detection time).  For tests and fast
        in-process runs; do not mix with :meth:`events_until` (each detection is
        handed out once, by whichever is called)."""
        lat = self.params.latency_s
        return [AcousticEvent(d.t_s + lat, source, self.epoch0_s + d.t_s, d.kind, d.beacon,
                              d.snr_db) for d in self._pop_detections(t_s)]

    def auv_truth(self, t_s: float) -> AuvTruth:
        """The AUV's true state at sim time ``t_s``."""
        return self.auv.truth(t_s)

    def sim_time(self, utc_epoch_s: float) -> float:
        """Sim time (s) of a UTC time (s since 1970) on the buoy's clock."""
        return utc_epoch_s - self.epoch0_s
