"""The control task executes the supervisor's directive and nothing else: NaN
never reaches a thruster, an invalid estimate, a stale or disarmed directive
gives zero thrust, so do a lost position, a lost heading and a silent thruster
controller whatever the mode (the drive interlock), manual thrust lasts only
for its lease."""

from __future__ import annotations

import asyncio
import contextlib
import math

from zarco_core.bus import Bus
from zarco_core.clock import Clock, run_virtual
from zarco_core.messages import (
    Fault,
    FixQuality,
    GuidanceStatus,
    Heading,
    Mode,
    NavState,
    ThrusterStatus,
)
from zarco_runtime.control.task import ControlTask
from zarco_runtime.guidance.directive import Directive, ManualThrust
from zarco_runtime.guidance.mission import Leg, Mission
from zarco_runtime.settings import RuntimeConfig

LEGS = (Leg(0, 0.0, 0.0, 100.0, 0.0, 1.0),)
LINES = Mission("lines", LEGS, "test")


def _nav(t: float, psi: float = 0.0, valid: bool = True, x: float = 20.0) -> NavState:
    return NavState(t, x, 0.3, 1.0, 0.0, psi, 0.0, 1.0, 0.0, 41.0, -8.0,
                    FixQuality.RTK_FIXED, valid, True)


class Rig:
    def __init__(self) -> None:
        self.bus = Bus()
        self.faults: list[Fault] = []
        self.status: list[GuidanceStatus] = []
        self.bus.listen(Fault, self.faults.append)
        self.bus.listen(GuidanceStatus, self.status.append)
        self.task = ControlTask(RuntimeConfig(), self.bus, Clock(utc_offset_s=0.0))

    def directive(self, t: float, mode: Mode, seq: int = 1, armed: bool = True,
                  **kw: object) -> None:
        self.bus.publish(Directive(t, seq, mode, armed=armed, **kw))  # type: ignore[arg-type]

    def sensors(self, t: float, heading: bool = True, status: bool = True,
                **nav: object) -> None:
        """A compass heading, a thruster controller status and the estimate at ``t``."""
        if heading:
            self.bus.publish(Heading(t, "compass", "HDT", 0.0, True, 0.0))
        if status:
            self.bus.publish(ThrusterStatus(t, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        self.bus.publish(_nav(t, **nav))  # type: ignore[arg-type]


def test_without_a_directive_the_boat_stays_idle() -> None:
    r = Rig()
    r.sensors(0.0)
    a = r.task.tick(0.0)
    assert (a.u1, a.u2) == (0.0, 0.0)


def test_nan_heading_gives_zero_thrust_and_a_fault() -> None:
    r = Rig()
    r.directive(0.0, Mode.LINES, mission=LINES)
    r.sensors(0.0)
    ok = r.task.tick(0.0)
    assert ok.u1 != 0.0 or ok.u2 != 0.0
    r.sensors(0.05, psi=math.nan)
    a = r.task.tick(0.05)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert r.faults and "non-finite" in r.faults[-1].reason
    # and it recovers when the input is sane again
    r.sensors(0.10)
    a = r.task.tick(0.10)
    assert a.u1 != 0.0 and math.isfinite(a.u1)
    assert r.task.fault == ""


def test_an_invalid_estimate_gives_zero_thrust_at_once_until_healthy_for_clear_after_s(
        ) -> None:
    """Zero at the first tick the estimate is invalid, and, once it is valid again,
    until it has been healthy for failsafe.clear_after_s (the condition latches)."""
    for wait in (0.5, 2.0, 3.7):
        r = Rig()
        r.task.cfg.failsafe.clear_after_s = wait
        r.directive(0.0, Mode.LINES, mission=LINES)
        r.sensors(0.0, valid=False)
        a = r.task.tick(0.0)
        assert (a.u1, a.u2) == (0.0, 0.0)
        assert r.task.reason == "not driving: position estimate invalid"
        ticks = [round(0.05 * k, 2) for k in range(1, int((wait + 0.5) / 0.05))]
        for t in ticks:
            r.directive(t, Mode.LINES, mission=LINES)
            r.sensors(t, valid=True)
            a = r.task.tick(t)
            if t < wait:
                assert (a.u1, a.u2) == (0.0, 0.0), (wait, t)
                assert "position estimate invalid; healthy for" in r.task.reason
            else:
                assert a.u1 != 0.0, (wait, t, r.task.reason)


def test_a_stale_directive_counts_as_idle() -> None:
    """A supervisor that stopped republishing cannot leave the boat driving."""
    r = Rig()
    timeout = r.task.cfg.supervisor.directive_timeout_s
    r.directive(0.0, Mode.LINES, mission=LINES)
    r.sensors(timeout * 0.9)
    assert r.task.tick(timeout * 0.9).u1 != 0.0
    r.sensors(timeout * 1.1)
    a = r.task.tick(timeout * 1.1)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert "no directive" in r.faults[-1].reason


def test_mission_completion_reports_complete_and_stops_thrust() -> None:
    r = Rig()
    r.directive(0.0, Mode.LINES, mission=LINES)
    r.sensors(0.0, x=100.5)
    a = r.task.tick(0.0)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert r.status[-1].complete and r.status[-1].mode == "lines"


def test_manual_thrust_holds_only_for_its_lease() -> None:
    r = Rig()
    r.directive(0.0, Mode.MANUAL)
    r.sensors(0.0)
    assert (r.task.tick(0.0).u1, r.task.tick(0.0).u2) == (0.0, 0.0)  # nothing sent yet
    r.bus.publish(ManualThrust(0.1, 40.0, -250.0, until=1.1))
    r.sensors(0.5)
    a = r.task.tick(0.5)
    assert (a.u1, a.u2) == (40.0, -100.0)  # clamped to the scale
    r.directive(0.9, Mode.MANUAL)  # the supervisor republishes it
    r.sensors(1.2)
    a = r.task.tick(1.2)
    assert (a.u1, a.u2) == (0.0, 0.0)
    r.bus.publish(ManualThrust(1.3, math.nan, 10.0, until=2.3))
    r.sensors(1.4)
    a = r.task.tick(1.4)
    assert (a.u1, a.u2) == (0.0, 10.0)


def test_manual_thrust_from_before_the_mode_was_entered_is_ignored() -> None:
    r = Rig()
    r.sensors(0.5)
    r.bus.publish(ManualThrust(0.0, 50.0, 50.0, until=5.0))
    r.directive(0.5, Mode.MANUAL)
    a = r.task.tick(0.6)
    assert (a.u1, a.u2) == (0.0, 0.0)


def test_manual_thrust_lasts_across_the_directive_being_republished() -> None:
    """The supervisor republishes the same directive every 0.2 s: a command within
    its lease still holds (only one from before the mode began is ignored)."""
    r = Rig()
    r.directive(0.0, Mode.MANUAL)
    r.sensors(0.0)
    r.task.tick(0.05)
    r.bus.publish(ManualThrust(0.1, 30.0, 20.0, until=1.1))
    r.directive(0.2, Mode.MANUAL)  # republished, same seq
    r.sensors(0.25)
    a = r.task.tick(0.25)
    assert (a.u1, a.u2) == (30.0, 20.0)


def test_idle_directive_stops_a_running_mission_at_the_next_tick() -> None:
    r = Rig()
    r.directive(0.0, Mode.LINES, mission=LINES)
    r.sensors(0.0)
    assert r.task.tick(0.0).u1 != 0.0
    r.directive(0.02, Mode.IDLE, seq=2)
    a = r.task.tick(0.05)
    assert (a.u1, a.u2) == (0.0, 0.0)


def test_the_run_loop_publishes_zero_when_a_tick_raises() -> None:
    """A guidance bug raises out of the loop (the component is restarted), but the
    last command it publishes is zero thrust."""
    from zarco_core.messages import ThrusterCommand

    async def main() -> list[ThrusterCommand]:
        r = Rig()
        cmds: list[ThrusterCommand] = []
        r.bus.listen(ThrusterCommand, cmds.append)
        r.task.clock = Clock(utc_offset_s=0.0)
        r.directive(0.0, Mode.LINES, mission=LINES)
        r.sensors(0.0)

        def boom(t: float, nav: NavState) -> object:
            raise ZeroDivisionError("guidance bug")

        r.task._tick_lines = boom  # type: ignore[method-assign,assignment]
        with contextlib.suppress(ZeroDivisionError):
            await r.task.run()
        return cmds

    cmds = run_virtual(main())
    assert cmds and (cmds[-1].u1, cmds[-1].u2) == (0.0, 0.0)
    assert "guidance bug" in cmds[-1].reason


def test_a_held_command_on_the_bus_says_why_it_is_zero() -> None:
    """What the thrusters are sent (and what is recorded) carries the reason the
    controller holds: disarmed, then a driving failsafe; nothing while it drives."""
    from zarco_core.messages import ThrusterCommand

    async def main() -> list[ThrusterCommand]:
        r = Rig()
        cmds: list[ThrusterCommand] = []
        r.bus.listen(ThrusterCommand, cmds.append)
        r.task.clock = Clock(utc_offset_s=0.0)
        r.directive(0.0, Mode.LINES, armed=False, mission=LINES)
        r.sensors(0.0)
        task = asyncio.create_task(r.task.run())
        await asyncio.sleep(0.3)
        r.directive(0.3, Mode.LINES, seq=2, driving_failsafes=("link",), mission=LINES)
        r.sensors(0.3)
        await asyncio.sleep(0.3)
        r.directive(0.6, Mode.LINES, seq=3, mission=LINES)
        r.sensors(0.6)
        await asyncio.sleep(0.3)
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        return cmds

    cmds = run_virtual(main())
    held = [c for c in cmds if c.t < 0.3]
    assert held and all((c.u1, c.u2) == (0.0, 0.0) and c.reason == "disarmed" for c in held)
    fs = [c for c in cmds if 0.35 <= c.t < 0.6]
    assert fs and all((c.u1, c.u2) == (0.0, 0.0) and "failsafe link" in c.reason for c in fs)
    driving = [c for c in cmds if c.t >= 0.65]
    assert driving and all(c.reason == "" for c in driving)
    assert any((c.u1, c.u2) != (0.0, 0.0) for c in driving)


def test_a_disarmed_directive_gives_zero_thrust_whatever_its_mode() -> None:
    for mode, kw in ((Mode.LINES, {"mission": LINES}), (Mode.MANUAL, {}),
                     (Mode.HOLD, {"point": (50.0, 0.0)})):
        r = Rig()
        r.directive(0.0, mode, armed=False, **kw)
        r.bus.publish(ManualThrust(0.01, 50.0, 50.0, until=5.0))
        r.sensors(0.05)
        a = r.task.tick(0.05)
        assert (a.u1, a.u2) == (0.0, 0.0) and r.task.reason == "disarmed", mode
        r.directive(0.06, mode, seq=2, armed=True, **kw)  # armed: the same mode drives
        r.bus.publish(ManualThrust(0.07, 50.0, 50.0, until=5.0))
        r.sensors(0.1)
        a = r.task.tick(0.1)
        assert (a.u1, a.u2) != (0.0, 0.0), mode


def test_the_interlock_stops_every_mode_while_driving_is_unsafe() -> None:
    """Heading lost, thruster controller silent, position lost: zero at the first
    tick past the failsafe table's limit, in manual too; thrust again once healthy."""
    fs = RuntimeConfig().failsafe
    cases = [("heading", fs.heading_lost_s, "no compass heading"),
             ("status", fs.thruster_silent_s, "no status from the thruster controller"),
             ("gps", fs.position_lost_s, "no GPS position")]
    for mode, kw in ((Mode.LINES, {"mission": LINES}), (Mode.MANUAL, {})):
        for what, limit, why in cases:
            r = Rig()
            r.directive(0.0, mode, **kw)
            r.sensors(0.0)
            t_in, t_out = 0.9 * limit, limit + 0.02
            for t in (t_in, t_out):
                r.bus.publish(ManualThrust(t, 30.0, 30.0, until=t + 1.0))
                r.directive(t, mode, **kw)
                if what != "heading":
                    r.bus.publish(Heading(t, "compass", "HDT", 0.0, True, 0.0))
                if what != "status":
                    r.bus.publish(ThrusterStatus(t, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
                n = _nav(0.0 if what == "gps" else t)
                n.gps_age_s = 0.0
                r.bus.publish(n)
                a = r.task.tick(t)
                if t == t_in:
                    assert (a.u1, a.u2) != (0.0, 0.0), (mode, what)
                else:
                    assert (a.u1, a.u2) == (0.0, 0.0), (mode, what)
                    assert why in r.task.reason, (mode, what, r.task.reason)


def test_the_interlock_holds_until_healthy_for_clear_after_s_and_a_flap_restarts_it() -> None:
    """A thruster controller that answers now and then: zero from the first silent
    tick, through every short answer, until it has answered for clear_after_s."""
    fs = RuntimeConfig().failsafe
    r = Rig()
    r.directive(0.0, Mode.LINES, mission=LINES)
    answers = {0.0} | {round(0.05 * k, 2) for k in range(38, 44)} \
        | {round(0.05 * k, 2) for k in range(60, 200)}  # silent 0.05-1.9 s and 2.2-3.0 s
    last_unsafe = -math.inf
    for k in range(200):
        t = round(0.05 * k, 2)
        r.directive(t, Mode.LINES, mission=LINES)
        r.sensors(t, status=t in answers)
        a = r.task.tick(t)
        # the controller's last answer is more than thruster_silent_s old
        last = max(x for x in answers if x <= t)
        if t - last > fs.thruster_silent_s:
            last_unsafe = t
        if t - last_unsafe < fs.clear_after_s:
            assert (a.u1, a.u2) == (0.0, 0.0), (t, r.task.reason)
        else:
            assert a.u1 != 0.0, (t, r.task.reason)
    assert last_unsafe > 2.2 and 9.9 - last_unsafe > fs.clear_after_s  # it did let go


def test_a_driving_failsafe_in_the_directive_gives_zero_thrust_until_it_clears() -> None:
    """The supervisor's latch: while the directive carries a driving failsafe, zero
    thrust in every mode though every sensor is healthy; thrust once it is gone."""
    for mode, kw in ((Mode.LINES, {"mission": LINES}), (Mode.MANUAL, {}),
                     (Mode.HOLD, {"point": (50.0, 0.0)}),
                     (Mode.RETURN, {"point": (-50.0, 0.0)})):
        for held in (("thruster_silent",), ("heading_lost", "position_lost")):
            r = Rig()
            r.directive(0.0, mode, driving_failsafes=held, **kw)
            r.bus.publish(ManualThrust(0.01, 50.0, 50.0, until=5.0))
            r.sensors(0.05)
            a = r.task.tick(0.05)
            assert (a.u1, a.u2) == (0.0, 0.0), (mode, held)
            assert r.task.reason == f"not driving: failsafe {', '.join(held)} until it clears"
            r.directive(0.06, mode, **kw)  # cleared: the same directive, republished
            r.sensors(0.1)
            a = r.task.tick(0.1)
            assert (a.u1, a.u2) != (0.0, 0.0), (mode, held, r.task.reason)
