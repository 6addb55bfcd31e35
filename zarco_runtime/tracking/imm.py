"""Interacting multiple models for the AUV's horizontal motion (Blom & Bar-Shalom).

Every model carries the same five states (x, y, vx, vy, ω): NED position (m),
velocity (m/s) and turn rate (rad/s, positive turning clockwise — from north
towards east, to starboard), at the filter's time :attr:`Imm.t` (any clock,
only differences are used).

Models:

* ``cv``: constant velocity, white acceleration of density q (m²/s³) on each
  axis; ω plays no part and is held at 0 with a small variance (so that mixing
  it into a turning model starts that model from straight flight);
* ``ct``: coordinated turn — the velocity rotates at ω, ω is a random walk
  (density q_ω, rad²/s³) — linearised about the estimate (extended Kalman
  filter), with white acceleration q on the velocity.

At every step the models are mixed by a Markov chain whose switching
probabilities follow the elapsed time (model j is left at the rate
1/``sojourn_s[j]``: the quiet model for the others in equal shares, a
manoeuvring one mostly for the quiet one, ``RETURN_SHARE``), each is propagated, and
each is weighted by how well it predicted the measurement.  Gating is on the
combined estimate (whose covariance holds the models' spread), or on a
coordinated-turn model that still holds ``GATE_TURN_MU`` of the probability:
a measurement that model predicts within the gate is taken even when the
combined estimate, still mostly straight, would refuse it (the fixes that
show a turn are the ones a straight filter finds too far; refused, they
left the filter going on along the old course metres past the turn, and the
one-range updates between them could not pull it back).  Each model
down-weights an accepted measurement beyond ``soft_chi2`` by its own d²
(Huber: the turning model takes a turn the quiet one discounts), and the
models' likelihoods are a Gaussian plus an outlier floor common to every model
(one outlier shifts the
probabilities by a bounded factor; a turn, several moderate innovations in a
row, still does).

The interface is :class:`~zarco_runtime.tracking.kalman.CvKalman`'s:
:attr:`Imm.x` and :attr:`Imm.P` are the combined (moment-matched) position and
velocity (4 states) and their covariance, refreshed after every step;
:attr:`Imm.omega` the combined turn rate; :attr:`Imm.mu` the model
probabilities.  Measurements are linear in the position (rows (a, b)).

Plain Python on lists: 5×5 matrices are cheaper without numpy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

N = 5
#: the share of the models left by a manoeuvring model that goes back to the
#: quiet one (model 0); the rest is spread over the other manoeuvring models
RETURN_SHARE = 0.8
#: probability that a measurement is an outlier, and the span (m) over which an
#: outlier may fall: the likelihood of every model has the floor
#: ε (2π)^(m/2) / span^m (m measurement rows) besides its Gaussian
OUTLIER_PROBABILITY = 0.05
OUTLIER_SPAN_M = 30.0
OUTLIER_DENSITY = tuple(OUTLIER_PROBABILITY * (2.0 * math.pi) ** (0.5 * m) / OUTLIER_SPAN_M ** m
                        for m in (1, 2))
#: a coordinated-turn model with at least this probability opens the gate to
#: the measurements it predicts within it (module docstring)
GATE_TURN_MU = 0.05
#: variance of ω in a constant-velocity model ((rad/s)²: about 3 °/s 1σ)
CV_OMEGA_VAR = 0.05 ** 2


def _zeros() -> list[list[float]]:
    return [[0.0] * N for _ in range(N)]


class _Model:
    """One model of the bank: state (x, y, vx, vy, ω), covariance, dynamics."""

    __slots__ = ("P", "kind", "omega0", "omega0_var", "omega_max", "q", "q_omega", "x")

    def __init__(self, kind: str, q: float, q_omega: float = 0.0, omega0: float = 0.0,
                 omega0_var: float = CV_OMEGA_VAR, omega_max: float = math.inf) -> None:
        if kind not in ("cv", "ct"):
            raise ValueError(f"model kind must be 'cv' or 'ct', got {kind!r}")
        self.kind = kind
        self.q = q
        self.q_omega = q_omega
        #: the turn rate (rad/s) a turning model takes from a straight one when
        #: they mix — the turn it expects the AUV to start — and its variance
        self.omega0 = omega0
        self.omega0_var = omega0_var
        #: the turn rate is held within ± this (rad/s): the AUV turns no faster
        self.omega_max = omega_max
        self.x = [0.0] * N
        self.P = _zeros()

    def _transition(self, dt: float) -> tuple[float, ...]:
        """The non-trivial entries of the transition Jacobian over ``dt``:
        rows 0–1 (position) and 2–3 (velocity) on columns 2, 3, 4 — the rest of
        F is the identity — as (f02, f03, f04, f12, f13, f14, f22, f23, f24,
        f32, f33, f34)."""
        x = self.x
        vx, vy, w = x[2], x[3], x[4]
        if self.kind == "cv":
            return (dt, 0.0, 0.0, 0.0, dt, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0)
        th = w * dt
        s, c = math.sin(th), math.cos(th)
        if abs(w) > 1e-4:
            a = s / w
            b = (1.0 - c) / w
            da = (dt * c * w - s) / (w * w)
            db = (dt * s * w - (1.0 - c)) / (w * w)
        else:
            a, b = dt, 0.5 * w * dt * dt
            da, db = -w * dt ** 3 / 3.0, 0.5 * dt * dt
        return (a, -b, da * vx - db * vy, b, a, db * vx + da * vy,
                c, -s, dt * (-s * vx - c * vy), s, c, dt * (c * vx - s * vy))

    def _propagate_state(self, dt: float, f: tuple[float, ...]) -> list[float]:
        x = self.x
        vx, vy = x[2], x[3]
        if self.kind == "cv":
            return [x[0] + vx * dt, x[1] + vy * dt, vx, vy, 0.0]
        # f02 = a, f03 = −b, f22 = c, f23 = −s (exact for the coordinated turn)
        a, mb, c, ms = f[0], f[1], f[6], f[7]
        return [x[0] + a * vx + mb * vy, x[1] - mb * vx + a * vy, c * vx + ms * vy,
                -ms * vx + c * vy, x[4]]

    def predict(self, dt: float) -> None:
        """Propagate state and covariance by ``dt`` s (extended Kalman filter)."""
        f = self._transition(dt)
        self.x = self._propagate_state(dt, f)
        f02, f03, f04, f12, f13, f14, f22, f23, f24, f32, f33, f34 = f
        P = self.P
        p0, p1, p2, p3, p4 = P
        # G = F P (rows)
        g0 = [p0[j] + f02 * p2[j] + f03 * p3[j] + f04 * p4[j] for j in range(N)]
        g1 = [p1[j] + f12 * p2[j] + f13 * p3[j] + f14 * p4[j] for j in range(N)]
        g2 = [f22 * p2[j] + f23 * p3[j] + f24 * p4[j] for j in range(N)]
        g3 = [f32 * p2[j] + f33 * p3[j] + f34 * p4[j] for j in range(N)]
        g4 = list(p4)
        # F P Fᵀ: column transform of G's rows
        out = []
        for g in (g0, g1, g2, g3, g4):
            c2, c3, c4 = g[2], g[3], g[4]
            out.append([g[0] + f02 * c2 + f03 * c3 + f04 * c4,
                        g[1] + f12 * c2 + f13 * c3 + f14 * c4,
                        f22 * c2 + f23 * c3 + f24 * c4,
                        f32 * c2 + f33 * c3 + f34 * c4,
                        c4])
        q = self.q
        dt2 = dt * dt
        qpp, qpv, qvv = q * dt2 * dt / 3.0, q * dt2 / 2.0, q * dt
        out[0][0] += qpp
        out[1][1] += qpp
        out[0][2] += qpv
        out[2][0] += qpv
        out[1][3] += qpv
        out[3][1] += qpv
        out[2][2] += qvv
        out[3][3] += qvv
        if self.kind == "cv":
            for k in range(N):
                out[4][k] = out[k][4] = 0.0
            out[4][4] = CV_OMEGA_VAR
        else:
            out[4][4] += self.q_omega * dt
        self.P = out
        self._clamp()

    def _clamp(self) -> None:
        """Hold the turn rate within ± ``omega_max``."""
        w = self.x[4]
        lim = self.omega_max
        if w > lim:
            self.x[4] = lim
        elif w < -lim:
            self.x[4] = -lim

    def set_turn_rate(self, w: float, var: float) -> None:
        """The turn rate set to ``w`` (rad/s) with variance ``var`` (rad²/s²),
        uncorrelated with the rest of the state."""
        self.x[4] = w
        for k in range(4):
            self.P[k][4] = self.P[4][k] = 0.0
        self.P[4][4] = var

    def predicted_position(self, dt: float) -> tuple[float, float, float, float, float]:
        """(x, y, Pxx, Pxy, Pyy) after ``dt`` s, without changing the model."""
        f = self._transition(dt)
        xs = self._propagate_state(dt, f)
        f02, f03, f04, f12, f13, f14 = f[:6]
        p0, p1, p2, p3, p4 = self.P
        g0 = [p0[j] + f02 * p2[j] + f03 * p3[j] + f04 * p4[j] for j in range(N)]
        g1 = [p1[j] + f12 * p2[j] + f13 * p3[j] + f14 * p4[j] for j in range(N)]
        qpp = self.q * dt ** 3 / 3.0
        pxx = g0[0] + f02 * g0[2] + f03 * g0[3] + f04 * g0[4] + qpp
        pxy = g0[1] + f12 * g0[2] + f13 * g0[3] + f14 * g0[4]
        pyy = g1[1] + f12 * g1[2] + f13 * g1[3] + f14 * g1[4] + qpp
        return xs[0], xs[1], pxx, pxy, pyy

    def innovation(self, rows: list[tuple[float, float]], z: list[float],
                   var: list[float]) -> tuple[float, float]:
        """(d², log det S) of position rows against this model (inf when singular)."""
        x, P = self.x, self.P
        m = len(rows)
        nu = [z[r] - (rows[r][0] * x[0] + rows[r][1] * x[1]) for r in range(m)]
        if m == 1:
            a, b = rows[0]
            s = a * a * P[0][0] + 2.0 * a * b * P[0][1] + b * b * P[1][1] + var[0]
            if s <= 0.0:
                return math.inf, math.inf
            return nu[0] * nu[0] / s, math.log(s)
        (a0, b0), (a1, b1) = rows
        s00 = a0 * a0 * P[0][0] + 2.0 * a0 * b0 * P[0][1] + b0 * b0 * P[1][1] + var[0]
        s11 = a1 * a1 * P[0][0] + 2.0 * a1 * b1 * P[0][1] + b1 * b1 * P[1][1] + var[1]
        s01 = a0 * a1 * P[0][0] + (a0 * b1 + b0 * a1) * P[0][1] + b0 * b1 * P[1][1]
        det = s00 * s11 - s01 * s01
        if det <= 0.0:
            return math.inf, math.inf
        n0, n1 = nu
        return (n0 * n0 * s11 - 2.0 * n0 * n1 * s01 + n1 * n1 * s00) / det, math.log(det)

    def update(self, rows: list[tuple[float, float]], z: list[float],
               var: list[float]) -> None:
        """Kalman update with 1 or 2 position rows (no gate)."""
        x, P = self.x, self.P
        m = len(rows)
        pht = [[P[k][0] * a + P[k][1] * b for a, b in rows] for k in range(N)]
        nu = [z[r] - (rows[r][0] * x[0] + rows[r][1] * x[1]) for r in range(m)]
        if m == 1:
            a, b = rows[0]
            s = a * pht[0][0] + b * pht[1][0] + var[0]
            if s <= 0.0:
                return
            gains = [[pht[k][0] / s] for k in range(N)]
        else:
            (a0, b0), (a1, b1) = rows
            s00 = a0 * pht[0][0] + b0 * pht[1][0] + var[0]
            s01 = a0 * pht[0][1] + b0 * pht[1][1]
            s11 = a1 * pht[0][1] + b1 * pht[1][1] + var[1]
            det = s00 * s11 - s01 * s01
            if det <= 0.0:
                return
            i00, i01, i11 = s11 / det, -s01 / det, s00 / det
            gains = [[p0 * i00 + p1 * i01, p0 * i01 + p1 * i11] for p0, p1 in pht]
        for k in range(N):
            x[k] += sum(gains[k][r] * nu[r] for r in range(m))
        for k in range(N):
            gk = gains[k]
            row = P[k]
            for j in range(k, N):
                v = row[j] - sum(gk[r] * pht[j][r] for r in range(m))
                row[j] = v
                P[j][k] = v
        self._clamp()


def turn_step(x: float, y: float, vx: float, vy: float, w: float, dt: float
              ) -> tuple[float, float, float, float]:
    """Position and velocity after ``dt`` s of a coordinated turn at ``w`` rad/s
    (positive to starboard; a straight line when w is 0)."""
    if abs(w) < 1e-6:
        return x + vx * dt, y + vy * dt, vx, vy
    th = w * dt
    s, c = math.sin(th), math.cos(th)
    a, b = s / w, (1.0 - c) / w
    return x + a * vx - b * vy, y + b * vx + a * vy, c * vx - s * vy, s * vx + c * vy


class ModelSpec(NamedTuple):
    """One model of the bank (:class:`_Model`): kind (``cv``, ``ct``), white
    acceleration q (m²/s³), turn-rate random walk q_ω (rad²/s³), the turn rate
    ω₀ (rad/s) and its variance it starts a turn with, the largest |ω| (rad/s)."""

    kind: str
    q: float
    q_omega: float = 0.0
    omega0: float = 0.0
    omega0_var: float = CV_OMEGA_VAR
    omega_max: float = math.inf


class Imm:
    """A bank of :class:`_Model` mixed by a Markov chain (module docstring)."""

    __slots__ = ("P", "initialised", "models", "mu", "mu_floor", "mu_init", "omega",
                 "omega_var", "sojourn_s", "t", "x")

    def __init__(self, models: Sequence[ModelSpec], sojourn_s: tuple[float, ...],
                 mu_init: tuple[float, ...] | None = None, mu_floor: float = 1e-3) -> None:
        """``models``: the bank (:class:`ModelSpec`, or a tuple of its fields);
        model 0 is the quiet straight-line one."""
        if len(models) < 2 or len(sojourn_s) != len(models):
            raise ValueError("Imm: at least two models, one sojourn time per model")
        n = len(models)
        self.models = [_Model(*m) for m in models]
        self.sojourn_s = tuple(sojourn_s)
        self.mu_init = tuple(mu_init) if mu_init is not None else tuple([1.0 / n] * n)
        self.mu_floor = mu_floor
        self.mu = list(self.mu_init)
        self.t = 0.0
        self.x = [0.0] * 4
        self.P = [[0.0] * 4 for _ in range(4)]
        self.omega = 0.0
        self.omega_var = 0.0
        self.initialised = False

    @property
    def q(self) -> float:
        """The quiet model's acceleration density (m²/s³)."""
        return self.models[0].q

    @property
    def quiet_turn_rate(self) -> tuple[float, float]:
        """The quiet model's turn rate (rad/s) and its variance: a steady arc."""
        m = self.models[0]
        return m.x[4], m.P[4][4]

    def reset_quiet_turn_rate(self, var: float) -> None:
        """Set the quiet model's turn rate back to 0 with variance ``var``
        (rad²/s²): a sharp turn is over, the AUV flies straight until its
        measurements say it arcs."""
        self.models[0].set_turn_rate(0.0, var)
        self._combine()

    def reset_turn_rates(self) -> None:
        """Every turning model but the quiet one back to the turn rate it
        expects (``omega0``, variance ``omega0_var``): what they learnt of a
        turn that is over."""
        for m in self.models[1:]:
            if m.kind == "ct":
                m.set_turn_rate(m.omega0, m.omega0_var)
        self._combine()

    @property
    def maneuver_probability(self) -> float:
        """Probability that the AUV is not flying straight (1 − μ of model 0)."""
        return 1.0 - self.mu[0]

    def init(self, t: float, x: float, y: float, vx: float = 0.0, vy: float = 0.0,
             pos_var: float = 25.0, vel_var: float = 1.0) -> None:
        """Start every model at time ``t`` from the same state (ω = 0)."""
        for mdl in self.models:
            mdl.x = [x, y, vx, vy, mdl.omega0]
            P = _zeros()
            P[0][0] = P[1][1] = pos_var
            P[2][2] = P[3][3] = vel_var
            P[4][4] = mdl.omega0_var
            mdl.P = P
        self.mu = list(self.mu_init)
        self.t = t
        self.initialised = True
        self._combine()

    def reset(self) -> None:
        self.initialised = False

    def _mixture(self, w: list[float], omega0: float = 0.0, omega0_var: float = CV_OMEGA_VAR
                 ) -> tuple[list[float], list[list[float]]]:
        """Moment-matched mean and covariance of the models weighted by ``w``, the
        straight models' turn rate taken as ``omega0`` (rad/s) with variance
        ``omega0_var``."""
        ms = self.models
        xs = [mdl.x if mdl.kind == "ct" else [*mdl.x[:4], omega0] for mdl in ms]
        x = [sum(w[i] * xs[i][k] for i in range(len(ms))) for k in range(N)]
        P = _zeros()
        for i, mdl in enumerate(ms):
            wi = w[i]
            if wi == 0.0:
                continue
            d = [xs[i][k] - x[k] for k in range(N)]
            Pi = mdl.P
            if mdl.kind == "cv" and Pi[4][4] != omega0_var:
                Pi = [*Pi[:4], [*Pi[4][:4], omega0_var]]
            for a in range(N):
                row, pa, da = P[a], Pi[a], d[a]
                for b in range(N):
                    row[b] += wi * (pa[b] + da * d[b])
        return x, P

    def _combine(self) -> None:
        x, P = self._mixture(self.mu)
        self.x = x[:4]
        self.P = [row[:4] for row in P[:4]]
        self.omega = x[4]
        self.omega_var = P[4][4]

    def predict(self, t: float) -> None:
        """Mix the models for the time elapsed, then propagate each to ``t``."""
        dt = t - self.t
        if dt <= 0.0:
            return
        ms = self.models
        n = len(ms)
        mu = self.mu
        p = []
        for i in range(n):
            stay = math.exp(-dt / self.sojourn_s[i])
            if i == 0 or n == 2:
                leave = (1.0 - stay) / (n - 1)
                p.append([stay if j == i else leave for j in range(n)])
                continue
            # a manoeuvre ends mostly back on a straight line
            back = (1.0 - stay) * RETURN_SHARE
            other = (1.0 - stay) * (1.0 - RETURN_SHARE) / (n - 2)
            p.append([stay if j == i else back if j == 0 else other for j in range(n)])
        cbar = [sum(p[i][j] * mu[i] for i in range(n)) for j in range(n)]
        mixed = [self._mixture([p[i][j] * mu[i] / cbar[j] if cbar[j] > 0.0 else 0.0
                                for i in range(n)], ms[j].omega0, ms[j].omega0_var)
                 for j in range(n)]
        for mdl, (x0, P0) in zip(ms, mixed, strict=True):
            mdl.x = x0
            mdl.P = P0
            mdl.predict(dt)
        self.mu = cbar
        self.t = t
        self._combine()

    def predicted(self, t: float) -> tuple[float, float, float, float, float]:
        """(x, y, Pxx, Pxy, Pyy) of the combined estimate predicted at ``t``
        (each model propagated without mixing, weighted by the current
        probabilities; the filter is not changed)."""
        dt = max(t - self.t, 0.0)
        preds = [mdl.predicted_position(dt) for mdl in self.models]
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
        """Measurement update (module docstring): refused when the combined
        estimate's d² exceeds ``gate_chi2`` and no coordinated-turn model with
        a probability of ``GATE_TURN_MU`` or more has its own d² within it.
        Returns (accepted, the combined estimate's d²)."""
        ms = self.models
        dl = [mdl.innovation(rows, z, var) for mdl in ms]
        x, P = self.x, self.P
        comb = _Model("cv", 0.0)
        comb.x = [*x, 0.0]
        comb.P = [[*row, 0.0] for row in P] + [[0.0] * N]
        d2c, _ = comb.innovation(rows, z, var)
        if not d2c <= gate_chi2 and not any(
                mdl.kind == "ct" and mu >= GATE_TURN_MU and dj <= gate_chi2
                for mdl, mu, (dj, _ldet) in zip(ms, self.mu, dl, strict=True)):
            return False, d2c
        logl = []
        for mdl, (dj, ldet) in zip(ms, dl, strict=True):
            if not math.isfinite(dj):
                logl.append(-math.inf)
                continue
            if dj > soft_chi2:
                mdl.update(rows, z, [v * dj / soft_chi2 for v in var])
            else:
                mdl.update(rows, z, var)
            # the model's Gaussian or an outlier, whatever the model: an innovation
            # far out in every model is no more evidence for one than for another
            # (one outlier is not a turn), while one a model explains well (a turn
            # the turning model follows) is
            floor = OUTLIER_DENSITY[len(rows) - 1]
            logl.append(math.log(math.exp(-0.5 * dj - 0.5 * ldet) + floor))
        top = max(logl)
        if math.isfinite(top):
            w = [m * math.exp(ll - top) for m, ll in zip(self.mu, logl, strict=True)]
            total = sum(w)
            mu = [max(v / total, self.mu_floor) for v in w]
            total = sum(mu)
            self.mu = [v / total for v in mu]
        self._combine()
        return True, d2c
