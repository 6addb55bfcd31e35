"""Thruster maps f (command → thrust) and their inverse f⁻¹ (paper section III.A).

A map is a calibrated, monotone, piecewise-linear table of bollard-pull
points (command U in -100..100, thrust F in newtons) with a deadband where
F = 0.  f⁻¹(F) returns the smallest-magnitude command that gives F: zero for
F = 0, just outside the deadband for small thrusts, and clamps to the table's
ends (the caller learns of saturation from :meth:`ThrusterMap.saturates`).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class ThrusterMap:
    """Piecewise-linear f and f⁻¹ over a monotone table."""

    u: tuple[float, ...]
    f: tuple[float, ...]

    @classmethod
    def from_table(cls, u: list[float], f_n: list[float]) -> ThrusterMap:
        if len(u) != len(f_n) or len(u) < 2:
            raise ValueError("thruster table: u and f_n must have the same length ≥ 2")
        for i in range(1, len(u)):
            if not (u[i] > u[i - 1] and f_n[i] >= f_n[i - 1]):
                raise ValueError(f"thruster table: not monotone at index {i}")
        return cls(tuple(float(x) for x in u), tuple(float(x) for x in f_n))

    @property
    def f_min(self) -> float:
        """Largest reverse thrust (N, negative)."""
        return self.f[0]

    @property
    def f_max(self) -> float:
        """Largest forward thrust (N)."""
        return self.f[-1]

    def forward(self, u: float) -> float:
        """f(U): thrust (N) for a command U, 0 inside the deadband."""
        us, fs = self.u, self.f
        if u <= us[0]:
            return fs[0]
        if u >= us[-1]:
            return fs[-1]
        i = bisect.bisect_right(us, u)
        u0, u1 = us[i - 1], us[i]
        return fs[i - 1] + (fs[i] - fs[i - 1]) * (u - u0) / (u1 - u0)

    def deadband(self) -> tuple[float, float]:
        """Command interval [lo, hi] (containing 0) over which F = 0."""
        us, fs = self.u, self.f
        zeros = [us[i] for i in range(len(us)) if fs[i] == 0.0]
        if not zeros:
            return (0.0, 0.0)
        return (min(min(zeros), 0.0), max(max(zeros), 0.0))

    def inverse(self, force: float) -> float:
        """f⁻¹(F): command for thrust F (N), clamped to the table; NaN → 0."""
        if not math.isfinite(force):
            return 0.0
        us, fs = self.u, self.f
        if force == 0.0:
            return 0.0
        if force >= fs[-1]:
            return us[-1]
        if force <= fs[0]:
            return us[0]
        if force > 0.0:
            # first point with F >= force, searching from the upper deadband edge
            i = bisect.bisect_left(fs, force)
            j = i - 1
        else:
            i = bisect.bisect_right(fs, force)
            j = i - 1
            if fs[i] == force:
                return us[i]
        f0, f1 = fs[j], fs[i]
        if f1 == f0:
            return us[i]
        return us[j] + (us[i] - us[j]) * (force - f0) / (f1 - f0)

    def saturates(self, force: float) -> bool:
        """True when the thrust asked for is beyond what the table can give."""
        return force > self.f[-1] or force < self.f[0]
