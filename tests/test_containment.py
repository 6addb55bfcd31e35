"""No component can take the process down: an exception injected into each
component (each parser, navigation, tracking, guidance, the supervisor itself)
is logged, counted and the component restarted; the simulation runs to its end,
and thrust goes to zero where it must (the supervisor's ``component failed``
failsafe, or the failsafe of the data that stopped)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from zarco_core.messages import Event, ThrusterCommand
from zarco_runtime.runtime import Runtime
from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import ExtraTask, SimResult, run_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"
AT_S = 40.0


def _run(scenario: str, inject: Callable[[Runtime, dict[str, Any]], None],
         limit_s: float = AT_S + 15.0) -> tuple[SimResult, dict[str, Any]]:
    marks: dict[str, Any] = {"cmds": []}

    async def task(rt: Runtime) -> None:
        rt.bus.listen(ThrusterCommand, lambda c: marks["cmds"].append((c.t, c.u1, c.u2)))
        await rt.clock.sleep_until(AT_S)
        inject(rt, marks)

    scn = load_scenario(SCENARIOS / scenario, [f"scenario.max_duration_s={limit_s}"], 1)
    extra: list[ExtraTask] = [task]
    res = run_scenario(scn, extra_tasks=extra)
    return res, marks


def _raiser(what: str, marks: dict[str, Any]) -> Callable[..., Any]:
    def boom(*_a: object, **_k: object) -> Any:
        marks[what] = marks.get(what, 0) + 1
        raise RuntimeError(f"injected fault in {what}")
    return boom


def _modes(res: SimResult) -> list[str]:
    return [d.mode.value for d in res.extra["directives"]]


def _events(res: SimResult, kind: str) -> list[Event]:
    return [e for e in res.extra["events"] if e.kind == kind]


def _thrust_after(marks: dict[str, Any], t0: float) -> list[tuple[float, float]]:
    return [(u1, u2) for t, u1, u2 in marks["cmds"] if t > t0]


def _ran_to_the_end(res: SimResult, limit_s: float = AT_S + 15.0) -> None:
    assert res.report["stop"] == f"time limit {limit_s} s"
    assert res.report["sim_seconds"] == pytest.approx(limit_s)


@pytest.mark.parametrize("device", ["gps", "compass"])
def test_a_parser_that_raises_is_counted_and_the_boat_stops(device: str) -> None:
    def inject(rt: Runtime, marks: dict[str, Any]) -> None:
        getattr(rt, device).parse = _raiser(f"{device} parser", marks)

    res, marks = _run("rectangle.toml", inject)
    _ran_to_the_end(res)
    assert marks[f"{device} parser"] > 10
    assert res.report["devices"][device]["parser_bug"] == marks[f"{device} parser"]
    # no data any more: its failsafe stopped the boat, and it stays stopped
    assert "idle" in _modes(res)[1:]
    fs = _events(res, "failsafe")
    assert fs and fs[0].text.startswith("position_lost" if device == "gps" else "heading_lost")
    # the GPS: dead reckoning until position_lost_s; the compass: at once
    wait = res.extra["runtime"].cfg.failsafe.position_lost_s if device == "gps" else 0.0
    tail = _thrust_after(marks, AT_S + wait + 1.0)
    assert tail and all(u == (0.0, 0.0) for u in tail)


def test_a_buoy_parser_that_raises_leaves_the_runtime_running() -> None:
    def inject(rt: Runtime, marks: dict[str, Any]) -> None:
        rt.buoy.parse = _raiser("buoy parser", marks)

    res, marks = _run("follow_turn.toml", inject)
    _ran_to_the_end(res)
    assert marks["buoy parser"] > 0
    assert res.report["devices"]["buoy"]["parser_bug"] == marks["buoy parser"]


def test_navigation_that_raises_is_restarted_and_thrust_goes_to_zero() -> None:
    def inject(rt: Runtime, marks: dict[str, Any]) -> None:
        assert rt.live.navigation is not None
        rt.live.navigation.nav.on_heading = _raiser("navigation", marks)  # type: ignore

    res, marks = _run("rectangle.toml", inject)
    _ran_to_the_end(res)
    assert marks["navigation"] == 1  # the failed instance is dropped, a fresh one runs
    comp = [e for e in _events(res, "component") if "navigation failed" in e.text]
    assert len(comp) == 1
    i = _modes(res).index("idle", 1)
    assert "component_failed" in res.extra["directives"][i].reason
    # zero thrust within a control period of the failure
    t_fail = comp[0].t
    first = [(t, u1, u2) for t, u1, u2 in marks["cmds"] if t >= t_fail + 0.1]
    assert first and (first[0][1], first[0][2]) == (0.0, 0.0)
    assert res.extra["runtime"].counters()["navigation_restarts"] == 1


def test_tracking_that_raises_is_restarted_and_the_boat_stops() -> None:
    def inject(rt: Runtime, marks: dict[str, Any]) -> None:
        assert rt.live.tracking is not None
        rt.live.tracking.tracker.process = _raiser("tracking", marks)  # type: ignore

    res, marks = _run("follow_turn.toml", inject)
    _ran_to_the_end(res)
    assert marks["tracking"] == 1
    assert any("tracking failed" in e.text for e in _events(res, "component"))
    assert "idle" in _modes(res)[1:]
    assert res.extra["runtime"].counters()["tracking_restarts"] == 1


@pytest.mark.parametrize("scenario", ["rectangle.toml", "follow_turn.toml"])
def test_guidance_that_raises_restarts_control_with_zero_thrust(scenario: str) -> None:
    from zarco_runtime.guidance.follow import FollowGuidance
    from zarco_runtime.guidance.lines import LineGuidance

    def inject(rt: Runtime, marks: dict[str, Any]) -> None:
        ctl = rt.live.control
        assert ctl is not None
        g: LineGuidance | FollowGuidance | None = ctl.lines or ctl.follow
        assert g is not None
        g.update = _raiser("guidance", marks)  # type: ignore[method-assign]

    res, marks = _run(scenario, inject)
    _ran_to_the_end(res)
    assert marks["guidance"] == 1
    assert any("control failed" in e.text for e in _events(res, "component"))
    # the failing tick itself published zero thrust, and the supervisor went idle
    at = [(t, u1, u2) for t, u1, u2 in marks["cmds"] if t > AT_S]
    assert (at[0][1], at[0][2]) == (0.0, 0.0)
    assert "idle" in _modes(res)[1:]


def test_a_supervisor_that_raises_is_restarted_idle_and_control_stops_meanwhile() -> None:
    def inject(rt: Runtime, marks: dict[str, Any]) -> None:
        sup = rt.live.supervisor
        assert sup is not None
        sup.evaluate = _raiser("supervisor", marks)  # type: ignore[method-assign]

    res, marks = _run("rectangle.toml", inject)
    _ran_to_the_end(res)
    assert marks["supervisor"] == 1
    assert any("supervisor failed" in e.text for e in _events(res, "component"))
    # the new supervisor boots idle: the boat stops and stays stopped
    tail = _thrust_after(marks, AT_S + 1.0)
    assert tail and all(u == (0.0, 0.0) for u in tail)
