"""The simulated-hardware backend's device tasks, on the runtime's clock.

Each simulated device is a task that writes real NMEA bytes into the device
end of an in-memory port (``sim://gps``, ``sim://compass``,
``sim://thrusters``) at its rate, after advancing the world to the current
time; the simulated thruster controller reads ``$PZTHR`` bytes, parses them
with the project's protocol parser and applies valid commands.  The same
world model serves HIL, where the ports are pseudo-terminals instead.
"""

from __future__ import annotations

import asyncio
from collections import Counter
from collections.abc import Callable

from drivers.nmea import NmeaError, NmeaFramer
from drivers.sim.world import SimWorld
from drivers.thruster_protocol import parse_pzthr
from drivers.transports import MemoryTransport, SimPorts
from zarco_runtime.clock import Clock

#: rate of $PZTHS status from the simulated thruster controller (Hz)
STATUS_RATE_HZ = 10.0


class SimBackend:
    """GPS, compass/IMU and thruster controller of a :class:`SimWorld`."""

    def __init__(self, world: SimWorld, ports: SimPorts, clock: Clock) -> None:
        self.world = world
        self.clock = clock
        self.gps_port: MemoryTransport = ports.create("gps")
        self.compass_port: MemoryTransport = ports.create("compass")
        self.thruster_port: MemoryTransport = ports.create("thrusters")
        self.counters: Counter[str] = Counter()

    def tasks(self) -> list[tuple[str, Callable[[], object]]]:
        return [
            ("gps", self.gps),
            ("compass", self.compass),
            ("thruster_controller", self.thruster_controller),
            ("thruster_status", self.thruster_status),
        ]

    async def _periodic(self, rate_hz: float, emit: Callable[[float], bytes],
                        port: MemoryTransport) -> None:
        clock, world = self.clock, self.world
        period = 1.0 / rate_hz
        k = 0
        while True:
            k += 1
            await clock.sleep_until(k * period)
            t = clock.now()
            world.advance_to(t)
            data = emit(t)
            if data:
                port.write_nowait(data)

    async def gps(self) -> None:
        await self._periodic(self.world.params.gps.rate_hz, self.world.gps_bytes, self.gps_port)

    async def compass(self) -> None:
        await self._periodic(self.world.params.compass.rate_hz, self.world.compass_bytes,
                             self.compass_port)

    async def thruster_status(self) -> None:
        await self._periodic(STATUS_RATE_HZ, self.world.thruster_status_bytes,
                             self.thruster_port)

    async def thruster_controller(self) -> None:
        framer = NmeaFramer()
        port = self.thruster_port
        while True:
            chunk = await port.read()
            if not chunk:
                await asyncio.sleep(0.1)
                continue
            t = self.clock.now()
            for line in framer.feed(chunk):
                try:
                    u1, u2 = parse_pzthr(line)
                except NmeaError as exc:
                    self.counters[exc.reason] += 1
                    continue
                self.counters["commands"] += 1
                self.world.command(t, u1, u2)
