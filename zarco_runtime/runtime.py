"""The runtime: one asyncio process, one named task per device or function.

The same :class:`Runtime` runs on the boat (real serial ports, monotonic
clock), in HIL (pseudo-terminals) and in simulation (``sim://`` ports on the
virtual clock); only the device URLs and the event loop differ.  Tasks run
under one TaskGroup and are cancelled and awaited on exit; the thruster
driver writes zero thrust as its last act.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable

from drivers.buoy_parser import parse_buoy
from drivers.compass_parser import parse_compass
from drivers.gps_parser import parse_gps
from drivers.nmea_device import NmeaDevice
from drivers.thruster_driver import ThrusterDriver
from drivers.transports import Ports
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_runtime.control.task import ControlTask
from zarco_runtime.guidance.mission import Leg
from zarco_runtime.navigation.task import Navigation
from zarco_runtime.settings import RuntimeConfig
from zarco_runtime.tracking.task import Tracking

log = logging.getLogger("zarco.runtime")


class Runtime:
    """Builds every task from a validated configuration (nothing starts on error)."""

    def __init__(self, cfg: RuntimeConfig, legs: list[Leg], bus: Bus | None = None,
                 clock: Clock | None = None, ports: Ports | None = None,
                 mode: str = "lines") -> None:
        self.cfg = cfg
        self.bus = bus or Bus()
        self.clock = clock or Clock()
        dev = cfg.devices
        gps_var = dev.gps.variation_deg
        cmp_var = dev.compass.variation_deg
        self.gps = NmeaDevice(
            "gps", dev.gps, self.bus, self.clock,
            lambda line, t: parse_gps(line, t, "gps", gps_var), ports,
        )
        self.compass = NmeaDevice(
            "compass", dev.compass, self.bus, self.clock,
            lambda line, t: parse_compass(line, t, "compass", cmp_var), ports,
        )
        self.thrusters = ThrusterDriver(dev.thrusters, self.bus, self.clock, ports)
        self.navigation = Navigation(cfg, self.bus, self.clock)
        self.control = ControlTask(cfg, self.bus, self.clock, legs, mode)
        self.buoy: NmeaDevice | None = None
        self.tracking: Tracking | None = None
        if dev.buoy.enabled:
            self.buoy = NmeaDevice("buoy", dev.buoy, self.bus, self.clock,
                                   lambda line, t: parse_buoy(line, t, "buoy"), ports)
            self.tracking = Tracking(cfg.tracker, self.bus, self.clock)

    def tasks(self) -> list[tuple[str, Callable[[], object]]]:
        out: list[tuple[str, Callable[[], object]]] = []
        if self.cfg.devices.gps.enabled:
            out.append(("gps", self.gps.run))
        if self.cfg.devices.compass.enabled:
            out.append(("compass", self.compass.run))
        out.append(("thrusters", self.thrusters.run))
        if self.buoy is not None and self.tracking is not None:
            out.append(("buoy", self.buoy.run))
            out.append(("tracking", self.tracking.run))
        out.append(("control", self.control.run))
        return out

    async def run(self) -> None:
        """Run every task until cancelled (or one fails unrecoverably)."""
        log.info("runtime starting: %s", ", ".join(n for n, _ in self.tasks()))
        async with asyncio.TaskGroup() as tg:
            for name, fn in self.tasks():
                tg.create_task(fn(), name=name)  # type: ignore[arg-type]
