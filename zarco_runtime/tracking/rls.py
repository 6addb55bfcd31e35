"""Recursive least squares with forgetting on the AUV's straight-line model (paper V).

Model, NED metres and m/s, t in seconds on any clock::

    x(t) = x0 + vx (t − t0)        y(t) = y0 + vy (t − t0)

Both axes share the regressor φ = [1, t − t0], hence one 2×2 matrix P for both
(paper V); the parameter covariance of each axis is σ² P.

* **Re-centred time origin.**  At every update the origin t0 moves to the
  measurement time: the parameters shift exactly (x0 ← x0 + vx Δ, P ← A P Aᵀ
  with A = [[1, Δ], [0, 1]]) and the regressor becomes [1, 0].  With raw epoch
  time (t ≈ 1.78e9 s) the normal matrix would hold 1 and t² ≈ 3e18 together
  and be numerically singular; re-centred, P stays as well conditioned as the
  data allow.
* **Time-based forgetting.**  Fixes are irregular (misses, dropped cycles), so
  the forgetting factor is per second: P ← P / λ^Δt, i.e. information decays
  as λ^age whatever the fix rate.
* **Turn detection.**  Each residual e (measurement − line prediction) is
  normalised by its predicted variance σ² (1 + p00); a one-sided CUSUM
  g ← max(0, g + |e|²/(2σ²(1 + p00)) − drift) declares a turn when it exceeds
  its threshold (outside a hold-off after the last one).  The caller then
  re-seeds the line with :meth:`LineRls.reset` (the tracker uses the Kalman
  filter's state and covariance), which is the covariance reset of the paper (section V).

Plain Python floats: a 2×2 problem is cheapest without numpy.
"""

from __future__ import annotations

import math


class LineRls:
    """RLS estimate of (x0, y0, vx, vy) with forgetting, re-centred origin, CUSUM."""

    __slots__ = ("cusum", "cusum_drift", "cusum_threshold", "holdoff_s", "initialised",
                 "lam", "last_reset_t", "last_z2", "p00", "p01", "p11", "sigma2", "t0",
                 "updates", "vx", "vy", "x0", "y0")

    def __init__(self, forgetting_per_s: float = 0.97, cusum_drift: float = 2.0,
                 cusum_threshold: float = 8.0, holdoff_s: float = 4.0) -> None:
        if not 0.0 < forgetting_per_s <= 1.0:
            raise ValueError(f"forgetting factor must be in (0, 1], got {forgetting_per_s}")
        self.lam = forgetting_per_s
        self.cusum_drift = cusum_drift
        self.cusum_threshold = cusum_threshold
        self.holdoff_s = holdoff_s
        self.initialised = False
        self.t0 = 0.0
        self.x0 = self.y0 = self.vx = self.vy = 0.0
        self.p00 = self.p11 = 1.0
        self.p01 = 0.0
        self.sigma2 = 1.0
        self.cusum = 0.0
        self.last_z2 = 0.0
        self.last_reset_t = -math.inf
        self.updates = 0

    def reset(self, t: float, x: float, y: float, vx: float, vy: float, var_pos: float,
              var_vel: float, cov_pv: float = 0.0, sigma_m: float = 1.0) -> None:
        """(Re)start at time ``t`` from a state and its covariance (per axis:
        position variance, velocity variance, their covariance; m², m²/s², m²/s),
        expressed in units of σ² = ``sigma_m``² of one measurement."""
        s2 = max(sigma_m * sigma_m, 1e-12)
        self.t0 = t
        self.x0, self.y0, self.vx, self.vy = x, y, vx, vy
        p00 = max(var_pos, 1e-12) / s2
        p11 = max(var_vel, 1e-12) / s2
        p01 = cov_pv / s2
        lim = 0.999 * math.sqrt(p00 * p11)
        self.p00, self.p01, self.p11 = p00, max(-lim, min(lim, p01)), p11
        self.sigma2 = s2
        self.cusum = 0.0
        self.last_reset_t = t
        self.updates = 0
        self.initialised = True

    def shift(self, t: float) -> None:
        """Move the time origin to ``t`` (exact re-parameterisation, with the
        forgetting λ^Δt for Δt = t − t0 > 0)."""
        d = t - self.t0
        if d == 0.0:
            return
        self.x0 += self.vx * d
        self.y0 += self.vy * d
        p01 = self.p01 + d * self.p11
        p00 = self.p00 + 2.0 * d * self.p01 + d * d * self.p11
        if d > 0.0 and self.lam < 1.0:
            f = self.lam ** d
            p00 /= f
            p01 /= f
            self.p11 /= f
        self.p00, self.p01 = p00, p01
        self.t0 = t

    def update(self, t: float, x: float, y: float, sigma_m: float) -> bool:
        """Fit one position (x, y) at ``t`` with 1σ ``sigma_m`` (used to normalise
        the residual).  Returns True when the CUSUM declares a turn (the caller
        re-seeds with :meth:`reset`); the measurement is applied either way.
        An uninitialised estimator starts at (x, y) with zero velocity."""
        if not self.initialised:
            self.reset(t, x, y, 0.0, 0.0, sigma_m * sigma_m, 1.0, 0.0, sigma_m)
            return False
        self.shift(t)
        self.sigma2 = s2 = max(sigma_m * sigma_m, 1e-12)
        ex = x - self.x0
        ey = y - self.y0
        p00, p01, p11 = self.p00, self.p01, self.p11
        s = 1.0 + p00
        z2 = (ex * ex + ey * ey) / (2.0 * s2 * s)
        self.last_z2 = z2
        k0 = p00 / s
        k1 = p01 / s
        self.x0 += k0 * ex
        self.y0 += k0 * ey
        self.vx += k1 * ex
        self.vy += k1 * ey
        self.p00 = p00 - p00 * k0
        self.p01 = p01 - p01 * k0
        self.p11 = p11 - p01 * k1
        self.updates += 1
        g = max(0.0, self.cusum + z2 - self.cusum_drift)
        if g > self.cusum_threshold and t - self.last_reset_t >= self.holdoff_s:
            self.cusum = 0.0
            return True
        self.cusum = g
        return False

    def position(self, t: float) -> tuple[float, float]:
        """Position on the current line at ``t`` (same clock as the updates)."""
        d = t - self.t0
        return self.x0 + self.vx * d, self.y0 + self.vy * d

    def covariance_at(self, t: float) -> tuple[float, ...]:
        """:meth:`covariance` with the time origin moved to ``t`` (the line's
        position then at ``t``; no forgetting applied)."""
        d = t - self.t0
        s2 = self.sigma2
        a = s2 * (self.p00 + 2.0 * d * self.p01 + d * d * self.p11)
        b = s2 * (self.p01 + d * self.p11)
        c = s2 * self.p11
        return (a, 0.0, b, 0.0,
                0.0, a, 0.0, b,
                b, 0.0, c, 0.0,
                0.0, b, 0.0, c)

    def covariance(self) -> tuple[float, ...]:
        """4×4 covariance of (x0, y0, vx, vy), row-major (σ² P on each axis,
        no cross-axis terms)."""
        s2 = self.sigma2
        a, b, d = s2 * self.p00, s2 * self.p01, s2 * self.p11
        return (a, 0.0, b, 0.0,
                0.0, a, 0.0, b,
                b, 0.0, d, 0.0,
                0.0, b, 0.0, d)
