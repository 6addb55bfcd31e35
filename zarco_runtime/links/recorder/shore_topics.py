"""The shore view's topics in a recording: what ``zarco shore foxglove`` shows
live, derived by the writer from the recorded messages, so that one Foxglove
layout serves a live boat and a recording alike.

* ``/shore/state`` (``zarco.shore.state``): the shore link's ``state`` object,
  at every vessel estimate (NavState) at most ``location_hz``, with the latest
  directive, guidance status, thruster command and status recorded before it;
* ``/shore/auv`` (``zarco.shore.auv``): the shore link's ``auv`` object, at
  every AUV track at most ``location_hz``;
* ``/foxglove/events`` (``foxglove.Log``): every event.

The objects are built by the shore link's own functions
(:mod:`zarco_runtime.links.shore.telemetry`) from the recorded fields, so they
are the link's, key for key.  Imported by the writer process only when it
records one of these topics.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

from zarco_core.auv_messages import AuvTrack
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    Event,
    FixQuality,
    GuidanceStatus,
    MissionProgress,
    Mode,
    NavState,
    ThrusterCommand,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.links.recorder.schema import foxglove_time, log_level
from zarco_runtime.links.shore import telemetry

T = TypeVar("T")

#: the recorded types whose latest record a state needs (schema name → key)
WATCHED = {"zarco.Directive": "directive", "zarco.GuidanceStatus": "guidance",
           "zarco.ThrusterCommand": "thrust", "zarco.VesselStatus": "status"}


def _make(cls: type[T], d: dict[str, Any], **over: Any) -> T:
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    return cls(**{**{k: v for k, v in d.items() if k in names}, **over})


def nav_state(d: dict[str, Any]) -> NavState:
    return _make(NavState, d, fix=FixQuality(int(d["fix"])), cov=tuple(d.get("cov") or ()))


def state(vessel: str, utc: float, nav: dict[str, Any], latest: dict[str, dict[str, Any]]
          ) -> dict[str, Any]:
    """The ``state`` object of the vessel estimate ``nav`` (a NavState record)."""
    n = nav_state(nav)
    g = latest.get("guidance")
    tc = latest.get("thrust")
    dr = latest.get("directive")
    st = latest.get("status")
    directive = (Directive(float(dr["t"]), int(dr.get("seq", 0)), Mode(dr["mode"]),
                           reason=str(dr.get("reason", ""))) if dr else None)
    status = (_make(VesselStatus, st, mission=_make(MissionProgress, st.get("mission") or {}),
                    failsafes=list(st.get("failsafes") or []))
              if st else None)
    return telemetry.state(vessel, utc, n.t, n, _make(GuidanceStatus, g) if g else None,
                           _make(ThrusterCommand, tc) if tc else None, directive, status)


def auv(utc: float, track: dict[str, Any], frame: LocalFrame, nav: dict[str, Any] | None
        ) -> dict[str, Any]:
    """The ``auv`` object of the track ``track`` (an AuvTrack record)."""
    tr = _make(AuvTrack, track, cov=tuple(track.get("cov") or ()))
    return telemetry.auv(utc, tr, frame, nav_state(nav) if nav else None)


def log(utc: float, ev: dict[str, Any]) -> dict[str, Any]:
    """The ``foxglove.Log`` of an event record (or of the shore ``event`` object)."""
    e = _make(Event, ev)
    return {"timestamp": foxglove_time(utc), "level": log_level(e.kind), "message": e.text,
            "name": f"{e.kind}/{e.source}", "file": "", "line": 0}
