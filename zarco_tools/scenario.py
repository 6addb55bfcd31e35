"""Scenario files: the simulated world, the mission and the runtime's config.

A scenario (``config/scenarios/*.toml``) has four tables:

``[scenario]``  name, seed, time limit
``[world]``     what the simulator simulates (drivers.sim.params.WorldParams)
``[mission]``   the lines mission (guidance.mission.MissionConfig)
``[runtime]``   the runtime's configuration, as in ``config/zarco.toml``
                (settings.RuntimeConfig); its devices default to ``sim://``

``--set world.current.speed_mps=0.4`` overrides any key by its dotted path.
The runtime's NED origin is the world's unless the scenario sets one.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivers.sim.acoustics import LblParams
from drivers.sim.auv import AuvParams
from drivers.sim.faults import FaultSpec
from drivers.sim.params import WorldParams
from zarco_core.config import ConfigError, apply_overrides, build, load_toml, spec
from zarco_runtime.config_file import load_runtime_config  # noqa: F401 (re-export)
from zarco_runtime.guidance.mission import MissionConfig
from zarco_runtime.settings import RuntimeConfig


@dataclass(slots=True)
class ScenarioMeta:
    name: str = spec("scenario", "", "name shown in reports")
    seed: int = spec(1, "", "random seed: one seed, bit-identical results", min=0)
    max_duration_s: float = spec(7200.0, "s", "stop the simulation after this long",
                                 min=1.0, max=1e6)
    record_hz: float = spec(10.0, "Hz", "rate of the true-track log", min=0.5, max=100.0)


@dataclass(slots=True)
class ScriptedCommand:
    """A command the scenario sends to the supervisor at ``at_s`` (``[[commands]]``),
    as an operator would: ``name`` and ``args`` as in the shore protocol
    (``name = "mode"``, ``args = {mode = "hold"}``)."""

    at_s: float = spec(0.0, "s", "when, seconds after the start", min=0.0, max=1e6)
    name: str = spec("stop", "", "command", choices=["stop", "mode", "mission", "follow",
                                                     "thrust", "resume", "arm", "disarm",
                                                     "param"])
    args: dict[str, Any] = spec(dict, "", "the command's arguments")


@dataclass(slots=True)
class Scenario:
    scenario: ScenarioMeta = spec(ScenarioMeta)
    world: WorldParams = spec(WorldParams)
    mission: MissionConfig = spec(MissionConfig)
    runtime: RuntimeConfig = spec(RuntimeConfig)
    auv: AuvParams | None = spec(None, "", "the simulated AUV (follow scenarios)")
    lbl: LblParams | None = spec(None, "", "the simulated LBL network and buoy (follow "
                                 "scenarios)")
    faults: list[FaultSpec] = spec(list, "", "fault schedule ([[faults]]), in zarco sim and "
                                   "zarco hil alike")
    commands: list[ScriptedCommand] = spec(list, "", "commands sent at their times "
                                           "([[commands]])")


def load_scenario(path: str | Path, overrides: list[str] | None = None,
                  seed: int | None = None) -> Scenario:
    """Read, override and validate a scenario; raises ConfigError naming file and key."""
    return scenario_from_data(load_toml(path), str(path), overrides, seed)


def scenario_from_data(data: dict[str, Any], file: str, overrides: list[str] | None = None,
                       seed: int | None = None) -> Scenario:
    """A scenario from its TOML already read (``data``, changed in place by the
    overrides; ``file`` names it in errors), as :func:`load_scenario`: what a
    campaign's worker runs without the file."""
    if overrides:
        apply_overrides(data, overrides, file=f"{file} (--set)")
    scn = build(Scenario, data, file)
    if seed is not None:
        if seed < 0:
            raise ConfigError(file, "scenario.seed", f"must be ≥ 0, got {seed}")
        scn.scenario.seed = seed
    if scn.mission.kind == "follow" or any(c.name == "follow" for c in scn.commands):
        if scn.auv is None or scn.lbl is None:
            raise ConfigError(file, "mission.kind",
                              "following the AUV needs the [auv] and [lbl] tables")
        scn.runtime.devices.buoy.enabled = True
    if scn.mission.autostart is None:
        scn.mission.autostart = True  # a scenario starts its mission by default
    for name, dev in scn.runtime.devices.items():
        if not dev.url:
            dev.url = f"sim://{name}"
    if "origin" not in data.get("runtime", {}):
        w = scn.world
        scn.runtime.origin.lat_deg = w.origin_lat_deg
        scn.runtime.origin.lon_deg = w.origin_lon_deg
    elif (abs(scn.runtime.origin.lat_deg - scn.world.origin_lat_deg) > 1e-9
          or abs(scn.runtime.origin.lon_deg - scn.world.origin_lon_deg) > 1e-9):
        raise ConfigError(file, "runtime.origin",
                          "must equal the world's origin in a scenario (or be left out)")
    return scn
