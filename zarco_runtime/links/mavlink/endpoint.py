"""The MAVLink endpoint: the boat as QGroundControl and MAVProxy see it.

One supervised component serves every ``[mavlink] url`` (each on its own
thread, :mod:`.link`).  The boat is a MAV_TYPE_SURFACE_BOAT with
MAV_AUTOPILOT_GENERIC, system ``system_id``, component ``component_id``.

Out, on every connection:

* HEARTBEAT at 1 Hz: the armed flag, the custom mode of the supervisor's mode
  (:mod:`.protocol`), system status STANDBY (idle), ACTIVE, or CRITICAL while a
  failsafe is active;
* streams at rates a GCS sets (SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM) per
  connection: SYS_STATUS, GPS_RAW_INT (RTK float / fixed as fix types 5 / 6),
  GLOBAL_POSITION_INT, ATTITUDE, VFR_HUD, SERVO_OUTPUT_RAW (the commanded
  thrust as PWM), MISSION_CURRENT (also at every change), HOME_POSITION (on
  request);
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
MAV_CMD_MISSION_START           ``mode {"mode": "lines"}`` (starts the loaded mission)
COMPONENT_ARM_DISARM            ``arm`` / ``disarm`` (disarmed is idle: zero thrust)
DO_SET_MODE, SET_MODE           ``mode`` of the custom mode (:mod:`.protocol`)
NAV_RETURN_TO_LAUNCH            ``mode {"mode": "return"}``
NAV_LOITER_UNLIM                ``mode {"mode": "hold"}`` (at the given point, if any)
MANUAL_CONTROL                  ``thrust {"u1", "u2"}`` (manual mode; renews the lease)
GPS_RTCM_DATA                   RtcmCorrections(source="mavlink"), blocks reassembled
HEARTBEAT from a GCS            OperatorHeartbeat(link="mavlink") (``failsafe.link``)
==============================  =======================================================

COMMAND_ACK results: ACCEPTED; TEMPORARILY_REJECTED when the supervisor refuses
(its reason follows as a STATUSTEXT); DENIED for arguments the boat does not
take; UNSUPPORTED for commands it does not know; FAILED when the supervisor did
not answer.  A MANUAL_CONTROL is passed on when it changes the thrust or every
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
import contextlib
import functools
import logging
import math
import time
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, field
from importlib import metadata
from typing import TYPE_CHECKING, Any

from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.component import ComponentContext
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    Attitude,
    CommandAck,
    Event,
    FixQuality,
    GpsFix,
    GpsVelocity,
    GuidanceStatus,
    Mode,
    NavState,
    OperatorHeartbeat,
    RtcmCorrections,
    ThrusterCommand,
    VesselStatus,
)
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.mission import MAX_ITEMS, Item, items_from_mission, parse_items
from zarco_runtime.links.mavlink.params import ParamTable
from zarco_runtime.links.mavlink.protocol import (
    CUSTOM_MODE,
    MODE_OF_CUSTOM,
    UINT16_MAX,
    base_mode,
    event_severity,
    mav,
    mix_manual,
    text_chunks,
    thrust_to_pwm,
)
from zarco_runtime.links.mavlink.rtcm import RtcmReassembler
from zarco_runtime.links.mavlink.settings import MAX_RATE_HZ, STREAMS, read_signing_key
from zarco_runtime.supervision.local import LocalCommands

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

log = logging.getLogger("zarco.mavlink")

#: an identical STATUSTEXT is not repeated within this time (s)
TEXT_REPEAT_S = 2.0
#: MANUAL_CONTROL → thrust: pass on a change at most this often, a steady command this often (s)
MANUAL_MIN_S = 0.04
MANUAL_KEEP_S = 0.2
#: mission upload: re-request an item after this long, this many times (s, count)
UPLOAD_RETRY_S = 1.0
UPLOAD_RETRIES = 5
#: a GCS heard again after this long is announced again (s)
GCS_QUIET_S = 5.0
#: REQUEST_DATA_STREAM groups (ArduPilot's): stream id → messages
DATA_STREAMS: dict[int, tuple[str, ...]] = {
    mav.MAV_DATA_STREAM_EXTENDED_STATUS: ("SYS_STATUS", "GPS_RAW_INT", "MISSION_CURRENT"),
    mav.MAV_DATA_STREAM_RC_CHANNELS: ("SERVO_OUTPUT_RAW",),
    mav.MAV_DATA_STREAM_POSITION: ("GLOBAL_POSITION_INT",),
    mav.MAV_DATA_STREAM_EXTRA1: ("ATTITUDE",),
    mav.MAV_DATA_STREAM_EXTRA2: ("VFR_HUD",),
}
MSG_ID = {name: int(getattr(mav, f"MAVLINK_MSG_ID_{name}")) for name in STREAMS}
MSG_NAME = {v: k for k, v in MSG_ID.items()}
#: GpsFix quality → GPS_RAW_INT fix_type
FIX_TYPE = {
    FixQuality.NONE: mav.GPS_FIX_TYPE_NO_FIX,
    FixQuality.SINGLE: mav.GPS_FIX_TYPE_3D_FIX,
    FixQuality.DGPS: mav.GPS_FIX_TYPE_DGPS,
    FixQuality.RTK_FLOAT: mav.GPS_FIX_TYPE_RTK_FLOAT,
    FixQuality.RTK_FIXED: mav.GPS_FIX_TYPE_RTK_FIXED,
}
#: a GpsFix older than this is reported as no fix (s)
GPS_STALE_S = 2.0


@dataclass(slots=True)
class Stream:
    interval_s: float  # 0: not streamed
    next_t: float = 0.0


@dataclass(slots=True)
class _Upload:
    """A mission upload in progress, from one GCS on one link."""

    link: Link
    sysid: int
    compid: int
    count: int
    items: list[Item | None]
    next: int = 0
    t_last: float = 0.0
    retries: int = 0
    done: bool = False


@dataclass(slots=True)
class _Manual:
    u1: float = 0.0
    u2: float = 0.0
    t: float = -math.inf


@dataclass(slots=True)
class Counters:
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


def _r(x: float) -> int:
    """``x`` rounded to an integer for a message field; 0 when not a number (a
    message must never fail to build on a NaN from an estimator)."""
    return round(x) if math.isfinite(x) else 0


@functools.cache
def _version() -> int:
    """``flight_sw_version``: major, minor, patch, type (dev) in the four bytes."""
    try:
        parts = [int(x) for x in metadata.version("zarco-runtime").split(".")[:3]]
    except (metadata.PackageNotFoundError, ValueError):
        parts = [0, 0, 0]
    parts += [0] * (3 - len(parts))
    return (parts[0] << 24) | (parts[1] << 16) | (parts[2] << 8) | int(
        mav.FIRMWARE_VERSION_TYPE_DEV)


class MavlinkEndpoint:
    """The MAVLink endpoint component (see the module docstring)."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock,
                 ctx: ComponentContext) -> None:
        s = cfg.mavlink
        self.cfg = cfg
        self.s = s
        self.bus = bus
        self.clock = clock
        self.key = read_signing_key(s.signing_key_file) if s.signing_key_file else None
        o = cfg.origin
        self.frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
        self.cmds = LocalCommands(bus, clock, source="mavlink", listen=ctx.listen)
        self.params = ParamTable(cfg)
        self.rtcm = RtcmReassembler()
        self.nav = bus.latest(NavState)
        self.gps = bus.latest(GpsFix)
        self.vel = bus.latest(GpsVelocity)
        self.att = bus.latest(Attitude)
        self.thrust = bus.latest(ThrusterCommand)
        self.status: VesselStatus | None = None
        ctx.listen(Event, self._on_event)
        ctx.listen(Directive, self._on_directive)
        ctx.listen(GuidanceStatus, self._on_guidance)
        ctx.listen(VesselStatus, self._on_status)
        ctx.listen(CommandAck, self._on_ack)
        ctx.listen(NavState, self._on_nav)
        self.links: list[Link] = []
        self.counters = Counters()
        self.mode = Mode.IDLE
        self.armed = False
        self.dir_seq = -1
        self.home: tuple[float, float] | None = None
        if cfg.supervisor.home:
            self.home = (float(cfg.supervisor.home[0]), float(cfg.supervisor.home[1]))
        # the mission as a GCS sees it
        self.items: list[Item] = []
        self.wp_seqs: list[int] = []
        self.wps: tuple[tuple[float, float], ...] = ()
        self.mission_state = mav.MISSION_STATE_NO_MISSION
        self.cur = 0  # the waypoint (index into wps) the boat is heading for
        self.upload: _Upload | None = None
        self.cleared = False  # the GCS cleared the mission (MISSION_CLEAR_ALL, count 0)
        self.unsigned_t: dict[tuple[int, str], float] = {}
        self.manual = _Manual()
        self.texts: dict[str, float] = {}
        self.text_id = 0
        self.gcs_seen: dict[int, float] = {}
        self.cpu = (time.process_time(), time.monotonic())
        self.load_permille = 0
        self._tasks: set[asyncio.Task[None]] = set()
        self._failure: BaseException | None = None
        self._handlers: dict[str, Callable[[Link, Any], None]] = {
            "HEARTBEAT": self._on_heartbeat,
            "COMMAND_LONG": lambda ln, m: self._on_command(ln, m, False),
            "COMMAND_INT": lambda ln, m: self._on_command(ln, m, True),
            "SET_MODE": self._on_set_mode,
            "PARAM_REQUEST_LIST": self._on_param_list,
            "PARAM_REQUEST_READ": self._on_param_read,
            "PARAM_SET": self._on_param_set,
            "MISSION_COUNT": self._on_mission_count,
            "MISSION_ITEM_INT": lambda ln, m: self._on_mission_item(ln, m, True),
            "MISSION_ITEM": lambda ln, m: self._on_mission_item(ln, m, False),
            "MISSION_REQUEST_LIST": self._on_mission_request_list,
            "MISSION_REQUEST_INT": lambda ln, m: self._on_mission_request(ln, m, True),
            "MISSION_REQUEST": lambda ln, m: self._on_mission_request(ln, m, False),
            "MISSION_CLEAR_ALL": self._on_mission_clear,
            "MISSION_SET_CURRENT": self._on_mission_set_current,
            "MISSION_ACK": lambda ln, m: None,
            "MANUAL_CONTROL": self._on_manual,
            "GPS_RTCM_DATA": self._on_rtcm,
            "REQUEST_DATA_STREAM": self._on_request_data_stream,
        }

    # ================================================================ running

    async def run(self) -> None:
        loop = asyncio.get_running_loop()
        s = self.s
        now = self.clock.now()
        for i, url in enumerate(s.urls()):
            link = Link(url, i, s.system_id, s.component_id, self.key, loop,
                        self._on_messages)
            for name, hz in STREAMS.items():
                hz = s.rates_hz.get(name, hz)
                link.streams[name] = Stream(1.0 / hz if hz > 0 else 0.0, now)
            self.links.append(link)
        log.info("MAVLink endpoint, system %d component %d%s, on %s", s.system_id,
                 s.component_id, ", signed" if self.key else "", ", ".join(s.urls()))
        for link in self.links:
            link.start()
        try:
            await self._tick_loop()
        finally:
            for link in self.links:
                link.stop()
            for t in list(self._tasks):
                t.cancel()

    async def _tick_loop(self) -> None:
        clock = self.clock
        while True:
            if self._failure is not None:
                raise self._failure
            now = clock.now()
            self._poll(now)
            nxt = now + 0.05
            for link in self.links:
                if not link.connected:
                    continue
                for name, st in link.streams.items():
                    if st.interval_s <= 0.0:
                        continue
                    if now >= st.next_t:
                        try:
                            self._send_stream(link, name, now)
                        except Exception:  # one message's bug must not stop the others
                            self.counters.handler_errors += 1
                            if self.counters.handler_errors <= 10:
                                log.exception("mavlink: building %s", name)
                        st.next_t += st.interval_s
                        if st.next_t <= now:
                            st.next_t = now + st.interval_s
                    nxt = min(nxt, st.next_t)
            await clock.sleep_until(nxt)

    def _spawn(self, coro: Coroutine[Any, Any, None]) -> None:
        t = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(t)
        t.add_done_callback(self._task_done)

    def _task_done(self, t: asyncio.Task[None]) -> None:
        self._tasks.discard(t)
        if not t.cancelled() and t.exception() is not None:
            self._failure = t.exception()  # fails the component (restarted)

    def _poll(self, now: float) -> None:
        for block in self.rtcm.poll(now):
            self.bus.publish(RtcmCorrections(now, "mavlink", block))
        up = self.upload
        if up is not None and not up.done and now - up.t_last > UPLOAD_RETRY_S:
            if up.retries >= UPLOAD_RETRIES:
                self.upload = None
                self._mission_ack(up.link, up.sysid, up.compid,
                                  mav.MAV_MISSION_OPERATION_CANCELLED)
                self._event("mission", f"mission upload from mavlink:{up.sysid} timed out at "
                            f"item {up.next} of {up.count}")
            else:
                up.retries += 1
                self._request_item(up, now)

    # ============================================================= receiving

    def _on_messages(self, link: Link, msgs: list[Any]) -> None:
        for m in msgs:
            try:
                self._handle(link, m)
            except Exception:  # a GCS's odd message must not stop the endpoint
                self.counters.handler_errors += 1
                if self.counters.handler_errors <= 10:
                    log.exception("mavlink: handling %s from %d", m.get_type(),
                                  m.get_srcSystem())

    def _handle(self, link: Link, m: Any) -> None:
        name = m.get_type()
        if m.get_srcSystem() == self.s.system_id and \
                m.get_srcComponent() == self.s.component_id:
            return  # our own, echoed (broadcast)
        h = self._handlers.get(name)
        if h is None:
            self.counters.ignored += 1
            return
        if self.key is not None and not getattr(m, "_signed", False):
            self._refuse_unsigned(link, m, name)
            return
        h(link, m)

    def _for_us(self, m: Any, sys_field: str = "target_system",
                comp_field: str | None = "target_component") -> bool:
        ts = int(getattr(m, sys_field, 0))
        if ts not in (0, self.s.system_id):
            return False
        if comp_field is None:
            return True
        tc = int(getattr(m, comp_field, 0))
        return tc in (0, self.s.component_id)

    def _refuse_unsigned(self, link: Link, m: Any, name: str) -> None:
        self.counters.unsigned_refused += 1
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        if name in ("COMMAND_LONG", "COMMAND_INT") and self._for_us(m):
            self._command_ack(link, src, comp, int(m.command), mav.MAV_RESULT_DENIED)
        elif name == "SET_MODE" and self._for_us(m, comp_field=None):
            self._command_ack(link, src, comp, mav.MAVLINK_MSG_ID_SET_MODE,
                              mav.MAV_RESULT_DENIED)
        elif name in ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM",
                      "MISSION_CLEAR_ALL") and self._for_us(m):
            self._mission_ack(link, src, comp, mav.MAV_MISSION_DENIED,
                              int(getattr(m, "mission_type", 0)))
        elif name == "PARAM_SET" and self._for_us(m):
            p = self.params.find(str(m.param_id), -1)
            if p is not None:
                self._param_value(link, p)
        else:
            return  # heartbeats, reads, corrections, joystick: dropped
        now = self.clock.now()
        if now - self.unsigned_t.get((src, name), -math.inf) >= TEXT_REPEAT_S:
            self.unsigned_t[(src, name)] = now  # said at most every 2 s per sender and kind
            self._event("link", f"unsigned or wrongly signed {name} from mavlink:{src} "
                        "refused")

    # ------------------------------------------------------------- heartbeat

    def _on_heartbeat(self, link: Link, m: Any) -> None:
        if m.type != mav.MAV_TYPE_GCS:
            return
        src = m.get_srcSystem()
        now = self.clock.now()
        self.counters.gcs_heartbeats += 1
        self.bus.publish(OperatorHeartbeat(now, "mavlink", str(src)))
        last = self.gcs_seen.get(src)
        self.gcs_seen[src] = now
        if last is None or now - last > GCS_QUIET_S:
            self._event("link", f"ground station mavlink:{src} on {link.url}")

    # -------------------------------------------------------------- commands

    def _on_command(self, link: Link, m: Any, is_int: bool) -> None:
        if not self._for_us(m):
            return
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        cmd = int(m.command)
        p1, p2 = float(m.param1), float(m.param2)
        self.counters.commands += 1

        def ack(result: int) -> None:
            self._command_ack(link, src, comp, cmd, result)

        def supervise(name: str, args: dict[str, Any]) -> None:
            self._spawn(self._supervised(link, src, comp, cmd, name, args))

        if cmd == mav.MAV_CMD_COMPONENT_ARM_DISARM:
            if p1 == 1.0:
                supervise("arm", {})
            elif p1 == 0.0:
                supervise("disarm", {})
            else:
                ack(mav.MAV_RESULT_DENIED)
        elif cmd == mav.MAV_CMD_DO_SET_MODE:
            self._set_mode(link, src, comp, cmd, int(p1), p2)
        elif cmd == mav.MAV_CMD_MISSION_START:
            if self.cleared:
                self._event("mission", f"MISSION_START from mavlink:{src} refused: the "
                            "mission was cleared")
                ack(mav.MAV_RESULT_DENIED)
            else:
                supervise("mode", {"mode": Mode.LINES.value})
        elif cmd == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            supervise("mode", {"mode": Mode.RETURN.value})
        elif cmd == mav.MAV_CMD_NAV_LOITER_UNLIM:
            if is_int:
                lat, lon = float(m.x) / 1e7, float(m.y) / 1e7
            else:
                lat, lon = float(m.param5), float(m.param6)
            args: dict[str, Any] = {"mode": Mode.HOLD.value}
            if math.isfinite(lat) and math.isfinite(lon) and (lat != 0.0 or lon != 0.0):
                args.update(lat_deg=lat, lon_deg=lon)
            supervise("mode", args)
        elif cmd == mav.MAV_CMD_REQUEST_MESSAGE:
            ack(self._request_message(link, src, comp, int(p1), p2))
        elif cmd == mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            ack(mav.MAV_RESULT_ACCEPTED)
            link.send(self._autopilot_version())
        elif cmd == mav.MAV_CMD_SET_MESSAGE_INTERVAL:
            ack(self._set_interval(link, int(p1), p2))
        elif cmd == mav.MAV_CMD_GET_MESSAGE_INTERVAL:
            r = self._request_message(link, src, comp, mav.MAVLINK_MSG_ID_MESSAGE_INTERVAL, p1)
            ack(r)
        else:
            ack(mav.MAV_RESULT_UNSUPPORTED)

    def _on_set_mode(self, link: Link, m: Any) -> None:
        if not self._for_us(m, comp_field=None):
            return
        self.counters.commands += 1
        self._set_mode(link, m.get_srcSystem(), m.get_srcComponent(),
                       mav.MAVLINK_MSG_ID_SET_MODE, int(m.base_mode), float(m.custom_mode))

    def _set_mode(self, link: Link, src: int, comp: int, cmd: int, base: int,
                  custom: float) -> None:
        mode = MODE_OF_CUSTOM.get(int(custom)) if custom == int(custom) else None
        if not base & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or mode is None:
            table = ", ".join(f"{v} {k.value}" for k, v in CUSTOM_MODE.items())
            self._event("mode", f"mode change from mavlink:{src} refused: custom mode "
                        f"{custom:g} unknown (custom modes: {table})")
            self._command_ack(link, src, comp, cmd, mav.MAV_RESULT_DENIED)
            return
        if mode is Mode.LINES and self.cleared:
            self._event("mission", f"mode lines from mavlink:{src} refused: the mission "
                        "was cleared")
            self._command_ack(link, src, comp, cmd, mav.MAV_RESULT_DENIED)
            return
        self._spawn(self._supervised(link, src, comp, cmd, "mode", {"mode": mode.value}))

    async def _supervised(self, link: Link, src: int, comp: int, cmd: int, name: str,
                          args: dict[str, Any]) -> None:
        ack = await self.cmds.send(name, args, source=f"mavlink:{src}")
        if ack.ok:
            self.counters.commands_accepted += 1
            result = mav.MAV_RESULT_ACCEPTED
        else:
            self.counters.commands_refused += 1
            result = (mav.MAV_RESULT_FAILED if ack.mode == "unknown"
                      else mav.MAV_RESULT_TEMPORARILY_REJECTED)
        self._command_ack(link, src, comp, cmd, result)

    def _command_ack(self, link: Link, src: int, comp: int, cmd: int, result: int) -> None:
        link.send(mav.MAVLink_command_ack_message(cmd, result, 0, 0, src, comp))

    # ---------------------------------------------------------- joystick, RTCM

    def _on_manual(self, link: Link, m: Any) -> None:
        if int(m.target) not in (0, self.s.system_id):
            return
        u1, u2 = mix_manual(int(m.x), int(m.r))
        now = self.clock.now()
        last = self.manual
        changed = abs(u1 - last.u1) >= 0.5 or abs(u2 - last.u2) >= 0.5
        dt = now - last.t
        if not ((changed and dt >= MANUAL_MIN_S) or dt >= MANUAL_KEEP_S):
            return
        self.manual = _Manual(u1, u2, now)
        self.counters.manual_forwarded += 1
        self._spawn(self._thrust(m.get_srcSystem(), u1, u2))

    async def _thrust(self, src: int, u1: float, u2: float) -> None:
        await self.cmds.send("thrust", {"u1": round(u1, 3), "u2": round(u2, 3)},
                             source=f"mavlink:{src}")

    def _on_rtcm(self, link: Link, m: Any) -> None:
        n = int(m.len)
        data = bytes(m.data[:n]) if n <= len(m.data) else bytes(n)  # too long: refused
        now = self.clock.now()
        for block in self.rtcm.feed(int(m.flags), data, now):
            self.bus.publish(RtcmCorrections(now, "mavlink", block))

    # ------------------------------------------------------------ parameters

    def _param_value(self, link: Link, p: Any) -> None:
        link.send(mav.MAVLink_param_value_message(p.name.encode(), self.params.value(p),
                                                  p.ptype, len(self.params), p.index))

    def _on_param_list(self, link: Link, m: Any) -> None:
        if not self._for_us(m):
            return
        for p in self.params.params:
            self._param_value(link, p)

    def _on_param_read(self, link: Link, m: Any) -> None:
        if not self._for_us(m):
            return
        p = self.params.find(str(m.param_id), int(m.param_index))
        if p is not None:
            self._param_value(link, p)

    def _on_param_set(self, link: Link, m: Any) -> None:
        if not self._for_us(m):
            return
        src = m.get_srcSystem()
        name = str(m.param_id)
        p = self.params.find(name, -1)
        if p is None:
            self._event("param", f"parameter {name} from mavlink:{src} refused: no such "
                        "parameter")
            return
        why, old, new = self.params.set(p, float(m.param_value))
        if why:
            self.counters.params_refused += 1
            self._event("param", f"parameter from mavlink:{src} refused: {why}")
            self._param_value(link, p)
            return
        self.counters.params_set += 1
        self._event("param", f"{p.name} ({p.section}.{p.field}) = {new} (was {old}) by "
                    f"mavlink:{src}")
        for ln in self.links:  # every GCS sees the new value
            self._param_value(ln, p)

    # --------------------------------------------------------------- mission

    def _mission_ack(self, link: Link, src: int, comp: int, result: int,
                     mission_type: int = 0) -> None:
        link.send(mav.MAVLink_mission_ack_message(src, comp, result, mission_type))

    def _on_mission_count(self, link: Link, m: Any) -> None:
        if not self._for_us(m):
            return
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        mtype = int(getattr(m, "mission_type", 0))
        count = int(m.count)
        if mtype != mav.MAV_MISSION_TYPE_MISSION:
            self._mission_ack(link, src, comp, mav.MAV_MISSION_ACCEPTED if count == 0
                              else mav.MAV_MISSION_UNSUPPORTED, mtype)
            return
        up = self.upload
        if up is not None and not up.done and (up.link, up.sysid) != (link, src):
            self._mission_ack(link, src, comp, mav.MAV_MISSION_DENIED)
            self._event("mission", f"mission upload from mavlink:{src} refused: another "
                        f"upload (mavlink:{up.sysid}) is in progress")
            return
        if count == 0:
            self.upload = None
            self._clear_mission()
            self._mission_ack(link, src, comp, mav.MAV_MISSION_ACCEPTED)
            return
        if count > MAX_ITEMS:
            self._mission_ack(link, src, comp, mav.MAV_MISSION_NO_SPACE)
            return
        self.upload = up = _Upload(link, src, comp, count, [None] * count)
        self._request_item(up, self.clock.now())

    def _request_item(self, up: _Upload, now: float) -> None:
        up.t_last = now
        up.link.send(mav.MAVLink_mission_request_int_message(up.sysid, up.compid, up.next,
                                                             mav.MAV_MISSION_TYPE_MISSION))

    def _on_mission_item(self, link: Link, m: Any, is_int: bool) -> None:
        if not self._for_us(m):
            return
        up = self.upload
        src = m.get_srcSystem()
        if up is None or up.done or (up.link, up.sysid) != (link, src):
            return
        if int(getattr(m, "mission_type", 0)) != mav.MAV_MISSION_TYPE_MISSION:
            return
        seq = int(m.seq)
        now = self.clock.now()
        if seq != up.next:
            if seq > up.next:  # one went missing: ask again for the one we need
                self._request_item(up, now)
            return  # a repeat of one we have
        up.items[seq] = Item.from_msg(m, is_int)
        up.next += 1
        up.retries = 0
        if up.next < up.count:
            self._request_item(up, now)
            return
        up.done = True
        self._spawn(self._finish_upload(up))

    async def _finish_upload(self, up: _Upload) -> None:
        items = [it for it in up.items if it is not None]
        parsed = parse_items(items, self.s.mission_speed_mps)
        source = f"mavlink:{up.sysid}"
        if parsed.result != mav.MAV_MISSION_ACCEPTED:
            self.counters.missions_refused += 1
            self._event("mission", f"mission upload from {source} refused: {parsed.reason}")
            self._mission_ack(up.link, up.sysid, up.compid, parsed.result)
        else:
            ack = await self.cmds.send("mission", {
                "waypoints": [[lat, lon] for lat, lon in parsed.waypoints],
                "speed_mps": parsed.speed_mps, "start": False,
                "name": f"{len(parsed.waypoints)} waypoints from {source}"}, source=source)
            if ack.ok:
                self.counters.missions_uploaded += 1
                self.cleared = False
                self.items = items
                self.wp_seqs = parsed.wp_seqs
                self.wps = tuple(parsed.waypoints)
                self.cur = 0
                self.mission_state = mav.MISSION_STATE_NOT_STARTED
                self._mission_ack(up.link, up.sysid, up.compid, mav.MAV_MISSION_ACCEPTED)
                self._broadcast_mission_current()
            else:
                self.counters.missions_refused += 1
                self._mission_ack(up.link, up.sysid, up.compid,
                                  mav.MAV_MISSION_ERROR if ack.mode == "unknown"
                                  else mav.MAV_MISSION_INVALID)
        if self.upload is up:
            self.upload = None

    def _clear_mission(self) -> None:
        # the supervisor keeps the mission it had loaded (it has no command to drop
        # it): starting it is refused here until a new one is uploaded
        self.cleared = True
        self.items, self.wp_seqs, self.wps = [], [], ()
        self.cur = 0
        self.mission_state = mav.MISSION_STATE_NO_MISSION
        self._broadcast_mission_current()

    def _on_mission_clear(self, link: Link, m: Any) -> None:
        if not self._for_us(m):
            return
        mtype = int(getattr(m, "mission_type", 0))
        if mtype in (mav.MAV_MISSION_TYPE_MISSION, mav.MAV_MISSION_TYPE_ALL):
            self._clear_mission()
        self._mission_ack(link, m.get_srcSystem(), m.get_srcComponent(),
                          mav.MAV_MISSION_ACCEPTED, mtype)

    def _on_mission_request_list(self, link: Link, m: Any) -> None:
        if not self._for_us(m):
            return
        mtype = int(getattr(m, "mission_type", 0))
        n = len(self.items) if mtype == mav.MAV_MISSION_TYPE_MISSION else 0
        link.send(mav.MAVLink_mission_count_message(m.get_srcSystem(), m.get_srcComponent(),
                                                    n, mtype))

    def _on_mission_request(self, link: Link, m: Any, is_int: bool) -> None:
        if not self._for_us(m):
            return
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        mtype = int(getattr(m, "mission_type", 0))
        seq = int(m.seq)
        if mtype != mav.MAV_MISSION_TYPE_MISSION or not 0 <= seq < len(self.items):
            self._mission_ack(link, src, comp, mav.MAV_MISSION_INVALID_SEQUENCE, mtype)
            return
        it = self.items[seq]
        current = int(self.mission_state == mav.MISSION_STATE_ACTIVE
                      and self.wp_seqs[min(self.cur, len(self.wp_seqs) - 1)] == seq)
        if is_int:
            x, y = it.int_xy()
            link.send(mav.MAVLink_mission_item_int_message(
                src, comp, seq, it.frame, it.command, current, it.autocontinue, it.param1,
                it.param2, it.param3, it.param4, x, y, it.z, mtype))
        else:
            link.send(mav.MAVLink_mission_item_message(
                src, comp, seq, it.frame, it.command, current, it.autocontinue, it.param1,
                it.param2, it.param3, it.param4, it.x, it.y, it.z, mtype))

    def _on_mission_set_current(self, link: Link, m: Any) -> None:
        if not self._for_us(m):
            return
        self._event("mission", f"MISSION_SET_CURRENT from mavlink:{m.get_srcSystem()} "
                    "refused: a mission runs from its start (or `resume`)")
        link.send(self._mission_current())

    # ---------------------------------------------------------------- streams

    def _on_request_data_stream(self, link: Link, m: Any) -> None:
        if not self._for_us(m):
            return
        sid = int(m.req_stream_id)
        names = (tuple(n for n in STREAMS if n not in ("HEARTBEAT", "HOME_POSITION"))
                 if sid == mav.MAV_DATA_STREAM_ALL else DATA_STREAMS.get(sid, ()))
        hz = float(m.req_message_rate) if int(m.start_stop) else 0.0
        for name in names:
            self._set_rate(link, name, hz)

    def _set_rate(self, link: Link, name: str, hz: float) -> None:
        st = link.streams[name]
        hz = min(MAX_RATE_HZ, hz)
        st.interval_s = 1.0 / hz if hz > 0.0 else 0.0
        st.next_t = self.clock.now()

    def _set_interval(self, link: Link, msg_id: int, interval_us: float) -> int:
        name = MSG_NAME.get(msg_id)
        if name is None or name == "HEARTBEAT":
            return int(mav.MAV_RESULT_DENIED)
        if interval_us == 0.0:  # the default rate
            hz = self.s.rates_hz.get(name, STREAMS[name])
        elif interval_us < 0.0:
            hz = 0.0
        else:
            hz = 1e6 / interval_us
        self._set_rate(link, name, hz)
        return int(mav.MAV_RESULT_ACCEPTED)

    def _request_message(self, link: Link, src: int, comp: int, msg_id: int,
                         p2: float) -> int:
        now = self.clock.now()
        if msg_id == mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            link.send(self._autopilot_version())
        elif msg_id == mav.MAVLINK_MSG_ID_MESSAGE_INTERVAL:
            name = MSG_NAME.get(int(p2))
            if name is None:
                return int(mav.MAV_RESULT_DENIED)
            st = link.streams[name]
            us = int(st.interval_s * 1e6) if st.interval_s > 0 else -1
            link.send(mav.MAVLink_message_interval_message(int(p2), us))
        elif msg_id in MSG_NAME:
            msg = self._build(MSG_NAME[msg_id], now)
            if msg is None:
                return int(mav.MAV_RESULT_TEMPORARILY_REJECTED)
            link.send(msg)
        else:
            return int(mav.MAV_RESULT_DENIED)
        return int(mav.MAV_RESULT_ACCEPTED)

    def _send_stream(self, link: Link, name: str, now: float) -> None:
        msg = self._build(name, now)
        if msg is None:
            return
        c = self.counters.telemetry
        c[name] = c.get(name, 0) + 1
        # in order with the replies: the heartbeat, and MISSION_CURRENT (also sent
        # as a reply at every change, so a queued older one must not follow it)
        link.send(msg, reply=name in ("HEARTBEAT", "MISSION_CURRENT"))

    def _build(self, name: str, now: float) -> Any:
        return getattr(self, f"_msg_{name.lower()}")(now)

    @staticmethod
    def _boot_ms(now: float) -> int:
        return int(now * 1000.0) & 0xFFFFFFFF

    def _usec(self, now: float) -> int:
        return int(self.clock.utc(now) * 1e6)

    def _msg_heartbeat(self, now: float) -> Any:
        st = self.status
        if st is None:
            state = mav.MAV_STATE_BOOT
        elif st.failsafes:
            state = mav.MAV_STATE_CRITICAL
        elif self.armed:
            state = mav.MAV_STATE_ACTIVE
        else:
            state = mav.MAV_STATE_STANDBY
        return mav.MAVLink_heartbeat_message(
            mav.MAV_TYPE_SURFACE_BOAT, mav.MAV_AUTOPILOT_GENERIC,
            base_mode(self.mode, self.armed), CUSTOM_MODE[self.mode], state, 3)

    def _msg_sys_status(self, now: float) -> Any:
        dev = self.cfg.devices
        st = self.status
        n = self.nav.value

        def ok(name: str) -> bool:
            d = st.devices.get(name) if st is not None else None
            return d is not None and d.state == "ok"

        present = health = 0
        for bit, on, good in (
            (mav.MAV_SYS_STATUS_SENSOR_GPS, dev.gps.enabled, ok("gps")),
            (mav.MAV_SYS_STATUS_SENSOR_3D_MAG, dev.compass.enabled, ok("compass")),
            (mav.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS, dev.thrusters.enabled, ok("thrusters")),
            (mav.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL, True,
             n is not None and n.pos_valid),
            (mav.MAV_SYS_STATUS_SENSOR_YAW_POSITION, True, n is not None and n.heading_valid),
        ):
            if on:
                present |= bit
                if good:
                    health |= bit
        # the geofence as ArduPilot reports it: healthy unless breached (a GCS says
        # "fence breach" when this bit drops)
        fence = self.cfg.geofence
        if fence.radius_m > 0.0 or fence.polygon:
            present |= mav.MAV_SYS_STATUS_GEOFENCE
        if st is None or "geofence" not in st.failsafes:
            health |= mav.MAV_SYS_STATUS_GEOFENCE
        sent = sum(ln.sent for ln in self.links) or 1
        drops = sum(ln.dropped_telemetry for ln in self.links)
        errors = min(UINT16_MAX, sum(ln.bad_data for ln in self.links))
        return mav.MAVLink_sys_status_message(
            present, present, health, self.load_permille, UINT16_MAX, -1, -1,
            min(10000, int(10000 * drops / (sent + drops))), errors, 0, 0, 0, 0)

    def _msg_gps_raw_int(self, now: float) -> Any:
        if not self.cfg.devices.gps.enabled:
            return mav.MAVLink_gps_raw_int_message(self._usec(now), mav.GPS_FIX_TYPE_NO_GPS,
                                                   0, 0, 0, UINT16_MAX, UINT16_MAX,
                                                   UINT16_MAX, UINT16_MAX, 255)
        g = self.gps.value
        v = self.vel.value
        if g is None or g.lat_deg is None or g.lon_deg is None \
                or not (math.isfinite(g.lat_deg) and math.isfinite(g.lon_deg)):
            return mav.MAVLink_gps_raw_int_message(self._usec(now), mav.GPS_FIX_TYPE_NO_FIX,
                                                   0, 0, 0, UINT16_MAX, UINT16_MAX,
                                                   UINT16_MAX, UINT16_MAX, 255)
        fix = FIX_TYPE[g.fix] if now - g.t <= GPS_STALE_S else mav.GPS_FIX_TYPE_NO_FIX
        vel = cog = UINT16_MAX
        if v is not None and now - v.t <= GPS_STALE_S:
            vel = min(UINT16_MAX - 1, _r(v.sog_mps * 100.0))
            if v.cog_rad is not None:
                cog = _r(math.degrees(v.cog_rad) * 100.0) % 36000
        eph = (min(UINT16_MAX - 1, _r(g.hdop * 100.0)) if g.hdop is not None
               else UINT16_MAX)
        return mav.MAVLink_gps_raw_int_message(
            self._usec(now), fix, _r(g.lat_deg * 1e7), _r(g.lon_deg * 1e7),
            _r((g.alt_m or 0.0) * 1000.0), eph, UINT16_MAX, vel, cog,
            g.num_sats if g.num_sats is not None else 255)

    def _msg_global_position_int(self, now: float) -> Any:
        n = self.nav.value
        if n is None or not (math.isfinite(n.lat_deg) and math.isfinite(n.lon_deg)):
            return None
        alt = _r(self.cfg.origin.alt_m * 1000.0)
        hdg = _r(math.degrees(n.psi_rad) * 100.0) % 36000
        return mav.MAVLink_global_position_int_message(
            self._boot_ms(now), _r(n.lat_deg * 1e7), _r(n.lon_deg * 1e7),
            alt, 0, _r(n.vn_mps * 100.0), _r(n.ve_mps * 100.0), 0, hdg)

    def _msg_attitude(self, now: float) -> Any:
        n = self.nav.value
        if n is None:
            return None
        a = self.att.value
        roll = a.roll_rad if a is not None and a.roll_rad is not None else 0.0
        pitch = a.pitch_rad if a is not None and a.pitch_rad is not None else 0.0
        return mav.MAVLink_attitude_message(self._boot_ms(now), roll, pitch,
                                            math.remainder(n.psi_rad, math.tau), 0.0, 0.0,
                                            n.r_rps)

    def _msg_vfr_hud(self, now: float) -> Any:
        n = self.nav.value
        if n is None:
            return None
        c = self.thrust.value
        throttle = 0 if c is None else _r(min(100.0, abs(c.u1 + c.u2) / 2.0))
        hdg = _r(math.degrees(n.psi_rad)) % 360
        return mav.MAVLink_vfr_hud_message(n.u_mps, math.hypot(n.vn_mps, n.ve_mps), hdg,
                                           throttle, self.cfg.origin.alt_m, 0.0)

    def _msg_servo_output_raw(self, now: float) -> Any:
        c = self.thrust.value
        u1, u2 = (0.0, 0.0) if c is None else (c.u1, c.u2)
        return mav.MAVLink_servo_output_raw_message(
            int(now * 1e6) & 0xFFFFFFFF, 0, thrust_to_pwm(u1), thrust_to_pwm(u2),
            0, 0, 0, 0, 0, 0)

    def _mission_current(self) -> Any:
        seq = 0
        if self.wp_seqs:
            seq = self.wp_seqs[min(self.cur, len(self.wp_seqs) - 1)]
        return mav.MAVLink_mission_current_message(
            seq, len(self.items), self.mission_state, int(self.mode is Mode.LINES))

    def _msg_mission_current(self, now: float) -> Any:
        return self._mission_current()

    def _msg_home_position(self, now: float) -> Any:
        if self.home is None:
            return None
        lat, lon = self.home
        x, y = self.frame.to_ned(lat, lon)
        return mav.MAVLink_home_position_message(
            _r(lat * 1e7), _r(lon * 1e7),
            _r(self.cfg.origin.alt_m * 1000.0), x, y, 0.0, [1.0, 0.0, 0.0, 0.0],
            0.0, 0.0, 0.0, self._usec(now))

    def _autopilot_version(self) -> Any:
        caps = (mav.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
                | mav.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                | mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | mav.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | mav.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST)
        return mav.MAVLink_autopilot_version_message(
            caps, _version(), 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, self.s.system_id)

    # ============================================================ bus → GCS

    def _on_nav(self, n: NavState) -> None:
        if self.home is None and n.pos_valid and math.isfinite(n.lat_deg) \
                and math.isfinite(n.lon_deg):
            self.home = (n.lat_deg, n.lon_deg)  # as the supervisor: the first valid position

    def _on_status(self, st: VesselStatus) -> None:
        self.status = st
        self.armed = st.armed
        with contextlib.suppress(ValueError):
            self.mode = Mode(st.mode)
        p, w = time.process_time(), time.monotonic()
        p0, w0 = self.cpu
        if w > w0:
            self.load_permille = max(0, min(1000, int(1000.0 * (p - p0) / (w - w0))))
        self.cpu = (p, w)

    def _on_ack(self, a: CommandAck) -> None:
        if a.ok and a.name == "arm":
            self.armed = True

    def _on_directive(self, d: Directive) -> None:
        if d.seq == self.dir_seq:
            return
        self.dir_seq = d.seq
        self.mode = d.mode
        self.armed = d.mode is not Mode.IDLE
        m = d.mission
        if d.mode is Mode.LINES and m is not None and m.legs:
            if not (self.wps and m.waypoints == self.wps):
                self.items, self.wp_seqs, self.wps = items_from_mission(m, self.frame)
            self.cur = max(0, min(d.start_leg, len(self.wps) - 1))
            self.mission_state = mav.MISSION_STATE_ACTIVE
        elif self.mission_state == mav.MISSION_STATE_ACTIVE:
            self.mission_state = mav.MISSION_STATE_PAUSED
        self._broadcast_mission_current()

    def _on_guidance(self, g: GuidanceStatus) -> None:
        # the last status of a mission (complete) comes after the supervisor has
        # already switched to hold, because of it
        if g.mode != "lines" or not self.wps or not (
                self.mission_state == mav.MISSION_STATE_ACTIVE
                or (g.complete and self.mission_state == mav.MISSION_STATE_PAUSED)):
            return
        last = len(self.wps) - 1
        if g.complete:
            c = last + 1
        elif g.leg == 0 and g.along_m < 0.0:
            c = 0
        else:
            c = min(last, g.leg + 1)
        if c <= self.cur and not g.complete:
            return
        for k in range(self.cur, min(c, last + 1)):
            for ln in self.links:
                ln.send(mav.MAVLink_mission_item_reached_message(self.wp_seqs[k]))
        self.cur = min(c, last)
        if g.complete:
            self.mission_state = mav.MISSION_STATE_COMPLETE
        self._broadcast_mission_current()

    def _broadcast_mission_current(self) -> None:
        for ln in self.links:
            ln.send(self._mission_current())

    def _event(self, kind: str, text: str) -> None:
        """An event of this endpoint's own: logged, on the bus, and so to every GCS."""
        log.info("%s: %s", kind, text)
        self.bus.publish(Event(self.clock.now(), kind, text, "mavlink"))

    def _on_event(self, e: Event) -> None:
        now = self.clock.now()
        last = self.texts.get(e.text)
        if last is not None and now - last < TEXT_REPEAT_S:
            self.counters.statustext_repeats += 1
            return
        self.texts[e.text] = now
        if len(self.texts) > 256:
            self.texts = {k: v for k, v in self.texts.items() if now - v < TEXT_REPEAT_S}
        sev = event_severity(e.kind, e.text)
        chunks = text_chunks(e.text)
        tid = 0
        if len(chunks) > 1:
            self.text_id = self.text_id % 65535 + 1
            tid = self.text_id
        self.counters.statustext += 1
        for ln in self.links:
            for i, c in enumerate(chunks):
                ln.send(mav.MAVLink_statustext_message(sev, c, tid, i))
