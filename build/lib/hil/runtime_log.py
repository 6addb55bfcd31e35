"""What the runtime says about its devices, read from its log (another process).

``zarco -v run`` logs every health transition of every device driver
(``drivers.nmea_device.DeviceLink.set_state``: ``gps: ok`` at INFO, ``gps:
disconnected: <reason>`` / ``stale`` / ``faulty`` at WARNING, rate-limited
per state with a ``(+N similar suppressed)`` count), every sentence it drops
(``gps: dropped '...': checksum: ...``, rate-limited per reason) and the
control task's failsafes.  The default log format is
``%(asctime)s %(levelname)s %(name)s: %(message)s``; ``asctime`` is local
wall-clock time to the millisecond, which the simulator matches with its own
``time.time()`` events.
"""

from __future__ import annotations

import re
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

DEVICES = ("gps", "compass", "thrusters")
_LINE_RE = re.compile(
    r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d),(\d{3}) ([A-Z]+) ([\w.]+): (.*)$")
_STATE_RE = re.compile(r"^(\w+): (ok|stale|disconnected|faulty)(?:: (.*?))?"
                       r"(?: \(\+(\d+) similar suppressed\))?$")
_DROP_RE = re.compile(r"^(\w+): dropped .*?['\"]: (\w+)(?::.*)?$")


def _wall(stamp: str, ms: str) -> float:
    return time.mktime(time.strptime(stamp, "%Y-%m-%d %H:%M:%S")) + int(ms) / 1000.0


@dataclass(slots=True)
class Transition:
    wall: float
    device: str
    state: str
    reason: str = ""
    suppressed: int = 0

    def as_dict(self, wall0: float = 0.0) -> dict[str, Any]:
        d: dict[str, Any] = {"t": round(self.wall - wall0, 3), "device": self.device,
                             "state": self.state}
        if self.reason:
            d["reason"] = self.reason
        if self.suppressed:
            d["suppressed"] = self.suppressed
        return d


@dataclass(slots=True)
class RuntimeLog:
    """Health transitions, drops and failsafes parsed from the runtime's log lines."""

    transitions: list[Transition] = field(default_factory=list)
    dropped: Counter[str] = field(default_factory=Counter)  # "gps:checksum" → log lines
    failsafes: list[tuple[float, str]] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)  # ERROR/CRITICAL lines + tracebacks
    lines: int = 0
    _last_level: str = ""

    def feed(self, line: str) -> None:
        self.lines += 1
        m = _LINE_RE.match(line.rstrip("\n"))
        if m is None:
            # a traceback or other text: part of the last record (a DEBUG record's
            # traceback is not an error), or printed by a dying process
            if self._last_level in ("", "ERROR", "CRITICAL") and line.strip():
                self.errors.append(line.rstrip("\n"))
            return
        stamp, ms, level, logger, msg = m.groups()
        wall = _wall(stamp, ms)
        self._last_level = level
        if level in ("ERROR", "CRITICAL"):
            self.errors.append(f"{logger}: {msg}")
        dev = logger.rsplit(".", 1)[-1]
        if logger.startswith("zarco.") and dev in DEVICES:
            s = _STATE_RE.match(msg)
            if s is not None and s[1] == dev:
                self.transitions.append(Transition(wall, dev, s[2], s[3] or "",
                                                   int(s[4] or 0)))
                return
            if msg == f"{dev}: opened, waiting for data":
                self.transitions.append(Transition(wall, dev, "stale", "opened"))
                return
            d = _DROP_RE.match(msg)
            if d is not None and d[1] == dev:
                self.dropped[f"{dev}:{d[2]}"] += 1
            return
        if logger == "zarco.control" and level == "WARNING" and "failsafe" in msg:
            self.failsafes.append((wall, msg))

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
