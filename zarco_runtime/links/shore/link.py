"""The shore link: a zenoh peer on the boat (``[shore] enabled = true``).

Out: ``zarco/<vessel>/state`` at ``state_hz``, ``health`` with every status
snapshot (1 Hz), ``auv`` with every AUV track update, ``event`` with every
event (payloads: :mod:`.telemetry`), ``map`` when it changes and every 10 s
(:mod:`.map_info`; also the reply to a query on it).  A query on ``access``
is answered ``{"role": "operator"}``: access control lets only operators
query it, so a shore tool learns whether its credentials may command before
offering commands.  In: ``cmd/<name>`` queries, each sent
to the supervisor as a :class:`~zarco_core.messages.Command` from
``shore:<user>`` and answered with exactly one reply ``{"ok", "id", "mode",
"reason"}``; the operator heartbeat ``operator`` (``{"t", "user"}``) becomes an
:class:`~zarco_core.messages.OperatorHeartbeat` (link ``shore``: the
supervisor's ``link_lost`` failsafe does the rest); ``rtcm`` bytes become
:class:`~zarco_core.messages.RtcmCorrections` for the GPS driver, which
passes only whole, CRC-valid RTCM3 frames.

A command query may carry a zenoh attachment, a JSON object with ``user``
(the operator's name, for the command's source) and ``id`` (echoed in the
reply; the link numbers commands otherwise).  Who may query at all is
zenoh's access control (operators only); zenoh does not tell the application
which authenticated user sent a query, so ``user`` is the name the client
gives.

Threads: zenoh calls its callbacks on its own threads.  They make no zenoh
call; they only append to an inbox and wake the event loop once
(``call_soon_threadsafe``), where
commands, heartbeats and corrections go on the bus.  Everything sent (puts,
replies) goes through one sender thread, so no zenoh call is ever made on
the event loop and a slow network cannot hold the control loop.  The
session is opened and closed on a worker thread, and always closed (zenoh
1.x does not let a process with an open session exit).
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import logging
import math
import queue
import threading
from collections import Counter, deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from zarco_core.auv_messages import AuvTrack, BuoyStatus
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.component import ComponentContext
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    Event,
    GuidanceStatus,
    NavState,
    OperatorHeartbeat,
    RtcmCorrections,
    ThrusterCommand,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.links.shore import telemetry
from zarco_runtime.links.shore.map_info import MAP_PERIOD_S, MapInfo
from zarco_runtime.links.shore.zenoh_config import TELEMETRY, boat_config, prefix
from zarco_runtime.supervision.local import LocalCommands

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.shore")
_ids = itertools.count(1)

#: inbox bound (items between the zenoh threads and the loop); a query beyond is
#: answered "busy" at once, a heartbeat or corrections chunk is dropped and counted
INBOX_MAX = 1024
#: sender queue bound (puts and replies); a put beyond is dropped and counted
OUTBOX_MAX = 1024
#: a command payload larger than this is refused unread (bytes)
MAX_COMMAND_BYTES = 65536
#: an ``rtcm`` sample larger than this is dropped and counted (bytes): a relay sends
#: what it read, a few frames of at most 1029 bytes; the GPS driver checks every byte
#: on the event loop, which must not be held by one huge sample
MAX_RTCM_BYTES = 16384


class _Inbox:
    """From zenoh's threads to the event loop: append, and wake the loop once."""

    def __init__(self, loop: asyncio.AbstractEventLoop,
                 handle: Callable[[tuple[Any, ...]], None]) -> None:
        self.loop = loop
        self.handle = handle
        self.items: deque[tuple[Any, ...]] = deque()
        self.lock = threading.Lock()
        self.scheduled = False
        self.closed = False
        self.dropped = 0

    def post(self, item: tuple[Any, ...]) -> bool:
        """Queue ``item`` (any thread); False if full or closed (not queued)."""
        with self.lock:
            if self.closed or len(self.items) >= INBOX_MAX:
                self.dropped += 1
                return False
            self.items.append(item)
            if self.scheduled:
                return True
            self.scheduled = True
        try:
            self.loop.call_soon_threadsafe(self._drain)
        except RuntimeError:  # the loop is closed: we are shutting down
            return False
        return True

    def _drain(self) -> None:
        with self.lock:
            items = list(self.items)
            self.items.clear()
            self.scheduled = False
        for it in items:
            self.handle(it)

    def close(self) -> list[tuple[Any, ...]]:
        with self.lock:
            self.closed = True
            items = list(self.items)
            self.items.clear()
        return items


