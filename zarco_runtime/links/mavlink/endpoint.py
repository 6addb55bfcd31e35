"""The MAVLink endpoint: the boat as QGroundControl and MAVProxy see it.

One supervised component serves every ``[mavlink] url`` (each on its own
thread, :mod:`.link`).  This module wires the parts and dispatches what
arrives: the telemetry (:mod:`.builders`) on per-connection schedules
(:mod:`.streams`), the mission protocol (:mod:`.transfer`), commands
(:mod:`.commands`), parameters (:mod:`.param_protocol`), corrections
(:mod:`.rtcm`), the runtime's events as STATUSTEXT, and the tracked AUV as a
second system (:mod:`.auv`).  The boat is a MAV_TYPE_SURFACE_BOAT with
MAV_AUTOPILOT_GENERIC, system ``system_id``, component ``component_id``.

Out, on every connection:

* HEARTBEAT at 1 Hz, from the supervisor's first status on (a ground station
  that hears the boat can ask for its home and get it): the armed flag, the
  custom mode of the supervisor's mode (:mod:`.protocol`), system status
  STANDBY (idle), ACTIVE, or CRITICAL while a failsafe is active;
* streams at rates a GCS sets (SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM) per
  connection: SYS_STATUS, GPS_RAW_INT (RTK float / fixed as fix types 5 / 6),
  GLOBAL_POSITION_INT, ATTITUDE, VFR_HUD, SERVO_OUTPUT_RAW (the commanded
  thrust as PWM), MISSION_CURRENT (also at every change), HOME_POSITION (on
  request, and at once when the supervisor's home becomes known or moves);
* a STATUSTEXT for every Event of the runtime (mode changes, acknowledgements,
  failsafes, faults), an identical text at most every 2 s;
* MISSION_ITEM_REACHED as each waypoint of the mission is passed.

In: what a GCS asks on connect (the parameter protocol, :mod:`.params`;
AUTOPILOT_VERSION; REQUEST_MESSAGE; mission download), and the commands, every
one through the supervisor as ``mavlink:<system id>`` and answered with a
COMMAND_ACK (or MISSION_ACK):

==============================  =======================================================
MAVLink                         supervisor
==============================  =======================================================
mission upload (MISSION_COUNT,  ``mission {"waypoints", "speed_mps", "start": false}``
MISSION_ITEM_INT …)             (:mod:`.mission`); MISSION_ACK accepted or refused
MISSION_CLEAR_ALL, 0 items      ``mission {"clear": true}`` (refused while it runs)
MAV_CMD_MISSION_START           ``mode {"mode": "lines"}`` (starts the loaded mission)
COMPONENT_ARM_DISARM            ``arm`` / ``disarm`` (disarmed is idle: zero thrust)
DO_SET_MODE, SET_MODE           ``mode`` of the custom mode (:mod:`.protocol`)
NAV_RETURN_TO_LAUNCH            ``mode {"mode": "return"}``
NAV_LOITER_UNLIM                ``mode {"mode": "hold"}`` (at the given point, if any)
MANUAL_CONTROL                  ``thrust {"u1", "u2"}`` (manual mode; renews the lease)
GPS_RTCM_DATA                   RtcmCorrections(source="mavlink"), blocks reassembled
HEARTBEAT from a GCS            OperatorHeartbeat(link="mavlink") (``failsafe.link``)
==============================  =======================================================

Arguments are built with the typed command schema (:mod:`zarco_core.commands`).
COMMAND_ACK results: ACCEPTED; TEMPORARILY_REJECTED when the supervisor refuses
(its reason goes just before, as a STATUSTEXT to the ground station that
asked, even when the supervisor's event of it is held back); DENIED for arguments the boat does not
take (the schema's field and reason follow as a STATUSTEXT); UNSUPPORTED for
commands it does not know; FAILED when the supervisor did not answer.  Mode,
armed and home are the supervisor's (its VesselStatus), never copies of the
endpoint's own.  A MANUAL_CONTROL is passed on when it changes the thrust or every
0.2 s, so that the lease (``supervisor.manual_lease_s``) lasts while the GCS
sends and ends when it stops.

Signing (``signing_key_file``): everything sent is signed; a message that is not
signed with the key (unsigned, wrong key, replayed) is refused: a command gets
COMMAND_ACK DENIED, a mission upload MISSION_ACK DENIED, a parameter write the
unchanged value, and nothing else it asks is done (its heartbeat does not keep
the link alive).
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from zarco_core.auv_messages import AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.component import ComponentContext
from zarco_core.messages import (
    Event,
    GpsFix,
    GuidanceStatus,
    OperatorHeartbeat,
    ParamChange,
    RtcmCorrections,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.links.mavlink.auv import AuvSystem
from zarco_runtime.links.mavlink.builders import Telemetry
from zarco_runtime.links.mavlink.commands import Commands
from zarco_runtime.links.mavlink.core import TEXT_REPEAT_S, Core, Counters
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.param_protocol import ParamProtocol
from zarco_runtime.links.mavlink.protocol import event_severity, mav
from zarco_runtime.links.mavlink.rtcm import RtcmReassembler
from zarco_runtime.links.mavlink.streams import Streams
from zarco_runtime.links.mavlink.transfer import MissionTransfer

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.mavlink")

#: a GCS heard again after this long is announced again (s)
GCS_QUIET_S = 5.0


class MavlinkEndpoint:
    """The MAVLink endpoint component (see the module docstring)."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock,
                 ctx: ComponentContext) -> None:
        self.core = core = Core(cfg, bus, clock, ctx)
        self.telemetry = Telemetry(core)
        self.transfer = MissionTransfer(core)
        self.auv = AuvSystem(core)
        self.streams = Streams(core, {**self.telemetry.builders(),
                                      "MISSION_CURRENT": lambda now: self.transfer.current()},
                               self.telemetry.autopilot_version, self.auv.after_boat_heartbeat)
        self.commands = Commands(core, self.streams, self.transfer)
        self.params = ParamProtocol(core)
        self.rtcm = RtcmReassembler()
        self.dir_seq = -1
        self.unsigned_t: dict[tuple[int, str], float] = {}
        self.gcs_seen: dict[int, float] = {}
        ctx.listen(Event, self._on_event)
        ctx.listen(GpsFix, self.telemetry.on_fix)
        ctx.listen(Directive, self._on_directive)
        ctx.listen(GuidanceStatus, self.transfer.on_guidance)
        ctx.listen(VesselStatus, self._on_status)
        ctx.listen(AuvTrack, self.auv.on_track)
        ctx.listen(ParamChange, self.params.on_change)
        t, cm, p = self.transfer, self.commands, self.params
        self._handlers: dict[str, Callable[[Link, Any], None]] = {
            "HEARTBEAT": self._on_heartbeat,
            "COMMAND_LONG": lambda ln, m: cm.on_command(ln, m, False),
            "COMMAND_INT": lambda ln, m: cm.on_command(ln, m, True),
            "SET_MODE": cm.on_set_mode,
            "PARAM_REQUEST_LIST": p.on_list,
            "PARAM_REQUEST_READ": p.on_read,
            "PARAM_SET": p.on_set,
            "MISSION_COUNT": t.on_count,
            "MISSION_ITEM_INT": lambda ln, m: t.on_item(ln, m, True),
            "MISSION_ITEM": lambda ln, m: t.on_item(ln, m, False),
            "MISSION_REQUEST_LIST": t.on_request_list,
            "MISSION_REQUEST_INT": lambda ln, m: t.on_request(ln, m, True),
            "MISSION_REQUEST": lambda ln, m: t.on_request(ln, m, False),
            "MISSION_CLEAR_ALL": t.on_clear,
            "MISSION_SET_CURRENT": t.on_set_current,
            "MISSION_ACK": lambda ln, m: None,
            "MANUAL_CONTROL": cm.on_manual,
            "GPS_RTCM_DATA": self._on_rtcm,
            "REQUEST_DATA_STREAM": self.streams.on_request_data_stream,
        }

    @property
    def links(self) -> list[Link]:
        return self.core.links

    @property
    def counters(self) -> Counters:
        return self.core.counters

    # ================================================================ running

    async def run(self) -> None:
        loop = asyncio.get_running_loop()
        core = self.core
        s = core.s
        now = core.clock.now()
        for i, url in enumerate(s.urls()):
            link = Link(url, i, s.system_id, s.component_id, core.key, loop,
                        self._on_messages)
            self.streams.add(link, now)
            core.links.append(link)
        log.info("MAVLink endpoint, system %d component %d%s, on %s", s.system_id,
                 s.component_id, ", signed" if core.key else "", ", ".join(s.urls()))
        for link in core.links:
            link.start()
        try:
            await self._tick_loop()
        finally:
            for link in core.links:
                link.stop()
            core.cancel_tasks()

    async def _tick_loop(self) -> None:
        core = self.core
        clock = core.clock
        while True:
            if core.failure is not None:
                raise core.failure  # fails the component (restarted)
            now = clock.now()
            self._poll(now)
            await clock.sleep_until(self.streams.send_due(now))

    def _poll(self, now: float) -> None:
        for block in self.rtcm.poll(now):
            self.core.bus.publish(RtcmCorrections(now, "mavlink", block))
        self.transfer.poll(now)

    # ============================================================= receiving

    def _on_messages(self, link: Link, msgs: list[Any]) -> None:
        counters = self.core.counters
        for m in msgs:
            try:
                self._handle(link, m)
            except Exception:  # a GCS's odd message must not stop the endpoint
                counters.handler_errors += 1
                if counters.handler_errors <= 10:
                    log.exception("mavlink: handling %s from %d", m.get_type(),
                                  m.get_srcSystem())

    def _handle(self, link: Link, m: Any) -> None:
        core = self.core
        name = m.get_type()
        sender = (m.get_srcSystem(), m.get_srcComponent())
        if sender in ((core.s.system_id, core.s.component_id), self.auv.source):
            return  # our own, echoed (broadcast)
        h = self._handlers.get(name)
        if h is None:
            core.counters.ignored += 1
            return
        if self.auv.addressed(m):
            self.auv.on_message(link, m, name)
            return
        if core.key is not None and not getattr(m, "_signed", False):
            self._refuse_unsigned(link, m, name)
            return
        h(link, m)

    def _refuse_unsigned(self, link: Link, m: Any, name: str) -> None:
        core = self.core
        core.counters.unsigned_refused += 1
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        if name in ("COMMAND_LONG", "COMMAND_INT") and core.for_us(m):
            core.command_ack(link, src, comp, int(m.command), mav.MAV_RESULT_DENIED)
        elif name == "SET_MODE" and core.for_us(m, comp_field=None):
            core.command_ack(link, src, comp, mav.MAVLINK_MSG_ID_SET_MODE,
                             mav.MAV_RESULT_DENIED)
        elif name in ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM",
                      "MISSION_CLEAR_ALL") and core.for_us(m):
            core.mission_ack(link, src, comp, mav.MAV_MISSION_DENIED,
                             int(getattr(m, "mission_type", 0)))
        elif name == "PARAM_SET" and core.for_us(m):
            self.params.refuse_unsigned(link, m)
        else:
            return  # heartbeats, reads, corrections, joystick: dropped
        now = core.clock.now()
        if now - self.unsigned_t.get((src, name), -math.inf) >= TEXT_REPEAT_S:
            self.unsigned_t[(src, name)] = now  # said at most every 2 s per sender and kind
            core.event("link", f"unsigned or wrongly signed {name} from mavlink:{src} "
                       "refused")

    def _on_heartbeat(self, link: Link, m: Any) -> None:
        if m.type != mav.MAV_TYPE_GCS:
            return
        core = self.core
        src = m.get_srcSystem()
        now = core.clock.now()
        core.counters.gcs_heartbeats += 1
        core.bus.publish(OperatorHeartbeat(now, "mavlink", str(src)))
        last = self.gcs_seen.get(src)
        self.gcs_seen[src] = now
        if last is None or now - last > GCS_QUIET_S:
            core.event("link", f"ground station mavlink:{src} on {link.url}")

    def _on_rtcm(self, link: Link, m: Any) -> None:
        n = int(m.len)
        data = bytes(m.data[:n]) if n <= len(m.data) else bytes(n)  # too long: refused
        now = self.core.clock.now()
        for block in self.rtcm.feed(int(m.flags), data, now):
            self.core.bus.publish(RtcmCorrections(now, "mavlink", block))

    # ============================================================ bus → GCS

    def _on_status(self, st: VesselStatus) -> None:
        core = self.core
        home = core.home
        core.status = st
        if core.home is not None and core.home != home:
            # a ground station that asked before home was known gets it now
            self.streams.broadcast("HOME_POSITION", core.clock.now())
        self.transfer.on_status(st)
        self.telemetry.measure_load()

    def _on_directive(self, d: Directive) -> None:
        if d.seq == self.dir_seq:
            return
        self.dir_seq = d.seq
        self.transfer.on_directive(d)

    def _on_event(self, e: Event) -> None:
        core = self.core
        core.broadcast_text(event_severity(e.kind, e.text), e.text, core.clock.now())
