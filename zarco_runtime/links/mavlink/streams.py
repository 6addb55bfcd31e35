"""Stream scheduling: which message goes out on which connection, how often.

Each connection has its own rate per stream (defaults from
``[mavlink] rates_hz`` over :data:`~.settings.STREAMS`); a ground station
changes them with SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM (ArduPilot's
groups) or asks for one message with REQUEST_MESSAGE.  Telemetry goes on a
connection's telemetry queue (the oldest dropped when a link cannot keep up),
except the HEARTBEAT and MISSION_CURRENT, which keep their order with the
replies.  Another system's heartbeat (the AUV's) follows the boat's on each
link, so that a ground station hears the boat first and makes it its vehicle."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from zarco_runtime.links.mavlink.builders import Builder
from zarco_runtime.links.mavlink.core import Core
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.protocol import mav, whole
from zarco_runtime.links.mavlink.settings import MAX_RATE_HZ, STREAMS

log = logging.getLogger("zarco.mavlink")

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
#: the longest the scheduler sleeps (s), so that a new connection starts soon
TICK_S = 0.05


@dataclass(slots=True)
class Stream:
    """One message's schedule on one connection."""

    interval_s: float  # 0: not streamed
    next_t: float = 0.0


class Streams:
    """The per-connection schedules and the requests that change them."""

    def __init__(self, core: Core, builders: dict[str, Builder],
                 autopilot_version: Callable[[], Any],
                 after_heartbeat: Callable[[Link], None] | None = None) -> None:
        missing = set(STREAMS) - set(builders)
        if missing:
            raise ValueError(f"no builder for {', '.join(sorted(missing))}")
        self.core = core
        self.builders = builders
        self.autopilot_version = autopilot_version
        #: called with the link after each of the boat's heartbeats on it
        self.after_heartbeat = after_heartbeat

    def add(self, link: Link, now: float) -> None:
        """Give ``link`` the default schedule, starting at ``now``."""
        rates = self.core.s.rates_hz
        for name, hz in STREAMS.items():
            hz = rates.get(name, hz)
            link.streams[name] = Stream(1.0 / hz if hz > 0 else 0.0, now)

    def build(self, name: str, now: float) -> Any:
        return self.builders[name](now)

    def send_due(self, now: float) -> float:
        """Send every stream that is due on every connected link; the next time
        one is due (at most :data:`TICK_S` ahead)."""
        nxt = now + TICK_S
        counters = self.core.counters
        for link in self.core.links:
            if not link.connected:
                continue
            for name, st in link.streams.items():
                if st.interval_s <= 0.0:
                    continue
                if now >= st.next_t:
                    try:
                        self._send(link, name, now)
                    except Exception:  # one message's bug must not stop the others
                        counters.handler_errors += 1
                        if counters.handler_errors <= 10:
                            log.exception("mavlink: building %s", name)
                    st.next_t += st.interval_s
                    if st.next_t <= now:
                        st.next_t = now + st.interval_s
                nxt = min(nxt, st.next_t)
        return nxt

    def _send(self, link: Link, name: str, now: float) -> None:
        msg = self.build(name, now)
        if msg is None:
            return
        c = self.core.counters.telemetry
        c[name] = c.get(name, 0) + 1
        # in order with the replies: the heartbeat, and MISSION_CURRENT (also sent
        # as a reply at every change, so a queued older one must not follow it)
        link.send(msg, reply=name in ("HEARTBEAT", "MISSION_CURRENT"))
        if name == "HEARTBEAT" and self.after_heartbeat is not None:
            self.after_heartbeat(link)

    def broadcast(self, name: str, now: float) -> None:
        """Send ``name`` now on every connected link (nothing when it has nothing
        to say), in order with the replies."""
        for link in self.core.links:
            if link.connected:
                msg = self.build(name, now)  # one message object per link
                if msg is not None:
                    link.send(msg)

    # ------------------------------------------------------------ requests

    def on_request_data_stream(self, link: Link, m: Any) -> None:
        if not self.core.for_us(m):
            return
        sid = int(m.req_stream_id)
        names = (tuple(n for n in STREAMS if n not in ("HEARTBEAT", "HOME_POSITION"))
                 if sid == mav.MAV_DATA_STREAM_ALL else DATA_STREAMS.get(sid, ()))
        hz = float(m.req_message_rate) if int(m.start_stop) else 0.0
        for name in names:
            self.set_rate(link, name, hz)

    def set_rate(self, link: Link, name: str, hz: float) -> None:
        st = link.streams[name]
        hz = min(MAX_RATE_HZ, hz)
        st.interval_s = 1.0 / hz if hz > 0.0 else 0.0
        st.next_t = self.core.clock.now()

    def set_interval(self, link: Link, msg_id: int, interval_us: float) -> int:
        """SET_MESSAGE_INTERVAL: the MAV_RESULT."""
        name = MSG_NAME.get(msg_id)
        if name is None or name == "HEARTBEAT":
            return int(mav.MAV_RESULT_DENIED)
        if interval_us == 0.0:  # the default rate
            hz = self.core.s.rates_hz.get(name, STREAMS[name])
        elif interval_us < 0.0:
            hz = 0.0
        else:
            hz = 1e6 / interval_us
        self.set_rate(link, name, hz)
        return int(mav.MAV_RESULT_ACCEPTED)

    def request_message(self, link: Link, msg_id: int, p2: float) -> int:
        """REQUEST_MESSAGE (and GET_MESSAGE_INTERVAL): the MAV_RESULT; the message
        goes out before its acknowledgement."""
        now = self.core.clock.now()
        if msg_id == mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            link.send(self.autopilot_version())
        elif msg_id == mav.MAVLINK_MSG_ID_MESSAGE_INTERVAL:
            asked = whole(p2, 0, 0xFFFF)
            name = MSG_NAME.get(asked) if asked is not None else None
            if asked is None or name is None:
                return int(mav.MAV_RESULT_DENIED)
            st = link.streams[name]
            us = int(st.interval_s * 1e6) if st.interval_s > 0 else -1
            link.send(mav.MAVLink_message_interval_message(asked, us))
        elif msg_id in MSG_NAME:
            msg = self.build(MSG_NAME[msg_id], now)
            if msg is None:
                return int(mav.MAV_RESULT_TEMPORARILY_REJECTED)
            link.send(msg)
        else:
            return int(mav.MAV_RESULT_DENIED)
        return int(mav.MAV_RESULT_ACCEPTED)
