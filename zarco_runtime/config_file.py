"""The vessel's configuration file (``config/zarco.toml``): read, override, validate."""

from __future__ import annotations

from pathlib import Path

from zarco_core.config import apply_overrides, build, load_toml
from zarco_runtime.guidance.mission import MissionConfig
from zarco_runtime.settings import RuntimeConfig


def load_runtime_config(path: str | Path, overrides: list[str] | None = None
                        ) -> tuple[RuntimeConfig, MissionConfig | None]:
    """Read and validate ``config/zarco.toml`` (the boat's configuration) and its
    optional ``[mission]`` table."""
    file = str(path)
    data = load_toml(path)
    if overrides:
        apply_overrides(data, overrides, file=f"{file} (--set)")
    mission_raw = data.pop("mission", None)
    cfg = build(RuntimeConfig, data, file)
    mission = build(MissionConfig, mission_raw, file, "mission") if mission_raw else None
    return cfg, mission
