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
the position and k is observable; the listener's own cycles (r_L measured
through τ_L) against the other cycles' r_L (through d_j) are a second lever,
which also works with two beacons — but then only for k and β_j + β_L
together.  With two beacons and no cycle on the listener's beacon nothing
separates k from the position: the estimate stays at the prior, with its σ.

Each hypothesis is an extended Kalman filter, apart from the tracker's
motion filter, on the state::

    [x, y, vx, vy, k, β_0 … β_{n−1}]       NED m, m/s, 1, m

with a loose constant-velocity model (white acceleration
``maneuver_accel_psd``: it ties the ranges of a few seconds together, but the
AUV's straight line is no evidence of the sound speed — a turn moves the
position, not k), k a slow random walk
(``sound_speed_walk_mps`` per √s, relative to c₀) about the prior
(``sound_speed_sigma_mps``), each β a constant with prior σ
``range_bias_sigma_m``.  Each range the tracker accepted is one scalar update
with its nominal range m predicted as m̂ = (ρ_b + s β_j − d)/k + d (ρ_b the
3-D range from the range's beacon b to the AUV at its known depth; s = +1,
d = 0 for a range to the cycle's beacon, s = −1, d = d_j for the listener's),
gated at ``CAL_GATE_CHI2`` and down-weighted beyond ``soft_gate_chi2`` as the
motion filter is.  Each range enters once: no information is counted twice.

The biases make k slow to observe (a bias on every beacon looks much like a
scale while the geometry changes little), and they are usually absent.  Two
hypotheses therefore run side by side, :class:`SoundSpeedEstimator`: the
turnarounds as configured (no β) and the turnarounds uncertain (β with prior
σ ``range_bias_sigma_m``); their innovation likelihoods (each d² capped at
``LIKELIHOOD_CAP_CHI2``: one outlier decides nothing) are summed, and the
estimate reported is the more likely hypothesis's, once it leads by
``SWITCH_NATS`` (a turnaround off by 1 ms shows within a minute or two; a
hypothesis with biases it does not need loses slowly, by the price of its
broader prior).  ``range_bias_sigma_m = 0`` keeps only the first.

The kinematic part starts from the motion filter's state (and again after a
re-acquisition); k and the β carry over.

Reported: the sound speed ĉ = k c₀ (m/s), its σ (m/s), and ``converged``
when σ is at most ``sound_speed_converged_mps``.
"""

from __future__ import annotations

import math

import numpy as np

from zarco_runtime.tracking.params import Network, TrackerParams

#: innovations beyond this χ² (1 dof) are not used by the calibration
CAL_GATE_CHI2 = 16.0
#: an innovation's d² counts at most this much against a hypothesis
LIKELIHOOD_CAP_CHI2 = 9.0
#: log-likelihood lead (nats) that makes the other hypothesis the reported one
SWITCH_NATS = 10.0
#: the kinematic states
KIN = 4
#: index of k
K = 4


class Calibration:
    """One hypothesis: EKF on [x, y, vx, vy, k, β…] (module docstring)."""

    __slots__ = ("P", "_dz", "_q_k", "c0", "initialised", "loglik", "n", "net0", "p",
                 "refused", "t", "updates", "x")

    def __init__(self, params: TrackerParams, net0: Network, bias_sigma_m: float) -> None:
        self.p = params
        self.net0 = net0
        self.c0 = net0.c
        self.n = net0.n
        n = KIN + 1 + self.n
        self.x = np.zeros(n)
        self.x[K] = 1.0
        self.P = np.zeros((n, n))
        self.P[K, K] = (params.sound_speed_sigma_mps / self.c0) ** 2
        for j in range(self.n):
            self.P[K + 1 + j, K + 1 + j] = bias_sigma_m ** 2
        self._q_k = (params.sound_speed_walk_mps / self.c0) ** 2
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
        m²) predicted as m̂ = (ρ_b + s β_j − d)/k + d; False when gated.  (The
        prediction depends on the state alone: a Jacobian taken on the noisy
        measurement would bias k.)"""
        net = self.net0
        x, P = self.x, self.P
        dx = x[0] - net.north[b]
        dy = x[1] - net.east[b]
        dz = self._dz[b]
        rho = math.sqrt(dx * dx + dy * dy + dz * dz)
        k = float(x[K])
        if rho < 1e-6 or k <= 0.0:
            return False
        ib = K + 1 + j
        u = rho + s * x[ib] - d
        H = np.zeros(x.size)
        H[0] = dx / (rho * k)
        H[1] = dy / (rho * k)
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
    """The two hypotheses (turnarounds as configured, turnarounds uncertain)
    and the one reported (module docstring)."""

    __slots__ = ("best", "models", "net0", "p")

    def __init__(self, params: TrackerParams, net0: Network) -> None:
        self.p = params
        self.net0 = net0
        self.models = [Calibration(params, net0, 0.0)]
        if params.range_bias_sigma_m > 0.0:
            self.models.append(Calibration(params, net0, params.range_bias_sigma_m))
        #: the hypothesis reported
        self.best = self.models[0]

    @property
    def initialised(self) -> bool:
        return self.best.initialised

    @property
    def sound_speed_mps(self) -> float:
        """The estimated sound speed ĉ (m/s)."""
        return self.best.sound_speed_mps

    @property
    def sound_speed_sigma_mps(self) -> float:
        """1σ of ĉ (m/s)."""
        return self.best.sound_speed_sigma_mps

    @property
    def converged(self) -> bool:
        """σ of ĉ at most ``sound_speed_converged_mps``."""
        return self.sound_speed_sigma_mps <= self.p.sound_speed_converged_mps

    @property
    def biased(self) -> bool:
        """The reported hypothesis is the one with range biases."""
        return self.best is not self.models[0]

    def bias(self, j: int) -> float:
        """Estimated range bias β_j of beacon index ``j`` (m; 0 unless the
        hypothesis with biases is the reported one)."""
        return self.best.bias(j)

    def start(self, t: float, x: float, y: float, vx: float, vy: float,
              P4: list[list[float]]) -> None:
        """(Re)start every hypothesis's kinematics (:meth:`Calibration.start`)."""
        for m in self.models:
            m.start(t, x, y, vx, vy, P4)

    def predict(self, t: float) -> None:
        for m in self.models:
            m.predict(t)

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
