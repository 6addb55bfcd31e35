"""The control task's safety: NaN never reaches a thruster; invalid nav → zero thrust."""

from __future__ import annotations

import math

from zarco_runtime.bus import Bus
from zarco_runtime.clock import Clock
from zarco_runtime.control.task import ControlTask
from zarco_runtime.guidance.mission import Leg
from zarco_runtime.messages import Fault, FixQuality, NavState
from zarco_runtime.settings import RuntimeConfig

LEGS = [Leg(0, 0.0, 0.0, 100.0, 0.0, 1.0)]


def _nav(t: float, psi: float = 0.0, valid: bool = True, x: float = 20.0) -> NavState:
    return NavState(t, x, 0.3, 1.0, 0.0, psi, 0.0, 1.0, 0.0, 41.0, -8.0,
                    FixQuality.RTK_FIXED, valid, True)


def _task() -> tuple[ControlTask, Bus, list[Fault]]:
    bus = Bus()
    faults: list[Fault] = []
    bus.tap(lambda m: faults.append(m) if isinstance(m, Fault) else None)
    return ControlTask(RuntimeConfig(), bus, Clock(utc_offset_s=0.0), LEGS), bus, faults


def test_nan_heading_gives_zero_thrust_and_a_fault() -> None:
    task, bus, faults = _task()
    bus.publish(_nav(0.0))
    ok = task.tick(0.0)
    assert ok.u1 != 0.0 or ok.u2 != 0.0
    bus.publish(_nav(0.05, psi=math.nan))
    a = task.tick(0.05)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert faults and "non-finite" in faults[-1].reason
    # and it recovers when the input is sane again
    bus.publish(_nav(0.10))
    a = task.tick(0.10)
    assert a.u1 != 0.0 and math.isfinite(a.u1)
    assert task.fault == ""


def test_invalid_position_for_too_long_commands_zero() -> None:
    task, bus, faults = _task()
    bus.publish(_nav(0.0, valid=False))
    a = task.tick(0.0)
    assert a.u1 != 0.0  # still within the grace period
    bus.publish(_nav(1.5, valid=False))
    a = task.tick(1.5)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert "no valid position" in faults[-1].reason
    bus.publish(_nav(1.6, valid=True))
    assert task.tick(1.6).u1 != 0.0


def test_mission_completion_sets_event_and_stops_thrust() -> None:
    task, bus, _ = _task()
    bus.publish(_nav(0.0, x=100.5))
    a = task.tick(0.0)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert task.complete.is_set()
