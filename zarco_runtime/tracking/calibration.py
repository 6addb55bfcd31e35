"""Online calibration of the acoustic network: sound speed and range biases.

The ranges of a cycle scale with the sound speed c, and a beacon whose
turnaround is not the configured one biases them.  With the configured
(prior) sound speed c₀, a cycle on beacon j gives the nominal ranges (m)::

    m_j = (c₀/2)(P − τ_j − δ)                     to beacon j
    m_L = m_j + d_j − c₀ (t^R − t^I − τ_j)        to the listener L

and, with k = c/c₀ and β_j = (c/2)(τ_j,true − τ_j) the range bias of beacon
j's turnaround, the true ranges are::

    r_j = k m_j − β_j            r_L = k (m_L − d_j) + d_j + β_j      (j ≠ L)
    r_L = k m_L − β_L                                                 (j = L)

Every accepted range is one more equation between the AUV's position, k and
the β.  With three or more beacons the ranges of a few seconds over-determine
the position and k is observable.  With two beacons nothing separates k from
the position and the beacons' distance (the listener's own cycles read r_L
through τ_L, the other cycles through d_j, but a d_j surveyed 2 m off over
300 m is a 0.7 % scale): k stays at the prior, its σ the configured one, and
the estimate never says converged; the β are still estimated.

A beacon surveyed off its true position biases its ranges by the offset's
component along the direction to the AUV: a bias that changes as the AUV
moves round, which neither k nor a constant β can represent (the estimate
was pulled up to 1 % off by it).  The third hypothesis therefore carries each
beacon's horizontal correction δ_b = (δN_b, δE_b), prior σ
``survey_sigma_m``: ρ_b is taken to the corrected position, and d_j in the
listener's ranges becomes the corrected distance D_j.  The timings cannot
tell a network scaled by s (with sound s times faster) from the true one:
under that hypothesis k is only as good as the survey's prior allows (about
σ_δ / (R √n) with beacons R from the AUV), and its σ says so — the estimate
does not converge to a value the survey pulled.

Each hypothesis is an extended Kalman filter, apart from the tracker's
motion filter, on the state::

    [x, y, vx, vy, k, β_0 … β_{n−1}, δN_0, δE_0 … δN_{n−1}, δE_{n−1}]
                                          NED m, m/s, 1, m, m

with a loose constant-velocity model (white acceleration
``maneuver_accel_psd``: it ties the ranges of a few seconds together, but the
AUV's straight line is no evidence of the sound speed — a turn moves the
position, not k), k a slow random walk
(``sound_speed_walk_mps`` per √s, relative to c₀) about the prior
(``sound_speed_sigma_mps``), each β a constant with prior σ
``range_bias_sigma_m``.  Each range the tracker accepted is one scalar update
with its nominal range m predicted as m̂ = (ρ_b + s β_j − D)/k + d (ρ_b the
3-D range from the range's beacon b, corrected, to the AUV at its known depth;
s = +1, D = d = 0 for a range to the cycle's beacon, s = −1, D = D_j and
d = d_j as configured for the listener's),
gated at ``CAL_GATE_CHI2`` and down-weighted beyond ``soft_gate_chi2`` as the
motion filter is.  Each range enters once: no information is counted twice.

The biases make k slow to observe (a bias on every beacon looks much like a
scale while the geometry changes little), and they are usually absent.  Three
hypotheses therefore run side by side, :class:`SoundSpeedEstimator`: the
network as configured (no β, no δ), the turnarounds uncertain (β with prior σ
``range_bias_sigma_m``), and the survey and turnarounds uncertain (β and δ;
three beacons or more); their innovation likelihoods (each d² capped at
``LIKELIHOOD_CAP_CHI2``: one outlier decides nothing) are summed, and the
estimate reported is the more likely hypothesis's, once it leads by
``SWITCH_NATS`` (a turnaround off by 1 ms shows within a minute or two; a
hypothesis with corrections it does not need loses slowly, by the price of its
broader prior).  ``range_bias_sigma_m = 0`` and ``survey_sigma_m = 0`` drop
theirs.

The kinematic part starts from the motion filter's state (and again after a
re-acquisition); k and the β carry over.  Before each cycle is folded in, a
hypothesis whose position has strayed from the motion filter's (Mahalanobis
d² above ``ANCHOR_CHI2`` over their summed covariances, and more than
``ANCHOR_M``) restarts its kinematics from the filter's
(:meth:`SoundSpeedEstimator.anchor`): its loose constant-velocity model can
coast through a turn onto the mirror of its beacons' ranges, where the ranges
still fit, and there k bends to explain what is left (seen: 70 m off and the
sound speed 0.26 % off, its σ a tenth of that, on a network of three beacons
with the calibration exact).

Reported: the sound speed ĉ = k c₀ (m/s) of the reported hypothesis, its σ
(m/s) about ĉ over the hypotheses weighted by their likelihoods (a rival that
is still in the running and puts c elsewhere widens it), and ``converged``
when σ is at most ``sound_speed_converged_mps`` (never with two beacons).
"""

