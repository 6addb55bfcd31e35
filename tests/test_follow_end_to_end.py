"""End to end: following the AUV through a 90° turn from the buoy feed alone."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario

ROOT = Path(__file__).resolve().parents[1]
TURN = ROOT / "config" / "scenarios" / "follow_turn.toml"


@pytest.fixture(scope="module")
def report() -> dict:
    return run_scenario(load_scenario(TURN, seed=5)).report


def test_follow_turn_distance_figures(report: dict) -> None:
    r = report
    assert 1.5 <= r["fix_interval_s"] <= 2.5  # the paper: a new fix every 2 s or more
    assert r["fixes"] > 150
    assert r["course_error_rms_deg"] <= 3.0
    # on the straight legs, a minute after the AUV starts and after its turn
    assert r["settled_distance_median_m"] <= 1.0
    assert r["settled_distance_p95_m"] <= 2.0
    # over the whole time from acquisition: the approach, the AUV's start from
    # its hover and the turn included (each leaves the boat a few metres behind
    # for some seconds; the campaign's target for the p95 is 4 m)
    assert r["acquired_s"] <= 20.0
    assert r["distance_median_m"] <= 1.0
    assert r["distance_p95_m"] <= 5.0
    assert r["distance_max_m"] <= 12.0
    assert len(r["turns"]) == 1
    turn = r["turns"][0]
    assert math.isfinite(turn["recovery_s"]) and turn["recovery_s"] <= 45.0
    assert r["track_lost_events"] == 0


def test_runtime_stopped_mid_mission_leaves_zero_thrust(report: dict) -> None:
    # the run ends at its time limit with the boat under way: the thruster
    # driver's last words on the port must be zero thrust
    assert report["stop"].startswith("time limit")
    assert tuple(report["last_thruster_command"]) == (0.0, 0.0)


def test_tracker_counted_what_it_dropped(report: dict) -> None:
    dev = report["devices"]["buoy"]
    assert dev["sentences_ok"] > 500 and dev.get("checksum", 0) == 0
    # with 10 % missed and 2 % false detections the tracker drops events with reasons
    dropped = report["tracker"]
    assert sum(dropped.values()) > 0
    assert dropped.get("internal", 0) == 0


def test_a_bad_follow_scenario_is_refused(tmp_path: Path) -> None:
    from zarco_core.config import ConfigError

    p = tmp_path / "f.toml"
    p.write_text("[mission]\nkind = \"follow\"\n")
    with pytest.raises(ConfigError, match="needs the \\[auv\\] and \\[lbl\\]"):
        load_scenario(p)


def test_an_unrecovered_turn_is_null_in_a_valid_json_report() -> None:
    import json

    # thrusters far too weak to keep up: the turn is never recovered
    scn = load_scenario(TURN, ["world.thrusters.fwd_max_n=20.0",
                               "world.thrusters.rev_max_n=20.0",
                               "scenario.max_duration_s=300.0"], seed=2)
    r = run_scenario(scn).report
    (turn,) = r["turns"]
    assert turn["recovery_s"] is None
    assert turn["kind"] == "turn" and turn["angle_deg"] == pytest.approx(90.0, abs=1.0)
    text = json.dumps(r, allow_nan=False)  # raises on a bare NaN or Infinity
    assert "NaN" not in text
