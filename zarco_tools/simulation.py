"""``zarco sim``: the runtime against the simulated backend, on the virtual clock.

One process, one event loop: the simulated devices (drivers.sim.backend)
write real NMEA bytes into in-memory ports; the *unchanged* runtime reads
them through its drivers, estimates, guides, controls and writes ``$PZTHR``
bytes back to the simulated thruster controller.  The virtual clock jumps
from event to event, so a mission simulates much faster than real time.
"""

from __future__ import annotations

import asyncio
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from drivers.sim.acoustics import AcousticWorld
from drivers.sim.auv import Auv
from drivers.sim.backend import SimBackend
from drivers.sim.ports import SimPorts
from drivers.sim.world import SimWorld
from zarco_core.auv_messages import AuvFix, AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock, run_virtual
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import Fault, GuidanceStatus, NavState, ThrusterCommand
from zarco_runtime.guidance.mission import Leg, build_legs
from zarco_runtime.runtime import Runtime
from zarco_tools.follow_report import finite_or_none, follow_figures
from zarco_tools.scenario import Scenario
from zarco_tools.sim_report import TrackLog, line_figures

ProgressFn = Callable[[float, float, int, int], None]


class _Stop(Exception):
    """Raised inside the task group to end the simulation."""


@dataclass(slots=True)
class SimResult:
    scenario: Scenario
    legs: list[Leg]
    log: TrackLog
    report: dict[str, Any]
    extra: dict[str, Any]


async def _simulate(scn: Scenario, legs: list[Leg], log: TrackLog,
                    progress: ProgressFn | None, counters: dict[str, Any]) -> None:
    world = SimWorld(scn.world, scn.scenario.seed)
    clock = Clock(utc_offset_s=world.utc_epoch_s(0.0))
    bus = Bus()
    ports = SimPorts()
    backend = SimBackend(world, ports, clock)
    follow = scn.mission.kind == "follow"
    acoustics: AcousticWorld | None = None
    if follow and scn.auv is not None and scn.lbl is not None:
        acoustics = AcousticWorld(scn.lbl, Auv(scn.auv), scn.scenario.seed + 1_000_003,
                                  world.utc_epoch_s(0.0),
                                  (scn.world.origin_lat_deg, scn.world.origin_lon_deg))
        backend.add_acoustics(acoustics)
        counters["acoustics"] = acoustics
        bus.tap(lambda m: counters.setdefault("auv_msgs", []).append(m)
                if isinstance(m, (AuvFix, AuvTrack)) else None)
    runtime = Runtime(scn.runtime, legs, bus, clock, ports=ports,
                      mode="follow" if follow else "lines")
    guid = bus.latest(GuidanceStatus)
    cmd = bus.latest(ThrusterCommand)
    faults: list[str] = []
    bus.tap(lambda m: faults.append(m.reason) if isinstance(m, Fault) else None)
    limit = scn.scenario.max_duration_s

    every = int(max(1, 10 * scn.scenario.record_hz))
    auv_log: list[tuple[float, float, float, float]] = counters.setdefault("auv_log", [])

    nav = bus.latest(NavState)
    nav_err: list[tuple[float, float, float, float]] = counters.setdefault("nav_err", [])

    def record(t: float) -> None:
        s = world.truth()
        g = guid.value
        c = cmd.value
        n = nav.value
        if n is not None and n.pos_valid and n.heading_valid:
            # the estimate as the controller uses it: extrapolated to now
            age = t - n.t
            nav_err.append((t, n.x_m + n.vn_mps * age - s.x_m, n.y_m + n.ve_mps * age - s.y_m,
                            math.remainder(n.psi_rad + n.r_rps * age - s.psi_rad, math.tau)))
        log.add(t, s.x_m, s.y_m, s.psi_rad, g.leg if g else 0,
                c.u1 if c else 0.0, c.u2 if c else 0.0)
        if acoustics is not None:
            a = acoustics.auv_truth(t)
            auv_log.append((t, a.x_m, a.y_m, a.psi_rad))
        if progress is not None and len(log.t) % every == 0:
            progress(t, limit, g.leg if g else 0, len(legs))

    backend.add_periodic(scn.scenario.record_hz, record)

    async def supervisor() -> None:
        done = runtime.control.complete if not follow else asyncio.Event()
        try:
            await asyncio.wait_for(done.wait(), timeout=limit)
            counters["stop"] = "mission complete"
        except TimeoutError:
            counters["stop"] = f"time limit {limit} s"
        counters["sim_seconds"] = clock.now()
        raise _Stop

    try:
        async with asyncio.TaskGroup() as tg:
            for name, fn in backend.tasks():
                tg.create_task(fn(), name=f"sim.{name}")
            tg.create_task(runtime.run(), name="runtime")
            tg.create_task(supervisor(), name="sim.supervisor")
    except* _Stop:
        pass
    counters["control_ticks"] = runtime.control.ticks
    counters["saturated_ticks"] = runtime.control.saturated_ticks
    counters["faults"] = sorted(set(faults))
    counters["devices"] = {
        "gps": dict(runtime.gps.counters),
        "compass": dict(runtime.compass.counters),
        "thrusters": dict(runtime.thrusters.counters),
    }
    counters["sim_thruster_controller"] = backend.counters
    ctl = world.thrusters
    counters["last_command"] = (ctl.u1, ctl.u2)
    if runtime.buoy is not None and runtime.tracking is not None:
        counters["devices"]["buoy"] = dict(runtime.buoy.counters)
        counters["tracker"] = runtime.tracking.tracker.counters()