from __future__ import annotations

import math

import numpy as np

from zarco_runtime.tracking.gates import mahalanobis2
from zarco_runtime.tracking.params import Network, TrackerParams

#: innovations beyond this χ² (1 dof) are not used by the calibration
CAL_GATE_CHI2 = 16.0
#: an innovation's d² counts at most this much against a hypothesis
LIKELIHOOD_CAP_CHI2 = 9.0
#: log-likelihood lead (nats) that makes the other hypothesis the reported one
SWITCH_NATS = 10.0
#: a hypothesis whose position is further than this (m) from the motion
#: filter's, and at this Mahalanobis d² (2 dof, over both covariances), is
#: restarted from the filter's kinematics
ANCHOR_M = 5.0
ANCHOR_CHI2 = 25.0
#: the kinematic states
KIN = 4
#: index of k
K = 4


class Calibration:
    """One hypothesis: EKF on [x, y, vx, vy, k, β…] (module docstring)."""

    __slots__ = ("P", "_dz", "_q_k", "c0", "initialised", "loglik", "n", "name", "net0",
                 "p", "refused", "t", "updates", "x")

    def __init__(self, params: TrackerParams, net0: Network, bias_sigma_m: float,
                 survey_sigma_m: float = 0.0, name: str = "") -> None:
        self.p = params
        self.net0 = net0
        self.c0 = net0.c
        self.n = net0.n
        #: what the hypothesis questions ("" the configured network as exact)
        self.name = name
        n = KIN + 1 + 3 * self.n
        self.x = np.zeros(n)
        self.x[K] = 1.0
        self.P = np.zeros((n, n))
        observable = self.n >= 3
        if observable:  # two beacons: the sound speed is not observable, k stays 1
            self.P[K, K] = (params.sound_speed_sigma_mps / self.c0) ** 2
        for j in range(self.n):
            self.P[K + 1 + j, K + 1 + j] = bias_sigma_m ** 2
            self.P[self._dn(j), self._dn(j)] = survey_sigma_m ** 2
            self.P[self._dn(j) + 1, self._dn(j) + 1] = survey_sigma_m ** 2
        self._q_k = (params.sound_speed_walk_mps / self.c0) ** 2 if observable else 0.0
        self._dz = tuple(params.auv_depth_m - z for z in net0.depth)
        self.t = 0.0
        self.initialised = False
        #: ranges used, and refused by the gate
        self.updates = 0
        self.refused = 0
        #: summed (capped) log-likelihood of the innovations (nats)
        self.loglik = 0.0

    # ------------------------------------------------------------ results

    @property
    def sound_speed_mps(self) -> float:
        """The estimated sound speed ĉ (m/s)."""
        return float(self.x[K]) * self.c0

    @property
    def sound_speed_sigma_mps(self) -> float:
        """1σ of ĉ (m/s)."""
        return math.sqrt(max(float(self.P[K, K]), 0.0)) * self.c0

    def bias(self, j: int) -> float:
        """Estimated range bias β_j of beacon index ``j`` (m)."""
        return float(self.x[K + 1 + j])

    def _dn(self, j: int) -> int:
        """State index of beacon index ``j``'s survey correction δN_j (δE_j next)."""
        return KIN + 1 + self.n + 2 * j

    def offset(self, j: int) -> tuple[float, float]:
        """Estimated survey correction (δN, δE) of beacon index ``j`` (m)."""
        i = self._dn(j)
        return float(self.x[i]), float(self.x[i + 1])

    # ------------------------------------------------------------ filter

    def start(self, t: float, x: float, y: float, vx: float, vy: float,
              P4: list[list[float]]) -> None:
        """(Re)start the kinematic part at UTC ``t`` from the motion filter's
        state and covariance (4×4: x, y, vx, vy); k and the β carry over, their
        correlation with the old kinematics dropped."""
        self.x[:KIN] = (x, y, vx, vy)
        self.P[:KIN, :] = 0.0
        self.P[:, :KIN] = 0.0
        self.P[:KIN, :KIN] = np.asarray(P4, dtype=float)
        self.t = t
        self.initialised = True

    def predict(self, t: float) -> None:
        """Propagate to UTC ``t`` (constant velocity; random walk of k)."""
        dt = t - self.t
        if dt <= 0.0:
            return
        q = self.p.maneuver_accel_psd
        x, P = self.x, self.P
        x[0] += x[2] * dt
        x[1] += x[3] * dt
        # F P Fᵀ with F = [[I, dt I], [0, I]] on the kinematic block
        P[0, :] += dt * P[2, :]
        P[1, :] += dt * P[3, :]
        P[:, 0] += dt * P[:, 2]
        P[:, 1] += dt * P[:, 3]
        dt2 = dt * dt
        qpp, qpv, qvv = q * dt2 * dt / 3.0, q * dt2 / 2.0, q * dt
        P[0, 0] += qpp
        P[1, 1] += qpp
        P[0, 2] += qpv
        P[2, 0] += qpv
        P[1, 3] += qpv
        P[3, 1] += qpv
        P[2, 2] += qvv
        P[3, 3] += qvv
        P[K, K] += self._q_k * dt
        self.t = t

    def update(self, b: int, j: int, s: float, d: float, m: float, var: float) -> bool:
        """One scalar update with the nominal range ``m`` (m, variance ``var``
        m²) predicted as m̂ = (ρ_b + s β_j − D)/k + d, ρ_b to beacon b at its
        corrected position, D = 0 for a range to the cycle's beacon (s = +1,
        d = 0) and the corrected distance D_j from beacon j to the listener for
        the listener's (s = −1, d = d_j as configured); False when gated.
        (The prediction depends on the state alone: a Jacobian taken on the
        noisy measurement would bias k.)"""
        net = self.net0
        x, P = self.x, self.P
        ib_n = self._dn(b)
        dx = x[0] - net.north[b] - x[ib_n]
        dy = x[1] - net.east[b] - x[ib_n + 1]
        dz = self._dz[b]
        rho = math.sqrt(dx * dx + dy * dy + dz * dz)
        k = float(x[K])
        if rho < 1e-6 or k <= 0.0:
            return False
        ib = K + 1 + j
        H = np.zeros(x.size)
        u = rho + s * x[ib]
        if s < 0.0:  # the reply travelled from beacon j to the listener b
            jn = self._dn(j)
            gx = net.north[j] + x[jn] - net.north[b] - x[ib_n]
            gy = net.east[j] + x[jn + 1] - net.east[b] - x[ib_n + 1]
            gz = net.depth[j] - net.depth[b]
            big_d = math.sqrt(gx * gx + gy * gy + gz * gz)
            if big_d > 1e-6:
                u -= big_d
                H[jn] -= gx / (big_d * k)
                H[jn + 1] -= gy / (big_d * k)
                H[ib_n] += gx / (big_d * k)
                H[ib_n + 1] += gy / (big_d * k)
        H[0] = dx / (rho * k)
        H[1] = dy / (rho * k)
        H[ib_n] -= dx / (rho * k)
        H[ib_n + 1] -= dy / (rho * k)
        H[K] = -u / (k * k)
        H[ib] = s / k
        PH = P @ H
        S = float(H @ PH) + var
        if S <= 0.0:
            return False
        nu = m - (u / k + d)
        d2 = nu * nu / S
        self.loglik -= 0.5 * (min(d2, LIKELIHOOD_CAP_CHI2) + math.log(S))
        if d2 > CAL_GATE_CHI2:
            self.refused += 1
            return False
        soft = self.p.soft_gate_chi2
        if d2 > soft:  # a moderate outlier moves the state as a soft-gate one would
            S += var * (d2 / soft - 1.0)
        gain = PH / S
        x += gain * nu
        P -= np.outer(gain, PH)
        P += P.T
        P *= 0.5
        self.updates += 1
        return True


