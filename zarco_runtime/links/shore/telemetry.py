"""The shore link's telemetry payloads, built from bus messages (pure functions).

Every object has ``t``, UTC seconds since the epoch; angles are degrees
clockwise from true north in [0, 360); a value the boat does not know is
``null``.  Field by field:

``state`` (5 Hz)
    ``mode`` (idle, manual, lines, follow, hold, return), ``lat_deg``,
    ``lon_deg`` (WGS-84), ``heading_deg``, ``course_deg`` and ``speed_mps``
    over ground, ``fix`` (none, single, dgps, rtk_float, rtk_fixed), ``leg``
    (0-based index of the active leg) of ``legs``, ``xtrack_m`` (cross-track
    error, + to starboard of the line), ``u1``, ``u2`` (thruster commands,
    −100..100, port and starboard), ``failsafes`` (active conditions); also
    ``vessel``, ``armed``, ``pos_valid``, ``heading_valid``, ``reason`` (why the
    vessel is in its mode).
``health`` (1 Hz)
    ``devices``: {name: {``state`` (ok, stale, disconnected, faulty),
    ``age_s`` since its last valid sentence, ``ok`` sentences accepted,
    ``bad`` refused, ``reason``, ``counters`` (the driver's: refusals by
    reason, reconnections, RTCM3 frames passed ``rtcm_frames``, bad
    ``rtcm_bad_frames``, bytes dropped ``rtcm_dropped_bytes``)}}; also
    ``components`` {name: {state, restarts}} and the ``link``'s own counters.
``auv`` (per track update)
    the AUV's estimated ``lat_deg``, ``lon_deg``, ``course_deg``,
    ``speed_mps``, ``status`` (acquiring, tracking, turning, stale, lost),
    ``distance_m``, the horizontal distance from the vessel, ``pos_cov_m2``
    [north², north·east, east²] (m²), the covariance of that position (the
    fitted line's at the message's time: its 1σ ellipse on a map), and
    ``sound_speed_mps``, ``sound_speed_sigma_mps``: the sound speed the
    tracker computes the ranges with (its online estimate) and its 1σ.
``event`` (per event)
    ``kind`` (mode, failsafe, ack, fault, component, mission), ``text``,
    ``source``.
"""

from __future__ import annotations

import math
from typing import Any

from zarco_core.auv_messages import AuvTrack, TrackFlags
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    Event,
    GuidanceStatus,
    NavState,
    ThrusterCommand,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive

#: guidance status older than this (s) no longer describes the mission (idle, manual)
GUIDANCE_FRESH_S = 1.0


def num(x: float | None, nd: int) -> float | None:
    """``x`` rounded to ``nd`` decimals; None for None, NaN or infinity (not JSON)."""
    if x is None or not math.isfinite(x):
        return None
    return round(x, nd)


def deg360(rad: float) -> float:
    return math.degrees(rad) % 360.0


def state(vessel: str, utc: float, now: float, nav: NavState | None,
          guid: GuidanceStatus | None, thrust: ThrusterCommand | None,
          directive: Directive | None, status: VesselStatus | None) -> dict[str, Any]:
    """The ``state`` object at runtime time ``now`` (UTC ``utc``)."""
    mode = (directive.mode.value if directive is not None
            else status.mode if status is not None else "idle")
    out: dict[str, Any] = {"t": round(utc, 3), "vessel": vessel, "mode": mode}
    if nav is not None:
        out.update(lat_deg=num(nav.lat_deg, 8), lon_deg=num(nav.lon_deg, 8),
                   heading_deg=num(deg360(nav.psi_rad), 2),
                   course_deg=num(deg360(math.atan2(nav.ve_mps, nav.vn_mps)), 2),
                   speed_mps=num(math.hypot(nav.vn_mps, nav.ve_mps), 3),
                   fix=nav.fix.label, pos_valid=nav.pos_valid,
                   heading_valid=nav.heading_valid)
    else:
        out.update(lat_deg=None, lon_deg=None, heading_deg=None, course_deg=None,
                   speed_mps=None, fix="none", pos_valid=False, heading_valid=False)
    if guid is not None and now - guid.t <= GUIDANCE_FRESH_S:
        out.update(leg=guid.leg if guid.leg >= 0 else None, legs=guid.legs,
                   xtrack_m=num(guid.xtrack_m, 3))
    elif status is not None and status.mission.legs:
        out.update(leg=status.mission.leg, legs=status.mission.legs, xtrack_m=None)
    else:
        out.update(leg=None, legs=0, xtrack_m=None)
    out.update(u1=num(thrust.u1, 1) if thrust else 0.0, u2=num(thrust.u2, 1) if thrust else 0.0)
    out["failsafes"] = list(status.failsafes) if status is not None else []
    out["armed"] = bool(status.armed) if status is not None else False
    out["reason"] = directive.reason if directive is not None else ""
    return out


