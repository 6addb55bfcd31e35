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
from zarco_tools.follow_report import follow_figures
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
    nav_err: list[NavError] = counters.setdefault("nav_err", [])

    def record(t: float) -> None:
        s = world.truth()
        g = guid.value
        c = cmd.value
        n = nav.value
        if n is not None and n.pos_valid and n.heading_valid:
            # the estimate as the controller uses it: extrapolated to now
            age = t - n.t
            nav_err.append(NavError(
                t, n.x_m + n.vn_mps * age - s.x_m, n.y_m + n.ve_mps * age - s.y_m,
                math.remainder(n.psi_rad + n.r_rps * age - s.psi_rad, math.tau),
                n.vn_mps - s.vn_mps, n.ve_mps - s.ve_mps, g.leg if g else 0, n.cov))
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
#: the heading error is counted from this time (s): from the first valid estimate on
NAV_HEADING_SETTLE_S = 0.0


@dataclass(slots=True)
class NavError:
    """Estimate − truth at one true-track sample: time (s), position north/east (m),
    heading (rad, wrapped), ground velocity north/east (m/s), the active leg, and the
    estimate's covariance of (x, y, vn, ve, ψ) (NavState.cov)."""

    t: float
    ex: float
    ey: float
    epsi: float
    evn: float
    eve: float
    leg: int
    cov: tuple[float, ...]


def _rms(xs: list[float]) -> float:
    return math.sqrt(sum(x * x for x in xs) / len(xs)) if xs else math.nan


def nees5(e: NavError) -> float:
    """Normalised estimation error squared of (x, y, vn, ve, ψ) (χ²₅ when consistent)."""
    import numpy as np

    if len(e.cov) != 25:
        return math.nan
    P = np.array(e.cov).reshape(5, 5)
    v = np.array([e.ex, e.ey, e.evn, e.eve, e.epsi])
    try:
        return float(v @ np.linalg.solve(P, v))
    except np.linalg.LinAlgError:
        return math.inf


def nav_figures(err: list[NavError]) -> dict[str, Any]:
    """The navigation estimate (as the controller extrapolates it) against the
    simulator's truth: horizontal position RMS (m) from ``NAV_SETTLE_S``; heading
    RMS (deg) over the whole run and over the first leg, from
    ``NAV_HEADING_SETTLE_S``; NEES of (x, y, vn, ve, ψ) (mean over samples 1 s
    apart from ``NAV_SETTLE_S``; 5 when the covariance is honest) and the share of
    its samples above χ²₅'s 99 % quantile (0.01 when honest)."""
    e = [x for x in err if x.t >= NAV_SETTLE_S]
    h = [x for x in err if x.t >= NAV_HEADING_SETTLE_S]
    nees = [nees5(x) for x in e[::10]]
    return {
        "nav_position_rms_m": _rms([math.hypot(x.ex, x.ey) for x in e]),
        "nav_heading_rms_deg": math.degrees(_rms([x.epsi for x in h])),
        "nav_heading_first_leg_rms_deg": math.degrees(_rms([x.epsi for x in h
                                                            if x.leg == 0])),
        "nav_heading_max_deg": math.degrees(max((abs(x.epsi) for x in h), default=math.nan)),
        "nav_nees_mean": sum(nees) / len(nees) if nees else math.nan,
        "nav_nees_above_99": (sum(n > CHI2_5_99 for n in nees) / len(nees) if nees
                              else math.nan),
    }


#: χ² with 5 degrees of freedom, 99 % quantile
CHI2_5_99 = 15.086


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
    return SimResult(scn, legs, log, report, counters)


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
