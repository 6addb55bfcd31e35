"""The supervisor, driven by scripted commands in the in-process simulator: the
vessel boots idle and disarmed, every command gets exactly one acknowledgement
(accepted, or refused with a reason a person can read), missions run to their
end and hold, ``return`` goes home and holds, ``resume`` continues where the
mission stopped, also after a restart (the state file).  The scripted operator
arms as one would, once the boat is ready (``ARM_AT``)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from zarco_core.geodesy import LocalFrame
from zarco_core.messages import CommandAck
from zarco_tools.scenario import ScriptedCommand, load_scenario
from zarco_tools.simulation import SimResult, run_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"


#: when the scripted operator arms (s): the boat is ready (position, heading, thruster
#: controller answering) within half a second of the start
ARM_AT = 1.0


def _sim(commands: list[tuple[float, str, dict[str, Any]]], limit_s: float,
         *overrides: str, arm_at: float | None = ARM_AT) -> SimResult:
    scn = load_scenario(SCENARIOS / "rectangle.toml",
                        ["mission.kind=idle", f"scenario.max_duration_s={limit_s}",
                         "world.current.speed_mps=0.0", *overrides], 1)
    if arm_at is not None:
        commands = [(arm_at, "arm", {}), *commands]
    scn.commands = [ScriptedCommand(at, name, args) for at, name, args in commands]
    return run_scenario(scn)


def _acks(res: SimResult, arm: bool = False) -> list[CommandAck]:
    """The acknowledgements (without the scripted operator's arming unless ``arm``)."""
    return [a for a in res.extra["acks"] if arm or a.name != "arm"]


def _modes(res: SimResult) -> list[str]:
    """The modes the directives took, in order (arming changes the directive, not
    the mode)."""
    out: list[str] = []
    for d in res.extra["directives"]:
        if not out or out[-1] != d.mode.value:
            out.append(d.mode.value)
    return out


def _geo(n: float, e: float) -> list[float]:
    from zarco_runtime.settings import Origin

    o = Origin()
    lat, lon, _ = LocalFrame(o.lat_deg, o.lon_deg).to_geodetic(n, e)
    return [lat, lon]


def test_boots_idle_and_disarmed_and_refuses_with_reasons() -> None:
    wps = [_geo(0, 0), _geo(30, 0)]
    res = _sim([
        (5.0, "thrust", {"u1": 10.0, "u2": 10.0}),
        (5.5, "mode", {"mode": "lines"}),
        (6.0, "follow", {}),
        (6.5, "mode", {"mode": "sideways"}),
        (7.0, "mission", {"waypoints": [[91.0, 0.0], [0.0, 0.0]]}),
        (7.2, "mission", {"waypoints": [_geo(0, 0), [41.0, -8.0]], "start": False}),
        (7.5, "mission", {"waypoints": wps, "speed_mps": 9.0}),
        (8.0, "mode", {"mode": "hold", "lat_deg": "north", "lon_deg": 0}),
        (8.5, "warp", {}),
        (8.7, "mission", {"waypoints": wps}),
        (8.8, "resume", {}),
        (8.9, "mode", {"mode": "manual"}),
        (9.0, "stop", {}),
    ], 12.0, arm_at=None)
    acks = _acks(res)
    assert len(acks) == 13  # exactly one acknowledgement each
    reasons = [a.reason for a in acks]
    assert [a.ok for a in acks] == [False] * 12 + [True]
    # whatever would move the boat is refused while disarmed
    assert reasons[0] == reasons[1] == reasons[2] == "disarmed"
    assert reasons[9] == reasons[10] == reasons[11] == "disarmed"
    assert reasons[3].startswith("mode: unknown mode 'sideways' (one of idle, manual")
    assert reasons[4] == "waypoints[0][0]: must be ≤ 90"
    assert reasons[5].startswith("waypoints[1]: ") and "km from the origin" in reasons[5]
    assert reasons[6] == "speed_mps: must be ≤ 3"
    assert reasons[7] == "lat_deg: must be a number, got text"
    assert reasons[8].startswith("unknown command 'warp' (one of stop, arm,")
    # never moved: idle and disarmed from boot, zero thrust all along
    assert {d.mode.value for d in res.extra["directives"]} == {"idle"}
    assert not any(d.armed for d in res.extra["directives"])
    assert max(abs(u) for u in res.log.u1 + res.log.u2) == 0.0


def test_armed_it_still_refuses_what_cannot_be_done() -> None:
    res = _sim([
        (3.0, "thrust", {"u1": 10.0, "u2": 10.0}),
        (3.5, "mode", {"mode": "lines"}),
        (4.0, "follow", {}),
        (4.5, "resume", {}),
    ], 6.0)
    assert _acks(res, arm=True)[0].ok  # armed once ready
    reasons = [a.reason for a in _acks(res)]
    assert reasons[0] == "not in manual mode"
    assert reasons[1] == "no mission loaded"
    assert reasons[2].startswith("buoy feed disabled")
    assert reasons[3] == "no mission to resume"
    assert max(abs(u) for u in res.log.u1 + res.log.u2) == 0.0


def test_arming_is_refused_until_the_boat_is_ready_then_stop_disarms() -> None:
    res = _sim([(0.01, "arm", {}), (4.0, "mission", {"waypoints": [_geo(0, 0), _geo(40, 0)]}),
                (10.0, "stop", {}), (11.0, "resume", {})], 13.0)
    a = _acks(res, arm=True)
    first, ok = a[0], a[1]
    assert not first.ok and first.reason == "no valid position"
    assert ok.ok and ok.t == ARM_AT
    assert [x.ok for x in a[2:]] == [True, True, False]
    assert a[-1].reason == "disarmed"  # stop disarmed: resume needs arming again
    t, u = res.log.t, [abs(p) + abs(q) for p, q in zip(res.log.u1, res.log.u2, strict=True)]
    assert max(ui for ti, ui in zip(t, u, strict=True) if ti < 4.0) == 0.0
    assert max(u) > 0.0
    assert max(ui for ti, ui in zip(t, u, strict=True) if ti > 10.1) == 0.0


def test_a_mission_runs_to_its_end_then_holds_at_its_last_waypoint() -> None:
    wps = [_geo(0.0, 0.0), _geo(40.0, 0.0), _geo(40.0, -20.0)]
    res = _sim([(5.0, "mission", {"waypoints": wps, "speed_mps": 1.2})], 150.0)
    assert _acks(res)[0].ok and _acks(res)[0].mode == "lines"
    assert _modes(res) == ["idle", "lines", "hold"]
    assert "mission complete" in res.extra["directives"][-1].reason
    hold = res.extra["directives"][-1]
    assert hold.point is not None and math.hypot(hold.point[0] - 40.0, hold.point[1] + 20.0) < 0.5
    # and it holds there
    assert math.hypot(res.log.x[-1] - 40.0, res.log.y[-1] + 20.0) < 2.0


def test_stop_then_resume_continues_the_same_leg() -> None:
    wps = [_geo(0.0, 0.0), _geo(60.0, 0.0), _geo(60.0, -30.0)]
    res = _sim([(5.0, "mission", {"waypoints": wps}),
                (45.0, "stop", {}),
                (48.0, "arm", {}),
                (50.0, "resume", {})], 60.0)
    a = _acks(res, arm=True)
    assert [x.ok for x in a] == [True, True, True, True, True]
    d = res.extra["directives"]
    assert _modes(res) == ["idle", "lines", "idle", "lines"]
    assert d[-1].start_leg == 0 and "resume" in d[-1].reason


def test_the_last_mission_survives_a_restart_and_resume_continues_it(tmp_path: Path) -> None:
    state = tmp_path / "state.json"
    wps = [_geo(0.0, 0.0), _geo(30.0, 0.0), _geo(30.0, -30.0), _geo(0.0, -30.0)]
    first = _sim([(5.0, "mission", {"waypoints": wps})], 45.0,
                 f'runtime.supervisor.state_file="{state}"')
    saved = json.loads(state.read_text())
    assert saved["leg"] >= 1 and not saved["complete"]
    # a new process: boots idle, knows the mission, continues it on `resume`
    second = _sim([(5.0, "resume", {})], 10.0, f'runtime.supervisor.state_file="{state}"')
    assert first.extra["directives"][-1].mode.value == "lines"
    boot = next(e.text for e in second.extra["events"] if e.kind == "mode")
    assert "can be resumed" in boot
    d = second.extra["directives"]
    assert d[0].mode.value == "idle"
    assert d[-1].mode.value == "lines" and d[-1].start_leg == saved["leg"]


def test_return_goes_home_and_holds() -> None:
    res = _sim([(3.0, "mission", {"waypoints": [_geo(0.0, 0.0), _geo(60.0, 0.0)]}),
                (40.0, "mode", {"mode": "return"})], 120.0)
    d = res.extra["directives"]
    assert _modes(res) == ["idle", "lines", "return", "hold"]
    assert "arrived home" in d[-1].reason
    home = next(x.point for x in d if x.mode.value == "return")
    assert home is not None and math.hypot(*home) < 1.0  # home: the first position
    assert math.hypot(res.log.x[-1] - home[0], res.log.y[-1] - home[1]) < 2.0


def test_waypoints_outside_the_geofence_are_refused() -> None:
    res = _sim([(5.0, "mission", {"waypoints": [_geo(0.0, 0.0), _geo(80.0, 0.0)]})], 8.0,
               "runtime.geofence.radius_m=50.0")
    a = _acks(res)[0]
    assert not a.ok and a.reason.startswith("waypoints[1]: outside the geofence")


def test_manual_needs_its_lease_renewed() -> None:
    res = _sim([(3.0, "mode", {"mode": "manual"}),
                (4.0, "thrust", {"u1": 40.0, "u2": 40.0}),
                (4.5, "thrust", {"u1": 40.0, "u2": 40.0})], 8.0)
    assert all(a.ok for a in _acks(res, arm=True))
    t, u1 = res.log.t, res.log.u1
    on = [ti for ti, u in zip(t, u1, strict=True) if u != 0.0]
    # thrust from the first command to one lease after the last, then zero
    assert on and min(on) >= 4.0 and 5.3 <= max(on) <= 5.6


def test_mission_with_leg_speeds_and_a_start_leg_then_cleared() -> None:
    wps = [_geo(0.0, 0.0), _geo(30.0, 0.0), _geo(30.0, -30.0)]
    res = _sim([(3.0, "mission", {"waypoints": wps, "leg_speeds_mps": [0.8, 1.4],
                                  "start_leg": 1}),
                (4.0, "mission", {"waypoints": wps, "leg_speeds_mps": [0.8]}),
                (5.0, "stop", {}),
                (6.0, "mission", {"clear": True}),
                (6.5, "arm", {}),
                (7.0, "mode", {"mode": "lines"})], 9.0)
    a = _acks(res)
    assert [x.ok for x in a] == [True, False, True, True, False]
    assert a[1].reason == "leg_speeds_mps: need one speed per leg (2), got 1"
    assert a[4].reason == "no mission loaded"
    d = next(x for x in res.extra["directives"] if x.mode.value == "lines")
    assert d.start_leg == 1
    assert d.mission is not None and [lg.speed_mps for lg in d.mission.legs] == [0.8, 1.4]


def test_thrust_renewals_are_counted_not_announced() -> None:
    res = _sim([(3.0, "mode", {"mode": "manual"})]
               + [(3.5 + 0.25 * k, "thrust", {"u1": 20.0, "u2": 20.0}) for k in range(8)],
               6.0)
    assert all(a.ok for a in _acks(res)) and len(_acks(res)) == 9
    acks = [e.text for e in res.extra["events"] if e.kind == "ack"]
    assert acks == ["arm from scenario: accepted", "mode from scenario: accepted"]


def test_autostart_applies_at_boot_but_never_after_a_restart(tmp_path: Path) -> None:
    """A boot autostarts the configured mission; a process that finds the last
    mission unfinished in the state file (it was killed under way) is a restart:
    idle and disarmed, saying why, until an operator resumes it."""
    state = tmp_path / "state.json"
    sets = ["mission.kind=lines", "mission.autostart=true",
            f'runtime.supervisor.state_file="{state}"']
    first = _sim([], 30.0, *sets, arm_at=None)
    assert "lines" in _modes(first)
    assert not json.loads(state.read_text())["complete"]  # the run ended under way
    second = _sim([(8.0, "arm", {}), (9.0, "resume", {})], 12.0, *sets, arm_at=None)
    d = second.extra["directives"]
    before = [x for x in d if x.t < 8.0]
    assert all(x.mode.value == "idle" and not x.armed for x in before), before
    assert any("not started" in e.text and "unfinished" in e.text
               for e in second.extra["events"])
    assert d[-1].mode.value == "lines" and "resume" in d[-1].reason
