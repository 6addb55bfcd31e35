"""Commands from a ground station, every one through the supervisor.

COMMAND_LONG and COMMAND_INT (arming, modes, mission start, return, hold),
SET_MODE and MANUAL_CONTROL become supervisor commands with source
``mavlink:<system id>``; each COMMAND_LONG / COMMAND_INT / SET_MODE gets one
COMMAND_ACK: ACCEPTED; TEMPORARILY_REJECTED when the supervisor refuses (its
reason goes just before, as a STATUSTEXT to that ground station,
:meth:`.Core.tell_refusal`); DENIED for arguments the boat does not take;
UNSUPPORTED for commands it does not know; FAILED when the supervisor did not
answer.  The requests a ground station makes on connecting (REQUEST_MESSAGE,
capabilities, message intervals) are answered here without the supervisor.

A MANUAL_CONTROL is passed on when it changes the thrust or every
:data:`MANUAL_KEEP_S`, so that the lease (``supervisor.manual_lease_s``) lasts
while the GCS sends and ends when it stops."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from zarco_core.messages import Mode
from zarco_runtime.links.mavlink.core import Core
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.protocol import (
    CUSTOM_MODE,
    MODE_OF_CUSTOM,
    mav,
    mix_manual,
    whole,
)
from zarco_runtime.links.mavlink.streams import Streams
from zarco_runtime.links.mavlink.transfer import MissionTransfer

log = logging.getLogger("zarco.mavlink")

#: COMPONENT_ARM_DISARM param2 that asks to force arming or disarming (MAVLink's
#: 21196; ArduPilot's and MAVProxy's ``arm throttle force`` send 2989 to arm):
#: never a way round the arming checks here, a forced arm is an ordinary one
FORCE = (2989.0, 21196.0)
#: the largest MAVLink 2 message id (24 bits)
MSG_ID_MAX = 0xFFFFFF
#: MANUAL_CONTROL → thrust: pass on a change at most this often, a steady command this often (s)
MANUAL_MIN_S = 0.04
MANUAL_KEEP_S = 0.2


@dataclass(slots=True)
class Manual:
    """The last joystick thrust passed on: U1, U2 (%) at ``t`` (s)."""

    u1: float = 0.0
    u2: float = 0.0
    t: float = -math.inf


class Commands:
    """COMMAND_LONG, COMMAND_INT, SET_MODE and MANUAL_CONTROL (see the module
    docstring)."""

    def __init__(self, core: Core, streams: Streams, transfer: MissionTransfer) -> None:
        self.core = core
        self.streams = streams
        self.transfer = transfer
        self.manual = Manual()

    def on_command(self, link: Link, m: Any, is_int: bool) -> None:
        """A COMMAND_LONG or COMMAND_INT: exactly one COMMAND_ACK, now or when the
        supervisor has answered, whatever its parameters (NaN, infinite, out of
        range: DENIED; a failure of ours: FAILED)."""
        c = self.core
        if not c.for_us(m):
            return
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        cmd = int(m.command)
        c.counters.commands += 1
        answered = False

        def ack(result: int) -> None:
            nonlocal answered
            if not answered:
                answered = True
                c.command_ack(link, src, comp, cmd, result)

        def supervise(name: str, args: dict[str, Any], refused_note: str = "") -> None:
            nonlocal answered
            answered = True  # by the task, once the supervisor has answered
            c.spawn(self._supervised(link, src, comp, cmd, name, args, refused_note))

        try:
            self._command(link, m, is_int, src, cmd, ack, supervise)
        except Exception:  # a bug of ours on an odd command: it still gets its answer
            c.counters.handler_errors += 1
            log.exception("mavlink: command %d from %d", cmd, src)
            ack(mav.MAV_RESULT_FAILED)

    def _command(self, link: Link, m: Any, is_int: bool, src: int, cmd: int,
                 ack: Callable[[int], None],
                 supervise: Callable[[str, dict[str, Any], str], None]) -> None:
        p1, p2 = float(m.param1), float(m.param2)
        if cmd == mav.MAV_CMD_COMPONENT_ARM_DISARM:
            if p1 == 1.0:
                supervise("arm", {}, f"arm from mavlink:{src}: force ({p2:g}) does not bypass "
                          "the arming checks" if p2 in FORCE else "")
            elif p1 == 0.0:
                supervise("disarm", {}, "")
            else:
                ack(mav.MAV_RESULT_DENIED)
        elif cmd == mav.MAV_CMD_DO_SET_MODE:
            base = whole(p1, 0, 255)
            if base is None:
                ack(mav.MAV_RESULT_DENIED)
            else:
                self._set_mode(link, src, m.get_srcComponent(), cmd, base, p2)
        elif cmd == mav.MAV_CMD_MISSION_START:
            supervise("mode", {"mode": Mode.LINES.value}, "")
        elif cmd == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            supervise("mode", {"mode": Mode.RETURN.value}, "")
        elif cmd == mav.MAV_CMD_NAV_LOITER_UNLIM:
            if is_int:
                lat, lon = float(m.x) / 1e7, float(m.y) / 1e7
            else:
                lat, lon = float(m.param5), float(m.param6)
            args: dict[str, Any] = {"mode": Mode.HOLD.value}
            if math.isfinite(lat) and math.isfinite(lon) and (lat != 0.0 or lon != 0.0):
                args.update(lat_deg=lat, lon_deg=lon)
            supervise("mode", args, "")
        elif cmd == mav.MAV_CMD_REQUEST_MESSAGE:
            msg_id = whole(p1, 0, MSG_ID_MAX)
            ack(mav.MAV_RESULT_DENIED if msg_id is None
                else self.streams.request_message(link, msg_id, p2))
        elif cmd == mav.MAV_CMD_GET_HOME_POSITION:  # deprecated, still asked
            ack(self.streams.request_message(link, mav.MAVLINK_MSG_ID_HOME_POSITION, 0.0))
        elif cmd == mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            link.send(self.streams.autopilot_version())
            ack(mav.MAV_RESULT_ACCEPTED)
        elif cmd == mav.MAV_CMD_SET_MESSAGE_INTERVAL:
            msg_id = whole(p1, 0, MSG_ID_MAX)
            ack(mav.MAV_RESULT_DENIED if msg_id is None or not math.isfinite(p2)
                else self.streams.set_interval(link, msg_id, p2))
        elif cmd == mav.MAV_CMD_GET_MESSAGE_INTERVAL:
            ack(mav.MAV_RESULT_DENIED if whole(p1, 0, MSG_ID_MAX) is None
                else self.streams.request_message(link, mav.MAVLINK_MSG_ID_MESSAGE_INTERVAL,
                                                  p1))
        else:
            ack(mav.MAV_RESULT_UNSUPPORTED)

    def on_set_mode(self, link: Link, m: Any) -> None:
        c = self.core
        if not c.for_us(m, comp_field=None):
            return
        c.counters.commands += 1
        self._set_mode(link, m.get_srcSystem(), m.get_srcComponent(),
                       mav.MAVLINK_MSG_ID_SET_MODE, int(m.base_mode), float(m.custom_mode))

    def _set_mode(self, link: Link, src: int, comp: int, cmd: int, base: int,
                  custom: float) -> None:
        c = self.core
        number = whole(custom, 0, 0xFFFFFFFF)
        mode = MODE_OF_CUSTOM.get(number) if number is not None else None
        if not base & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or mode is None:
            table = ", ".join(f"{v} {k.value}" for k, v in CUSTOM_MODE.items())
            c.event("mode", f"mode change from mavlink:{src} refused: custom mode "
                    f"{custom:g} unknown (custom modes: {table})")
            c.command_ack(link, src, comp, cmd, mav.MAV_RESULT_DENIED)
            return
        c.spawn(self._supervised(link, src, comp, cmd, "mode", {"mode": mode.value}))

    async def _supervised(self, link: Link, src: int, comp: int, cmd: int, name: str,
                          args: dict[str, Any], refused_note: str = "") -> None:
        """``name`` to the supervisor; its verdict as the COMMAND_ACK, after its
        reason (and ``refused_note``) as status texts when it refuses."""
        c = self.core
        try:
            ack = await c.supervise(name, args, src)
        except Exception:  # ours, not the ground station's: answered, never a restart
            c.counters.handler_errors += 1
            log.exception("mavlink: %s from %d", name, src)
            c.command_ack(link, src, comp, cmd, mav.MAV_RESULT_FAILED)
            return
        if ack is None:  # arguments the boat does not take (said as a status text)
            c.counters.commands_refused += 1
            c.command_ack(link, src, comp, cmd, mav.MAV_RESULT_DENIED)
            return
        if ack.ok:
            c.counters.commands_accepted += 1
            result = mav.MAV_RESULT_ACCEPTED
        else:
            c.counters.commands_refused += 1
            result = (mav.MAV_RESULT_FAILED if ack.mode == "unknown"
                      else mav.MAV_RESULT_TEMPORARILY_REJECTED)
            c.tell_refusal(link, ack)
            if refused_note:
                c.send_text(link, int(mav.MAV_SEVERITY_WARNING), refused_note)
        c.command_ack(link, src, comp, cmd, result)

    # -------------------------------------------------------------- joystick

    def on_manual(self, link: Link, m: Any) -> None:
        c = self.core
        if int(m.target) not in (0, c.s.system_id):
            return
        u1, u2 = mix_manual(int(m.x), int(m.r))
        now = c.clock.now()
        last = self.manual
        changed = abs(u1 - last.u1) >= 0.5 or abs(u2 - last.u2) >= 0.5
        dt = now - last.t
        if not ((changed and dt >= MANUAL_MIN_S) or dt >= MANUAL_KEEP_S):
            return
        self.manual = Manual(u1, u2, now)
        c.counters.manual_forwarded += 1
        c.spawn(self._thrust(m.get_srcSystem(), u1, u2))

    async def _thrust(self, src: int, u1: float, u2: float) -> None:
        try:
            await self.core.supervise("thrust", {"u1": round(u1, 3), "u2": round(u2, 3)}, src)
        except Exception:  # a joystick has no answer; ours is counted, never a restart
            self.core.counters.handler_errors += 1
            log.exception("mavlink: thrust from %d", src)
