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
import signal
import time
from collections.abc import Callable, Coroutine
from dataclasses import dataclass
from pathlib import Path
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
from zarco_core.messages import (
    CommandAck,
    Event,
    Fault,
    GuidanceStatus,
    NavState,
    ThrusterCommand,
)
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.guidance.mission import Leg, Mission, build_legs, plan_points
from zarco_runtime.runtime import Runtime
from zarco_runtime.supervision.local import LocalCommands
from zarco_runtime.supervision.supervisor import Boot
from zarco_tools.follow_report import finite_or_none, follow_figures
from zarco_tools.hold_report import hold_figures
from zarco_tools.scenario import Scenario
from zarco_tools.sim_report import TrackLog, line_figures
from zarco_tools.status_line import TtyLine

ProgressFn = Callable[[float, float, int, int], None]


@dataclass(slots=True)
class SimTruth:
    """The simulator's truth, on the bus only when a simulation is recorded
    (``zarco sim --record``), so that a recording can be plotted as ``zarco sim
    --plot`` plots the run: the vessel's true position ``x_m``, ``y_m`` (NED m)
    and heading ``psi_rad``, the active ``leg`` and the commands ``u1``, ``u2``
    then; the AUV's true position ``auv_x_m``, ``auv_y_m`` and course
    ``auv_psi_rad`` (NaN without an AUV)."""

    t: float
    x_m: float
    y_m: float
    psi_rad: float
    leg: int
    u1: float
    u2: float
    auv_x_m: float = math.nan
    auv_y_m: float = math.nan
    auv_psi_rad: float = math.nan


class _Stop(Exception):
    """Raised inside the task group to end the simulation."""


@dataclass(slots=True)
class SimResult:
    scenario: Scenario
    legs: list[Leg]
    log: TrackLog
    report: dict[str, Any]
    extra: dict[str, Any]


def boot_mission(scn: Scenario, legs: list[Leg]) -> Boot:
    """The scenario's mission as the runtime's boot mission."""
    if scn.mission.kind == "follow":
        o = scn.runtime.origin
        mission: Mission | None = Mission(
            "follow", name=scn.scenario.name,
            auv_plan=plan_points(scn.mission, LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)))
    elif scn.mission.kind == "lines" and legs:
        mission = Mission("lines", tuple(legs), scn.scenario.name)
    else:
        mission = None
    return Boot(mission, bool(scn.mission.autostart))


async def _simulate(scn: Scenario, legs: list[Leg], log: TrackLog,
                    progress: ProgressFn | None, counters: dict[str, Any]) -> None:
    world = SimWorld(scn.world, scn.scenario.seed)
    clock = Clock(utc_offset_s=world.utc_epoch_s(0.0))
    bus = Bus()
    ports = SimPorts()
    backend = SimBackend(world, ports, clock, scn.faults, scn.scenario.seed)
    follow = scn.mission.kind == "follow" or scn.runtime.devices.buoy.enabled
    acoustics: AcousticWorld | None = None
    if follow and scn.auv is not None and scn.lbl is not None:
        acoustics = AcousticWorld(scn.lbl, Auv(scn.auv), scn.scenario.seed + 1_000_003,
                                  world.utc_epoch_s(0.0),
                                  (scn.world.origin_lat_deg, scn.world.origin_lon_deg))
        backend.add_acoustics(acoustics)
        counters["acoustics"] = acoustics
        bus.tap(lambda m: counters.setdefault("auv_msgs", []).append(m)
                if isinstance(m, (AuvFix, AuvTrack)) else None)
    runtime = Runtime(scn.runtime, bus, clock, ports, boot_mission(scn, legs))
    counters["runtime"] = runtime
    if counters.get("realtime"):
        clock = Clock()  # real UTC: telemetry times are comparable with the shore's
        runtime.clock = clock
    guid = bus.latest(GuidanceStatus)
    cmd = bus.latest(ThrusterCommand)
    faults: list[str] = []
    bus.tap(lambda m: faults.append(m.reason) if isinstance(m, Fault) else None)
    realtime_stop = asyncio.Event()

    def on_fault(f: Fault) -> None:
        # a recording asked for and not written ends the run: nothing more of it
        # would be kept (the recorder has stopped for good)
        if f.source == "recorder" and "record_error" not in counters:
            counters["record_error"] = f.reason
            if counters.get("end_on_record_failure", True):
                counters["stop"] = f"recording failed at {clock.now():.1f} s"
                done.set()
                realtime_stop.set()

    bus.listen(Fault, on_fault)
    events: list[Event] = counters.setdefault("events", [])
    bus.listen(Event, events.append)
    acks: list[CommandAck] = counters.setdefault("acks", [])
    bus.listen(CommandAck, acks.append)
    directives: list[Directive] = counters.setdefault("directives", [])
    bus.listen(Directive, lambda d: directives.append(d)
               if not directives or directives[-1].seq != d.seq else None)
    limit = scn.scenario.max_duration_s
    done = asyncio.Event()

    #: (time s, mode) at every change of the guidance's mode: when the follow
    #: guidance first steered by the AUV's track (acquisition), when it held
    modes: list[tuple[float, str]] = counters.setdefault("guidance_modes", [])

    def on_guidance(g: GuidanceStatus) -> None:
        if not modes or modes[-1][1] != g.mode:
            modes.append((g.t, g.mode))
        if g.mode == "lines" and g.complete and not scn.commands:
            done.set()

    bus.listen(GuidanceStatus, on_guidance)

    every = int(max(1, 10 * scn.scenario.record_hz))
    auv_log: list[tuple[float, float, float, float]] = counters.setdefault("auv_log", [])

    nav = bus.latest(NavState)
    nav_err: list[NavError] = counters.setdefault("nav_err", [])
    recording = scn.runtime.record.enabled

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
        if recording:
            bus.publish(SimTruth(t, s.x_m, s.y_m, s.psi_rad, log.leg[-1], log.u1[-1],
                                 log.u2[-1], *(auv_log[-1][1:] if acoustics is not None
                                               else ())))
        if progress is not None and len(log.t) % every == 0:
            progress(t, limit, g.leg if g else 0, len(legs))

    backend.add_periodic(scn.scenario.record_hz, record)
    local = LocalCommands(bus, clock, source="scenario")

    async def script() -> None:
        for c in sorted(scn.commands, key=lambda c: c.at_s):
            await clock.sleep_until(c.at_s)
            await local.send(c.name, dict(c.args))

    async def supervisor() -> None:
        realtime = counters.get("realtime", False)
        stop = done
        if realtime:  # the boat runs until a signal or the time limit
            stop = realtime_stop
            loop = asyncio.get_running_loop()
            for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
                loop.add_signal_handler(sig, lambda s=sig: (counters.__setitem__(
                    "stop", f"signal {s.name}"), stop.set()))
        try:
            await asyncio.wait_for(stop.wait(), timeout=limit)
            counters.setdefault("stop", "mission complete")
        except TimeoutError:
            counters["stop"] = f"time limit {limit} s"
        counters["sim_seconds"] = clock.now()
        raise _Stop

    try:
        async with asyncio.TaskGroup() as tg:
            for name, fn in backend.tasks():
                tg.create_task(fn(), name=f"sim.{name}")
            tg.create_task(runtime.run(), name="runtime")
            tg.create_task(script(), name="sim.script")
            for i, extra in enumerate(counters.get("extra_tasks", [])):
                tg.create_task(extra(runtime), name=f"sim.extra{i}")
            tg.create_task(supervisor(), name="sim.supervisor")
    except* _Stop:
        pass
    ctl = runtime.live.control
    counters["control_ticks"] = ctl.ticks if ctl else 0
    counters["saturated_ticks"] = ctl.saturated_ticks if ctl else 0
    counters["faults"] = sorted(set(faults))
    counters["devices"] = {
        "gps": dict(runtime.gps.counters),
        "compass": dict(runtime.compass.counters),
        "thrusters": dict(runtime._thrusters.counters) if runtime._thrusters else {},
    }
    counters["sim_thruster_controller"] = backend.counters
    counters["sim_events"] = backend.events
    wt = world.thrusters
    counters["last_command"] = (wt.u1, wt.u2)
    if runtime.cfg.devices.buoy.enabled and runtime.live.tracking is not None:
        counters["devices"]["buoy"] = dict(runtime.buoy.counters)
        counters["tracker"] = runtime.live.tracking.tracker.counters()
    rec = next((c.instance for c in runtime.components if c.name == "recorder"), None)
    counters["record_paths"] = list(getattr(rec, "paths", []))


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


