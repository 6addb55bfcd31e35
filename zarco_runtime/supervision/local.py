"""The local command path: commands to the supervisor from this process, and
from other processes on the vessel computer through a unix socket.

:class:`LocalCommands` publishes a :class:`~zarco_core.messages.Command` on
the bus and waits for its :class:`~zarco_core.messages.CommandAck`; the
scenario script, the tests, the shore link and the MAVLink endpoint all
send commands this way.

:class:`ControlSocket` serves ``supervisor.control_socket`` (mode 0660: the
vessel's operators' group).  One JSON object per line in, one per line out::

    → {"name": "mode", "args": {"mode": "hold"}}
    ← {"ok": true, "id": "...", "mode": "hold", "reason": ""}
    → {"name": "status"}
    ← {"t": ..., "mode": "hold", ...}        (the latest status snapshot)

``zarco ctl`` is its client.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import itertools
import json
import logging
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from zarco_core.bus import Bus, Listen
from zarco_core.clock import Clock
from zarco_core.commands import CommandArgs, CommandRefused, decode
from zarco_core.messages import Command, CommandAck, VesselStatus
from zarco_runtime.guidance.directive import Directive

log = logging.getLogger("zarco.local")
_ids = itertools.count(1)


#: what a link hands over as a command's arguments: raw JSON, a parsed mapping,
#: typed arguments, or nothing (``{}``)
Payload = CommandArgs | Mapping[str, Any] | bytes | str | None


class LocalCommands:
    """Send commands over the bus and await their acknowledgement.

    The payload is decoded here (:func:`zarco_core.commands.decode`): a payload
    that is not a valid command is refused at once with the field and the
    reason (a :class:`CommandAck` on the bus like the supervisor's, so it is
    counted, recorded and told to the operator), and only typed commands reach
    the supervisor.
    """

    def __init__(self, bus: Bus, clock: Clock, source: str = "local",
                 listen: Listen | None = None) -> None:
        self.bus = bus
        self.clock = clock
        self.source = source
        self._pending: dict[str, asyncio.Future[CommandAck]] = {}
        (listen or bus.listen)(CommandAck, self._on_ack)
        self.directive = bus.latest(Directive)

    def _on_ack(self, ack: CommandAck) -> None:
        f = self._pending.pop(ack.id, None)
        if f is not None and not f.done():
            f.set_result(ack)

    def _mode(self) -> str:
        d = self.directive.value
        return d.mode.value if d is not None else "idle"

    async def send(self, name: str, args: Payload = None, timeout_s: float = 2.0,
                   source: str | None = None, cmd_id: str | None = None) -> CommandAck:
        """Send ``name`` with ``args`` (see :data:`Payload`); the supervisor's
        acknowledgement, a refusal of the payload (field and reason), or a
        refusal of our own if no acknowledgement came within ``timeout_s``."""
        src = source or self.source
        cid = cmd_id or f"{src}-{os.getpid()}-{next(_ids)}"
        try:
            typed = decode(name, args)
        except CommandRefused as exc:
            shown = name[:64] if isinstance(name, str) else "?"
            ack = CommandAck(self.clock.now(), cid, src, shown, False, self._mode(), str(exc))
            self.bus.publish(ack)
            return ack
        fut: asyncio.Future[CommandAck] = asyncio.get_running_loop().create_future()
        self._pending[cid] = fut
        self.bus.publish(Command(self.clock.now(), cid, src, name, typed))
        try:
            return await asyncio.wait_for(fut, timeout_s)
        except TimeoutError:
            self._pending.pop(cid, None)
            return CommandAck(self.clock.now(), cid, src, name, False, "unknown",
                              "no acknowledgement from the supervisor")


def status_json(st: VesselStatus | None) -> dict[str, Any]:
    """The status snapshot as a JSON-able dict (``{}`` before the first)."""
    return dataclasses.asdict(st) if st is not None else {}


class ControlSocket:
    """Serves local commands on a unix socket (see the module docstring)."""

    def __init__(self, path: str, bus: Bus, clock: Clock, listen: Listen | None = None) -> None:
        self.path = path
        self.bus = bus
        self.commands = LocalCommands(bus, clock, listen=listen)
        self.status = bus.latest(VesselStatus)

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = "local"
        with contextlib.suppress(Exception):
            import socket
            import struct

            sock = writer.get_extra_info("socket")
            creds = sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED,
                                    struct.calcsize("3i"))
            _pid, uid, _gid = struct.unpack("3i", creds)
            peer = f"local:uid{uid}"
        try:
            while line := await reader.readline():
                try:
                    req = json.loads(line)
                    if not isinstance(req, dict) or not isinstance(req.get("name"), str):
                        raise ValueError("expected {\"name\": ..., \"args\": {...}}")
                    if req["name"] == "status":
                        out: dict[str, Any] = status_json(self.status.value)
                    else:
                        args = req.get("args", {})
                        if not isinstance(args, dict):
                            raise ValueError("args must be an object")
                        ack = await self.commands.send(req["name"], args, source=peer,
                                                       cmd_id=req.get("id"))
                        out = {"ok": ack.ok, "id": ack.id, "mode": ack.mode,
                               "reason": ack.reason}
                except ValueError as exc:
                    out = {"ok": False, "id": None, "mode": None, "reason": f"bad request: {exc}"}
                writer.write((json.dumps(out) + "\n").encode())
                await writer.drain()
        except (ConnectionError, asyncio.IncompleteReadError):
            pass
        finally:
            writer.close()

    async def run(self) -> None:
        p = Path(self.path)
        p.parent.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
        server = await asyncio.start_unix_server(self._client, path=self.path)
        os.chmod(self.path, 0o660)
        log.info("local commands on %s", self.path)
        try:
            async with server:
                await server.serve_forever()
        finally:
            with contextlib.suppress(OSError):
                p.unlink()
