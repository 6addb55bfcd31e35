"""A heading error near 180° must turn the boat, not leave it chattering on the
wrong heading (the wrapped error flips sign at every tick there)."""

from __future__ import annotations

import math

from zarco_core.vessel import VesselModel
from zarco_runtime.control.line_tracking import LineController
from zarco_runtime.control.settings import Control


def test_the_turn_keeps_its_direction_past_180_degrees() -> None:
    ctl = LineController(VesselModel(), Control(), 0.15, 0.05)
    ref = 0.0
    # the boat points 179° right of the reference: turn left (negative error) ...
    e1 = ctl.heading_error(ref, math.radians(179.0))
    assert e1 < 0.0
    # ... and as it swings through 180° the error must not flip to a right turn
    e2 = ctl.heading_error(ref, math.radians(-179.0))
    assert e2 < 0.0 and math.isclose(e2, math.radians(-181.0), abs_tol=1e-9)
    # once under the commitment angle the plain wrapped error is back
    e3 = ctl.heading_error(ref, math.radians(-100.0))
    assert math.isclose(e3, math.radians(100.0), abs_tol=1e-9)


def test_small_errors_are_the_wrapped_difference() -> None:
    ctl = LineController(VesselModel(), Control(), 0.15, 0.05)
    for deg in (-120.0, -10.0, 0.0, 10.0, 120.0):
        assert math.isclose(ctl.heading_error(math.radians(deg), 0.0), math.radians(deg))
