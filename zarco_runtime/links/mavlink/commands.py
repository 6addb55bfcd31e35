"""Commands from a ground station, every one through the supervisor.

COMMAND_LONG and COMMAND_INT (arming, modes, mission start, return, hold),
SET_MODE and MANUAL_CONTROL become supervisor commands with source
``mavlink:<system id>``; each COMMAND_LONG / COMMAND_INT / SET_MODE gets one
COMMAND_ACK: ACCEPTED; TEMPORARILY_REJECTED when the supervisor refuses (its
reason follows as a STATUSTEXT); DENIED for arguments the boat does not take;
UNSUPPORTED for commands it does not know; FAILED when the supervisor did not
answer.  The requests a ground station makes on connecting (REQUEST_MESSAGE,
capabilities, message intervals) are answered here without the supervisor.

A MANUAL_CONTROL is passed on when it changes the thrust or every
:data:`MANUAL_KEEP_S`, so that the lease (``supervisor.manual_lease_s``) lasts
while the GCS sends and ends when it stops."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from zarco_core.messages import Mode
from zarco_runtime.links.mavlink.core import Core
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.protocol import CUSTOM_MODE, MODE_OF_CUSTOM, mav, mix_manual
from zarco_runtime.links.mavlink.streams import Streams
from zarco_runtime.links.mavlink.transfer import MissionTransfer

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
        c = self.core
        if not c.for_us(m):
            return
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        cmd = int(m.command)
        p1, p2 = float(m.param1), float(m.param2)
        c.counters.commands += 1

        def ack(result: int) -> None:
            c.command_ack(link, src, comp, cmd, result)

        def supervise(name: str, args: dict[str, Any]) -> None:
            c.spawn(self._supervised(link, src, comp, cmd, name, args))

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
            if self.transfer.cleared:
                c.event("mission", f"MISSION_START from mavlink:{src} refused: the "
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
            ack(self.streams.request_message(link, int(p1), p2))
        elif cmd == mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            ack(mav.MAV_RESULT_ACCEPTED)
            link.send(self.streams.autopilot_version())
        elif cmd == mav.MAV_CMD_SET_MESSAGE_INTERVAL:
            ack(self.streams.set_interval(link, int(p1), p2))
        elif cmd == mav.MAV_CMD_GET_MESSAGE_INTERVAL:
            ack(self.streams.request_message(link, mav.MAVLINK_MSG_ID_MESSAGE_INTERVAL, p1))
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
        mode = MODE_OF_CUSTOM.get(int(custom)) if custom == int(custom) else None
        if not base & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or mode is None:
            table = ", ".join(f"{v} {k.value}" for k, v in CUSTOM_MODE.items())
            c.event("mode", f"mode change from mavlink:{src} refused: custom mode "
                    f"{custom:g} unknown (custom modes: {table})")
            c.command_ack(link, src, comp, cmd, mav.MAV_RESULT_DENIED)
            return
        if mode is Mode.LINES and self.transfer.cleared:
            c.event("mission", f"mode lines from mavlink:{src} refused: the mission "
                    "was cleared")
            c.command_ack(link, src, comp, cmd, mav.MAV_RESULT_DENIED)
            return
        c.spawn(self._supervised(link, src, comp, cmd, "mode", {"mode": mode.value}))

    async def _supervised(self, link: Link, src: int, comp: int, cmd: int, name: str,
                          args: dict[str, Any]) -> None:
        c = self.core
        ack = await c.cmds.send(name, args, source=f"mavlink:{src}")
        if ack.ok:
            c.counters.commands_accepted += 1
            result = mav.MAV_RESULT_ACCEPTED
        else:
            c.counters.commands_refused += 1
            result = (mav.MAV_RESULT_FAILED if ack.mode == "unknown"
                      else mav.MAV_RESULT_TEMPORARILY_REJECTED)
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
        await self.core.cmds.send("thrust", {"u1": round(u1, 3), "u2": round(u2, 3)},
                                  source=f"mavlink:{src}")
