"""The reference thruster map f (command → thrust) of the Zarco's thrusters.

``f(U) = 0`` for ``|U| ≤ deadband``; otherwise, with
``s = (|U| − deadband)/(100 − deadband)`` and ``g = 0.3 s + 0.7 s²``,
``F = fwd_max_n · g`` for U > 0 and ``F = −rev_max_n · g`` for U < 0.
The curve is convex (thrust grows roughly with the square of propeller
speed) and weaker in reverse.  Commands are in the normalised −100..100
scale and are clamped to it; thrust in newtons, along the thruster axis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from drivers.sim.params import ThrusterParams

#: full-scale command (normalised units, as on the wire in $PZTHR)
U_MAX = 100.0
#: linear and quadratic weights of the normalised thrust curve g(s)
G_LIN = 0.3
G_QUAD = 0.7

#: command points of the default calibration table (same grid as the runtime's
#: default in ``zarco_runtime.settings``); ±deadband, 0 and ±100 are always added
DEFAULT_POINTS: tuple[float, ...] = (
    -100.0, -90.0, -80.0, -70.0, -60.0, -50.0, -40.0, -30.0, -20.0, -15.0, -10.0,
    10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0,
)


def nominal_thrust(u: float, p: ThrusterParams) -> float:
    """f(U): nominal thrust (N) of one thruster for command ``u`` (−100..100, clamped).

    Non-finite commands give zero thrust.
    """
    a = abs(u)
    if not a > p.deadband:  # also catches NaN
        return 0.0
    if a > U_MAX:
        if math.isinf(a):
            return 0.0
        a = U_MAX
    s = (a - p.deadband) / (U_MAX - p.deadband)
    g = G_LIN * s + G_QUAD * s * s
    return p.fwd_max_n * g if u > 0.0 else -p.rev_max_n * g


def thruster_thrust(u: float, p: ThrusterParams, index: int) -> float:
    """f_i(U): thrust (N) of thruster ``index`` (1 port, 2 starboard) with the
    mismatch Δf = mismatch · f: f1 = (1 + mismatch) f, f2 = (1 − mismatch) f."""
    scale = 1.0 + p.mismatch if index == 1 else 1.0 - p.mismatch
    return scale * nominal_thrust(u, p)


def nominal_table(p: ThrusterParams, points: Sequence[float] | None = None,
                  decimals: int | None = 3) -> tuple[list[float], list[float]]:
    """A bollard-pull calibration table (U, F) sampled from f.

    ``points`` are command values (default :data:`DEFAULT_POINTS`); the
    deadband edges ±deadband and U = 0 (all with F = 0) and the ends ±100 are
    always included, points outside −100..100 are dropped, duplicates merged.
    U is strictly increasing and F non-decreasing, as the runtime's f⁻¹
    (``zarco_core.thruster_map``) requires.  ``decimals`` rounds F
    (rounding is monotone, so the table stays monotone); None keeps full
    precision.
    """
    pts = set(DEFAULT_POINTS if points is None else points)
    pts.update((-U_MAX, -p.deadband, 0.0, p.deadband, U_MAX))
    us = sorted(float(u) for u in pts if math.isfinite(u) and -U_MAX <= u <= U_MAX)
    fs = [nominal_thrust(u, p) for u in us]
    if decimals is not None:
        fs = [round(f, decimals) + 0.0 for f in fs]  # + 0.0 turns −0.0 into 0.0
    return us, fs
