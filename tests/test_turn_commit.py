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


def test_the_turn_committed_to_is_the_shorter_way_to_the_leg_course() -> None:
    """From a standstill the reference is the leg's course plus an intercept
    of tens of degrees on the boat's drift; with the course at 156° to
    starboard and an intercept of 26° the reference is 178° to port. The
    boat turns the shorter way to the course (starboard), not round the long
    way to the reference."""
    psi = math.radians(-74.0)
    course = math.radians(82.0)
    ref = math.radians(108.0)
    ctl = LineController(VesselModel(), Control(), 0.15, 0.05)
    e = ctl.heading_error(ref, psi, course)
    assert e > 0.0 and math.isclose(e, math.radians(182.0), abs_tol=1e-9)
    # and it keeps that way as it swings on
    e2 = ctl.heading_error(ref, math.radians(-20.0), course)
    assert math.isclose(e2, math.radians(128.0), abs_tol=1e-9)
    # without the course, the wrapped error's sign (the long way here)
    plain = LineController(VesselModel(), Control(), 0.15, 0.05)
    assert plain.heading_error(ref, psi) < 0.0
