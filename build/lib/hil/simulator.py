"""The HIL simulator: the simulated world behind one pseudo-terminal per device.

The same :class:`drivers.sim.world.SimWorld` as ``zarco sim`` (vessel,
disturbances, GPS, compass, thruster controller, one seed), connected the
other way: on the monotonic clock, in real time, through pseudo-terminals
(:class:`hil.ptys.PtyPort`) that the runtime opens as serial ports.

* GPS (``RUN/dev/gps``) and compass (``RUN/dev/compass``) write their
  sentences at their rates, exactly as in ``zarco sim`` (same emitters, same
  call times t = k / rate, so the same seed gives the same noise);
* the thruster controller (``RUN/dev/thrusters``) writes ``$PZTHS`` at 5 Hz and
  applies every valid ``$PZTHR`` read from the port as it arrives (the world is
  advanced to the arrival time first), which closes the loop;
* when the scenario follows the AUV (``[mission] kind = "follow"``, ``[auv]``,
  ``[lbl]``), the buoy (``RUN/dev/buoy``) writes the LBL listener's
  ``$PZBAE`` / ``$PZBST`` sentences of :class:`drivers.sim.acoustics.AcousticWorld`
  (the same acoustic world and seed as ``zarco sim``) at the first 20 Hz tick
  after each report time;
* the fault schedule (:class:`drivers.sim.faults.FaultPlan`) decides, write
  by write, what each device really sends, and unplugs / replugs ports;
* the true track is recorded at ``scenario.record_hz``, with the active leg
  from a shadow copy of the runtime's line guidance run on the true position
  (the runtime's own guidance state is in another process), and the AUV's
  true position when following.

Times: ``t`` (s) is simulation time, the loop's monotonic time minus the
start; events also carry the wall-clock time (``time.time()``), to be matched
with the runtime's log.
"""

from __future__ import annotations

import asyncio
import contextlib
import heapq
import math
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivers.nmea import NmeaError, NmeaFramer
from drivers.sim.acoustics import AcousticWorld
from drivers.sim.auv import Auv
from drivers.sim.backend import STATUS_RATE_HZ
from drivers.sim.faults import FaultPlan, FaultSpec
from drivers.sim.world import SimWorld
from drivers.thruster_protocol import parse_pzthr
from hil.ptys import PtyPort
from zarco_runtime.guidance.lines import LineGuidance
from zarco_runtime.guidance.mission import Leg
from zarco_tools.scenario import Scenario
from zarco_tools.sim_report import TrackLog

#: how often the ports are checked for the runtime opening / closing them (s)
ATTACH_POLL_S = 0.005
#: noise bursts are written in slices this long (s)
NOISE_SLICE_S = 0.01
#: the buoy feed is written at this rate (s⁻¹), as in zarco sim (drivers/sim/backend.py)
BUOY_RATE_HZ = 20.0
#: the acoustic world's seed is the scenario's plus this (as in zarco sim)
ACOUSTIC_SEED_OFFSET = 1_000_003


@dataclass(slots=True)
class Event:
    t: float  # simulation time (s)
    wall: float  # time.time()
    device: str
    what: str
    detail: str = ""

    def as_dict(self) -> dict[str, Any]:
        d = {"t": round(self.t, 4), "wall": round(self.wall, 4), "device": self.device,
             "what": self.what}
        if self.detail:
            d["detail"] = self.detail
        return d


class DeviceOut:
    """Ordered output of one device: immediate writes, or paced pieces (split faults)."""

    def __init__(self, port: PtyPort) -> None:
        self.port = port
        self._q: deque[tuple[list[bytes], float]] = deque()
        self._task: asyncio.Task[None] | None = None

    def send(self, chunks: list[bytes], gap_s: float) -> None:
        if not chunks:
            return
        if gap_s <= 0.0 and not self._q and self._task is None:
            for c in chunks:
                self.port.write(c)
            return
        self._q.append((chunks, gap_s))
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._drain())

    async def _drain(self) -> None:
        """Write the pieces ``gap`` apart on an absolute schedule: a late wake-up
        (a loaded machine) shortens the next gaps instead of delaying every piece
        after it, as a device's own clock would."""
        loop = asyncio.get_running_loop()
        try:
            due = loop.time()
            while self._q:
                chunks, gap = self._q.popleft()
                due = max(due, loop.time())
                for c in chunks:
                    self.port.write(c)
                    due += gap
                    delay = due - loop.time()
                    if gap > 0.0 and delay > 0.0:
                        await asyncio.sleep(delay)
        finally:
            self._task = None

    def cancel(self) -> None:
        self._q.clear()
        if self._task is not None:
            self._task.cancel()


@dataclass(slots=True)
class Timing:
    """Raw timing records (monotonic seconds)."""

    #: every valid $PZTHR read from the thruster port: (time, u1, u2)
    commands: list[tuple[float, float, float]] = field(default_factory=list)
    #: end of each GPS epoch write while no fault was active anywhere
    gps_writes: list[float] = field(default_factory=list)


