"""The live Foxglove view: shore telemetry → a Foxglove WebSocket server.

Every vessel heard over zenoh (the console's configuration and credentials)
gets the topics a recording holds (:data:`~zarco_runtime.links.recorder.schema.SHARED_TOPICS`),
with the same schemas:

=====================  ========================  ===============================
topic                  schema                    from the shore key
=====================  ========================  ===============================
``/foxglove/vessel``   ``foxglove.LocationFix``  ``state`` (with a valid position)
``/foxglove/auv``      ``foxglove.LocationFix``  ``auv`` (a track, not lost)
``/shore/state``       ``zarco.shore.state``     ``state``, as sent
``/shore/auv``         ``zarco.shore.auv``       ``auv``, as sent
``/foxglove/events``   ``foxglove.Log``          ``event``
=====================  ========================  ===============================

under ``/<vessel>/…`` for each vessel, and, for the *primary* vessel (the
console's ``vessel``, ``--vessel``, or the first heard), also under the bare
names a recording uses, so the shipped layout shows it live as it shows a
recording.  A message's log time is the boat's ``t`` (UTC).  Nothing is sent
to the boats: the server offers no services or parameters.
"""

from __future__ import annotations

import json
import logging
import threading
from typing import Any

from zarco_runtime.links.recorder.schema import foxglove_time, shared_schema
from zarco_runtime.links.recorder.shore_topics import log as event_log

log = logging.getLogger("zarco.shore.foxglove")

BOAT_COLOR = {"r": 0.1, "g": 0.4, "b": 1.0, "a": 1.0}
AUV_COLOR = {"r": 1.0, "g": 0.3, "b": 0.1, "a": 1.0}


def _fix(t: float, what: str, lat: float, lon: float, cov: list[float] | None,
         color: dict[str, float]) -> dict[str, Any]:
    if cov and len(cov) == 3 and all(isinstance(c, (int, float)) for c in cov):
        nn, ne, ee = cov  # (north, east) → East-North-Up, row-major
        pc, kind = [ee, ne, 0.0, ne, nn, 0.0, 0.0, 0.0, 0.0], 3
    else:
        pc, kind = [0.0] * 9, 0
    return {"timestamp": foxglove_time(t), "frame_id": what, "latitude": lat,
            "longitude": lon, "altitude": 0.0, "position_covariance": pc,
            "position_covariance_type": kind, "color": color}


def messages(kind: str, obj: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """The (topic, message) pairs of one shore sample."""
    t = obj.get("t")
    if not isinstance(t, (int, float)):
        return []
    lat, lon = obj.get("lat_deg"), obj.get("lon_deg")
    located = isinstance(lat, (int, float)) and isinstance(lon, (int, float))
    if kind == "state":
        out = [("/shore/state", obj)]
        if located and obj.get("pos_valid", True):
            out.append(("/foxglove/vessel", _fix(t, "vessel", lat, lon, None, BOAT_COLOR)))
        return out
    if kind == "auv":
        out = [("/shore/auv", obj)]
        if located and obj.get("status") not in ("acquiring", "lost"):
            out.append(("/foxglove/auv", _fix(t, "auv", lat, lon, obj.get("pos_cov_m2"),
                                              AUV_COLOR)))
        return out
    if kind == "event":
        return [("/foxglove/events", event_log(t, {"t": t, "kind": str(obj.get("kind", "")),
                                                   "text": str(obj.get("text", "")),
                                                   "source": str(obj.get("source", ""))}))]
    return []


class Bridge:
    """Shore samples → Foxglove channels (thread-safe: zenoh calls from its threads)."""

    def __init__(self, primary: str = "") -> None:
        import foxglove

        self.foxglove = foxglove
        self.ctx = foxglove.Context()
        self.primary = primary
        self.channels: dict[str, Any] = {}
        self.lock = threading.Lock()
        self.logged = 0
        self.server: Any = None

    def start(self, host: str, port: int) -> Any:
        self.server = self.foxglove.start_server(name="zarco shore", host=host, port=port,
                                                 context=self.ctx)
        return self.server

    def stop(self) -> None:
        if self.server is not None:
            self.server.stop()
            self.server = None

    def _channel(self, topic: str, shared: str) -> Any:
        ch = self.channels.get(topic)
        if ch is None:
            name, data = shared_schema(shared)
            fg = self.foxglove
            ch = fg.Channel(topic, message_encoding="json", context=self.ctx,
                            schema=fg.Schema(name=name, encoding="jsonschema", data=data))
            self.channels[topic] = ch
        return ch

    def on_sample(self, vessel: str, kind: str, obj: Any, _now: float = 0.0) -> None:
        """A shore sample (the console client's callback)."""
        if not isinstance(obj, dict):
            return
        msgs = messages(kind, obj)
        if not msgs:
            return
        ns = int(float(obj["t"]) * 1e9)
        with self.lock:
            if not self.primary:
                self.primary = vessel
                log.info("primary vessel: %s", vessel)
            prefixes = [f"/{vessel}"] + ([""] if vessel == self.primary else [])
            for topic, m in msgs:
                data = json.dumps(m, separators=(",", ":")).encode()
                for p in prefixes:
                    self._channel(p + topic, topic).log(data, log_time=ns)
                    self.logged += 1


