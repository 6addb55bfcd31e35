"""The shore link: a zenoh peer on the boat (``[shore] enabled = true``).

Out: ``zarco/<vessel>/state`` at ``state_hz``, ``health`` with every status
snapshot (1 Hz), ``auv`` with every AUV track update, ``event`` with every
event (payloads: :mod:`.telemetry`), ``map`` when it changes and every 10 s
(:mod:`.map_info`; also the reply to a query on it).  A query on ``access``
is answered ``{"role": "operator"}``: access control lets only operators
query it, so a shore tool learns whether its credentials may command before
offering commands.  In: ``cmd/<name>`` queries, each read and bounded
(:mod:`.requests`), sent to the supervisor as a
:class:`~zarco_core.messages.Command` from ``shore:<user>`` and answered
with exactly one reply ``{"ok", "id", "mode", "reason"}``, whatever the
payload; the operator heartbeat ``operator`` (``{"t", "user"}``) becomes an
:class:`~zarco_core.messages.OperatorHeartbeat` (link ``shore``: the
supervisor's ``link_lost`` failsafe does the rest); ``rtcm`` bytes, within
the byte budget ``rtcm_budget_bps``, become
:class:`~zarco_core.messages.RtcmCorrections` of whole, CRC-valid RTCM3
frames for the GPS driver (:mod:`.rtcm_relay`).

A command query may carry a zenoh attachment, a JSON object with ``user``
(the operator's name, for the command's source) and ``id`` (echoed in the
reply; the link numbers commands otherwise).  Who may query at all is
zenoh's access control (operators only); zenoh does not tell the application
which authenticated user sent a query, so ``user`` is the name the client
gives.

Threads: zenoh calls the queryable's callback on its own threads; it reads
and bounds the query, refuses there and then ("busy", answered on that
thread) a source's commands beyond ``commands_per_s`` (``stop`` excepted),
and posts the rest to the :mod:`.inbox`, which the event loop drains in
slices of a few milliseconds.  Heartbeats and RTCM are kept by zenoh in ring channels
and read at a bounded pace by threads of their own (:mod:`.ring_reader`),
so that a flood costs no Python work beyond that pace.  Each item is
handled in isolation: an exception from one becomes a refusal (for a
command) and a counted ``fault``, never a restart of the link, and the next
item is handled as usual.  Everything sent (puts, replies) goes through the
:mod:`.sender` thread, so no zenoh call is ever made on the event loop and a
slow network cannot hold the control loop.  The session is opened and
closed on a worker thread, and always closed (zenoh 1.x does not let a
process with an open session exit).
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import logging
import math
import threading
from collections import Counter
from typing import TYPE_CHECKING, Any

from drivers.nmea_device import RateLimitedLog
from zarco_core.auv_messages import AuvPlan, AuvTrack, BuoyStatus
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
from zarco_runtime.links.shore import requests, telemetry
from zarco_runtime.links.shore.inbox import Corrections, Heartbeat, Inbox, Item, Query
from zarco_runtime.links.shore.map_info import MAP_PERIOD_S, MapInfo
from zarco_runtime.links.shore.requests import (
    MAX_ATTACHMENT_BYTES,
    MAX_COMMAND_BYTES,
    MAX_HEARTBEAT_BYTES,
    BadRequest,
)
from zarco_runtime.links.shore.ring_reader import RingReader
from zarco_runtime.links.shore.rtcm_relay import READ_PERIOD_S, RING, RtcmRelay, TokenBucket
from zarco_runtime.links.shore.sender import Sender
from zarco_runtime.links.shore.zenoh_config import TELEMETRY, boat_config, prefix
from zarco_runtime.supervision.local import LocalCommands

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.shore")
_ids = itertools.count(1)
#: operator heartbeats zenoh keeps (the latest); at most this many are read
#: every HEARTBEAT_PERIOD_S (s)
HEARTBEAT_RING = 16
HEARTBEAT_PERIOD_S = 0.05
#: command sources with a rate bucket of their own; the others share one
SOURCES_MAX = 64


def _reply_body(ok: bool, cid: str | None, mode: str | None, reason: str) -> str:
    return json.dumps({"ok": ok, "id": cid, "mode": mode, "reason": reason})


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
        self.plan = bus.latest(AuvPlan)
        self.map = MapInfo(cfg, self.frame)
        #: the last ``map`` object sent (JSON; read by zenoh's threads to answer queries)
        self._map_json = ""
        self._map_key = ""
        self._map_sent_t = -math.inf
        self.counters: Counter[str] = Counter()  # written on the event loop only
        #: written on zenoh's threads, under its lock
        self._thread_counters: Counter[str] = Counter()
        self._thread_lock = threading.Lock()
        self.sender = Sender(TELEMETRY)
        self.relay = RtcmRelay(self.cfg.rtcm_budget_bps, self._post_corrections)
        self.readers = [
            RingReader("heartbeat", HEARTBEAT_PERIOD_S, HEARTBEAT_RING, self._on_operator,
                       self._thread_fault),
            RingReader("rtcm", READ_PERIOD_S, RING, self.relay.on_sample, self._thread_fault)]
        self._buckets: dict[str, TokenBucket] = {}
        self.rlog = RateLimitedLog(log)
        ctx.listen(VesselStatus, self._on_status)
        ctx.listen(Event, self._on_event)
        ctx.listen(AuvTrack, self._on_track)
        self._inbox: Inbox | None = None
        self._tasks: set[asyncio.Task[None]] = set()
        self._session: Any = None

    # ------------------------------------------------------------- counters

    def _count(self, key: str, n: int = 1) -> None:
        """Count from any thread."""
        with self._thread_lock:
            self._thread_counters[key] += n

    def _thread_fault(self, exc: Exception) -> None:
        self._count("faults")
        log.debug("shore: %s: %s", type(exc).__name__, exc)

    def link_counters(self) -> dict[str, int]:
        """Every counter of the link (the ``health`` object's ``link``)."""
        with self._thread_lock:
            out = dict(self._thread_counters)
        out.update(self.counters)
        out.update(self.sender.counters())
        out.update(self.relay.counters())
        if self._inbox is not None:
            out.update(self._inbox.dropped)
        return out

    # ------------------------------------------------------------- outgoing

    def _put(self, key: str, obj: dict[str, Any]) -> None:
        """Queue a telemetry object for the sender thread (never blocks)."""
        if self._session is None:
            return
        self.sender.put(key, json.dumps(obj, separators=(",", ":")))

    def _utc(self, t: float) -> float:
        return self.clock.utc(t)

    def _on_status(self, st: VesselStatus) -> None:
        self._put("health", telemetry.health(self._utc(st.t), st, self.link_counters()))
        self._map_update(st.t)

    def _map_update(self, now: float) -> None:
        """Send the ``map`` object if it changed, or every :data:`MAP_PERIOD_S`."""
        obj = self.map.build(0.0, self.status.value, self.directive.value, self.buoy.value,
                             self.plan.value)
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

    def _mode(self) -> str:
        d = self.directive.value
        return d.mode.value if d is not None else "idle"

    def _reply(self, query: Any, key: str, ok: bool, cid: str | None, mode: str | None,
               reason: str) -> None:
        """Queue the one reply to ``query`` (never blocks)."""
        self.sender.reply(query, key, _reply_body(ok, cid, mode, reason))

    # ------------------------------------------------- zenoh's threads: read, bound, post

    def _on_query(self, query: Any) -> None:
        """A ``cmd/**`` query (zenoh's thread): posted, or refused here at once.

        A refusal made here (over the source's rate, the inbox full, a query that
        cannot be read) is answered on this thread, without the event loop or the
        sender's queue: a flood is refused at the pace its own client's traffic
        is read, and the other clients' replies do not queue behind it."""
        key = ""
        try:
            key = str(query.key_expr)
            att = query.attachment
            att_size = len(att) if att is not None else 0
            att_b = att.to_bytes() if att is not None and att_size <= MAX_ATTACHMENT_BYTES \
                else b""
            source = requests.peek_user(att_b)
            if not key.endswith("/cmd/stop") and not self._admit(source):
                self._count("commands_rate_limited")
                why = (f"busy: more than {self.cfg.commands_per_s:g} commands per second from "
                       f"shore{':' + source if source else ''}; not acted on")
            else:
                body = query.payload
                size = len(body) if body is not None else 0
                item = Query(query, key,
                             body.to_bytes() if body is not None and size <= MAX_COMMAND_BYTES
                             else b"", size, att_b, att_size)
                inbox = self._inbox
                if inbox is not None and inbox.post(item):
                    return
                why = "busy: too many commands queued" if inbox is not None else \
                    "shore link starting"
        except Exception as exc:  # an unreadable query still gets its reply
            self._count("faults")
            why = f"unreadable query ({type(exc).__name__})"
        self._count("commands_refused_at_once")
        try:
            query.reply(key, _reply_body(False, None, None, why))
        except Exception as exc:  # the query already gone, the session closing
            self._count("send_errors_at_once")
            log.debug("shore: reply failed: %s", exc)
        finally:
            with contextlib.suppress(Exception):
                query.drop()

    def _on_info_query(self, query: Any) -> None:
        """A query on ``map`` (the latest map object) or ``access`` (operators only,
        by access control: the answer says the asker may command); zenoh's thread,
        answered there (nothing to compute)."""
        try:
            key = str(query.key_expr)
            body = json.dumps({"role": "operator"}) if key.endswith("/access") else \
                self._map_json or json.dumps({"t": None})
            query.reply(key, body)
        except Exception as exc:  # the query already gone, the session closing
            self._count("send_errors_at_once")
            log.debug("shore: reply failed: %s", exc)
        finally:
            with contextlib.suppress(Exception):
                query.drop()

    def _admit(self, source: str) -> bool:
        """Whether ``source`` may send one more command now (its token bucket:
        ``commands_per_s``, a burst of twice that; ``stop`` is never limited)."""
        with self._thread_lock:
            b = self._buckets.get(source)
            if b is None:
                if len(self._buckets) >= SOURCES_MAX:
                    source = "\0others"
                    b = self._buckets.get(source)
                if b is None:
                    rate = self.cfg.commands_per_s
                    b = self._buckets[source] = TokenBucket(rate, 2.0 * rate)
        return b.take(1.0)

    def _on_operator(self, sample: Any) -> None:
        """An operator heartbeat (the heartbeat reader's thread): decoded, posted."""
        try:
            inbox = self._inbox
            if inbox is None:
                return
            if len(sample.payload) > MAX_HEARTBEAT_BYTES:
                self._count("bad_heartbeats")
                return
            user = requests.heartbeat(sample.payload.to_bytes())
        except BadRequest:
            self._count("bad_heartbeats")
            return
        except Exception:  # counted; the next heartbeat is read as usual
            self._count("faults")
            return
        inbox.post(Heartbeat(user))

    def _post_corrections(self, frames: bytes) -> None:
        """Whole valid frames from the relay thread, to the event loop."""
        inbox = self._inbox
        if inbox is not None:
            inbox.post(Corrections(frames))

    # ------------------------------------------------------- the event loop: act

    def _handle(self, item: Item) -> None:
        """One item from the inbox, on the event loop."""
        if isinstance(item, Query):
            self._command(item)
        elif isinstance(item, Heartbeat):
            self.counters["heartbeats"] += 1
            self.bus.publish(OperatorHeartbeat(self.clock.now(), "shore", item.user))
        else:
            self.counters["rtcm_bytes"] += len(item.data)
            self.bus.publish(RtcmCorrections(self.clock.now(), "shore", item.data))

    def _fault(self, item: Item | None, exc: BaseException, sent: bool = False) -> None:
        """An exception while handling ``item``: counted, a refusal for a command
        (a ``stop`` the link failed to read is sent anyway, unless ``sent``: the
        failure was in sending it)."""
        self.counters["faults"] += 1
        self.rlog.warning(f"fault:{type(exc).__name__}",
                          f"shore: {type(exc).__name__} handling "
                          f"{type(item).__name__ if item else 'a command'}: {exc}")
        if isinstance(item, Query):
            if item.key == f"{self.key}/cmd/stop" and not sent:
                with contextlib.suppress(Exception):
                    self._stop_anyway(item)  # a stop still stops
                    return
            self.counters["commands_refused"] += 1
            self._reply(item.query, item.key, False, None, self._mode(),
                        f"refused: the link failed to handle it ({type(exc).__name__})")

    def _command(self, q: Query) -> None:
        self.counters["commands"] += 1
        try:
            r = requests.request(q.key, self.key, q.payload, q.attachment, q.size,
                                 q.att_size)
        except BadRequest as exc:
            if q.key == f"{self.key}/cmd/stop":
                self._stop_anyway(q)
                return
            self.counters["commands_bad"] += 1
            self._reply(q.query, q.key, False, f"shore-{next(_ids)}", self._mode(),
                        f"bad request: {exc}")
            return
        cid = r.id or f"shore-{next(_ids)}"
        source = f"shore:{r.user}" if r.user else "shore"
        # the raw payload: the supervisor's command schema types it (a refusal
        # naming the field is acknowledged on the bus, so it is recorded too)
        task = asyncio.ensure_future(self._send_command(q, r.name, q.payload or b"{}", source,
                                                        cid))
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    def _stop_anyway(self, q: Query) -> None:
        """``stop`` is always accepted: whatever its payload or attachment, it is
        sent (with ``{}``; the attachment's user and id when they can be read)."""
        self.counters["stops_unread"] += 1
        try:
            user, cid = requests.attachment(q.attachment, q.att_size)
        except BadRequest:
            user, cid = requests.peek_user(q.attachment), None
        cid = cid or f"shore-{next(_ids)}"
        task = asyncio.ensure_future(self._send_command(
            q, "stop", b"{}", f"shore:{user}" if user else "shore", cid))
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _send_command(self, q: Query, name: str, args: bytes,
                            source: str, cid: str) -> None:
        try:
            ack = await self.commands.send(name, args, source=source, cmd_id=cid)
        except asyncio.CancelledError:
            # shutting down: the query still gets its one reply
            self._reply(q.query, q.key, False, cid, self._mode(), "shore link stopping")
            raise
        except Exception as exc:
            self._fault(q, exc, sent=True)
            return
        self.counters["commands_accepted" if ack.ok else "commands_refused"] += 1
        self._reply(q.query, q.key, ack.ok, ack.id, ack.mode, ack.reason)

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
            subs = [session.declare_subscriber(f"{self.key}/operator",
                                               zenoh.handlers.RingChannel(HEARTBEAT_RING)),
                    session.declare_subscriber(f"{self.key}/rtcm",
                                               zenoh.handlers.RingChannel(RING))]
        except BaseException:
            session.close()
            raise
        for reader, sub in zip(self.readers, subs, strict=True):
            reader.start(sub)
        return session, pubs

    def _close(self, session: Any) -> None:
        """Stop the threads and close the session (a worker thread)."""
        for reader in self.readers:
            reader.stop()
        self.sender.stop()
        if session is not None:
            session.close()

    async def run(self) -> None:
        loop = asyncio.get_running_loop()
        self._inbox = Inbox(loop, self._handle, self._fault)
        session: Any = None
        opening = loop.run_in_executor(None, self._open)
        try:
            session, pubs = await asyncio.shield(opening)
            self._session = session
            self.sender.start(pubs)
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
            for q in self._inbox.close():  # queries not yet handled get their reply
                self._reply(q.query, q.key, False, None, self._mode(), "shore link stopping")
            for task in list(self._tasks):
                task.cancel()
            if self._tasks:  # their replies go out before the sender stops
                with contextlib.suppress(asyncio.CancelledError):
                    await asyncio.gather(*self._tasks, return_exceptions=True)
            if session is None:  # cancelled while opening: close what the worker opens
                with contextlib.suppress(BaseException):
                    session, _ = await asyncio.shield(opening)
            closing = loop.run_in_executor(None, self._close, session)
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.shield(closing)