#: the devices behind pseudo-terminals (and the buoy when following the AUV)
HIL_DEVICES = ("gps", "compass", "thrusters")
BUOY = "buoy"


def serves_buoy(scn: Scenario) -> bool:
    """Does the rig serve a buoy feed for this scenario (it follows the AUV)?"""
    return scn.runtime.devices.buoy.enabled and scn.auv is not None and scn.lbl is not None


class HilSimulator:
    """World + devices + faults behind pseudo-terminals in ``run_dir/dev``."""

    def __init__(self, scn: Scenario, faults: list[FaultSpec], legs: list[Leg],
                 run_dir: str | Path) -> None:
        self.scn = scn
        seed = scn.scenario.seed
        self.world = SimWorld(scn.world, seed)
        self.plan = FaultPlan(faults, seed)
        self.base_fix = scn.world.gps.fix
        self.legs = legs
        g = scn.runtime.guidance
        self.guidance = LineGuidance(legs, g.switching, math.radians(g.turn_rate_dps)) \
            if legs else None
        self.leg = 0
        self.complete = asyncio.Event()
        self.acoustics: AcousticWorld | None = None
        if serves_buoy(scn):
            assert scn.auv is not None and scn.lbl is not None
            w = scn.world
            self.acoustics = AcousticWorld(scn.lbl, Auv(scn.auv), seed + ACOUSTIC_SEED_OFFSET,
                                           self.world.utc_epoch_s(0.0),
                                           (w.origin_lat_deg, w.origin_lon_deg))
        self.devices = HIL_DEVICES + ((BUOY,) if self.acoustics is not None else ())
        self.dev_dir = Path(run_dir) / "dev"
        self.ports = {d: PtyPort(d, self.dev_dir / d) for d in self.devices}
        self.out = {d: DeviceOut(p) for d, p in self.ports.items()}
        self.links = {d: str(p.link) for d, p in self.ports.items()}
        self.attached = dict.fromkeys(self.devices, False)
        self.log = TrackLog()
        #: the AUV's true track when following: (t, north m, east m, heading rad)
        self.auv_log: list[tuple[float, float, float, float]] = []
        self.events: list[Event] = []
        self.timing = Timing()
        self.counters: Counter[str] = Counter()  # the thruster controller's
        self._framer = NmeaFramer()
        self._reading: set[str] = set()
        self.t0 = math.nan
        self.recording = False
        self.last_cmd = (0.0, 0.0)
        self.progress: Callable[[float], None] | None = None

    # ------------------------------------------------------------ time, events

    def now(self) -> float:
        """Simulation time (s since the start; negative before it)."""
        return asyncio.get_running_loop().time() - self.t0 if math.isfinite(self.t0) else 0.0

    def event(self, device: str, what: str, detail: str = "") -> None:
        self.events.append(Event(self.now(), time.time(), device, what, detail))

    # ------------------------------------------------------------------ ports

    def plug_all(self) -> None:
        for p in self.ports.values():
            p.plug()

    def close(self) -> None:
        loop = asyncio.get_running_loop()
        for name, p in self.ports.items():
            self.out[name].cancel()
            if name in self._reading:
                loop.remove_reader(p.master)
                self._reading.discard(name)
            p.close()

    def _start_reading(self, name: str) -> None:
        p = self.ports[name]
        if name not in self._reading and p.master >= 0:
            asyncio.get_running_loop().add_reader(p.master, self._on_readable, name)
            self._reading.add(name)

    def _stop_reading(self, name: str) -> None:
        if name in self._reading:
            with contextlib.suppress(ValueError, OSError):
                asyncio.get_running_loop().remove_reader(self.ports[name].master)
            self._reading.discard(name)

    def _on_readable(self, name: str) -> None:
        p = self.ports[name]
        data = p.read()
        if not data:
            if not p.attached():  # hang-up: nobody on the other side any more
                self._stop_reading(name)
            return
        if name != "thrusters":
            self.counters[f"{name}_bytes_from_runtime"] += len(data)
            return
        tm = asyncio.get_running_loop().time()
        t = tm - self.t0 if math.isfinite(self.t0) else 0.0
        for line in self._framer.feed(data):
            try:
                u1, u2 = parse_pzthr(line)
            except NmeaError as exc:
                self.counters[exc.reason] += 1
                continue
            self.counters["commands"] += 1
            self.last_cmd = (u1, u2)
            self.timing.commands.append((tm, u1, u2))
            if math.isfinite(self.t0):
                self.world.command(max(t, self.world.t_s), u1, u2)

    async def watch_ports(self) -> None:
        """Follow the runtime opening and closing each port (POLLHUP on the master)."""
        while True:
            for name, p in self.ports.items():
                a = p.attached()
                if a != self.attached[name]:
                    self.attached[name] = a
                    self.event(name, "attached" if a else "detached")
                    if a:
                        if name == "thrusters":
                            self._framer.reset()
                        self._start_reading(name)
                    else:
                        if name in self._reading:  # what it wrote before closing
                            for _ in range(64):
                                if not self.ports[name].plugged:
                                    break
                                before = self.ports[name].counters["bytes_read"]
                                self._on_readable(name)
                                if self.ports[name].counters["bytes_read"] == before:
                                    break
                        self._stop_reading(name)
            await asyncio.sleep(ATTACH_POLL_S)

    async def wait_attached(self, timeout_s: float) -> bool:
        """Wait until the runtime has every port open."""
        loop = asyncio.get_running_loop()
        end = loop.time() + timeout_s
        while not all(self.attached.values()):
            if loop.time() > end:
                return False
            await asyncio.sleep(ATTACH_POLL_S)
        return True

    # ---------------------------------------------------------------- devices

    def _emit(self, device: str, t: float, data: bytes) -> bool:
        """Send a device's bytes through the fault plan; True if sent unharmed."""
        if not self.ports[device].plugged:
            return False
        chunks, gap = self.plan.shape(device, t, data)
        self.out[device].send(chunks, gap)
        return bool(chunks) and not self.plan.any_active(t)

    def _gps(self, t: float) -> None:
        mode = self.plan.fix_mode(t, self.base_fix)
        if mode != self.world.gps.fix:
            self.world.set_fix(mode)
            self.event("gps", "fix", mode)
        clean = self._emit("gps", t, self.world.gps_bytes(t))
        if clean and self.recording:
            self.timing.gps_writes.append(asyncio.get_running_loop().time())

    def _compass(self, t: float) -> None:
        self._emit("compass", t, self.world.compass_bytes(t))

    def _status(self, t: float) -> None:
        self._emit("thrusters", t, self.world.thruster_status_bytes(t))

    def _buoy(self, t: float) -> None:
        assert self.acoustics is not None
        data = b"".join(b for _t, b in self.acoustics.events_until(t))
        if data:
            self._emit(BUOY, t, data)

    def _record(self, t: float) -> None:
        if not self.recording:
            return
        s = self.world.truth()
        if self.guidance is not None:
            ls = self.guidance.update(s.x_m, s.y_m)
            self.leg = ls.leg.index
            if ls.complete:
                self.complete.set()
        u1, u2 = self.last_cmd
        self.log.add(t, s.x_m, s.y_m, s.psi_rad, self.leg, u1, u2)
        if self.acoustics is not None:
            a = self.acoustics.auv_truth(t)
            self.auv_log.append((t, a.x_m, a.y_m, a.psi_rad))
        if self.progress is not None:
            self.progress(t)

    def _noise(self, t: float, last: list[float]) -> None:
        for d in self.devices:
            if self.ports[d].plugged:
                junk = self.plan.noise(d, last[0], t)
                if junk:
                    self.out[d].send([junk], 0.0)
        last[0] = t

    def _apply_plugs(self) -> None:
        t = self.now()
        for d, p in self.ports.items():
            want = self.plan.plugged(d, t)
            if want and not p.plugged:
                p.plug()
                self.event(d, "replugged", p.pts)
            elif not want and p.plugged:
                self._stop_reading(d)
                self.out[d].cancel()
                p.unplug()
                self.attached[d] = False
                self.event(d, "unplugged")

    # -------------------------------------------------------------------- run

    async def _fault_edges(self) -> None:
        loop = asyncio.get_running_loop()
        for edge in self.plan.edges():
            delay = self.t0 + edge - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            self._apply_plugs()
            for f in self.plan.faults:
                if f.at_s == edge:
                    self.event(f.device, "fault", f.label)

    async def _periodic(self) -> None:
        w = self.scn.world
        devices: list[tuple[float, Callable[[float], None]]] = [
            (w.gps.rate_hz, self._gps),
            (w.compass.rate_hz, self._compass),
            (STATUS_RATE_HZ, self._status),
        ]
        if self.acoustics is not None:
            devices.append((BUOY_RATE_HZ, self._buoy))
        devices.append((self.scn.scenario.record_hz, self._record))
        if any(f.kind == "noise" for f in self.plan.faults):
            last = [0.0]
            devices.append((1.0 / NOISE_SLICE_S, lambda t: self._noise(t, last)))
        loop = asyncio.get_running_loop()
        heap = [(1.0 / rate, i, 1) for i, (rate, _fn) in enumerate(devices)]
        heapq.heapify(heap)
        while True:
            due = heap[0][0]
            delay = self.t0 + due - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            t = self.now()
            self.world.advance_to(t)
            while heap and heap[0][0] <= t + 1e-9:
                due, i, k = heapq.heappop(heap)
                rate, fn = devices[i]
                fn(due)  # the nominal time: the same emitter calls as zarco sim
                heapq.heappush(heap, ((k + 1) / rate, i, k + 1))

    def start(self) -> list[asyncio.Task[None]]:
        """Start the world clock now and the device tasks (cancel them to stop)."""
        loop = asyncio.get_running_loop()
        self.t0 = loop.time()
        self.recording = True
        self.event("sim", "start")
        return [loop.create_task(self._periodic(), name="hil.devices"),
                loop.create_task(self._fault_edges(), name="hil.faults")]
