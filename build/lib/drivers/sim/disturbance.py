"""First-order Gauss–Markov processes and a fast scalar normal stream.

A Gauss–Markov (Ornstein–Uhlenbeck) process with stationary standard
deviation σ and correlation time τ obeys ``dx = −x/τ dt + σ √(2/τ) dW``.
Its exact discretisation over a step Δt is

    x_{k+1} = a x_k + σ √(1 − a²) w_k,   a = exp(−Δt/τ),   w_k ~ N(0, 1),

which keeps the variance at σ² for any Δt (no discretisation error, and
irregular steps are fine).  Processes start from the stationary distribution
x_0 ~ N(0, σ²), so there is no warm-up transient.

Normal variates come from a numpy ``Generator`` drawn in blocks and handed
out one at a time as Python floats: one ``standard_normal(4096)`` call costs
about as much as a handful of scalar calls.  A stream consumes its generator
only through blocks, so the sequence of values it hands out depends only on
the generator's seed, never on how the calls interleave with other streams.
"""

from __future__ import annotations

import math

import numpy as np

#: normals drawn per block
BLOCK = 4096


class NormalStream:
    """Standard normal variates N(0, 1) from ``rng``, drawn ``block`` at a time."""

    __slots__ = ("_block", "_buf", "_i", "_rng")

    def __init__(self, rng: np.random.Generator, block: int = BLOCK) -> None:
        self._rng = rng
        self._block = block
        self._buf: list[float] = []
        self._i = 0

    def next(self) -> float:
        """The next N(0, 1) variate."""
        i = self._i
        buf = self._buf
        if i >= len(buf):
            buf = self._buf = self._rng.standard_normal(self._block).tolist()
            i = 0
        self._i = i + 1
        return buf[i]


class GaussMarkov:
    """Scalar first-order Gauss–Markov process (stationary 1σ ``sigma``, time
    constant ``tau_s`` seconds), in whatever unit ``sigma`` has.

    ``value`` holds the current value; :meth:`step` advances it by ``dt``
    seconds with the exact discretisation and returns the new value.
    """

    __slots__ = ("_a", "_dt", "_q", "normals", "sigma", "tau_s", "value")

    def __init__(self, sigma: float, tau_s: float, normals: NormalStream) -> None:
        if tau_s <= 0.0:
            raise ValueError(f"tau_s must be > 0, got {tau_s}")
        if sigma < 0.0:
            raise ValueError(f"sigma must be ≥ 0, got {sigma}")
        self.sigma = sigma
        self.tau_s = tau_s
        self.normals = normals
        self.value = sigma * normals.next()  # stationary start
        self._dt = -1.0
        self._a = 1.0
        self._q = 0.0

    def _coeffs(self, dt: float) -> None:
        a = math.exp(-dt / self.tau_s)
        self._dt = dt
        self._a = a
        self._q = self.sigma * math.sqrt(max(0.0, 1.0 - a * a))

    def step(self, dt: float) -> float:
        """Advance by ``dt`` ≥ 0 seconds; returns the new value."""
        if dt != self._dt:
            self._coeffs(dt)
        self.value = self._a * self.value + self._q * self.normals.next()
        return self.value
