"""Scenarios for HIL: a ``zarco sim`` scenario and its ``[[faults]]`` schedule.

``Scenario.faults`` (a list of :class:`drivers.sim.faults.FaultSpec`) is part
of the scenario schema, validated with the rest (one ConfigError naming file
and key); ``zarco sim`` and ``zarco hil`` both inject it.  The rig serves a
buoy feed only when the scenario follows the AUV (``[mission] kind =
"follow"`` with the ``[auv]`` and ``[lbl]`` tables): a buoy device or a buoy
fault in any other scenario is refused.
"""

from __future__ import annotations

from pathlib import Path

from drivers.sim.faults import FaultSpec
from zarco_core.config import ConfigError
from zarco_tools.scenario import Scenario, load_scenario


def load_hil_scenario(path: str | Path, overrides: list[str] | None = None,
                      seed: int | None = None) -> tuple[Scenario, list[FaultSpec]]:
    """Read, override and validate a scenario; return it and its fault schedule."""
    scn = load_scenario(path, overrides, seed)
    file = str(path) if not overrides else f"{path} (with --set)"
    buoy = scn.runtime.devices.buoy.enabled
    if buoy and (scn.auv is None or scn.lbl is None):
        raise ConfigError(file, "runtime.devices.buoy.enabled",
                          "the rig serves a buoy feed only from a simulated AUV and LBL "
                          "network (the [auv] and [lbl] tables)")
    for i, f in enumerate(scn.faults):
        if f.device == "buoy" and not buoy:
            raise ConfigError(file, f"faults[{i}].device", "a buoy fault needs the buoy "
                              "feed: only a scenario that follows the AUV has one")
    return scn, list(scn.faults)
