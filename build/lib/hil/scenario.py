"""Scenarios for HIL: a ``zarco sim`` scenario and its ``[[faults]]`` schedule.

``Scenario.faults`` (a list of :class:`drivers.sim.faults.FaultSpec`) is part
of the scenario schema, validated with the rest (one ConfigError naming file
and key); ``zarco sim`` ignores it, ``zarco hil`` injects it.
"""

from __future__ import annotations

from pathlib import Path

from drivers.sim.faults import FaultSpec
from zarco_tools.scenario import Scenario, load_scenario


def load_hil_scenario(path: str | Path, overrides: list[str] | None = None,
                      seed: int | None = None) -> tuple[Scenario, list[FaultSpec]]:
    """Read, override and validate a scenario; return it and its fault schedule."""
    scn = load_scenario(path, overrides, seed)
    return scn, list(scn.faults)
