"""Every failsafe of the table, provoked in the in-process simulator by a scripted
fault, takes its action, in time (simulated time: deterministic)."""

from __future__ import annotations

import pytest

from zarco_tools.failsafe_cases import CASES, measure


@pytest.mark.parametrize("i", range(len(CASES)), ids=[f"{c.name}:{c.note}" for c in CASES])
def test_failsafe_takes_its_action_in_time(i: int) -> None:
    case = CASES[i]
    r = measure(case, seed=1)
    assert r["ok"], r
    dt = r["condition_to_action_s"]
    if case.name in ("heading_lost", "thruster_silent"):
        assert dt <= 1.0, r  # a lost heading or a silent controller stops the boat within 1 s
        assert r["condition_to_zero_thrust_s"] <= 1.0, r
    elif case.name == "position_lost":
        # dead reckoning until the estimate is invalid or position_lost_s, not beyond
        assert dt <= r["configured_delay_s"] + 0.2, r
    else:
        assert r["configured_delay_s"] - 0.01 <= dt <= r["configured_delay_s"] + 0.2, r