class ShoreLink:
    """The shore link component (see the module docstring)."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock,
                 ctx: ComponentContext) -> None:
        self.cfg = cfg.shore
        self.bus = bus
        self.clock = clock
        self.key = prefix(self.cfg.vessel)
        o = cfg.origin
        self.frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
        self.commands = LocalCommands(bus, clock, source="shore", listen=ctx.listen)
        self.nav = bus.latest(NavState)
        self.guidance = bus.latest(GuidanceStatus)
        self.thrust = bus.latest(ThrusterCommand)
        self.directive = bus.latest(Directive)
        self.status = bus.latest(VesselStatus)
        self.buoy = bus.latest(BuoyStatus)
        self.map = MapInfo(cfg, self.frame)
        #: the last ``map`` object sent (JSON; read by zenoh's threads to answer queries)
        self._map_json = ""
        self._map_key = ""
        self._map_sent_t = -math.inf
        self.counters: Counter[str] = Counter()  # written on the event loop only
        #: written by the sender thread only (keys fixed: safe to copy from the loop)
        self.sent: dict[str, int] = {**{f"{k}_sent": 0 for k in TELEMETRY},
                                     "replies_sent": 0, "send_errors": 0}
        ctx.listen(VesselStatus, self._on_status)
        ctx.listen(Event, self._on_event)
        ctx.listen(AuvTrack, self._on_track)
        self._out: queue.Queue[tuple[Any, ...] | None] = queue.Queue(OUTBOX_MAX)
        self._inbox: _Inbox | None = None
        self._tasks: set[asyncio.Task[None]] = set()
        self._session: Any = None
        self._pubs: dict[str, Any] = {}

    # ------------------------------------------------------------- outgoing

    def _put(self, key: str, obj: dict[str, Any]) -> None:
        """Queue a telemetry object for the sender thread (never blocks)."""
        if self._session is None:
            return
        try:
            self._out.put_nowait(("put", key, json.dumps(obj, separators=(",", ":"))))
        except queue.Full:
            self.counters["telemetry_dropped"] += 1

    def _utc(self, t: float) -> float:
        return self.clock.utc(t)

    def _on_status(self, st: VesselStatus) -> None:
        self._put("health", telemetry.health(self._utc(st.t), st,
                                             {**self.counters, **self.sent}))
        self._map_update(st.t)

    def _map_update(self, now: float) -> None:
        """Send the ``map`` object if it changed, or every :data:`MAP_PERIOD_S`."""
        obj = self.map.build(0.0, self.status.value, self.directive.value, self.buoy.value)
        key = json.dumps(obj, separators=(",", ":"))
        if key == self._map_key and now - self._map_sent_t < MAP_PERIOD_S:
            return
        obj["t"] = round(self._utc(now), 3)
        self._map_key = key
        self._map_json = json.dumps(obj, separators=(",", ":"))
        self._map_sent_t = now
        self._put("map", obj)

    def _on_event(self, ev: Event) -> None:
        self._put("event", telemetry.event(self._utc(ev.t), ev))

    def _on_track(self, tr: AuvTrack) -> None:
        self._put("auv", telemetry.auv(self._utc(tr.t), tr, self.frame, self.nav.value))

    def state_now(self) -> dict[str, Any]:
        now = self.clock.now()
        return telemetry.state(self.cfg.vessel, self._utc(now), now, self.nav.value,
                               self.guidance.value, self.thrust.value, self.directive.value,
                               self.status.value)

    def _sender(self, pubs: dict[str, Any]) -> None:
        """The sender thread: every zenoh put and reply, in order."""
        while True:
            item = self._out.get()
            if item is None:
                return
            try:
                if item[0] == "put":
                    pubs[item[1]].put(item[2])
                    self.sent[f"{item[1]}_sent"] += 1
                else:  # ("reply", query, key, payload)
                    q = item[1]
                    try:
                        q.reply(item[2], item[3])
                        self.sent["replies_sent"] += 1
                    finally:
                        q.drop()
            except Exception as exc:  # a closed session, a dropped query
                self.sent["send_errors"] += 1
                log.debug("shore: send failed: %s", exc)

    def _reply(self, query: Any, key: str, body: dict[str, Any]) -> None:
        """Queue the one reply to ``query`` (never blocks: with the sender 1024 items
        behind, the query is dropped unanswered and counted)."""
        try:
            self._out.put_nowait(("reply", query, key, json.dumps(body)))
        except queue.Full:
            self.counters["replies_dropped"] += 1
            with contextlib.suppress(Exception):
                query.drop()

    # ------------------------------------------------------------- incoming

    def _on_query(self, query: Any) -> None:  # a zenoh thread: no zenoh call here
        try:
            key = str(query.key_expr)
            payload = query.payload.to_bytes() if query.payload is not None else b""
            att = query.attachment.to_bytes() if query.attachment is not None else b""
        except Exception as exc:  # let zenoh drop it (no reply)
            log.debug("shore: unreadable query: %s", exc)
            return
        inbox = self._inbox
        if inbox is None or not inbox.post(("cmd", query, key, payload, att)):
            busy = json.dumps({"ok": False, "id": None, "mode": None,
                               "reason": "busy: too many commands queued"})
            with contextlib.suppress(queue.Full):  # else zenoh drops it (no reply)
                self._out.put_nowait(("reply", query, key, busy))

    def _on_info_query(self, query: Any) -> None:  # a zenoh thread: no zenoh call here
        """A query on ``map`` (the latest map object) or ``access`` (operators only,
        by access control: the answer says the asker may command)."""
        try:
            key = str(query.key_expr)
        except Exception as exc:  # let zenoh drop it
            log.debug("shore: unreadable query: %s", exc)
            return
        if key.endswith("/access"):
            body = json.dumps({"role": "operator"})
        else:
            body = self._map_json or json.dumps({"t": None})
        with contextlib.suppress(queue.Full):  # else zenoh drops it (no reply)
            self._out.put_nowait(("reply", query, key, body))

    def _on_sample(self, kind: str) -> Callable[[Any], None]:
        def cb(sample: Any) -> None:  # a zenoh thread
            inbox = self._inbox
            if inbox is None:
                return
            if kind == "rtcm" and len(sample.payload) > MAX_RTCM_BYTES:
                inbox.post(("rtcm_oversize", len(sample.payload)))
                return
            inbox.post((kind, sample.payload.to_bytes()))
        return cb

    def _handle(self, item: tuple[Any, ...]) -> None:
        """One item from zenoh, on the event loop."""
        kind = item[0]
        if kind == "rtcm":
            self.counters["rtcm_bytes"] += len(item[1])
            self.bus.publish(RtcmCorrections(self.clock.now(), "shore", item[1]))
        elif kind == "rtcm_oversize":
            self.counters["rtcm_oversize_dropped"] += 1
            log.warning("shore: an rtcm sample of %d bytes dropped (more than %d)", item[1],
                        MAX_RTCM_BYTES)
        elif kind == "operator":
            self._heartbeat(item[1])
        elif kind == "cmd":
            self._command(*item[1:])

    def _heartbeat(self, payload: bytes) -> None:
        try:
            d = json.loads(payload)
            if not isinstance(d, dict):
                raise ValueError("not an object")
            user = str(d.get("user", ""))[:64]
        except (ValueError, UnicodeDecodeError):
            self.counters["bad_heartbeats"] += 1
            return
        self.counters["heartbeats"] += 1
        self.bus.publish(OperatorHeartbeat(self.clock.now(), "shore", user))

    def _mode(self) -> str:
        d = self.directive.value
        return d.mode.value if d is not None else "idle"

    def _command(self, query: Any, key: str, payload: bytes, att: bytes) -> None:
        base = f"{self.key}/cmd/"
        name = key[len(base):] if key.startswith(base) else ""
        cid: str | None = None
        user = ""
        why = ""
        args: dict[str, Any] = {}
        try:
            if att:
                meta = json.loads(att)
                if isinstance(meta, dict):
                    user = str(meta.get("user", ""))[:64]
                    cid = str(meta["id"])[:64] if meta.get("id") is not None else None
            if not name or "/" in name or "*" in name or "$" in name:
                raise ValueError(f"{key}: expected {base}<name>, one command")
            if len(payload) > MAX_COMMAND_BYTES:
                raise ValueError(f"payload larger than {MAX_COMMAND_BYTES} bytes")
            raw = json.loads(payload) if payload.strip() else {}
            if not isinstance(raw, dict):
                raise ValueError("the payload must be a JSON object")
            args = raw
        except (ValueError, UnicodeDecodeError) as exc:
            why = f"bad request: {exc}"
        cid = cid or f"shore-{next(_ids)}"
        self.counters["commands"] += 1
        if why:
            self.counters["commands_bad"] += 1
            self._reply(query, key, {"ok": False, "id": cid, "mode": self._mode(),
                                     "reason": why})
            return
        source = f"shore:{user}" if user else "shore"
        task = asyncio.ensure_future(self._send_command(query, key, name, args, source, cid))
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _send_command(self, query: Any, key: str, name: str, args: dict[str, Any],
                            source: str, cid: str) -> None:
        try:
            ack = await self.commands.send(name, args, source=source, cmd_id=cid)
        except BaseException:
            # cancelled (shutting down): the query still gets its one reply
            self._reply(query, key, {"ok": False, "id": cid, "mode": self._mode(),
                                     "reason": "shore link stopping"})
            raise
        self.counters["commands_accepted" if ack.ok else "commands_refused"] += 1
        self._reply(query, key, {"ok": ack.ok, "id": ack.id, "mode": ack.mode,
                                 "reason": ack.reason})

    # ------------------------------------------------------------------ run

    def _open(self) -> tuple[Any, dict[str, Any]]:
        """Open the session and declare everything (a worker thread)."""
        import zenoh

        conf = zenoh.Config.from_json5(json.dumps(boat_config(self.cfg)))
        session: Any = zenoh.open(conf)
        try:
            pubs = {k: session.declare_publisher(f"{self.key}/{k}") for k in TELEMETRY}
            session.declare_queryable(f"{self.key}/cmd/**", self._on_query)
            session.declare_queryable(f"{self.key}/map", self._on_info_query)
            session.declare_queryable(f"{self.key}/access", self._on_info_query)
            session.declare_subscriber(f"{self.key}/operator", self._on_sample("operator"))
            session.declare_subscriber(f"{self.key}/rtcm", self._on_sample("rtcm"))
        except BaseException:
            session.close()
            raise
        return session, pubs

    def _close(self, session: Any, sender: threading.Thread | None) -> None:
        """Stop the sender and close the session (a worker thread)."""
        if sender is not None:
            self._out.put(None)
            sender.join(timeout=5.0)
        if session is not None:
            session.close()

    async def run(self) -> None:
        loop = asyncio.get_running_loop()
        self._inbox = _Inbox(loop, self._handle)
        session: Any = None
        sender: threading.Thread | None = None
        opening = loop.run_in_executor(None, self._open)
        try:
            session, self._pubs = await asyncio.shield(opening)
            self._session = session
            sender = threading.Thread(target=self._sender, args=(self._pubs,),
                                      name="zarco-shore-send", daemon=True)
            sender.start()
            log.info("shore link: vessel %s listening on %s (auth %s)", self.cfg.vessel,
                     ", ".join(self.cfg.listen), self.cfg.auth)
            self._map_update(self.clock.now())
            period = 1.0 / self.cfg.state_hz
            k = 0
            t0 = self.clock.now()
            while True:
                self._put("state", self.state_now())
                k += 1
                await self.clock.sleep_until(t0 + k * period)
        finally:
            self._session = None
            for item in self._inbox.close():  # queries not yet handled get their reply
                if item[0] == "cmd":
                    self._reply(item[1], item[2], {"ok": False, "id": None,
                                                   "mode": self._mode(),
                                                   "reason": "shore link stopping"})
            for task in list(self._tasks):
                task.cancel()
            if self._tasks:  # their replies go out before the sender stops
                with contextlib.suppress(asyncio.CancelledError):
                    await asyncio.gather(*self._tasks, return_exceptions=True)
            if session is None:  # cancelled while opening: close what the worker opens
                with contextlib.suppress(BaseException):
                    session, _ = await asyncio.shield(opening)
            closing = loop.run_in_executor(None, self._close, session, sender)
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.shield(closing)

