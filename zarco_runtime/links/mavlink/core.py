"""What every part of the MAVLink endpoint shares: the settings, the bus and
clock, the connections, the counters, the command path to the supervisor, the
vessel as the supervisor's status says it (mode, armed, home: never a copy of
its own), and the few helpers each part needs (is a message addressed to the boat, send a
COMMAND_ACK or MISSION_ACK, say something as an event, run a coroutine as a
task of the endpoint)."""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Coroutine
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.commands import CommandRefused, decode
from zarco_core.component import ComponentContext
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import CommandAck, Event, Mode, VesselStatus
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.protocol import mav, text_chunks
from zarco_runtime.links.mavlink.settings import read_signing_key
from zarco_runtime.supervision.local import LocalCommands

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.mavlink")

#: an identical STATUSTEXT (or refusal notice) is not repeated within this time (s)
TEXT_REPEAT_S = 2.0
#: texts remembered for the repeat check
MAX_TEXTS = 256


@dataclass(slots=True)
class Counters:
    """What the endpoint did, since it started."""

    commands: int = 0
    commands_accepted: int = 0
    commands_refused: int = 0
    unsigned_refused: int = 0
    ignored: int = 0
    handler_errors: int = 0
    statustext: int = 0
    statustext_repeats: int = 0
    params_set: int = 0
    params_refused: int = 0
    missions_uploaded: int = 0
    missions_refused: int = 0
    manual_forwarded: int = 0
    gcs_heartbeats: int = 0
    telemetry: dict[str, int] = field(default_factory=dict)


