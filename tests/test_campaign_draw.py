"""``zarco campaign``'s spec, draws and judgement: a mission is a pure function
of (spec, seed, index); the follow campaign draws the field's errors and
routes within the spec's ranges; a report is judged against its targets, with
what physics forbids set apart."""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import pytest

from drivers.sim.params import ThrusterParams
from drivers.sim.thruster_model import U_MAX, thruster_thrust
from zarco_core.config import ConfigError, parse_override
from zarco_tools.campaign.draw import draw_mission
from zarco_tools.campaign.follow_judge import judge_follow
from zarco_tools.campaign.physics import straight_thrust, survey_scale_pct
from zarco_tools.campaign.spec import load_spec, parse_choice, with_choices
from zarco_tools.campaign.tables import summarise

ROOT = Path(__file__).resolve().parents[1]
FOLLOW = ROOT / "config" / "campaigns" / "follow.toml"


def sets(overrides: list[str]) -> dict[str, Any]:
    return {".".join(k): v for k, v in (parse_override(o) for o in overrides)}


@pytest.fixture(scope="module")
def spec() -> Any:
    return load_spec(FOLLOW)


@pytest.fixture(scope="module")
def drawn(spec: Any) -> list[Any]:
    return [draw_mission(spec, 11, k) for k in range(240)]


def test_a_mission_depends_only_on_the_spec_seed_and_index(spec: Any) -> None:
    a = draw_mission(spec, 3, 17)
    for k in (5, 40, 2):  # other draws in between change nothing
        draw_mission(spec, 3, k)
    b = draw_mission(spec, 3, 17)
    assert (a.overrides, a.scenario_seed, a.factors) == (b.overrides, b.scenario_seed,
                                                         b.factors)
    assert draw_mission(spec, 3, 18).overrides != a.overrides
    assert draw_mission(spec, 4, 17).overrides != a.overrides


def test_every_family_and_calibration_is_drawn(drawn: list[Any]) -> None:
    assert {m.family for m in drawn} == {"lawnmower", "tight_lawnmower", "random_legs",
                                         "arcs", "spiral"}
    assert {m.factors["calibration"] for m in drawn} == {"exact", "sound_speed", "survey",
                                                         "turnaround", "all"}
    assert {m.factors["beacons"] for m in drawn} == {2, 3, 4}


def test_the_field_errors_stay_within_the_issue_ranges(drawn: list[Any]) -> None:
    speeds = []
    for m in drawn:
        s = sets(m.overrides)
        cal = m.factors["calibration"]
        c_true, c_cfg = s["lbl.sound_speed_mps"], s["runtime.tracker.network.sound_speed_mps"]
        off = abs(c_true / c_cfg - 1.0)
        assert off <= 0.01 + 1e-6
        assert (off > 0.0) == (cal in ("sound_speed", "all") and off > 0.0)
        if cal not in ("sound_speed", "all"):
            assert c_true == c_cfg
        survey = [math.dist(a[:2], b[:2]) for a, b in zip(
            s["lbl.beacons"], s["runtime.tracker.network.beacons"], strict=True)]
        assert max(survey) <= 2.0 + 0.01
        if cal in ("survey", "all"):
            assert min(survey) >= 1.0 - 0.01  # every beacon off
        else:
            assert max(survey) <= 0.01
        tau = [abs(a - b) for a, b in zip(s["lbl.turnaround_s"],
                                          s["runtime.tracker.network.turnaround_s"],
                                          strict=True)]
        assert max(tau) <= 0.002 + 1e-9
        if cal not in ("turnaround", "all"):
            assert max(tau) == 0.0
        speeds.append(s["auv.speed_mps"])
    assert 0.5 <= min(speeds) < 0.6 and 1.3 < max(speeds) <= 1.4


