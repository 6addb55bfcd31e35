"""Angle helpers shared by navigation and control."""

from __future__ import annotations

import math


def wrap(a: float) -> float:
    """Angle ``a`` (rad) wrapped to [−π, π]."""
    return math.remainder(a, math.tau)
