"""What the runtime says about itself, read from its ``--status FILE`` (another process).

``zarco run --status FILE`` appends JSON lines: the supervisor's status snapshot
(``"kind": "status"``, 1 Hz: mode, mission progress, active failsafes, every
device's health and counters, components, counters), every event as it
happens (mode changes, acknowledgements, failsafe entries and exits, device
health changes, component failures: ``t``, ``kind``, ``text``, ``source``),
and a last snapshot with ``"final": true`` and the control loop's figures
when it exits.  Every line carries ``wall`` (``time.time()`` when written),
which the simulator matches with its own events.

An event line's ``kind`` is the event's own (``mode``, ``failsafe``, ``ack``,
``fault``, ``component``, ``mission``: the event's fields are written over the
line's ``"kind": "event"``), or ``event`` with the event's kind under
``event``; a line is a snapshot when its kind is ``status``.  A device's
health change is a ``fault`` event whose source is the device and whose text
is ``"gps: ok"`` or ``"gps: disconnected: <why>"``.  A device's first state
(``stale``: the port opened, nothing read yet) has no event; it is taken from
the first snapshot that lists the device.

The runtime's stderr log is read only for errors (:class:`ErrorLog`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from zarco_core.messages import HealthState
from zarco_runtime.supervision.supervisor import _NOT_REFUSALS as NOT_REFUSALS

#: health states of a device
STATES = tuple(s.value for s in HealthState)


@dataclass(slots=True)
class Transition:
    """A device's health changed (``wall``: when the runtime wrote it)."""

    wall: float
    device: str
    state: str
    reason: str = ""

    def as_dict(self, wall0: float = 0.0) -> dict[str, Any]:
        d: dict[str, Any] = {"t": round(self.wall - wall0, 3), "device": self.device,
                             "state": self.state}
        if self.reason:
            d["reason"] = self.reason
        return d


@dataclass(slots=True)
class RuntimeEvent:
    """One event of the runtime (``t``: its own clock; ``wall``: when written)."""

    wall: float
    t: float
    kind: str
    text: str
    source: str

    def as_dict(self, wall0: float = 0.0) -> dict[str, Any]:
        return {"t": round(self.wall - wall0, 3), "kind": self.kind, "text": self.text,
                "source": self.source}


def health_change(ev: RuntimeEvent) -> tuple[str, str] | None:
    """(state, reason) if ``ev`` is a device's health change, else None."""
    if ev.kind != "fault" or not ev.text.startswith(f"{ev.source}: "):
        return None
    state, _, reason = ev.text[len(ev.source) + 2:].partition(": ")
    return (state, reason) if state in STATES else None