class Core:
    """The endpoint's shared state and helpers (see the module docstring)."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock,
                 ctx: ComponentContext) -> None:
        self.cfg = cfg
        self.s = cfg.mavlink
        self.bus = bus
        self.clock = clock
        self.key = (read_signing_key(self.s.signing_key_file) if self.s.signing_key_file
                    else None)
        o = cfg.origin
        self.frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
        self.cmds = LocalCommands(bus, clock, source="mavlink", listen=ctx.listen)
        self.links: list[Link] = []
        self.counters = Counters()
        self._tasks: set[asyncio.Task[None]] = set()
        self.failure: BaseException | None = None
        #: the vessel as the supervisor last told it (mode, armed, home, mission)
        self.status: VesselStatus | None = None
        #: status texts sent to every link: text → when (s), for the repeat check
        self.texts: dict[str, float] = {}
        #: refusals told to one link: (link index, text) → when (s)
        self.told: dict[tuple[int, str], float] = {}
        self.text_id = 0

    # --------------------------------------------------------------- vessel

    @property
    def mode(self) -> Mode:
        """The supervisor's mode (idle before its first status)."""
        st = self.status
        if st is None:
            return Mode.IDLE
        try:
            return Mode(st.mode)
        except ValueError:
            return Mode.IDLE

    @property
    def armed(self) -> bool:
        """Armed, as the supervisor says."""
        return self.status is not None and self.status.armed

    @property
    def home(self) -> tuple[float, float] | None:
        """Home (lat, lon degrees) as the supervisor has it; None while unknown."""
        st = self.status
        if st is None or st.home_lat_deg is None or st.home_lon_deg is None:
            return None
        return st.home_lat_deg, st.home_lon_deg

    # ------------------------------------------------------------- commands

    async def supervise(self, name: str, args: dict[str, Any], src: int) -> CommandAck | None:
        """Command ``name`` with ``args`` (what a ground station's message maps to)
        to the supervisor as ``mavlink:<src>``: its acknowledgement, or None when
        the arguments are not a valid command (the field and the reason said as
        an event, so the ground station reads them as a STATUSTEXT)."""
        source = f"mavlink:{src}"
        try:
            typed = decode(name, args)
        except CommandRefused as exc:
            self.event("ack", f"{name} from {source}: refused: {exc}")
            return None
        return await self.cmds.send(name, typed, source=source)

    # ---------------------------------------------------------------- tasks

    def spawn(self, coro: Coroutine[Any, Any, None]) -> None:
        """Run ``coro`` as a task of the endpoint; if it raises, the endpoint fails
        (and is restarted)."""
        t = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(t)
        t.add_done_callback(self._task_done)

    def _task_done(self, t: asyncio.Task[None]) -> None:
        self._tasks.discard(t)
        if not t.cancelled() and t.exception() is not None:
            self.failure = t.exception()

    def cancel_tasks(self) -> None:
        for t in list(self._tasks):
            t.cancel()

    # ------------------------------------------------------------- messages

    def for_us(self, m: Any, sys_field: str = "target_system",
               comp_field: str | None = "target_component") -> bool:
        """Is ``m`` addressed to the boat (its system, or every system; its
        component, or every component)?"""
        ts = int(getattr(m, sys_field, 0))
        if ts not in (0, self.s.system_id):
            return False
        if comp_field is None:
            return True
        tc = int(getattr(m, comp_field, 0))
        return tc in (0, self.s.component_id)

    def command_ack(self, link: Link, src: int, comp: int, cmd: int, result: int) -> None:
        link.send(mav.MAVLink_command_ack_message(cmd, result, 0, 0, src, comp))

    def mission_ack(self, link: Link, src: int, comp: int, result: int,
                    mission_type: int = 0) -> None:
        link.send(mav.MAVLink_mission_ack_message(src, comp, result, mission_type))

    def broadcast_text(self, severity: int, text: str, now: float) -> bool:
        """``text`` as STATUSTEXT on every link, unless the same text went out
        within :data:`TEXT_REPEAT_S`; whether it was sent."""
        last = self.texts.get(text)
        if last is not None and now - last < TEXT_REPEAT_S:
            self.counters.statustext_repeats += 1
            return False
        self.texts[text] = now
        if len(self.texts) > MAX_TEXTS:
            self.texts = {k: v for k, v in self.texts.items() if now - v < TEXT_REPEAT_S}
            if len(self.texts) > MAX_TEXTS:  # a flood of distinct texts: forget them
                self.texts = {text: now}
        self.counters.statustext += 1
        for ln in self.links:
            self.send_text(ln, severity, text)
        return True

    def send_text(self, link: Link, severity: int, text: str) -> None:
        """``text`` as STATUSTEXT on ``link`` (chunked, bounded)."""
        chunks = text_chunks(text)
        tid = 0
        if len(chunks) > 1:
            self.text_id = self.text_id % 65535 + 1
            tid = self.text_id
        for i, c in enumerate(chunks):
            link.send(mav.MAVLink_statustext_message(severity, c, tid, i))

    def tell_refusal(self, link: Link, ack: CommandAck) -> None:
        """The supervisor's reason for refusing a ground station's command, to that
        ground station (before its COMMAND_ACK, PARAM_VALUE or MISSION_ACK), in
        the supervisor's words, unless every link has just had it as the
        supervisor's event: that event is held back when a source has had more
        than a few acknowledgements told in the last second, the reply never."""
        text = f"{ack.name} from {ack.source}: refused: {ack.reason}"
        now = self.clock.now()
        last = max(self.texts.get(text, -math.inf),
                   self.told.get((link.index, text), -math.inf))
        if now - last < TEXT_REPEAT_S:  # not again within 2 s (a flood: once)
            self.counters.statustext_repeats += 1
            return
        self.told[(link.index, text)] = now
        if len(self.told) > MAX_TEXTS:
            self.told = {k: v for k, v in self.told.items() if now - v < TEXT_REPEAT_S}
            if len(self.told) > MAX_TEXTS:
                self.told = {(link.index, text): now}
        self.send_text(link, int(mav.MAV_SEVERITY_WARNING), text)

    def event(self, kind: str, text: str) -> None:
        """An event of this endpoint's own: logged, on the bus, and so to every GCS."""
        log.info("%s: %s", kind, text)
        self.bus.publish(Event(self.clock.now(), kind, text, "mavlink"))
