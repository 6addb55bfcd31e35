"""Constant-velocity Kalman filter of the AUV's horizontal motion, run at the
emission times of the fixes (DESIGN.md §6).

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


def _innovation(x: list[float], P: list[list[float]], rows: list[tuple[float, float]],
                z: list[float], var: list[float]) -> tuple[float, float]:
    """(d², log det S) of the innovation of 1 or 2 position rows against the
    state (x, P) (inf, inf when S is singular)."""
    m = len(rows)
    pht = [[P[k][0] * a + P[k][1] * b for a, b in rows] for k in range(2)]
    nu = [z[r] - (rows[r][0] * x[0] + rows[r][1] * x[1]) for r in range(m)]
    if m == 1:
        a, b = rows[0]
        s = a * pht[0][0] + b * pht[1][0] + var[0]
        if s <= 0.0:
            return math.inf, math.inf
        return nu[0] * nu[0] / s, math.log(s)
    (a0, b0), (a1, b1) = rows
    s00 = a0 * pht[0][0] + b0 * pht[1][0] + var[0]
    s01 = a0 * pht[0][1] + b0 * pht[1][1]
    s11 = a1 * pht[0][1] + b1 * pht[1][1] + var[1]
    det = s00 * s11 - s01 * s01
    if det <= 0.0:
        return math.inf, math.inf
    n0, n1 = nu
    return (n0 * n0 * s11 - 2.0 * n0 * n1 * s01 + n1 * n1 * s00) / det, math.log(det)


class ImmCv:
    """Interacting multiple models (Blom & Bar-Shalom): constant-velocity filters
    with different white-acceleration densities run side by side — a quiet one
    for straight legs, a loud one for manoeuvres — mixed at every step by a
    Markov chain whose switching probabilities follow the elapsed time (model
    j is left at the rate 1/``sojourn_s[j]``), weighted by how well each
    predicted the measurement.

    The same interface as :class:`CvKalman`: :attr:`x` and :attr:`P` are the
    combined (moment-matched) estimate, refreshed after every step;
    :attr:`mu` the model probabilities.  Gating is decided on the combined
    estimate, so an outlier is refused (or down-weighted) exactly as by one
    filter; the models' likelihoods use the down-weighted variances, so one
    outlier moves the probabilities no more than a ``soft_chi2`` innovation.
    """

    __slots__ = ("P", "initialised", "models", "mu", "mu_floor", "mu_init", "sojourn_s", "t",
                 "x")

    def __init__(self, accel_psds: tuple[float, ...], sojourn_s: tuple[float, ...],
                 mu_init: tuple[float, ...] | None = None, mu_floor: float = 1e-3) -> None:
        if len(accel_psds) < 2 or len(sojourn_s) != len(accel_psds):
            raise ValueError("ImmCv: at least two models, one sojourn time per model")
        n = len(accel_psds)
        self.models = [CvKalman(q) for q in accel_psds]
        self.sojourn_s = tuple(sojourn_s)
        self.mu_init = tuple(mu_init) if mu_init is not None else tuple([1.0 / n] * n)
        self.mu_floor = mu_floor
        self.mu = list(self.mu_init)
        self.t = 0.0
        self.x = [0.0, 0.0, 0.0, 0.0]
        self.P = [[0.0] * 4 for _ in range(4)]
        self.initialised = False

    @property
    def q(self) -> float:
        """The quiet model's spectral density (m²/s³)."""
        return self.models[0].q

    def init(self, t: float, x: float, y: float, vx: float = 0.0, vy: float = 0.0,
             pos_var: float = 25.0, vel_var: float = 1.0) -> None:
        """Start every model at time ``t`` from the same state (as :meth:`CvKalman.init`)."""
        for mdl in self.models:
            mdl.init(t, x, y, vx, vy, pos_var, vel_var)
        self.mu = list(self.mu_init)
        self.t = t
        self.initialised = True
        self._combine()

    def reset(self) -> None:
        self.initialised = False
        for mdl in self.models:
            mdl.reset()

    def _combine(self) -> None:
        mu = self.mu
        ms = self.models
        x = [sum(mu[j] * ms[j].x[k] for j in range(len(ms))) for k in range(4)]
        P = [[0.0] * 4 for _ in range(4)]
        for j, mdl in enumerate(ms):
            dx = [mdl.x[k] - x[k] for k in range(4)]
            w = mu[j]
            Pj = mdl.P
            for a in range(4):
                row = P[a]
                pa = Pj[a]
                da = dx[a]
                for b in range(4):
                    row[b] += w * (pa[b] + da * dx[b])
        self.x = x
        self.P = P

    def _transition(self, dt: float) -> list[list[float]]:
        """p[i][j]: probability of switching from model i to model j over ``dt`` s."""
        n = len(self.models)
        p = []
        for i in range(n):
            stay = math.exp(-dt / self.sojourn_s[i])
            leave = (1.0 - stay) / (n - 1)
            p.append([stay if j == i else leave for j in range(n)])
        return p

    def predict(self, t: float) -> None:
        """Mix the models for the time elapsed, then propagate each to ``t``."""
        dt = t - self.t
        if dt <= 0.0:
            return
        ms = self.models
        n = len(ms)
        p = self._transition(dt)
        mu = self.mu
        cbar = [sum(p[i][j] * mu[i] for i in range(n)) for j in range(n)]
        mixed = []
        for j in range(n):
            w = [p[i][j] * mu[i] / cbar[j] if cbar[j] > 0.0 else 0.0 for i in range(n)]
            x0 = [sum(w[i] * ms[i].x[k] for i in range(n)) for k in range(4)]
            P0 = [[0.0] * 4 for _ in range(4)]
            for i in range(n):
                dx = [ms[i].x[k] - x0[k] for k in range(4)]
                Pi = ms[i].P
                for a in range(4):
                    for b in range(4):
                        P0[a][b] += w[i] * (Pi[a][b] + dx[a] * dx[b])
            mixed.append((x0, P0))
        for j, (x0, P0) in enumerate(mixed):
            ms[j].x = x0
            ms[j].P = P0
            ms[j].predict(t)
        self.mu = cbar
        self.t = t
        self._combine()

    def predicted(self, t: float) -> tuple[float, float, float, float, float]:
        """(x, y, Pxx, Pxy, Pyy) of the combined estimate predicted at ``t``
        (each model propagated, weighted by the current probabilities; the
        filter is not changed)."""
        preds = [mdl.predicted(t) for mdl in self.models]
        mu = self.mu
        x = sum(w * pr[0] for w, pr in zip(mu, preds, strict=True))
        y = sum(w * pr[1] for w, pr in zip(mu, preds, strict=True))
        pxx = pxy = pyy = 0.0
        for w, (px, py, a, b, d) in zip(mu, preds, strict=True):
            ex, ey = px - x, py - y
            pxx += w * (a + ex * ex)
            pxy += w * (b + ex * ey)
            pyy += w * (d + ey * ey)
        return x, y, pxx, pxy, pyy

    def pos_sigma(self) -> float:
        """RMS of the two position standard deviations of the combined estimate (m)."""
        return math.sqrt(max(0.5 * (self.P[0][0] + self.P[1][1]), 0.0))

    def inflate(self, pos_var: float, vel_var: float) -> None:
        """Add position and velocity variance (m², m²/s²) to every model."""
        for mdl in self.models:
            P = mdl.P
            P[0][0] += pos_var
            P[1][1] += pos_var
            P[2][2] += vel_var
            P[3][3] += vel_var
        self._combine()

    def update(self, rows: list[tuple[float, float]], z: list[float], var: list[float],
               gate_chi2: float = math.inf, soft_chi2: float = math.inf) -> tuple[bool, float]:
        """Measurement update (as :meth:`CvKalman.update`): gate on the combined
        estimate, update every model, re-weight them by their likelihoods."""
        d2, _ = _innovation(self.x, self.P, rows, z, var)
        if not d2 <= gate_chi2:
            return False, d2
        if d2 > soft_chi2:
            var = [v * d2 / soft_chi2 for v in var]
        ms = self.models
        logl = []
        for mdl in ms:
            dj, ldet = _innovation(mdl.x, mdl.P, rows, z, var)
            logl.append(-0.5 * (dj + ldet) if math.isfinite(dj) else -math.inf)
            mdl.update(rows, z, var)
        top = max(logl)
        if not math.isfinite(top):
            self._combine()
            return True, d2
        w = [m * math.exp(ll - top) for m, ll in zip(self.mu, logl, strict=True)]
        s = sum(w)
        mu = [max(v / s, self.mu_floor) for v in w]
        s = sum(mu)
        self.mu = [v / s for v in mu]
        self._combine()
        return True, d2
