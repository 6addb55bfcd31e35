"""The vessel's configuration file (``config/zarco.toml``): read, override, validate."""

from __future__ import annotations

import os
from pathlib import Path

from drivers.transports import SYSTEM_SCHEMES, url_scheme
from zarco_core.config import ConfigError, apply_overrides, build, load_toml
from zarco_core.geodesy import LocalFrame
from zarco_runtime.guidance.mission import Mission, MissionConfig, build_legs, plan_points
from zarco_runtime.settings import RuntimeConfig
from zarco_runtime.supervision.supervisor import Boot


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


def _device_key(url: str) -> str:
    """A device URL reduced to what identifies the device (symlinks resolved)."""
    if url.startswith("serial://"):
        url = url[len("serial://"):]
    if url.startswith("/"):
        return os.path.realpath(url)
    return url.rstrip("/").lower()


def check_runtime(cfg: RuntimeConfig, mission: MissionConfig | None, file: str,
                  schemes: tuple[str, ...] = SYSTEM_SCHEMES) -> None:
    """Refuse, before anything starts, a configuration that cannot run here:
    an enabled device without a URL, a URL of a scheme this backend does not
    open (``sim://`` outside the simulator, ``foo://``), two devices on one
    URL, or a mission that needs a disabled device.  Raises ConfigError naming
    the file, the key and the reason."""
    seen: dict[str, str] = {}
    for name, dev in cfg.devices.items():
        if not dev.enabled:
            continue
        key = f"devices.{name}.url"
        for k, url in ((key, dev.url), (f"devices.{name}.corrections_url",
                                        dev.corrections_url)):
            if k.endswith("corrections_url") and not url:
                continue
            if k.endswith("corrections_url") and url.startswith("file://"):
                continue
            if not url.strip():
                raise ConfigError(file, k, "empty device address (a serial path, "
                                  "serial://PATH or tcp://HOST:PORT)")
            scheme = url_scheme(url)
            if scheme == "sim":
                raise ConfigError(file, k, f"{url}: sim:// ports exist only in the simulator "
                                  "(zarco sim); give the device's serial path or tcp:// URL")
            if scheme not in schemes:
                raise ConfigError(file, k, f"{url}: unknown device scheme "
                                  f"{scheme or '(none)'!r}; expected "
                                  + ", ".join(f"{s}://" for s in schemes)
                                  + " or a serial path")
            ident = _device_key(url)
            if ident in seen:
                raise ConfigError(file, k, f"{url} is the same device as {seen[ident]}")
            seen[ident] = k
    if mission is not None and mission.kind != "idle":
        needs = ["gps", "compass", "thrusters"] + (["buoy"] if mission.kind == "follow" else [])
        for name in needs:
            if not getattr(cfg.devices, name).enabled:
                what = "the buoy feed" if name == "buoy" else f"the {name}"
                raise ConfigError(file, "mission.kind", f"a {mission.kind} mission needs "
                                  f"{what}, but devices.{name}.enabled = false")


def boot_mission(cfg: RuntimeConfig, mc: MissionConfig | None, name: str = "mission"
                 ) -> Boot:
    """The configured mission as the supervisor's boot mission (autostart: false
    unless the file says so)."""
    if mc is None or mc.kind == "idle":
        return Boot()
    o = cfg.origin
    frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    if mc.kind == "follow":
        return Boot(Mission("follow", name=name, auv_plan=plan_points(mc, frame)),
                    bool(mc.autostart))
    legs = build_legs(mc, frame)
    wps: tuple[tuple[float, float], ...] = ()
    if mc.frame == "geodetic":
        wps = tuple((float(w[0]), float(w[1])) for w in mc.waypoints)
    return Boot(Mission("lines", tuple(legs), name, wps), bool(mc.autostart))