def test_tight_lawnmowers_arcs_and_spirals_have_their_geometry(drawn: list[Any]) -> None:
    for m in drawn:
        s = sets(m.overrides)
        wps = s["auv.waypoints"]
        if m.factors["plan"] == "adaptive":  # an adaptive AUV leaves its route part-way
            if m.family != "tight_lawnmower":
                continue
            wps = s["mission.auv_plan"]  # the route as planned
        legs = [math.dist(a, b) for a, b in itertools.pairwise(wps)]
        if m.family == "tight_lawnmower":
            long, short = legs[0::2], legs[1::2]
            assert all(40.0 - 0.2 <= x <= 80.0 + 0.2 for x in long)
            assert all(10.0 - 0.2 <= x <= 20.0 + 0.2 for x in short)
            if m.factors["plan"] != "adaptive":  # the turns the AUV flies
                assert all(abs(abs(a) - 90) <= 1 for a in m.factors["planned_turns_deg"])
        elif m.family == "arcs":
            arcs = s["auv.arcs"]
            assert len(arcs) == len(wps) - 2
            assert all(15.0 <= a[1] <= 60.0 and 90.0 <= abs(a[2]) <= 400.0 and a[3] == 0.0
                       for a in arcs)
        elif m.family == "spiral":
            ((k, r, ang, g),) = s["auv.arcs"]
            assert k == 1 and 15.0 <= r <= 30.0 and 540.0 <= abs(ang) <= 900.0
            assert 10.0 <= g <= 25.0
        else:
            assert s["auv.arcs"] == []


def test_plans_are_the_route_or_left_part_way_along_a_leg(drawn: list[Any]) -> None:
    kinds = {"none": 0, "plan": 0, "adaptive": 0}
    for m in drawn:
        s = sets(m.overrides)
        kind = m.factors["plan"]
        kinds[kind] += 1
        wps = s["auv.waypoints"]
        if kind == "none":
            assert "mission.auv_plan" not in s
            continue
        plan = s["mission.auv_plan"]
        if kind == "plan":
            if s["auv.arcs"]:  # the arcs sampled: every waypoint is a point of the plan
                assert all(w in plan for w in wps) and len(plan) > len(wps)
            else:
                assert plan == wps
            continue
        # adaptive: the plan's first legs, then part-way along the next one the AUV
        # turns off it by 60–150° onto legs of its own (checked on the routes of
        # straight legs, where the plan is the waypoints)
        if m.factors["route"] not in ("lawnmower", "random"):
            continue
        j = next(i for i, (a, b) in enumerate(zip(wps, plan, strict=False)) if a != b)
        assert j >= 2 and wps[:j] == plan[:j]
        a, b, p = plan[j - 1], plan[j], wps[j]
        frac = math.dist(a, p) / math.dist(a, b)
        assert 0.3 - 0.01 <= frac <= 0.7 + 0.01
        assert abs((p[0] - a[0]) * (b[1] - a[1]) - (p[1] - a[1]) * (b[0] - a[0])) \
            <= 0.2 * math.dist(a, b)  # on the leg (to the waypoints' rounding)
        c_plan = math.atan2(b[1] - a[1], b[0] - a[0])
        q = wps[j + 1]
        c_own = math.atan2(q[1] - p[1], q[0] - p[0])
        turn = abs(math.degrees(math.remainder(c_own - c_plan, math.tau)))
        assert 60.0 - 1.0 <= turn <= 150.0 + 1.0
    # none = 2, plan = 1, adaptive = 1
    assert kinds["none"] > kinds["plan"] > 0 and kinds["none"] > kinds["adaptive"] > 0