class RealTimeLoop(asyncio.SelectorEventLoop):
    """A normal event loop whose time starts at 0 when it is made (the simulated
    world's time origin): ``zarco sim --realtime``."""

    def __init__(self) -> None:
        super().__init__()
        self._t0 = time.monotonic()

    def time(self) -> float:
        return time.monotonic() - self._t0


ExtraTask = Callable[[Runtime], Coroutine[Any, Any, None]]


def run_scenario(scn: Scenario, progress: ProgressFn | None = None,
                 realtime: bool = False, extra_tasks: list[ExtraTask] | None = None,
                 record: str | None = None, end_on_record_failure: bool = True) -> SimResult:
    """Simulate ``scn`` to the end of its mission (or its time limit); with
    ``realtime``, at 1× on a real clock until a signal or the time limit, with
    whichever links the runtime's configuration enables; with ``record``, into
    that MCAP file (as ``zarco run`` records).  ``extra_tasks`` run beside the
    runtime (given it): a test's or benchmark's fake operator, say.

    A recording that fails (the recorder's Fault: a write error, the disk below
    ``record.min_free_mb``) ends the run (``extra["record_error"]`` says why)
    unless ``end_on_record_failure`` is false: then the run goes on without
    it, as the boat does.  ``extra["record_paths"]``: the files recorded."""
    if record:
        scn.runtime.record.enabled = True
        scn.runtime.record.file = str(Path(record).resolve())
    o = scn.runtime.origin
    legs = build_legs(scn.mission, LocalFrame(o.lat_deg, o.lon_deg, o.alt_m))
    log = TrackLog()
    counters: dict[str, Any] = {"extra_tasks": list(extra_tasks or []),
                                "end_on_record_failure": end_on_record_failure}
    w0 = time.perf_counter()
    if realtime:
        import datetime as dt

        counters["realtime"] = True
        scn.world.start_utc = dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
        loop = RealTimeLoop()
        try:
            asyncio.set_event_loop(loop)
            loop.run_until_complete(_simulate(scn, legs, log, progress, counters))
        finally:
            asyncio.set_event_loop(None)
            loop.close()
    else:
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
        **(line_figures(log, legs) if scn.mission.kind == "lines"
           else follow_figures(log, counters) if scn.mission.kind == "follow" else {}),
        **hold_figures(log, counters.get("directives", [])),
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

    def __init__(self, stream: Any = None) -> None:
        self.line = TtyLine(stream, time.perf_counter)
        self.w0 = time.perf_counter()

    def __call__(self, t: float, limit: float, leg: int, legs: int) -> None:
        if not self.line.due():
            return
        wall = self.line.last - self.w0
        speed = t / wall if wall > 0 else 0.0
        self.line.write(f"sim {t:7.1f} s  leg {leg + 1}/{legs}  {speed:6.0f}× real time")

    def close(self) -> None:
        self.line.end("\r" + " " * 60 + "\r")
