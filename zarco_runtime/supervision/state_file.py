"""The supervisor's state file: the last mission and how far it got, kept across
restarts (``supervisor.state_file``), written off the control path.

A write (JSON to a temporary file, ``fsync``, rename over the old one) takes
milliseconds on a busy SD card, and leg switches happen inside the control
tick, so the supervisor never writes itself: :meth:`StateFile.save` keeps the
newest state in memory and wakes :meth:`StateFile.run`, a task that writes it
on a worker thread (a burst of saves becomes one write of the last).  What was
saved and not yet written is written on the way out.  The instance outlives a
restarted supervisor, which takes the last state from memory rather than from
a file that may still be being written.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from zarco_runtime.guidance.mission import Leg, Mission

log = logging.getLogger("zarco.supervisor")


def mission_to_json(m: Mission) -> dict[str, Any]:
    return {"kind": m.kind, "name": m.name, "waypoints": [list(w) for w in m.waypoints],
            "legs": [[lg.n0, lg.e0, lg.n1, lg.e1, lg.speed_mps] for lg in m.legs],
            "auv_plan": [list(p) for p in m.auv_plan]}


def mission_from_json(d: dict[str, Any]) -> Mission:
    legs = tuple(Leg(i, *map(float, lg)) for i, lg in enumerate(d.get("legs", [])))
    wps = tuple((float(a), float(b)) for a, b in d.get("waypoints", []))
    plan = tuple((float(a), float(b)) for a, b in d.get("auv_plan", []))
    return Mission(str(d["kind"]), legs, str(d.get("name", "")), wps, plan)


@dataclass(slots=True)
class SavedMission:
    """The last lines/follow mission and how far it got (kept across restarts)."""

    mission: Mission
    leg: int = 0
    complete: bool = False


class StateFile:
    """The state file at ``path`` ("" : none), written by :meth:`run`."""

    def __init__(self, path: str) -> None:
        self.path = path
        self._latest: SavedMission | None = None
        self._loaded = False
        self._pending: dict[str, Any] | None = None
        self._wake: asyncio.Event | None = None
        self._lock = threading.Lock()  # one write at a time (a cancelled one may still run)
        self.writes = 0
        self.write_errors = 0

    def load(self) -> SavedMission | None:
        """The last saved state: this process's own if it saved one, else the file's."""
        if self._loaded:
            return self._latest
        self._loaded = True
        path = self.path
        if not path or not os.path.exists(path):
            return None
        try:
            d = json.loads(Path(path).read_text())
            self._latest = SavedMission(mission_from_json(d["mission"]), int(d.get("leg", 0)),
                                        bool(d.get("complete", False)))
        except (OSError, ValueError, KeyError, TypeError) as exc:
            log.warning("state file %s unreadable (%s); no last mission", path, exc)
        return self._latest

    def save(self, s: SavedMission, utc_s: float) -> None:
        """Keep ``s`` as the last state and have it written (never blocks)."""
        self._latest = SavedMission(s.mission, s.leg, s.complete)
        self._loaded = True
        if not self.path:
            return
        self._pending = {"mission": mission_to_json(s.mission), "leg": s.leg,
                         "complete": s.complete, "utc_s": utc_s}
        if self._wake is not None:
            self._wake.set()

    def write(self, data: dict[str, Any]) -> None:
        """Write ``data`` atomically (a blocking call: a worker thread's)."""
        path = self.path
        tmp = f"{path}.tmp"
        with self._lock:
            try:
                Path(path).parent.mkdir(parents=True, exist_ok=True)
                with open(tmp, "w") as fh:
                    json.dump(data, fh)
                    fh.flush()
                    os.fsync(fh.fileno())
                os.replace(tmp, path)
                self.writes += 1
            except OSError as exc:
                self.write_errors += 1
                log.warning("cannot write the state file %s: %s", path, exc)

    async def run(self) -> None:
        """Write each saved state on a worker thread, until cancelled."""
        self._wake = wake = asyncio.Event()
        try:
            while True:
                if self._pending is None:
                    wake.clear()
                    await wake.wait()
                data, self._pending = self._pending, None
                if data is not None:
                    await asyncio.to_thread(self.write, data)
        finally:
            self._wake = None
            data, self._pending = self._pending, None
            if data is not None:  # on the way out: what is left, now
                self.write(data)