#: navigation errors are counted from this time (s): the first fixes and headings
NAV_SETTLE_S = 10.0


def nav_figures(err: list[tuple[float, float, float, float]]) -> dict[str, Any]:
    """RMS of the navigation estimate (as the controller extrapolates it) against the
    simulator's truth from ``NAV_SETTLE_S``: horizontal position (m), heading (deg)."""
    e = [x for x in err if x[0] >= NAV_SETTLE_S]
    if not e:
        return {"nav_position_rms_m": math.nan, "nav_heading_rms_deg": math.nan}
    return {
        "nav_position_rms_m": math.sqrt(sum(a * a + b * b for _, a, b, _ in e) / len(e)),
        "nav_heading_rms_deg": math.degrees(math.sqrt(sum(p * p for *_, p in e) / len(e))),
    }


def command_step_rms(log: TrackLog) -> float:
    """RMS change of the thruster commands between true-track samples (% of full
    scale, both thrusters): how busy the thrusters are kept."""
    import numpy as np

    if len(log.u1) < 2:
        return 0.0
    du = np.concatenate([np.diff(log.u1), np.diff(log.u2)])
    return round(float(np.sqrt(np.mean(du * du))), 3)


def run_scenario(scn: Scenario, progress: ProgressFn | None = None) -> SimResult:
    """Simulate ``scn`` to the end of its mission (or its time limit)."""
    o = scn.runtime.origin
    legs = build_legs(scn.mission, LocalFrame(o.lat_deg, o.lon_deg, o.alt_m))
    log = TrackLog()
    counters: dict[str, Any] = {}
    w0 = time.perf_counter()
    run_virtual(_simulate(scn, legs, log, progress, counters))
    wall = time.perf_counter() - w0
    sim_s = float(counters.get("sim_seconds", log.t[-1] if log.t else 0.0))
    ticks = max(1, int(counters.get("control_ticks", 1)))
    report: dict[str, Any] = {
        "scenario": scn.scenario.name,
        "seed": scn.scenario.seed,
        "stop": counters.get("stop"),
        "sim_seconds": round(sim_s, 3),
        "wall_seconds": round(wall, 3),
        "speedup": round(sim_s / wall, 1) if wall > 0 else math.inf,
        **(line_figures(log, legs) if scn.mission.kind != "follow"
           else follow_figures(log, counters)),
        **nav_figures(counters.get("nav_err", [])),
        "saturation_fraction": counters.get("saturated_ticks", 0) / ticks,
        "command_step_rms": command_step_rms(log),
        "faults": counters.get("faults", []),
        "devices": counters.get("devices", {}),
        "sim_thruster_controller": counters.get("sim_thruster_controller", {}),
        "last_thruster_command": counters.get("last_command"),
        **({"tracker": counters["tracker"]} if "tracker" in counters else {}),
    }
    # JSON has no NaN: a figure that could not be computed is None
    return SimResult(scn, legs, log, finite_or_none(report), counters)


class StatusLine:
    """A running status on stderr: rewritten in place on a terminal, sparse otherwise."""

    def __init__(self, stream: Any = sys.stderr) -> None:
        self.stream = stream
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self.w0 = time.perf_counter()
        self.last = -1e9

    def __call__(self, t: float, limit: float, leg: int, legs: int) -> None:
        now = time.perf_counter()
        if now - self.last < (0.2 if self.tty else 5.0):
            return
        self.last = now
        wall = now - self.w0
        speed = t / wall if wall > 0 else 0.0
        msg = f"sim {t:7.1f} s  leg {leg + 1}/{legs}  {speed:6.0f}× real time"
        if self.tty:
            self.stream.write("\r" + msg)
        else:
            self.stream.write(msg + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write("\r" + " " * 60 + "\r")
            self.stream.flush()
