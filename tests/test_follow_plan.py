"""Following an AUV that flies its a-priori plan, in the simulator: a tight
lawnmower's U-turns with the plan peak within 6 m and are recovered (within
3 m for 10 s) in 20 s; an AUV that leaves its plan is noticed and still
followed.  Missions drawn from the field's ranges (legs 40–60 m, 10–20 m
apart, the AUV at 0.5–1.2 m/s turning at 8–15 °/s, current up to 0.2 m/s from
any direction), a few simulated minutes each."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario

FOLLOW = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "follow_turn.toml"
#: the AUV hovers this long while the tracker acquires it (s)
HOVER_S = 30.0


def _mission(seed: int) -> tuple[list[list[float]], list[str]]:
    """A tight lawnmower of two lines and its overrides (without the plan)."""
    rng = np.random.default_rng(seed)
    length, gap = rng.uniform(40.0, 60.0), rng.uniform(10.0, 20.0)
    a = rng.uniform(0.0, math.tau)
    side = rng.choice([-1.0, 1.0])
    ux, uy = math.cos(a), math.sin(a)
    nx, ny = -uy * side, ux * side
    x0, y0 = 170.0 + rng.uniform(-20, 20), 150.0 + rng.uniform(-20, 20)
    pts = [[x0, y0], [x0 + length * ux, y0 + length * uy],
           [x0 + length * ux + gap * nx, y0 + length * uy + gap * ny],
           [x0 + gap * nx, y0 + gap * ny]]
    pts = [[round(p, 2) for p in q] for q in pts]
    v, rate = rng.uniform(0.5, 1.2), rng.uniform(8.0, 15.0)
    dur = HOVER_S + (2.0 * length + gap) / v + 45.0
    sets = [f"auv.waypoints={json.dumps(pts)}", f"auv.speed_mps={v:.3f}",
            f"auv.turn_rate_dps={rate:.2f}", f"auv.start_delay_s={HOVER_S}",
            f"world.x_m={x0 - 3.0:.2f}", f"world.y_m={y0:.2f}",
            f"runtime.tracker.prior_north_m={x0:.2f}",
            f"runtime.tracker.prior_east_m={y0:.2f}",
            f"world.current.speed_mps={rng.uniform(0.0, 0.2):.3f}",
            f"world.current.direction_deg={rng.uniform(0.0, 360.0):.1f}",
            f"scenario.max_duration_s={dur:.1f}"]
    return pts, sets


def _run(sets: list[str], seed: int) -> dict[str, Any]:
    res = run_scenario(load_scenario(FOLLOW, sets, seed))
    rep = res.report
    rep["tracker_events"] = [e.text for e in res.extra["events"] if e.source == "tracker"]
    return rep


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_a_u_turn_with_the_plan_peaks_within_6_m_and_recovers_within_20_s(seed: int) -> None:
    pts, sets = _mission(seed)
    rep = _run([*sets, f"mission.auv_plan={json.dumps(pts)}"], seed)
    assert any(t.startswith("AUV on its plan") for t in rep["tracker_events"])
    uturns = [t for t in rep["turns"] if t["kind"] == "uturn"]
    assert len(uturns) == 1, rep["turns"]
    u = uturns[0]
    assert u["distance_max_m"] <= 6.0, u
    assert u["recovery_s"] is not None and u["recovery_s"] <= 20.0, u
    assert not any(t.startswith("AUV left its plan") for t in rep["tracker_events"])


def test_an_auv_leaving_its_plan_is_noticed_and_still_followed() -> None:
    """The plan says a lawnmower; half-way along its first line the AUV turns
    90° away and flies 60 m on a line the plan does not have: the tracker says
    it left the plan, and the boat follows it off the plan (its turn within the
    plan-free targets: ≤ 12 m, recovered within 40 s)."""
    pts, sets = _mission(21)
    a, b = np.array(pts[0]), np.array(pts[1])
    mid = a + 0.5 * (b - a)
    u = (b - a) / np.linalg.norm(b - a)
    away = mid + 60.0 * np.array([-u[1], u[0]])
    flown = [pts[0], mid.round(2).tolist(), away.round(2).tolist()]
    sets = [s for s in sets if not s.startswith(("auv.waypoints", "scenario.max_duration_s"))]
    sets += [f"auv.waypoints={json.dumps(flown)}", "scenario.max_duration_s=210.0",
             f"mission.auv_plan={json.dumps(pts)}"]
    rep = _run(sets, 21)
    ev = rep["tracker_events"]
    assert any(t.startswith("AUV on its plan") for t in ev), ev
    assert any(t.startswith("AUV left its plan (") for t in ev), ev
    turns = [t for t in rep["turns"] if t["kind"] == "turn"]
    assert turns and all(t["distance_max_m"] <= 12.0 for t in turns), rep["turns"]
    assert all(t["recovery_s"] is not None and t["recovery_s"] <= 40.0 for t in turns)