def test_a_choice_redrawn_keeps_every_other_draw_of_the_missions(spec: Any) -> None:
    with_plan = with_choices(spec, dict([parse_choice("plan=plan", "follow")]))
    without = with_choices(spec, dict([parse_choice("plan = none", "follow")]))
    for k in range(40):
        a, b = draw_mission(with_plan, 5, k), draw_mission(without, 5, k)
        assert a.factors["plan"] == "plan" and b.factors["plan"] == "none"
        assert [o for o in a.overrides if not o.startswith("mission.auv_plan=")] \
            == b.overrides and len(a.overrides) == len(b.overrides) + 1
        assert a.scenario_seed == b.scenario_seed
    weights = parse_choice("plan=none:2,adaptive", "follow")
    assert weights == ("plan", {"none": 2.0, "adaptive": 1.0})


@pytest.mark.parametrize(("text", "why"), [
    ("plan", "NAME=VALUE"), ("route=lawnmower", "NAME=VALUE"),
    ("plan=sometimes", "unknown"), ("plan=plan:x", "not a number"),
    ("plan=plan:-1", "≥ 0"), ("plan=plan:0", "add up to 0")])
def test_a_bad_choice_is_refused_with_the_reason(text: str, why: str) -> None:
    with pytest.raises(ConfigError) as e:
        parse_choice(text, "follow")
    assert why in str(e.value)


def test_two_beacon_routes_keep_to_one_side_of_the_baseline(drawn: list[Any]) -> None:
    for m in drawn:
        s = sets(m.overrides)
        beacons = s["runtime.tracker.network.beacons"]
        if len(beacons) != 2:
            continue
        (x0, y0, _), (x1, y1, _) = beacons
        n = math.dist((x0, y0), (x1, y1))
        side = [((x - x0) * (y1 - y0) - (y - y0) * (x1 - x0)) / n
                for x, y in s["auv.waypoints"]]
        assert min(side) > 0.0 or max(side) < 0.0


def test_the_sim_command_names_the_scenario_and_every_override(spec: Any) -> None:
    m = draw_mission(spec, 1, 0)
    cmd = m.command(spec.scenario_file, ["runtime.follow.k_s=0.3"])
    assert cmd.startswith("zarco sim config/scenarios/follow_turn.toml --seed ")
    assert cmd.count("--set") == len(m.overrides) + 1 and cmd.endswith("runtime.follow.k_s=0.3")


@pytest.mark.parametrize(("line", "bad", "key"), [
    ("auv_speed_mps = [0.5, 1.4]", "auv_speed_mps = [1.5, 0.5]", "ranges.auv_speed_mps"),
    ("auv_speed_mps = [0.5, 1.4]", "auv_speed = [0.5, 1.0]", "ranges.auv_speed"),
    ("p_miss = [0.0, 0.20]", "p_miss = [0.0, 2.0]", "ranges.p_miss"),
    ("distance_median_m = 1.0", "distance_median_m = -1", "targets.distance_median_m"),
    ('route = "spiral"', 'route = "zigzag"', "families.spiral.route"),
    ("turnaround = 1", 'turnaround = "x"', "choices.calibration.turnaround"),
    ("plan_uturn_max_m = 6.0", "", "targets.plan_uturn_max_m"),
])
def test_a_bad_spec_is_refused_naming_the_key(tmp_path: Path, line: str, bad: str,
                                              key: str) -> None:
    text = FOLLOW.read_text()
    assert line in text
    text = text.replace(line, bad, 1).replace(
        '"../scenarios/follow_turn.toml"',
        '"' + str(ROOT / "config" / "scenarios" / "follow_turn.toml") + '"')
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ConfigError) as e:
        load_spec(p)
    assert e.value.key == key


# --------------------------------------------------------------------- judgement

TARGETS = {"distance_median_m": 1.0, "distance_p95_m": 4.0, "survey_distance_median_m": 2.5,
           "survey_distance_p95_m": 6.0, "turn_max_m": 12.0, "turn_recovery_s": 40.0,
           "uturn_max_m": 15.0, "uturn_recovery_s": 45.0, "plan_uturn_max_m": 6.0,
           "plan_uturn_recovery_s": 20.0, "arc_max_m": 12.0, "lost_max_s": 10.0,
           "sound_speed_error_pct": 0.2}


