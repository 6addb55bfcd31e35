"""The page server's link to the boats: telemetry fanned out to the open pages,
the role probe, the operator heartbeat, commands.

One :class:`~zarco_tools.shore.client.ShoreClient` (the console's
configuration and credentials, a zenoh session per endpoint) feeds the hub from
zenoh's threads; the hub keeps the latest of every vessel on the event loop
and hands each sample, encoded once, to every page's bounded queue (a page
that falls behind loses its oldest samples, counted; the next state makes up
for them).  Blocking zenoh calls (queries, puts) run on a small thread pool,
never on the event loop.

A vessel's *role* is what the boat grants these credentials: ``operator`` when
the boat answers a query on ``zarco/<vessel>/access`` (access control lets
only operators ask), ``viewer`` when it does not, ``unknown`` until asked.
Commands are offered, and sent, only for an operator's vessel.

While at least one page is open, the hub publishes the operator heartbeat to
the vessels it may command (their ``link lost`` failsafe watches it, as for
``zarco shore status``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from zarco_tools.shore.client import ShoreClient

log = logging.getLogger("zarco.shore.web")

#: samples a page may have waiting before its oldest are dropped
PAGE_QUEUE = 512
#: events kept per vessel (sent to a page when it opens)
EVENTS = 50
#: a vessel's role is asked again this often (s), and when it is heard again
PROBE_EVERY_S = 60.0
#: a vessel silent this long (s) is asked again for its map and role when heard
SILENT_S = 10.0

#: commands the page may send, and the modes ``mode`` may ask for
COMMANDS = ("stop", "arm", "disarm", "mode", "resume", "follow")
PAGE_MODES = ("hold", "return", "idle")


class CommandError(ValueError):
    """A command the page server refuses before sending it (the reason, in words)."""


def check_command(name: str, args: Any) -> dict[str, Any]:
    """The arguments of a page's command, checked: only the commands the page
    offers, with the arguments it sends; raises :class:`CommandError`."""
    if name not in COMMANDS:
        raise CommandError(f"unknown command {name!r} (one of {', '.join(COMMANDS)})")
    if not isinstance(args, dict):
        raise CommandError("args: must be an object")
    if name != "mode":
        if args:
            raise CommandError(f"{name}: takes no arguments")
        return {}
    extra = set(args) - {"mode", "lat_deg", "lon_deg"}
    if extra:
        raise CommandError(f"mode: unexpected {sorted(extra)}")
    mode = args.get("mode")
    if mode not in PAGE_MODES:
        raise CommandError(f"mode: one of {', '.join(PAGE_MODES)}")
    out: dict[str, Any] = {"mode": mode}
    if ("lat_deg" in args) != ("lon_deg" in args):
        raise CommandError("mode: give lat_deg and lon_deg, or neither")
    if "lat_deg" in args:
        if mode != "hold":
            raise CommandError("mode: a point only for hold")
        lat, lon = args["lat_deg"], args["lon_deg"]
        ok = all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                 for v in (lat, lon))
        if not ok or not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise CommandError("mode: lat_deg, lon_deg must be a latitude and a longitude")
        out.update(lat_deg=float(lat), lon_deg=float(lon))
    return out


@dataclass(slots=True)
class Vessel:
    """The latest of one vessel, as the pages see it (event loop only)."""

    name: str
    latest: dict[str, dict[str, Any]] = field(default_factory=dict)
    events: deque[dict[str, Any]] = field(default_factory=lambda: deque(maxlen=EVENTS))
    received: dict[str, float] = field(default_factory=dict)
    role: str = "unknown"
    probed: float = -math.inf
    probing: bool = False

    def snapshot(self, now: float) -> dict[str, Any]:
        return {"name": self.name, "role": self.role, **self.latest,
                "events": list(self.events),
                "age_s": {k: round(now - t, 3) for k, t in self.received.items()}}


class Page:
    """One open page: its queue of encoded messages."""

    def __init__(self, maxsize: int = PAGE_QUEUE) -> None:
        self.queue: asyncio.Queue[str] = asyncio.Queue(maxsize)
        self.dropped = 0
        self.sent = 0
        self.bytes = 0

    def push(self, msg: str) -> None:
        while True:
            try:
                self.queue.put_nowait(msg)
                return
            except asyncio.QueueFull:
                with contextlib.suppress(asyncio.QueueEmpty):
                    self.queue.get_nowait()
                    self.dropped += 1


class Hub:
    """Telemetry of every vessel heard → the open pages; commands → the boats."""

    def __init__(self, client: ShoreClient, probe_timeout_s: float = 2.0,
                 command_timeout_s: float = 3.0, workers: int = 8) -> None:
        self.client = client
        self.probe_timeout_s = probe_timeout_s
        self.command_timeout_s = command_timeout_s
        self.vessels: dict[str, Vessel] = {}
        self.pages: set[Page] = set()
        self.pool = ThreadPoolExecutor(workers, thread_name_prefix="zarco-web")
        self.loop: asyncio.AbstractEventLoop | None = None
        self.samples = 0
        self._tasks: set[asyncio.Task[Any]] = set()

    # ------------------------------------------------------------ zenoh side

    def attach(self, loop: asyncio.AbstractEventLoop) -> Callable[[str, str, Any, float], None]:
        """The client's ``on_sample`` callback, bound to ``loop``."""
        self.loop = loop

        def on_sample(vessel: str, kind: str, obj: Any, _now: float) -> None:
            with contextlib.suppress(RuntimeError):  # the loop is closed: shutting down
                loop.call_soon_threadsafe(self.sample, vessel, kind, obj)

        return on_sample

    def sample(self, vessel: str, kind: str, obj: dict[str, Any]) -> None:
        """One telemetry sample (event loop)."""
        now = time.monotonic()
        v = self.vessels.get(vessel)
        fresh = v is None
        if v is None:
            v = self.vessels[vessel] = Vessel(vessel)
        else:
            last = max(v.received.values(), default=-math.inf)
            fresh = now - last > SILENT_S
        v.received[kind] = now
        self.samples += 1
        if kind == "event":
            v.events.append(obj)
        else:
            v.latest[kind] = obj
        self.broadcast({"type": "s", "v": vessel, "k": kind, "d": obj})
        if fresh or (now - v.probed > PROBE_EVERY_S and not v.probing):
            self._spawn(self._probe(v, with_map=fresh))

    def broadcast(self, msg: dict[str, Any]) -> None:
        if not self.pages:
            return
        text = json.dumps(msg, separators=(",", ":"))
        for p in self.pages:
            p.push(text)

    def _spawn(self, coro: Any) -> None:
        task = asyncio.ensure_future(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    def _sessions(self, vessel: str) -> list[Any]:
        snap = self.client.snapshot().get(vessel)
        return [s for c, s in self.client.sessions
                if snap is None or c.endpoint == snap.endpoint]

    def _query(self, vessel: str, what: str, timeout_s: float) -> list[dict[str, Any]]:
        """Replies to a query on ``zarco/<vessel>/<what>`` (a worker thread)."""
        out: list[dict[str, Any]] = []
        for s in self._sessions(vessel):
            try:
                for r in s.get(f"zarco/{vessel}/{what}", timeout=timeout_s):
                    if r.ok is None:
                        continue
                    with contextlib.suppress(ValueError):
                        d = json.loads(r.ok.payload.to_bytes())
                        if isinstance(d, dict):
                            out.append(d)
            except Exception as exc:  # a session closing under us
                log.debug("query %s/%s: %s", vessel, what, exc)
        return out

    async def _probe(self, v: Vessel, with_map: bool) -> None:
        """Ask the boat for the role of these credentials (and its map)."""
        loop = asyncio.get_running_loop()
        v.probing = True
        try:
            if with_map:
                maps = await loop.run_in_executor(self.pool, self._query, v.name, "map",
                                                  self.probe_timeout_s)
                if maps and maps[0].get("t") is not None and "map" not in v.latest:
                    self.sample(v.name, "map", maps[0])
            got = await loop.run_in_executor(self.pool, self._query, v.name, "access",
                                             self.probe_timeout_s)
        finally:
            v.probing = False
        v.probed = time.monotonic()
        role = "operator" if any(d.get("role") == "operator" for d in got) else "viewer"
        if role != v.role:
            log.info("%s: %s", v.name, role)
            v.role = role
            self.broadcast({"type": "role", "v": v.name, "role": role})

    # -------------------------------------------------------------- pages

    def hello(self) -> dict[str, Any]:
        now = time.monotonic()
        return {"type": "hello", "user": self.client.config.user,
                "vessel": self.client.config.vessel,
                "vessels": {n: v.snapshot(now) for n, v in sorted(self.vessels.items())}}

    def operator_vessels(self) -> list[str]:
        return sorted(n for n, v in self.vessels.items() if v.role == "operator")

    async def heartbeat_loop(self) -> None:
        """The operator heartbeat, while a page is open, to the vessels we may command."""
        loop = asyncio.get_running_loop()
        period = 1.0 / max(0.2, self.client.config.heartbeat_hz)
        while True:
            vessels = self.operator_vessels()
            if self.pages and vessels:
                try:
                    await loop.run_in_executor(self.pool, self.client.heartbeat, vessels)
                except Exception as exc:  # a session closing under us
                    log.debug("heartbeat: %s", exc)
            await asyncio.sleep(period)

    async def command(self, vessel: str, name: str, args: Any) -> dict[str, Any]:
        """Send a page's command; the boat's reply (or why it was not sent)."""
        a = check_command(name, args)
        v = self.vessels.get(vessel)
        if v is None:
            raise CommandError(f"no vessel {vessel!r} heard")
        if v.role != "operator":
            raise CommandError(f"{vessel}: these credentials may not command it "
                               f"(role {v.role})")
        loop = asyncio.get_running_loop()
        t0 = time.monotonic()
        replies = await loop.run_in_executor(self.pool, self.client.command, vessel, name, a,
                                             self.command_timeout_s)
        if not replies:
            return {"ok": False, "vessel": vessel, "name": name, "id": None, "mode": None,
                    "reason": "no reply from the boat (not reachable, or not an operator)",
                    "rtt_ms": round((time.monotonic() - t0) * 1000.0, 1)}
        r = replies[0]
        return {"ok": r.ok, "vessel": vessel, "name": name, "id": r.id, "mode": r.mode,
                "reason": r.reason, "rtt_ms": round(r.rtt_s * 1000.0, 1)}

    def close(self) -> None:
        for t in list(self._tasks):
            t.cancel()
        self.pool.shutdown(wait=False, cancel_futures=True)
