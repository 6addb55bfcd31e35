"""The AUV's plan as an operator gives it: ``[mission] auv_plan`` in the
mission's frame, and the ``follow`` command's ``auv_plan``; a bad one is
refused with one line naming the key (or the point) and why; a good one is
published on the bus as local NED points when following starts, and cleared
when it ends."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from zarco_core.auv_messages import AuvPlan
from zarco_core.config import ConfigError
from zarco_core.geodesy import LocalFrame
from zarco_runtime.config_file import boot_mission, load_runtime_config
from zarco_runtime.runtime import Runtime
from zarco_tools.scenario import ScriptedCommand, load_scenario
from zarco_tools.simulation import run_scenario

ROOT = Path(__file__).resolve().parents[1]
FOLLOW = ROOT / "config" / "scenarios" / "follow_turn.toml"
VESSEL = ROOT / "config" / "zarco.toml"


@pytest.mark.parametrize(("override", "reason"), [
    ("mission.auv_plan=[[0.0, 0.0]]", "mission.auv_plan: a plan needs at least 2 points"),
    ("mission.auv_plan=[[0.0, 0.0], [1.0]]",
     "mission.auv_plan[1]: must be [north, east], has 1 numbers"),
    ("mission.auv_plan=[[0.0, 0.0], ['x', 1.0]]", "mission.auv_plan[1][0]: expected a number"),
    ("mission.auv_plan=[[0.0, 0.0], [0.5, 0.0]]",
     "mission.auv_plan[1]: less than 1 m from point 0"),
    ("mission.auv_plan=[[0.0, 0.0], [90000.0, 0.0]]",
     "mission.auv_plan[1]: 90 km from the origin (at most 50 km)"),
    ("mission.auv_plan=[[0.0, 0.0], [10.0, 0.0]]\nmission.kind='lines'", ""),
])
def test_a_bad_plan_in_the_mission_is_refused_naming_the_key(override: str,
                                                              reason: str) -> None:
    sets = override.split("\n")
    if reason == "":  # a lines mission has no AUV to plan for
        sets.append("mission.waypoints=[[0.0, 0.0], [10.0, 0.0]]")
        reason = "mission.auv_plan: only a follow mission has an AUV plan (kind = 'lines')"
    with pytest.raises(ConfigError) as exc:
        load_scenario(FOLLOW, sets)
    assert str(exc.value).startswith(f"{FOLLOW}: {reason}"), str(exc.value)
    assert "\n" not in str(exc.value)


def test_a_geodetic_plan_is_checked_in_degrees_and_converted_about_the_origin() -> None:
    with pytest.raises(ConfigError, match=r"mission\.auv_plan\[0\]: not a latitude"):
        load_scenario(FOLLOW, ['mission.frame="geodetic"',
                               "mission.auv_plan=[[95.0, -8.7], [41.19, -8.7]]"])
    cfg, mc = load_runtime_config(VESSEL, [
        'mission.kind="follow"', 'mission.frame="geodetic"',
        "mission.auv_plan=[[41.186, -8.704], [41.187, -8.704], [41.187, -8.703]]",
        "devices.buoy.enabled=true", 'devices.buoy.url="/dev/null"'])
    boot = boot_mission(cfg, mc)
    assert boot.mission is not None and boot.mission.kind == "follow"
    frame = LocalFrame(cfg.origin.lat_deg, cfg.origin.lon_deg, cfg.origin.alt_m)
    want = [frame.to_ned(41.186, -8.704), frame.to_ned(41.187, -8.704),
            frame.to_ned(41.187, -8.703)]
    assert _flat(boot.mission.auv_plan) == pytest.approx(_flat(want))
    # about 111 m north, then about 84 m east at this latitude
    (a, _b), (c, d), (_e, f) = boot.mission.auv_plan
    assert c - a == pytest.approx(111.1, abs=0.3) and f - d == pytest.approx(83.9, abs=0.3)


def _flat(points: Any) -> list[float]:
    return [v for p in points for v in p]


def _plans(res_runtime: list[Runtime], seen: list[AuvPlan]) -> Any:
    async def tap(rt: Runtime) -> None:
        res_runtime.append(rt)
        rt.bus.listen(AuvPlan, seen.append)

    return tap


def test_the_follow_command_takes_a_plan_or_refuses_it_with_the_point_and_why() -> None:
    frame = LocalFrame(41.185, -8.705)

    def geo(n: float, e: float) -> list[float]:
        lat, lon, _ = frame.to_geodetic(n, e)
        return [lat, lon]

    good = [geo(100.0, 100.0), geo(160.0, 100.0), geo(160.0, 115.0)]
    scn = load_scenario(FOLLOW, ["mission.kind=idle", "scenario.max_duration_s=16.0",
                                 "runtime.devices.buoy.enabled=true",
                                 "mission.auv_plan=[]"])
    scn.commands = [ScriptedCommand(at, "follow", args) for at, args in [
        (5.0, {"auv_plan": [geo(0.0, 0.0), [91.0, 0.0]]}),
        (5.5, {"auv_plan": [geo(0.0, 0.0)]}),
        (6.0, {"auv_plan": [geo(0.0, 0.0), geo(0.3, 0.0)]}),
        (6.5, {"auv_plan": "north"}),
        (7.0, {"auv_plan": [geo(0.0, 0.0), [41.0, "w"]]}),
        (7.5, {"auv_plan": [geo(0.0, 0.0)] + [geo(10.0 * i, 0.0) for i in range(1, 1001)]}),
        (8.0, {"auv_plan": good}),
    ]] + [ScriptedCommand(4.0, "arm", {}), ScriptedCommand(12.0, "stop", {})]
    seen: list[AuvPlan] = []
    rts: list[Runtime] = []
    res = run_scenario(scn, extra_tasks=[_plans(rts, seen)])
    acks = [a for a in res.extra["acks"] if a.name == "follow"]
    assert len(acks) == 7 and len(res.extra["acks"]) == 9
    reasons = [a.reason for a in acks]
    # the command's schema: shapes, ranges, sizes
    assert reasons[0] == "auv_plan[1][0]: must be ≤ 90"
    assert reasons[3] == "auv_plan: must be a list, got text"
    assert reasons[4] == "auv_plan[1][1]: must be a number, got text"
    assert reasons[5] == "auv_plan: at most 1000 items"
    # the plan itself, about this vessel's origin
    assert reasons[1] == "auv_plan: a plan needs at least 2 points (or none)"
    assert reasons[2] == "auv_plan[1]: less than 1 m from point 0"
    assert acks[6].ok and acks[6].mode == "follow"
    assert all(a.ok for a in res.extra["acks"] if a.name in ("arm", "stop"))
    # published when following started, as NED points; cleared when it stopped
    assert [len(p.points) for p in seen] == [3, 0]
    assert _flat(seen[0].points) == pytest.approx([100.0, 100.0, 160.0, 100.0, 160.0, 115.0],
                                                  abs=1e-6)
    assert seen[0].source == "scenario"
    texts = [e.text for e in res.extra["events"] if e.source == "tracker"]
    assert texts[0].startswith("AUV plan of 2 legs (75 m) from scenario")
    assert texts[-1] == "AUV plan cleared; tracking without it"


def test_without_a_plan_in_the_command_the_configured_one_is_used() -> None:
    """``follow {}`` follows with ``[mission] auv_plan``; ``follow
    {"auv_plan": []}`` without any."""
    scn = load_scenario(FOLLOW, ["mission.kind=follow", "mission.autostart=false",
                                 "scenario.max_duration_s=12.0",
                                 "mission.auv_plan=[[100.0, 100.0], [300.0, 100.0]]"])
    scn.commands = [ScriptedCommand(4.0, "arm", {}), ScriptedCommand(5.0, "follow", {}),
                    ScriptedCommand(8.0, "follow", {"auv_plan": []})]
    seen: list[AuvPlan] = []
    res = run_scenario(scn, extra_tasks=[_plans([], seen)])
    assert all(a.ok for a in res.extra["acks"])
    assert [p.points for p in seen][:2] == [((100.0, 100.0), (300.0, 100.0)), ()]
    assert seen[0].source == "mission"
    assert math.isclose(seen[1].t, 8.0, abs_tol=0.5)
