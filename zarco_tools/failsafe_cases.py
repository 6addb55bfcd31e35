"""Every failsafe of the table, provoked in simulation by a scripted fault, and the
time from its condition to its action measured.

Each case runs a shipped scenario with one fault (``[[faults]]`` of the
simulated devices, or a fault of the runtime itself: a component that raises,
an operator link that stops, a boat sent outside its geofence) and reads, on
the supervisor's events and the simulated thruster controller's input:

``onset_s``   when the condition began: the fault's start, or for
              conditions with a time of their own (position lost, AUV lost)
              when the runtime could first see it
``action_s``  when the supervisor changed mode for it (its event)
``zero_s``    for an ``idle`` action, when the thruster controller received
              zero thrust
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivers.sim.faults import FaultSpec
from zarco_core.auv_messages import AuvTrack
from zarco_core.messages import OperatorHeartbeat
from zarco_runtime.runtime import Runtime
from zarco_tools.scenario import Scenario, load_scenario
from zarco_tools.simulation import ExtraTask, run_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "config" / "scenarios"
#: the fault starts this long into the run (s): the mission is under way by then
FAULT_AT_S = 60.0


@dataclass(slots=True)
class Case:
    name: str          # the failsafe
    scenario: str
    overrides: list[str]
    faults: list[FaultSpec]
    extra: list[Callable[[dict[str, Any]], ExtraTask]]
    limit_s: float
    expect: str        # the mode it must end in
    note: str


def _fault(kind: str, device: str, at: float = FAULT_AT_S, dur: float = 20.0) -> FaultSpec:
    return FaultSpec(kind=kind, device=device, at_s=at, duration_s=dur)


def _heartbeats(until_s: float) -> Callable[[dict[str, Any]], ExtraTask]:
    """An operator whose heartbeat (1 Hz, shore link) stops at ``until_s``."""
    def make(marks: dict[str, Any]) -> ExtraTask:
        async def task(rt: Runtime) -> None:
            t = 1.0
            while t <= until_s:
                await rt.clock.sleep_until(t)
                rt.bus.publish(OperatorHeartbeat(rt.clock.now(), "shore", "bench"))
                marks["last_heartbeat"] = rt.clock.now()
                t += 1.0
        return task
    return make


def _raise_in_navigation(at_s: float) -> Callable[[dict[str, Any]], ExtraTask]:
    """The navigation estimator raises on the first GPS fix after ``at_s``."""
    def make(marks: dict[str, Any]) -> ExtraTask:
        async def task(rt: Runtime) -> None:
            await rt.clock.sleep_until(at_s)
            nav = rt.live.navigation
            assert nav is not None
            inner = nav.nav

            def boom(*_a: object) -> None:
                marks.setdefault("raised", rt.clock.now())
                raise RuntimeError("injected estimator fault")

            inner.on_fix = boom  # type: ignore[method-assign]
        return task
    return make


def _watch_auv(marks: dict[str, Any]) -> ExtraTask:
    async def task(rt: Runtime) -> None:
        def on(m: AuvTrack) -> None:
            if m.lost and "auv_lost" not in marks and m.t > FAULT_AT_S:
                marks["auv_lost"] = m.t
        rt.bus.listen(AuvTrack, on)
    return task


CASES: list[Case] = [
    Case("heading_lost", "rectangle.toml", [], [_fault("silence", "compass")], [],
         FAULT_AT_S + 10, "idle", "the compass goes silent"),
    Case("heading_lost", "rectangle.toml", [], [_fault("unplug", "compass")], [],
         FAULT_AT_S + 10, "idle", "the compass is unplugged"),
    Case("thruster_silent", "rectangle.toml", [], [_fault("silence", "thrusters")], [],
         FAULT_AT_S + 10, "idle", "the thruster controller stops answering"),
    Case("thruster_silent", "rectangle.toml", [],
         [FaultSpec(kind="silence", device="thrusters", at_s=0.0, duration_s=1e5)], [],
         30.0, "disarmed", "the thruster controller never answered: the boat never arms"),
    Case("position_lost", "rectangle.toml", [], [_fault("silence", "gps", dur=40.0)], [],
         FAULT_AT_S + 20, "idle", "the GPS goes silent (dead reckoning for position_lost_s)"),
    Case("link_lost", "rectangle.toml", ["runtime.failsafe.link_lost_s=5.0"], [],
         [_heartbeats(FAULT_AT_S)], FAULT_AT_S + 15, "hold",
         "the operator's heartbeat stops (link_lost_s = 5 s)"),
    Case("geofence", "rectangle.toml", ["runtime.geofence.radius_m=60.0"], [], [],
         120.0, "hold", "the mission leaves a 60 m geofence"),
    Case("component_failed", "rectangle.toml", [], [], [_raise_in_navigation(FAULT_AT_S)],
         FAULT_AT_S + 10, "idle", "the navigation estimator raises"),
    Case("auv_lost", "follow_turn.toml", [],
         [FaultSpec(kind="silence", device="buoy", at_s=150.0, duration_s=200.0)], [],
         260.0, "hold", "the buoy feed goes silent while following"),
]


def build(case: Case, seed: int) -> Scenario:
    scn = load_scenario(SCENARIOS / case.scenario, case.overrides, seed)
    scn.faults = list(case.faults)
    scn.scenario.max_duration_s = case.limit_s
    return scn


def measure(case: Case, seed: int = 1) -> dict[str, Any]:
    """Run one case; the timing of its failsafe (s of simulated time)."""
    marks: dict[str, Any] = {}
    extra = [make(marks) for make in case.extra]
    if case.name == "auv_lost":
        extra.append(_watch_auv(marks))
    scn = build(case, seed)
    res = run_scenario(scn, extra_tasks=extra)
    ev = res.extra["events"]
    fs = next((e for e in ev if e.kind == "failsafe" and e.text.startswith(case.name + ":")),
              None)
    if case.expect == "disarmed":
        return _never_armed(case, scn, res, fs, seed)
    action_ev = None
    if fs is not None:
        action_ev = next((e for e in ev if e.kind == "mode" and e.t >= fs.t
                          and f"failsafe {case.name}" in e.text), None)
    # when the condition began
    if case.name == "thruster_silent" and case.faults[0].at_s == 0.0:
        onset = next((t for t, d, what in res.extra["sim_events"]
                      if d == "thrusters" and what == "thrust"), math.nan)
    elif case.name == "link_lost":
        onset = float(marks.get("last_heartbeat", math.nan))
    elif case.name == "geofence":
        onset = _left_fence(res, 60.0)
    elif case.name == "component_failed":
        onset = float(marks.get("raised", math.nan))
    elif case.name == "auv_lost":
        onset = float(marks.get("auv_lost", math.nan))
    else:
        onset = case.faults[0].at_s
    zero = math.nan
    if case.expect == "idle" and action_ev is not None:
        zero = next((t for t, d, what in res.extra["sim_events"]
                     if d == "thrusters" and what == "zero" and t >= onset), math.nan)
    # the mode the failsafe chose ("mode idle: failsafe ...")
    action_mode = action_ev.text.split()[1].rstrip(":") if action_ev else "?"
    delay = _delay(case, scn)
    return {
        "failsafe": case.name, "seed": seed, "note": case.note,
        "configured_delay_s": delay,
        "onset_s": _r(onset),
        "action_s": _r(action_ev.t) if action_ev else None,
        "condition_to_action_s": _r(action_ev.t - onset) if action_ev else None,
        "condition_to_zero_thrust_s": _r(zero - onset) if math.isfinite(zero) else None,
        "action": action_mode,
        "expected": case.expect,
        "ok": action_ev is not None and action_mode == case.expect,
    }


def _never_armed(case: Case, scn: Scenario, res: Any, fs: Any, seed: int) -> dict[str, Any]:
    """A fault from the start: the failsafe must enter (disarmed), ``mission.autostart``
    must never arm, and the thrusters never get a non-zero command."""
    armed = any(d.armed for d in res.extra["directives"])
    moved = any(d == "thrusters" and what == "thrust" for _t, d, what in res.extra["sim_events"])
    first_cmd = 1.0 / scn.runtime.control.rate_hz  # the first command: the first tick
    return {
        "failsafe": case.name, "seed": seed, "note": case.note,
        "configured_delay_s": _delay(case, scn),
        "onset_s": _r(first_cmd),
        "action_s": _r(fs.t) if fs else None,
        "condition_to_action_s": _r(fs.t - first_cmd) if fs else None,
        "condition_to_zero_thrust_s": 0.0 if not moved else None,
        "action": "disarmed" if not armed else "armed",
        "expected": case.expect,
        "ok": fs is not None and not armed and not moved,
    }


def _delay(case: Case, scn: Scenario) -> float:
    fs = scn.runtime.failsafe
    return float(getattr(fs, f"{case.name}_s"))


def _left_fence(res: Any, radius_m: float) -> float:
    log = res.log
    x0, y0 = log.x[0], log.y[0]
    for t, x, y in zip(log.t, log.x, log.y, strict=True):
        if math.hypot(x - x0, y - y0) > radius_m:
            return float(t)
    return math.nan


def _r(v: float) -> float | None:
    return round(v, 3) if math.isfinite(v) else None
