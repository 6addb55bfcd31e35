"""Thruster controller driver: ``$PZTHR`` out, ``$PZTHS`` in (docs/protocols.md).

Each ThrusterCommand on the bus is written at once, in the publisher's
context (a bus listener, no scheduling delay; the write is non-blocking), and
the controller publishes one per control tick, so commands go out at the
control rate.  A watchdog
sends zero thrust when the controller has said nothing for ``hold_s``, and
the driver always writes zero before it exits (shutdown, crash of a sibling
task), so a stopping runtime stops the boat, not only the controller's 0.5 s
timeout.  Non-finite commands never reach the wire (they become zero and are
counted).
"""

from __future__ import annotations

import asyncio
import contextlib
import math

from drivers.nmea import NmeaError, NmeaFramer
from drivers.nmea_device import DeviceLink
from drivers.settings import Device
from drivers.thruster_protocol import encode_pzthr, parse_pzths
from drivers.transports import Ports, Transport, TransportError
from zarco_core.bus import Bus, Listen
from zarco_core.clock import Clock
from zarco_core.messages import HealthState, ThrusterCommand

#: silence from the controller after which the driver commands zero (s)
HOLD_S = 0.3
ZERO = encode_pzthr(0.0, 0.0)


class ThrusterDriver(DeviceLink):
    def __init__(self, cfg: Device, bus: Bus, clock: Clock, ports: Ports | None = None,
                 name: str = "thrusters", listen: Listen | None = None) -> None:
        super().__init__(name, cfg, bus, clock, ports)
        (listen or bus.listen)(ThrusterCommand, self.on_command)
        self.tr: Transport | None = None
        self.last_cmd_t = -math.inf
        self.last_sent: tuple[float, float] = (0.0, 0.0)

    def _send(self, data: bytes) -> None:
        tr = self.tr
        if tr is None:
            self.counters["not_sent_disconnected"] += 1
            return
        try:
            tr.write_nowait(data)
            self.counters["commands_sent"] += 1
            if self.raw is not None:
                self.raw("tx", self.clock.now(), data)
        except (TransportError, OSError) as exc:
            self.counters["write_errors"] += 1
            self.set_state(HealthState.DISCONNECTED, f"write failed: {exc}")
            self.tr = None

    def on_command(self, cmd: ThrusterCommand) -> None:
        """Put a command on the wire now; non-finite values become zero thrust."""
        u1, u2 = cmd.u1, cmd.u2
        if not (math.isfinite(u1) and math.isfinite(u2)):
            self.counters["nonfinite_commands"] += 1
            u1 = u2 = 0.0
        self.last_cmd_t = cmd.t
        self.last_sent = (u1, u2)
        self._send(encode_pzthr(u1, u2))

    async def run(self) -> None:
        try:
            async with asyncio.TaskGroup() as tg:
                tg.create_task(self.watch(), name=f"{self.name}.health")
                tg.create_task(self._io_loop(), name=f"{self.name}.status")
                tg.create_task(self._watchdog(), name=f"{self.name}.watchdog")
        finally:
            # last words: zero thrust, whatever ended us
            if self.tr is not None:
                with contextlib.suppress(Exception):
                    self.tr.write_nowait(ZERO)
                    self.counters["commands_sent"] += 1
                    if self.raw is not None:
                        self.raw("tx", self.clock.now(), ZERO)

    async def _watchdog(self) -> None:
        clock = self.clock
        while True:
            # wake when the last command would become too old
            await clock.sleep_until(max(clock.now() + HOLD_S / 4, self.last_cmd_t + HOLD_S))
            if clock.now() - self.last_cmd_t >= HOLD_S:
                self.counters["watchdog_zero"] += 1
                self.last_sent = (0.0, 0.0)
                self._send(ZERO)

    async def _io_loop(self) -> None:
        now = self.clock.now
        while True:
            tr = await self.open()
            self.tr = tr
            framer = NmeaFramer()
            try:
                while True:
                    chunk = await self.read_or_reopen(tr)
                    t = now()
                    for line in framer.feed(chunk):
                        try:
                            st = parse_pzths(line, t)
                        except NmeaError as exc:
                            self.counters[exc.reason] += 1
                            continue
                        self.counters["status_ok"] += 1
                        self.last_ok = t
                        if self.state is not HealthState.OK:
                            self.set_state(HealthState.OK)
                        self.bus.publish(st)
            except (TransportError, OSError) as exc:
                self.counters["reconnects"] += 1
                self.set_state(HealthState.DISCONNECTED, str(exc))
            finally:
                self.tr = None
                with contextlib.suppress(Exception):  # last words before the port closes
                    tr.write_nowait(ZERO)
                    self.counters["commands_sent"] += 1
                    if self.raw is not None:
                        self.raw("tx", self.clock.now(), ZERO)
                with contextlib.suppress(Exception):
                    await tr.close()
