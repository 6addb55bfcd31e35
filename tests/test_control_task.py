"""The control task's safety: NaN never reaches a thruster; invalid nav → zero thrust."""

from __future__ import annotations

import math

from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.messages import Fault, FixQuality, NavState
from zarco_runtime.control.task import ControlTask
from zarco_runtime.guidance.mission import Leg
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


def _nav_age(t: float, gps_age_s: float) -> NavState:
    return NavState(t, 20.0, 0.3, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 41.0, -8.0,
                    FixQuality.RTK_FIXED, True, True, (), gps_age_s)


def _task_policy(policy: str, continue_s: float = 10.0) -> tuple[ControlTask, Bus, list[Fault]]:
    cfg = RuntimeConfig()
    cfg.failsafe.gps_lost = policy
    cfg.failsafe.gps_lost_continue_s = continue_s
    bus = Bus()
    faults: list[Fault] = []
    bus.tap(lambda m: faults.append(m) if isinstance(m, Fault) else None)
    return ControlTask(cfg, bus, Clock(utc_offset_s=0.0), LEGS), bus, faults


def test_gps_lost_with_policy_zero_holds_thrust_at_zero_until_a_fix() -> None:
    task, bus, faults = _task_policy("zero")
    bus.publish(_nav_age(0.0, 0.1))
    assert task.tick(0.0).u1 != 0.0
    # the estimate is still valid (dead reckoning) but the GPS is 0.6 s old
    bus.publish(_nav_age(0.1, 0.6))
    a = task.tick(0.1)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert "GPS lost" in faults[-1].reason
    bus.publish(_nav_age(0.2, 0.05))
    assert task.tick(0.2).u1 != 0.0
    assert task.fault == ""


def test_gps_lost_with_policy_continue_goes_on_for_n_seconds() -> None:
    task, bus, faults = _task_policy("continue", continue_s=5.0)
    bus.publish(_nav_age(0.0, 4.9))
    assert task.tick(0.0).u1 != 0.0
    assert not faults
    # the age is extrapolated with the state: a NavState 0.2 s old at 4.9 s is 5.1 s
    a = task.tick(0.2)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert "more than 5 s" in faults[-1].reason


def test_no_fix_yet_is_not_a_gps_loss() -> None:
    """Before the first fix (gps_age inf) the estimate is invalid: the nav_invalid_s
    grace applies, not the GPS-loss policy."""
    task, bus, faults = _task_policy("zero")
    bus.publish(NavState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, math.nan, math.nan,
                         FixQuality.NONE, False, True, (), math.inf))
    task.tick(0.0)
    assert not faults
