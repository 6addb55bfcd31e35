"""Constant-velocity Kalman filter of the AUV's horizontal motion, run at the
emission times of the fixes (paper IV–V).

State (x, y, vx, vy): NED position (m, x north, y east) and velocity (m/s) at
time :attr:`CvKalman.t` (UTC seconds — any clock works, only differences are
used, so epoch-sized times lose nothing).  Process model: white acceleration of
spectral density q (m²/s³) on each axis.

Measurements are linear in the position only: each row (a, b) measures
a·x + b·y with variance σ², which covers both a range linearised at a point
(a, b = the unit vector from the beacon, scaled by ρ/r) and a plain position
component.  A two-circle fix is applied as its two linearised ranges, so a fix
on the baseline (circles tangent, the position singular across it) is still a
well-posed update.  Innovation gating on the Mahalanobis distance².

Plain Python on lists: for a 4-state filter it is several times faster than
numpy (whose per-call overhead dominates tiny matrices); see the tracker's
benchmark test.
"""

from __future__ import annotations

import math


class CvKalman:
    """4-state constant-velocity Kalman filter (plain floats, no numpy)."""

    __slots__ = ("P", "initialised", "q", "t", "x")

    def __init__(self, accel_psd: float) -> None:
        self.q = accel_psd
        self.t = 0.0
        self.x = [0.0, 0.0, 0.0, 0.0]
        self.P = [[0.0] * 4 for _ in range(4)]
        self.initialised = False

    def init(self, t: float, x: float, y: float, vx: float = 0.0, vy: float = 0.0,
             pos_var: float = 25.0, vel_var: float = 1.0) -> None:
        """Start at time ``t`` from a position/velocity with diagonal variances."""
        self.t = t
        self.x = [x, y, vx, vy]
        self.P = [[pos_var, 0.0, 0.0, 0.0], [0.0, pos_var, 0.0, 0.0],
                  [0.0, 0.0, vel_var, 0.0], [0.0, 0.0, 0.0, vel_var]]
        self.initialised = True

    def reset(self) -> None:
        """Forget the state (not initialised)."""
        self.initialised = False

    def predict(self, t: float) -> None:
        """Propagate to time ``t``; a time at or before the current one is a no-op."""
        dt = t - self.t
        if dt <= 0.0:
            return
        x = self.x
        x[0] += x[2] * dt
        x[1] += x[3] * dt
        P = self.P
        # F P Fᵀ with F = [[I, dt I], [0, I]]
        for k in range(4):
            row = P[k]
            row[0] += dt * row[2]
            row[1] += dt * row[3]
        r0, r1, r2, r3 = P
        for j in range(4):
            r0[j] += dt * r2[j]
            r1[j] += dt * r3[j]
        q = self.q
        dt2 = dt * dt
        qpp = q * dt2 * dt / 3.0
        qpv = q * dt2 / 2.0
        qvv = q * dt
        r0[0] += qpp
        r1[1] += qpp
        r0[2] += qpv
        r2[0] += qpv
        r1[3] += qpv
        r3[1] += qpv
        r2[2] += qvv
        r3[3] += qvv
        self.t = t

    def predicted(self, t: float) -> tuple[float, float, float, float, float]:
        """(x, y, Pxx, Pxy, Pyy) predicted at ``t`` without changing the filter."""
        dt = max(t - self.t, 0.0)
        x = self.x
        P = self.P
        pxx = P[0][0] + 2.0 * dt * P[0][2] + dt * dt * P[2][2] + self.q * dt ** 3 / 3.0
        pyy = P[1][1] + 2.0 * dt * P[1][3] + dt * dt * P[3][3] + self.q * dt ** 3 / 3.0
        pxy = P[0][1] + dt * (P[0][3] + P[2][1]) + dt * dt * P[2][3]
        return x[0] + x[2] * dt, x[1] + x[3] * dt, pxx, pxy, pyy

    def pos_sigma(self) -> float:
        """RMS of the two position standard deviations (m)."""
        return math.sqrt(max(0.5 * (self.P[0][0] + self.P[1][1]), 0.0))

    def inflate(self, pos_var: float, vel_var: float) -> None:
        """Add position and velocity variance (m², m²/s²) on both axes."""
        P = self.P
        P[0][0] += pos_var
        P[1][1] += pos_var
        P[2][2] += vel_var
        P[3][3] += vel_var

    def update(self, rows: list[tuple[float, float]], z: list[float], var: list[float],
               gate_chi2: float = math.inf, soft_chi2: float = math.inf) -> tuple[bool, float]:
        """Measurement update with 1 or 2 independent rows at the current time.

        ``rows[r] = (a, b)`` measures a x + b y, observed as ``z[r]`` with
        variance ``var[r]``.  Returns (accepted, d²): when the Mahalanobis
        distance² d² of the innovation exceeds ``gate_chi2`` nothing changes;
        between ``soft_chi2`` and the gate the measurement variances are scaled
        by d²/``soft_chi2`` (a Huber-like down-weighting: a moderate outlier moves
        the state as little as a ``soft_chi2`` innovation would).
        """
        x = self.x
        P = self.P
        m = len(rows)
        # P Hᵀ (4 × m)
        pht = [[P[k][0] * a + P[k][1] * b for a, b in rows] for k in range(4)]
        nu = [z[r] - (rows[r][0] * x[0] + rows[r][1] * x[1]) for r in range(m)]
        if m == 1:
            a, b = rows[0]
            s = a * pht[0][0] + b * pht[1][0] + var[0]
            if s <= 0.0:
                return False, math.inf
            d2 = nu[0] * nu[0] / s
            if d2 > gate_chi2:
                return False, d2
            gains = [[pht[k][0] / s] for k in range(4)]
        elif m == 2:
            (a0, b0), (a1, b1) = rows
            s00 = a0 * pht[0][0] + b0 * pht[1][0] + var[0]
            s01 = a0 * pht[0][1] + b0 * pht[1][1]
            s11 = a1 * pht[0][1] + b1 * pht[1][1] + var[1]
            det = s00 * s11 - s01 * s01
            if det <= 0.0:
                return False, math.inf
            i00, i01, i11 = s11 / det, -s01 / det, s00 / det
            n0, n1 = nu
            d2 = n0 * (i00 * n0 + i01 * n1) + n1 * (i01 * n0 + i11 * n1)
            if d2 > gate_chi2:
                return False, d2
            gains = [[p0 * i00 + p1 * i01, p0 * i01 + p1 * i11] for p0, p1 in pht]
        else:
            raise ValueError(f"1 or 2 measurement rows, got {m}")
        if d2 > soft_chi2:
            scale = d2 / soft_chi2
            ok, _ = self.update(rows, z, [v * scale for v in var])
            return ok, d2
        for k in range(4):
            gk = gains[k]
            x[k] += sum(gk[r] * nu[r] for r in range(m))
        for k in range(4):
            gk = gains[k]
            row = P[k]
            for j in range(k, 4):
                pj = pht[j]
                v = row[j] - sum(gk[r] * pj[r] for r in range(m))
                row[j] = v
                P[j][k] = v
        return True, d2

