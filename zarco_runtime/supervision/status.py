"""The supervisor's 1 Hz status snapshot (:func:`snapshot`): the mode, arming,
mission progress and the loaded mission's points, the active failsafes, each
device's health summarised, each component's state, home and the counters.
:func:`snapshot` is a function of the
:class:`~zarco_runtime.supervision.supervisor.Supervisor`, which owns the
state."""

from __future__ import annotations

from typing import TYPE_CHECKING

from zarco_core.messages import (
    ComponentState,
    DeviceHealth,
    DeviceSummary,
    MissionProgress,
    Mode,
    VesselStatus,
)
from zarco_runtime.supervision.missions import mission_points

if TYPE_CHECKING:
    from zarco_runtime.supervision.supervisor import Supervisor

#: counters of a device that are not refusals (the rest are reasons a sentence was dropped)
NOT_REFUSALS = frozenset({
    "bytes", "sentences_ok", "status_ok", "reconnects", "open_failures", "bytes_discarded",
    "corrections_bytes", "corrections_dropped_bytes", "corrections_source_errors",
    "commands_sent", "watchdog_zero", "not_sent_disconnected", "write_errors",
    "nonfinite_commands", "rtcm_frames", "rtcm_dropped_bytes", "rtcm_bad_frames",
})


def device_summaries(devices: dict[str, DeviceHealth], now: float) -> dict[str, DeviceSummary]:
    """Each device's state, reason, age of its last good sentence (s), sentences
    accepted (``ok``) and refused (``bad``)."""
    out: dict[str, DeviceSummary] = {}
    for name, h in devices.items():
        c = h.counters
        ok = c.get("sentences_ok", 0) + c.get("status_ok", 0)
        bad = sum(v for k, v in c.items() if k not in NOT_REFUSALS)
        age = None if h.last_ok_t is None else round(now - h.last_ok_t, 3)
        out[name] = DeviceSummary(h.state.value, h.reason, age, ok, bad, dict(c))
    return out


def shown_points(sup: Supervisor) -> tuple[tuple[float, float], ...]:
    """The waypoints of the lines mission loaded or running (its id changes with them)."""
    m = sup.mission if sup.mode is Mode.LINES and sup.mission is not None \
        else sup.loaded
    if m is not sup.shown[0]:
        pts = mission_points(m, sup.frame)
        if pts != sup.shown[1]:
            sup.mission_id += 1
        sup.shown = (m, pts)
    return sup.shown[1]


def snapshot(sup: Supervisor, now: float) -> VesselStatus:
    """The VesselStatus at ``now`` (runtime clock, s): what the shore, MAVLink,
    ``zarco ctl status`` and the recording show."""
    counters = dict(sup.counters_fn()) if sup.counters_fn is not None else {}
    counters["bus_published"] = sup.bus.published
    counters["bus_listener_errors"] = sup.bus.listener_errors
    counters["commands_accepted"] = sup.acks["accepted"]
    counters["commands_refused"] = sup.acks["refused"]
    counters["commands_rate_limited"] = sup.buckets.limited
    counters["command_faults"] = sup.command_faults
    counters["state_file_writes"] = sup.state.writes
    counters["state_file_write_errors"] = sup.state.write_errors
    home_lat = home_lon = None
    if sup.home is not None:
        home_lat, home_lon = home_geodetic(sup, sup.home)
    p = sup.progress
    prog = MissionProgress(p.kind, p.name, p.leg, p.legs, p.complete, p.xtrack_m, p.along_m,
                           p.phase)
    points = shown_points(sup)
    return VesselStatus(now, sup.clock.utc(now), sup.mode.value, sup.armed, prog,
                        sorted(sup.failsafes.active),
                        device_summaries(sup.health.devices, now),
                        components(sup), counters, sup.directive.reason,
                        home_lat, home_lon, points, sup.mission_id)


def home_geodetic(sup: Supervisor, home: tuple[float, float]) -> tuple[float, float]:
    """(lat, lon) degrees of ``home``, converted once per home (pymap3d costs
    a fraction of a millisecond a call, and a status goes out every second)."""
    if sup.home_ll is None or sup.home_ll[0] != home:
        lat, lon, _ = sup.frame.to_geodetic(*home)
        sup.home_ll = (home, (lat, lon))
    return sup.home_ll[1]


def components(sup: Supervisor) -> dict[str, ComponentState]:
    """Every component's state: the runtime's account, with what the bus said."""
    out = dict(sup.health.components)
    if sup.components_fn is not None:
        out.update(sup.components_fn())
    return out
