"""The simulated-hardware backend's devices, on the runtime's clock.

The simulated devices write real NMEA bytes into the device end of in-memory
ports (``sim://gps``, ``sim://compass``, ``sim://thrusters``) at their rates,
after advancing the world to the current time.  One scheduler task serves
every periodic device (a heap of due times, as a discrete-event simulator
does), so a device costs no task switch of its own.  The simulated thruster
controller reacts to ``$PZTHR`` bytes as they arrive, parses them with the
project's protocol parser and applies the valid ones.  The same world model
serves HIL, where the ports are pseudo-terminals instead.
"""

from __future__ import annotations

import heapq
from collections import Counter
from collections.abc import Callable

from drivers.nmea import NmeaError, NmeaFramer
from drivers.sim.acoustics import AcousticWorld
from drivers.sim.ports import SimPorts
from drivers.sim.world import SimWorld
from drivers.thruster_protocol import parse_pzthr
from drivers.transports import MemoryTransport
from zarco_core.clock import Clock

#: rate of $PZTHS status from the simulated thruster controller (Hz)
STATUS_RATE_HZ = 5.0

Emitter = Callable[[float], None]


class SimBackend:
    """GPS, compass/IMU and thruster controller of a :class:`SimWorld`."""

    def __init__(self, world: SimWorld, ports: SimPorts, clock: Clock) -> None:
        self.world = world
        self.clock = clock
        self.ports = ports
        self.gps_port: MemoryTransport = ports.create("gps")
        self.compass_port: MemoryTransport = ports.create("compass")
        self.thruster_port: MemoryTransport = ports.create("thrusters")
        self.counters: Counter[str] = Counter()
        self._framer = NmeaFramer()
        self.thruster_port.on_receive(self._on_thruster_bytes)
        w = world
        self._devices: list[tuple[float, Emitter]] = [
            (w.params.gps.rate_hz, lambda t: self.gps_port.write_nowait(w.gps_bytes(t))),
            (w.params.compass.rate_hz,
             lambda t: self.compass_port.write_nowait(w.compass_bytes(t))),
            (STATUS_RATE_HZ,
             lambda t: self.thruster_port.write_nowait(w.thruster_status_bytes(t))),
        ]

    def add_acoustics(self, acoustics: AcousticWorld, rate_hz: float = 20.0) -> None:
        """Serve the buoy feed (``sim://buoy``): every ``$PZBAE``/``$PZBST``
        sentence is written at the first device tick after its report time."""
        port = self.ports.create("buoy")
        self.buoy_port = port

        def emit(t: float) -> None:
            data = b"".join(b for _t, b in acoustics.events_until(t))
            if data:
                port.write_nowait(data)

        self.add_periodic(rate_hz, emit)

    def add_periodic(self, rate_hz: float, fn: Emitter) -> None:
        """Call ``fn(t)`` at ``rate_hz`` after the world has advanced to ``t``
        (before starting; used for the true-track recorder)."""
        self._devices.append((rate_hz, fn))

    def tasks(self) -> list[tuple[str, Callable[[], object]]]:
        return [("devices", self.run_devices)]

    async def run_devices(self) -> None:
        """Emit every periodic device's output when it is due, in a fixed order."""
        clock, world = self.clock, self.world
        # (due time, device index, period index): ties resolve by device index
        heap = [(1.0 / rate, i, 1) for i, (rate, _fn) in enumerate(self._devices)]
        heapq.heapify(heap)
        while True:
            due, i, k = heap[0]
            await clock.sleep_until(due)
            t = clock.now()
            world.advance_to(t)
            while heap and heap[0][0] <= t + 1e-9:
                due, i, k = heapq.heappop(heap)
                rate, fn = self._devices[i]
                fn(t)
                heapq.heappush(heap, ((k + 1) / rate, i, k + 1))

    def _on_thruster_bytes(self, data: bytes) -> None:
        t = self.clock.now()
        for line in self._framer.feed(data):
            try:
                u1, u2 = parse_pzthr(line)
            except NmeaError as exc:
                self.counters[exc.reason] += 1
                continue
            self.counters["commands"] += 1
            self.world.command(t, u1, u2)
