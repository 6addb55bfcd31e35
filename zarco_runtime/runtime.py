"""The runtime: one asyncio process, one named, supervised task per device or function.

The same :class:`Runtime` runs on the boat (real serial ports, monotonic
clock), in HIL (pseudo-terminals) and in simulation (the simulator's port
backend, virtual clock); only the port backend and the event loop differ.

Every component (device drivers, navigation, tracking, control, the
supervisor, the links) runs under :class:`~zarco_core.component.Supervised`:
an exception is logged with its traceback, counted, reported to the
supervisor (the ``component failed`` failsafe) and the component is
restarted with backoff; nothing a component does ends the process.  All
tasks run under one TaskGroup and are cancelled and awaited on exit; the
thruster driver writes zero thrust as its last act.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from dataclasses import dataclass

from drivers.buoy_parser import parse_buoy
from drivers.compass_parser import parse_compass
from drivers.gps_parser import parse_gps
from drivers.nmea_device import NmeaDevice
from drivers.thruster_driver import ThrusterDriver
from drivers.transports import Ports, SystemPorts
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.component import ComponentContext, Factory, Runnable, Supervised
from zarco_core.messages import ComponentState, HealthState, ThrusterCommand, VesselStatus
from zarco_runtime.control.task import ControlTask
from zarco_runtime.navigation.task import Navigation
from zarco_runtime.sd_notify import Notifier, devices_opened
from zarco_runtime.settings import RuntimeConfig
from zarco_runtime.supervision.local import ControlSocket
from zarco_runtime.supervision.state_file import StateFile
from zarco_runtime.supervision.supervisor import Boot, Capabilities, Supervisor
from zarco_runtime.tracking.task import Tracking

log = logging.getLogger("zarco.runtime")

#: components whose failure stops the boat (the ``component failed`` failsafe)
CONTROL_PATH = frozenset({"gps", "compass", "thrusters", "navigation", "control"})


@dataclass(slots=True)
class Instances:
    """The live instance of each component (replaced when one is restarted)."""

    gps: NmeaDevice | None = None
    compass: NmeaDevice | None = None
    thrusters: ThrusterDriver | None = None
    buoy: NmeaDevice | None = None
    navigation: Navigation | None = None
    tracking: Tracking | None = None
    control: ControlTask | None = None
    supervisor: Supervisor | None = None


class Runtime:
    """Builds every component from a validated configuration (nothing starts on error)."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus | None = None, clock: Clock | None = None,
                 ports: Ports | None = None, boot: Boot | None = None,
                 notify: tuple[str, int | None] | None = None,
                 config_dir: str = ".") -> None:
        self.cfg = cfg
        self.config_dir = config_dir  # relative paths of the configuration start here
        self.bus = bus or Bus()
        self.clock = clock or Clock()
        self.ports = ports or SystemPorts()
        self.boot = boot or Boot()
        self.live = Instances()
        dev = cfg.devices
        self.caps = Capabilities(dev.gps.enabled, dev.compass.enabled, dev.thrusters.enabled,
                                 dev.buoy.enabled)
        gps_var, cmp_var = dev.gps.variation_deg, dev.compass.variation_deg
        # device drivers keep their instance (and counters) across restarts
        self.gps = NmeaDevice("gps", dev.gps, self.bus, self.clock,
                              lambda line, t: parse_gps(line, t, "gps", gps_var), self.ports,
                              rtcm=True)
        self.compass = NmeaDevice("compass", dev.compass, self.bus, self.clock,
                                  lambda line, t: parse_compass(line, t, "compass", cmp_var),
                                  self.ports)
        self.buoy = NmeaDevice("buoy", dev.buoy, self.bus, self.clock,
                               lambda line, t: parse_buoy(line, t, "buoy"), self.ports)
        self._thrusters: ThrusterDriver | None = None
        #: the supervisor's state file, kept across its restarts
        self.state_file = StateFile(cfg.supervisor.state_file)
        self.components: list[Supervised] = []
        add = self._add
        # the links are imported only when enabled (zenoh, pymavlink and mcap are
        # heavy to load; a runtime without them starts faster)
        if cfg.record.enabled:
            from zarco_runtime.links.recorder.recorder import recorder_factory

            add("recorder", recorder_factory(cfg, self.bus, self.clock, self.boot, lambda: (
                self.gps, self.compass, self.buoy, self._thrusters), self.config_dir))
        if dev.gps.enabled:
            add("gps", lambda ctx: self._keep("gps", self.gps))
        if dev.compass.enabled:
            add("compass", lambda ctx: self._keep("compass", self.compass))
        if dev.thrusters.enabled:
            add("thrusters", self._make_thrusters)
        if dev.buoy.enabled:
            add("buoy", lambda ctx: self._keep("buoy", self.buoy))
            add("tracking", self._make_tracking)
        add("navigation", self._make_navigation)
        add("control", self._make_control)
        add("supervisor", self._make_supervisor)
        if cfg.supervisor.control_socket:
            add("local", lambda ctx: ControlSocket(cfg.supervisor.control_socket, self.bus,
                                                   self.clock, ctx.listen, cfg))
        if cfg.mavlink.enabled:
            from zarco_runtime.links.mavlink.endpoint import MavlinkEndpoint

            add("mavlink", lambda ctx: MavlinkEndpoint(cfg, self.bus, self.clock, ctx))
        if cfg.shore.enabled:
            from zarco_runtime.links.shore.link import ShoreLink

            add("shore", lambda ctx: ShoreLink(cfg, self.bus, self.clock, ctx))
        self.extra: list[tuple[str, Callable[[], object]]] = []
        self.notifier: Notifier | None = None
        if notify is not None:
            self.notifier = Notifier(notify[0], notify[1], self._ticks, self._supervisor_ok,
                                     devices_opened(self._device_states))
            self.bus.listen(VesselStatus, self.notifier.on_status)
            self.add_task("notify", self.notifier.run)

    def _ticks(self) -> int:
        c = self.live.control
        return c.ticks if c is not None else 0

    def _supervisor_ok(self) -> bool:
        """The supervisor runs and has evaluated its failsafes within the last second."""
        sup = self.live.supervisor
        comp = next((c for c in self.components if c.name == "supervisor"), None)
        return (sup is not None and comp is not None and comp.state == "running"
                and self.clock.now() - sup.last_eval < 1.0)

    def _device_states(self) -> list[HealthState]:
        out = []
        for name in ("gps", "compass", "thrusters", "buoy"):
            dev = getattr(self.live, name)
            if dev is not None:
                out.append(HealthState.DISCONNECTED if dev.reason == "not opened yet"
                           or dev.state is HealthState.DISCONNECTED else dev.state)
        return out

    # ------------------------------------------------------------ factories

    def _add(self, name: str, factory: Factory) -> None:
        self.components.append(Supervised(name, factory, self.bus, self.clock))

    def _keep(self, name: str, obj: NmeaDevice) -> NmeaDevice:
        setattr(self.live, name, obj)
        return obj

    def _make_thrusters(self, ctx: ComponentContext) -> Runnable:
        if self._thrusters is None:
            self._thrusters = ThrusterDriver(self.cfg.devices.thrusters, self.bus, self.clock,
                                             self.ports, listen=ctx.listen)
        else:  # same driver (counters), listener registered again for this run
            ctx.listen(ThrusterCommand, self._thrusters.on_command)
        self.live.thrusters = self._thrusters
        return self._thrusters

    def _make_navigation(self, ctx: ComponentContext) -> Runnable:
        self.live.navigation = Navigation(self.cfg, self.bus, self.clock, listen=ctx.listen)
        return self.live.navigation

    def _make_tracking(self, ctx: ComponentContext) -> Runnable:
        self.live.tracking = Tracking(self.cfg.tracker, self.bus, self.clock, listen=ctx.listen)
        return self.live.tracking

    def _make_control(self, ctx: ComponentContext) -> Runnable:
        self.live.control = ControlTask(self.cfg, self.bus, self.clock, listen=ctx.listen)
        return self.live.control

    def _make_supervisor(self, ctx: ComponentContext) -> Runnable:
        follow = frozenset({"buoy", "tracking"})
        self.live.supervisor = Supervisor(self.cfg, self.bus, self.clock, ctx, self.boot,
                                          self.caps, self.counters, CONTROL_PATH | follow,
                                          self.component_states, self.state_file)
        # a supervisor restarted after a failure boots idle: no second autostart
        self.boot = Boot(self.boot.mission, autostart=False)
        return self.live.supervisor

    # --------------------------------------------------------------- status

    def counters(self) -> dict[str, int]:
        """Counters of the control loop and of the components, for the status snapshot."""
        out: dict[str, int] = {}
        c = self.live.control
        if c is not None:
            out.update(control_ticks=c.ticks, control_saturated_ticks=c.saturated_ticks,
                       control_faults=c.faults)
        for comp in self.components:
            out[f"{comp.name}_restarts"] = comp.restarts
        return out

    def component_states(self) -> dict[str, ComponentState]:
        """Each supervised component's state, restarts and failures."""
        now = self.clock.now()
        return {c.name: ComponentState(now, c.name, c.state, c.restarts, c.failures,
                                       c.last_error) for c in self.components}

    def add_task(self, name: str, fn: Callable[[], object]) -> None:
        """Run an extra (unsupervised) task with the runtime (a link's server, say)."""
        self.extra.append((name, fn))

    def add_component(self, name: str, factory: Factory) -> None:
        """Run an extra supervised component (a link) with the runtime."""
        self._add(name, factory)

    async def run(self) -> None:
        """Run every component until cancelled."""
        log.info("runtime starting: %s", ", ".join(c.name for c in self.components))
        async with asyncio.TaskGroup() as tg:
            for comp in self.components:
                tg.create_task(comp.run(), name=comp.name)
            for name, fn in self.extra:
                tg.create_task(fn(), name=name)  # type: ignore[arg-type]