def health(utc: float, status: VesselStatus, link: dict[str, int]) -> dict[str, Any]:
    """The ``health`` object from the status snapshot."""
    devices = {name: {"state": d.state, "age_s": num(d.age_s, 3), "ok": d.ok, "bad": d.bad,
                      "reason": d.reason, "counters": dict(d.counters)}
               for name, d in status.devices.items()}
    comps = {name: {"state": c.state, "restarts": c.restarts}
             for name, c in status.components.items()}
    return {"t": round(utc, 3), "mode": status.mode, "devices": devices, "components": comps,
            "link": dict(link)}


def auv_status(flags: int, lost: bool) -> str:
    f = TrackFlags(flags)
    if lost or TrackFlags.LOST in f:
        return "lost"
    if TrackFlags.STALE in f:
        return "stale"
    if TrackFlags.INITIALISED not in f:
        return "acquiring"
    if TrackFlags.TURNING in f:
        return "turning"
    return "tracking"


def line_position_cov(cov: tuple[float, ...], dt: float) -> list[float | None] | None:
    """[north², north·east, east²] (m²): the covariance of x0 + vx·dt, y0 + vy·dt
    from the 4×4 covariance of (x0, y0, vx, vy) (row-major); None if it is not 4×4."""
    if len(cov) != 16:
        return None
    c = cov
    nn = c[0] + 2.0 * dt * c[2] + dt * dt * c[10]
    ee = c[5] + 2.0 * dt * c[7] + dt * dt * c[15]
    ne = c[1] + dt * (c[3] + c[9]) + dt * dt * c[11]
    return [num(nn, 4), num(ne, 4), num(ee, 4)]


def auv(utc: float, track: AuvTrack, frame: LocalFrame, nav: NavState | None
        ) -> dict[str, Any]:
    """The ``auv`` object: the track's line model evaluated at the message's time."""
    dt = track.t - track.t0
    x = track.x0_m + track.vx_mps * dt
    y = track.y0_m + track.vy_mps * dt
    dist = None
    if math.isfinite(x) and math.isfinite(y):
        lat, lon, _ = frame.to_geodetic(x, y)
        if nav is not None and nav.pos_valid:
            age = track.t - nav.t
            dist = math.hypot(nav.x_m + nav.vn_mps * age - x, nav.y_m + nav.ve_mps * age - y)
    else:
        lat = lon = math.nan
    return {"t": round(utc, 3), "lat_deg": num(lat, 8), "lon_deg": num(lon, 8),
            "course_deg": num(deg360(track.psi_auv_rad), 2),
            "speed_mps": num(track.v_auv_mps, 3),
            "status": auv_status(track.flags, track.lost), "distance_m": num(dist, 2),
            "pos_cov_m2": line_position_cov(track.cov, dt),
            "sound_speed_mps": num(track.sound_speed_mps, 2),
            "sound_speed_sigma_mps": num(track.sound_speed_sigma_mps, 2)}


def event(utc: float, ev: Event) -> dict[str, Any]:
    return {"t": round(utc, 3), "kind": ev.kind, "text": ev.text, "source": ev.source}
