"""The simulated-hardware backend's devices, on the runtime's clock.

The simulated devices write real NMEA bytes into the device end of in-memory
ports (``sim://gps``, ``sim://compass``, ``sim://thrusters``, ``sim://buoy``)
at their rates, after advancing the world to the current time.  One
scheduler task serves every periodic device (a heap of due times, as a
discrete-event simulator does), so a device costs no task switch of its own.
The simulated thruster controller reacts to ``$PZTHR`` bytes as they arrive,
parses them with the project's protocol parser and applies the valid ones.

Every write goes through the scenario's fault plan (``[[faults]]``, the same
schedule and the same :class:`~drivers.sim.faults.FaultPlan` as HIL):
a device can be unplugged (its port vanishes and comes back), silent,
frozen, noisy, truncated, split or given bad checksums, and the GPS can
change fix type, all at simulation speed.
"""

from __future__ import annotations

import heapq
from collections import Counter
from collections.abc import Callable

from drivers.nmea import NmeaError, NmeaFramer
from drivers.sim.acoustics import AcousticWorld
from drivers.sim.faults import FaultPlan, FaultSpec
from drivers.sim.ports import SimPorts
from drivers.sim.world import SimWorld
from drivers.thruster_protocol import parse_pzthr
from drivers.transports import TransportError
from zarco_core.clock import Clock

#: rate of $PZTHS status from the simulated thruster controller (Hz)
STATUS_RATE_HZ = 5.0

Emitter = Callable[[float], None]


class SimBackend:
    """GPS, compass/IMU, thruster controller (and buoy) of a :class:`SimWorld`."""

    def __init__(self, world: SimWorld, ports: SimPorts, clock: Clock,
                 faults: list[FaultSpec] | None = None, seed: int = 0) -> None:
        self.world = world
        self.clock = clock
        self.ports = ports
        self.plan = FaultPlan(list(faults or []), seed)
        self.base_fix = world.params.gps.fix
        for name in ("gps", "compass", "thrusters"):
            ports.create(name)
        self.counters: Counter[str] = Counter()
        self.events: list[tuple[float, str, str]] = []
        self._framer = NmeaFramer()
        ports.device_end("thrusters").on_receive(self._on_thruster_bytes)
        self._last_noise: dict[str, float] = {}
        self._moving = False
        w = world
        self._devices: list[tuple[float, Emitter]] = [
            (w.params.gps.rate_hz, self._gps),
            (w.params.compass.rate_hz, lambda t: self.emit("compass", t, w.compass_bytes(t))),
            (STATUS_RATE_HZ, lambda t: self.emit("thrusters", t, w.thruster_status_bytes(t))),
        ]

    # ------------------------------------------------------------- faults

    def _plug(self, name: str, t: float) -> bool:
        """Apply unplug/replug at ``t``; True if the device is plugged."""
        want = self.plan.plugged(name, t)
        have = self.ports.plugged(name)
        if want and not have:
            self.ports.replug(name)
            self.events.append((t, name, "replugged"))
        elif not want and have:
            self.ports.unplug(name)
            self.events.append((t, name, "unplugged"))
        return want

    def emit(self, name: str, t: float, data: bytes) -> None:
        """Write a device's bytes at ``t`` through the fault plan."""
        plan = self.plan
        if plan.faults:
            if not self._plug(name, t):
                return
            t0 = self._last_noise.get(name, t)
            self._last_noise[name] = t
            junk = plan.noise(name, t0, t) if t > t0 else b""
            chunks, _gap = plan.shape(name, t, data)
            data = junk + b"".join(chunks)
        if data:
            try:
                self.ports.device_end(name).write_nowait(data)
            except TransportError:
                # the runtime has its end closed (reopening the port after a fault):
                # a real device goes on sending into the void, and so does this one
                self.counters[f"{name}_bytes_unheard"] += len(data)

    def _gps(self, t: float) -> None:
        if self.plan.faults:
            mode = self.plan.fix_mode(t, self.base_fix)
            if mode != self.world.gps.fix:
                self.world.set_fix(mode)
                self.events.append((t, "gps", f"fix {mode}"))
        self.emit("gps", t, self.world.gps_bytes(t))

    # ------------------------------------------------------------ devices

    def add_acoustics(self, acoustics: AcousticWorld, rate_hz: float = 20.0) -> None:
        """Serve the buoy feed (``sim://buoy``): every ``$PZBAE``/``$PZBST``
        sentence is written at the first device tick after its report time."""
        self.ports.create("buoy")

        def emit(t: float) -> None:
            data = b"".join(b for _t, b in acoustics.events_until(t))
            if data or self.plan.faults:
                self.emit("buoy", t, data)

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
            moving = u1 != 0.0 or u2 != 0.0
            if moving != self._moving:  # thrust on/off as the controller sees it
                self._moving = moving
                self.events.append((t, "thrusters", "thrust" if moving else "zero"))
            self.world.command(t, u1, u2)
