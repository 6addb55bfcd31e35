"""The shipped follow scenarios run the vessel's configuration: what is tested is
what sails."""

from __future__ import annotations

from pathlib import Path

import pytest

from zarco_runtime.config_file import load_runtime_config
from zarco_tools.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
FOLLOW = sorted((ROOT / "config" / "scenarios").glob("follow_*.toml"))


def test_there_are_follow_scenarios() -> None:
    assert len(FOLLOW) >= 2


@pytest.mark.parametrize("path", FOLLOW, ids=lambda p: p.stem)
def test_follow_scenario_runs_the_vessel_navigation(path: Path) -> None:
    vessel, _ = load_runtime_config(ROOT / "config" / "zarco.toml")
    rt = load_scenario(path).runtime
    assert rt.navigation.estimator == vessel.navigation.estimator == "ekf"
    assert rt.navigation == vessel.navigation
    assert rt.ekf == vessel.ekf
    # the controller and the follow guidance are the vessel's too
    assert rt.control == vessel.control
    assert rt.follow == vessel.follow
    assert rt.guidance == vessel.guidance