class SoundSpeedEstimator:
    """The hypotheses (network as configured, turnarounds uncertain, survey
    and turnarounds uncertain) and the one reported (module docstring)."""

    __slots__ = ("best", "models", "net0", "p")

    def __init__(self, params: TrackerParams, net0: Network) -> None:
        self.p = params
        self.net0 = net0
        self.models = [Calibration(params, net0, 0.0)]
        if params.range_bias_sigma_m > 0.0:
            self.models.append(Calibration(params, net0, params.range_bias_sigma_m,
                                           name="turnarounds"))
        if params.survey_sigma_m > 0.0 and self.observable:
            self.models.append(Calibration(params, net0, params.range_bias_sigma_m,
                                           params.survey_sigma_m, name="survey"))
        #: the hypothesis reported
        self.best = self.models[0]

    @property
    def observable(self) -> bool:
        """Three beacons or more: the ranges tell the sound speed (with two,
        nothing separates it from the AUV's position and the beacons' distance:
        the prior is kept)."""
        return self.net0.n >= 3

    @property
    def initialised(self) -> bool:
        return self.best.initialised

    @property
    def sound_speed_mps(self) -> float:
        """The estimated sound speed ĉ (m/s)."""
        return self.best.sound_speed_mps

    @property
    def sound_speed_sigma_mps(self) -> float:
        """1σ of ĉ (m/s; the configured uncertainty when not observable)."""
        if not self.observable:
            return self.p.sound_speed_sigma_mps
        # about the reported estimate, over the hypotheses weighted by their
        # likelihoods: a rival still in the running that puts the sound speed
        # elsewhere widens it
        c = self.best.sound_speed_mps
        top = max(m.loglik for m in self.models)
        w_sum = var = 0.0
        for m in self.models:
            w = math.exp(m.loglik - top)
            w_sum += w
            var += w * (m.sound_speed_sigma_mps ** 2 + (m.sound_speed_mps - c) ** 2)
        return math.sqrt(var / w_sum)

    @property
    def converged(self) -> bool:
        """Observable, and σ of ĉ at most ``sound_speed_converged_mps``."""
        return self.observable and (self.sound_speed_sigma_mps
                                    <= self.p.sound_speed_converged_mps)

    @property
    def hypothesis(self) -> str:
        """What the reported hypothesis questions: "" (nothing: the network as
        configured), "turnarounds" or "survey" (the beacons' positions and
        turnarounds)."""
        return self.best.name

    @property
    def biased(self) -> bool:
        """The reported hypothesis is the one with range biases."""
        return self.best is not self.models[0]

    def bias(self, j: int) -> float:
        """Estimated range bias β_j of beacon index ``j`` (m; 0 unless the
        hypothesis with biases is the reported one)."""
        return self.best.bias(j)

    def offsets(self) -> list[tuple[float, float]]:
        """Each beacon's estimated survey correction (north, east, m; zeros
        unless the survey hypothesis is the reported one)."""
        return [self.best.offset(j) for j in range(self.net0.n)]

    def start(self, t: float, x: float, y: float, vx: float, vy: float,
              P4: list[list[float]]) -> None:
        """(Re)start every hypothesis's kinematics (:meth:`Calibration.start`)."""
        for m in self.models:
            m.start(t, x, y, vx, vy, P4)

    def predict(self, t: float) -> None:
        for m in self.models:
            m.predict(t)

    def anchor(self, x: float, y: float, vx: float, vy: float,
               P4: list[list[float]]) -> int:
        """Restart the kinematics of every hypothesis (predicted to the motion
        filter's time) whose position strayed from the filter's (x, y: NED m,
        velocity m/s, 4×4 covariance) by more than ``ANCHOR_M`` and a
        Mahalanobis d² of ``ANCHOR_CHI2`` (module docstring); how many were."""
        n = 0
        for m in self.models:
            ex, ey = m.x[0] - x, m.x[1] - y
            if math.hypot(ex, ey) <= ANCHOR_M:
                continue
            m2 = mahalanobis2(ex, ey, m.P[0, 0] + P4[0][0], m.P[0, 1] + P4[0][1],
                              m.P[1, 1] + P4[1][1])
            if m2 is None or m2 > ANCHOR_CHI2:
                m.start(m.t, x, y, vx, vy, P4)
                n += 1
        return n

    def beacon_range(self, j: int, m: float, var: float) -> None:
        """The nominal range m_j (m, motion-corrected, at the prior sound speed)
        to beacon index ``j`` of a cycle on it (variance ``var``, m²)."""
        for mdl in self.models:
            mdl.update(j, j, 1.0, 0.0, m, var)
        self._select()

    def listener_range(self, j: int, m_l: float, var: float) -> None:
        """The nominal range m_L (m) to the listener of a cycle on beacon index
        ``j`` ≠ L (variance ``var``, m²)."""
        d = self.net0.d[j]
        for mdl in self.models:
            mdl.update(self.net0.listener, j, -1.0, d, m_l, var)
        self._select()

    def _select(self) -> None:
        lead = max(self.models, key=lambda m: m.loglik)
        if lead is not self.best and lead.loglik - self.best.loglik >= SWITCH_NATS:
            self.best = lead