def report(**kw: Any) -> dict[str, Any]:
    r = {"distance_median_m": 0.8, "distance_p95_m": 3.0, "lost_max_s": 2.0,
         "sound_speed_error_max_pct": 0.1, "acquired_s": 8.0, "turns": []}
    r.update(kw)
    return r


def uturn(peak: float, rec: float | None) -> dict[str, Any]:
    return {"t_s": 100.0, "angle_deg": 180.0, "kind": "uturn", "distance_max_m": peak,
            "recovery_s": rec}


FACT = {"calibration": "exact", "plan": "none", "beacons": 3, "closing_mps": 0.4,
        "sound_speed_error_pct": 0.0}


def test_a_mission_within_every_target_passes() -> None:
    j = judge_follow(TARGETS, FACT, report(turns=[uturn(14.0, 44.0)]))
    assert j.fails == {} and j.exempt == {} and j.turns_ok == (True,)
    assert j.severity == pytest.approx(44.0 / 45.0, abs=1e-3)  # the recovery, nearest its target


def test_each_target_fails_on_its_own_figure() -> None:
    j = judge_follow(TARGETS, FACT, report(distance_median_m=1.2, distance_p95_m=4.5,
                                           lost_max_s=12.0, turns=[uturn(16.0, 30.0),
                                                                   uturn(5.0, None)]))
    assert set(j.fails) == {"median", "p95", "lost", "uturn"}
    assert j.turns_ok == (False, False) and len(j.fails["uturn"]) == 2
    assert j.severity == 3.0  # an unrecovered U-turn


def test_the_plan_tightens_the_uturn_targets_and_a_survey_error_relaxes_the_distance() -> None:
    planned = {**FACT, "plan": "plan"}
    assert "uturn" in judge_follow(TARGETS, planned, report(turns=[uturn(7.0, 15.0)])).fails
    assert "uturn" not in judge_follow(TARGETS, FACT, report(turns=[uturn(7.0, 15.0)])).fails
    surveyed = {**FACT, "calibration": "survey"}
    r = report(distance_median_m=2.0, distance_p95_m=5.5)
    assert judge_follow(TARGETS, surveyed, r).fails == {}
    assert set(judge_follow(TARGETS, FACT, r).fails) == {"median", "p95"}


def test_what_physics_forbids_is_exempt_with_its_figure_not_a_miss() -> None:
    slow = {**FACT, "closing_mps": -0.08}
    j = judge_follow(TARGETS, slow, report(distance_p95_m=9.0, lost_max_s=12.0,
                                           turns=[uturn(25.0, None)]))
    assert set(j.exempt) == {"p95", "uturn"} and "-0.08 m/s" in j.exempt["p95"]
    assert set(j.fails) == {"lost"}  # losing the track is not physics
    assert j.severity == pytest.approx(1.2)
    assert j.left_out  # no boat could: out of "every target"
    # a closing speed ≤ 0 whose targets were met anyway leaves nothing out
    assert not judge_follow(TARGETS, slow, report()).left_out


def test_sound_speed_with_two_beacons_is_not_observable() -> None:
    two = {**FACT, "beacons": 2, "sound_speed_error_pct": 0.8}
    j = judge_follow(TARGETS, two, report(sound_speed_error_max_pct=0.8))
    assert "sound_speed" in j.exempt and j.fails == {}
    assert not j.left_out  # the following is judged all the same
    three = {**FACT, "sound_speed_error_pct": 0.8}
    assert "sound_speed" in judge_follow(TARGETS, three,
                                         report(sound_speed_error_max_pct=0.8)).fails