@dataclass(slots=True)
class RuntimeStatus:
    """The runtime's status file, read as it grows (:meth:`poll`) or at once."""

    path: Path | None = None
    transitions: list[Transition] = field(default_factory=list)
    events: list[RuntimeEvent] = field(default_factory=list)
    snapshots: int = 0
    #: the latest snapshot (the final one once the runtime has exited)
    last: dict[str, Any] = field(default_factory=dict)
    final: dict[str, Any] | None = None
    #: modes seen in the snapshots and mode events, in order (repeats collapsed)
    modes: list[str] = field(default_factory=list)
    #: every failsafe name ever active in a snapshot
    failsafes_seen: set[str] = field(default_factory=set)
    #: per snapshot: (wall, mode, mission progress's along-track, cross-track (m), phase)
    progress: list[tuple[float, str, float | None, float | None, str]] = \
        field(default_factory=list)
    bad_lines: int = 0
    _offset: int = 0
    _partial: str = ""
    _state: dict[str, str] = field(default_factory=dict)

    def poll(self) -> int:
        """Read what was appended to the file since the last call; lines read."""
        if self.path is None:
            return 0
        try:
            with self.path.open("rb") as fh:
                fh.seek(self._offset)
                data = fh.read()
        except FileNotFoundError:
            return 0
        self._offset += len(data)
        text = self._partial + data.decode("utf-8", "replace")
        lines = text.split("\n")
        self._partial = lines.pop()  # a line still being written
        self.feed(lines)
        return len(lines)

    def feed(self, lines: Iterable[str]) -> None:
        for ln in lines:
            if not ln.strip():
                continue
            try:
                rec = json.loads(ln)
            except ValueError:
                self.bad_lines += 1
                continue
            if isinstance(rec, dict):
                self.record(rec)
            else:
                self.bad_lines += 1

    def record(self, rec: dict[str, Any]) -> None:
        wall = float(rec.get("wall", 0.0))
        if rec.get("kind") == "status":
            self._snapshot(wall, rec)
        elif "text" in rec:
            self._event(wall, rec)
        else:
            self.bad_lines += 1

    def _mode(self, mode: str) -> None:
        if mode and (not self.modes or self.modes[-1] != mode):
            self.modes.append(mode)

    def _snapshot(self, wall: float, rec: dict[str, Any]) -> None:
        self.snapshots += 1
        self.last = rec
        if rec.get("final"):
            self.final = rec
        mode = str(rec.get("mode", ""))
        self._mode(mode)
        self.failsafes_seen.update(rec.get("failsafes") or [])
        mp = rec.get("mission") or {}
        self.progress.append((wall, mode, mp.get("along_m"), mp.get("xtrack_m"),
                              str(mp.get("phase") or "")))
        for dev, d in (rec.get("devices") or {}).items():
            if dev not in self._state:  # its first state (no event for it)
                self._transition(wall, dev, str(d.get("state", "")), str(d.get("reason", "")))

    def _event(self, wall: float, rec: dict[str, Any]) -> None:
        kind = rec.get("kind", "")
        if kind == "event":  # an event line that keeps its own kind apart
            kind = rec.get("event", "")
        ev = RuntimeEvent(wall, float(rec.get("t", 0.0)), str(kind),
                          str(rec.get("text", "")), str(rec.get("source", "")))
        self.events.append(ev)
        hc = health_change(ev)
        if hc is not None:
            self._transition(wall, ev.source, *hc)
        elif ev.kind == "mode" and ev.text.startswith("mode "):
            self._mode(ev.text[5:].split(" ", 1)[0].rstrip(":"))

    def _transition(self, wall: float, device: str, state: str, reason: str) -> None:
        self._state[device] = state
        self.transitions.append(Transition(wall, device, state, reason))

    # ------------------------------------------------------------ queries

    def state(self, device: str) -> str:
        """The device's latest known state ("?" before any)."""
        return self._state.get(device, "?")

    def states(self, device: str) -> list[str]:
        """The device's successive states (repeats collapsed)."""
        out: list[str] = []
        for tr in self.transitions:
            if tr.device == device and (not out or out[-1] != tr.state):
                out.append(tr.state)
        return out

    def first(self, device: str, state: str, after_wall: float) -> Transition | None:
        for tr in self.transitions:
            if tr.device == device and tr.state == state and tr.wall >= after_wall:
                return tr
        return None

    def of_kind(self, kind: str) -> list[RuntimeEvent]:
        return [e for e in self.events if e.kind == kind]

    def devices(self) -> dict[str, dict[str, Any]]:
        """Every device of the latest snapshot: its summary (state, reason, age_s,
        ok, bad, counters) plus ``dropped`` (sentences refused, by reason)."""
        out: dict[str, dict[str, Any]] = {}
        for dev, d in (self.last.get("devices") or {}).items():
            c = d.get("counters") or {}
            out[dev] = {**d, "dropped": {k: v for k, v in sorted(c.items())
                                         if k not in NOT_REFUSALS and v}}
        return out

    def steering_since(self, mode: str) -> float | None:
        """Wall time of the first snapshot in ``mode`` whose guidance steers by
        something: a follow mission's phase is ``follow`` (the tracker has acquired
        the AUV: above a still AUV the boat holds over it, with no line to be off),
        or the mission progress has a non-zero along- or cross-track error (while
        waiting for a track both are exactly 0)."""
        for wall, m, along, xtrack, phase in self.progress:
            if m == mode and (phase == "follow" or (along is not None and along != 0.0)
                              or (xtrack is not None and xtrack != 0.0)):
                return wall
        return None

    def ready(self, devices: Iterable[str]) -> bool:
        """Has a snapshot listed every one of ``devices`` (the runtime is up)?"""
        return all(d in self._state for d in devices)


#: a log record of the runtime's default format: "2026-06-01 10:00:00,001 LEVEL name: msg"
_RECORD_RE = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} ([A-Z]+) ([\w.]+): (.*)$")


@dataclass(slots=True)
class ErrorLog:
    """Errors in the runtime's stderr log: ERROR / CRITICAL records with their
    tracebacks, and text a dying process prints outside any record.  A lower
    record's traceback (a DEBUG or WARNING with ``exc_info``) is not an error."""

    errors: list[str] = field(default_factory=list)
    lines: int = 0
    _last_level: str = ""

    def feed(self, line: str) -> None:
        self.lines += 1
        text = line.rstrip("\n")
        m = _RECORD_RE.match(text)
        if m is None:
            if self._last_level in ("", "ERROR", "CRITICAL") and text.strip():
                self.errors.append(text)
            return
        level, logger, msg = m.groups()
        self._last_level = level
        if level in ("ERROR", "CRITICAL"):
            self.errors.append(f"{logger}: {msg}")