def test_a_survey_whose_own_scale_is_off_makes_the_sound_speed_unobservable() -> None:
    # three beacons 120 m apart, each 2 m off: the surveyed network is 1.6 %
    # larger than the true one, and no timing tells that from faster sound
    true = [(26.5, 120.49), (4.08, 4.52), (105.77, 69.96)]
    surveyed = [(26.0, 122.4), (2.3, 4.0), (105.3, 71.9)]
    scale = survey_scale_pct(true, surveyed)
    assert scale == pytest.approx(1.62, abs=0.01)
    # a rotated, shifted copy has the true scale; a 0.2 % larger one, that
    c, s = math.cos(0.3), math.sin(0.3)
    turned = [(c * n - s * e + 5.0, s * n + c * e - 3.0) for n, e in true]
    assert survey_scale_pct(true, turned) == pytest.approx(0.0, abs=1e-9)
    assert survey_scale_pct(true, [(1.002 * n, 1.002 * e) for n, e in turned]
                            ) == pytest.approx(0.2, abs=1e-9)
    off = {**FACT, "calibration": "survey", "survey_scale_pct": scale}
    j = judge_follow(TARGETS, off, report(sound_speed_error_max_pct=0.9))
    assert "sound_speed" in j.exempt and "+1.62 %" in j.exempt["sound_speed"]
    assert "sound_speed" not in j.fails
    # a survey off by less than the target's own tolerance is judged
    near = {**FACT, "calibration": "survey", "survey_scale_pct": -0.15}
    assert "sound_speed" in judge_follow(TARGETS, near,
                                         report(sound_speed_error_max_pct=0.3)).fails


def test_nan_in_a_report_fails_the_json_check() -> None:
    j = judge_follow(TARGETS, FACT, report(track_error_rms_m=float("nan")))
    assert "json" in j.fails


@pytest.mark.parametrize("mismatch", [-0.1, 0.0, 0.06])
def test_the_closing_speed_counts_only_the_thrust_a_boat_going_straight_has(
        mismatch: float) -> None:
    """With the simulated thrusters' mismatch (one stronger than the other) a
    boat going straight holds the stronger back to the weaker's full thrust:
    that, not the two full thrusts, is its top speed."""
    p = ThrusterParams(mismatch=mismatch)
    f1, f2 = thruster_thrust(U_MAX, p, 1), thruster_thrust(U_MAX, p, 2)
    assert straight_thrust(p.fwd_max_n, mismatch, 0.0, 0.0) == pytest.approx(2.0 * min(f1, f2))
    assert straight_thrust(p.fwd_max_n, mismatch, 3.0, -2.0) < 2.0 * min(f1, f2)
    if mismatch:
        assert straight_thrust(p.fwd_max_n, mismatch, 0.0, 0.0) < f1 + f2


def test_every_target_leaves_out_only_what_physics_forbids() -> None:
    """An unobservable sound speed drops that check alone: the mission counts
    in "every target", passed or failed on the rest; a mission no boat could
    follow is left out; a record from before the judges said so is counted
    as it was then (any exemption left it out)."""
    def rec(i: int, fails: dict[str, list[str]], exempt: dict[str, str],
            **kw: Any) -> dict[str, Any]:
        return {"index": i, "family": "lawnmower", "factors": {}, "fails": fails,
                "exempt": exempt, "severity": 0.0, "scenario_seed": 1, "overrides": [],
                "figures": {}, **kw}
    unobservable = {"sound_speed": "not observable with 2 beacons"}
    recs = [rec(0, {}, unobservable, left_out=False),                   # passes
            rec(1, {"p95": ["5.0 m"]}, unobservable, left_out=False),  # fails
            rec(2, {}, {"p95": "closing speed -0.10 m/s"}, left_out=True),
            rec(3, {}, unobservable),                                   # as before
            rec(4, {}, {}, left_out=False),
            rec(5, {"median": ["1.2 m"]}, {}, left_out=False)]
    every = summarise(recs, ("median", "p95", "sound_speed"), "follow.toml", [])["all"][
        "every_target"]
    assert every == {"applicable": 4, "passed": 2, "exempt": 2}
