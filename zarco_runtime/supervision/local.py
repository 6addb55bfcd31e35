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
    → {"name": "params"}
    ← [{"name": "failsafe.link_lost_s", "kind": "float", "value": 10.0, ...}, ...]

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
import re
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import msgspec

from zarco_core.bus import Bus, Listen
from zarco_core.clock import Clock
from zarco_core.commands import (
    MAX_DEPTH,
    MAX_PAYLOAD_BYTES,
    MAX_TEXT,
    CommandArgs,
    CommandRefused,
    decode,
    nesting_ok,
    shown,
)
from zarco_core.messages import Command, CommandAck, VesselStatus
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.supervision.params import param_table

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

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
            # the name as told in the event stream: bounded, no control characters
            told = shown(name[:MAX_TEXT]) if isinstance(name, str) else "?"
            ack = CommandAck(self.clock.now(), cid, src, told, False, self._mode(), str(exc))
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


class _Request(msgspec.Struct, forbid_unknown_fields=True):
    """One line of the control socket: a command (its arguments kept raw for
    :func:`~zarco_core.commands.decode`), ``status`` or ``params``."""

    name: Annotated[str, msgspec.Meta(max_length=MAX_TEXT)]
    args: msgspec.Raw = msgspec.Raw(b"{}")
    id: Annotated[str, msgspec.Meta(max_length=MAX_TEXT)] | None = None


_REQUEST = msgspec.json.Decoder(_Request)
#: a line that begins as a stop request (``{"name": "stop"``), read or not
_STOP = re.compile(rb'\s*\{\s*"name"\s*:\s*"stop"\s*[,}]')


class _Unread(ValueError):
    """A request line that cannot be read (the reason)."""
#: longest request line (bytes): a command payload and its envelope
MAX_LINE = MAX_PAYLOAD_BYTES + 1024


async def _discard_line(reader: asyncio.StreamReader) -> None:
    """Read and drop the rest of a line longer than the reader's limit."""
    while True:
        try:
            await reader.readuntil(b"\n")
            return
        except asyncio.LimitOverrunError as exc:
            await reader.readexactly(exc.consumed)


class ControlSocket:
    """Serves local commands on a unix socket (see the module docstring).

    Every line gets exactly one reply line, whatever it holds: a line longer
    than :data:`MAX_LINE`, not JSON, nested too deep or not a request is
    refused ("bad request: ..."), a command's arguments are decoded and
    checked like any link's (:class:`LocalCommands`)."""

    def __init__(self, path: str, bus: Bus, clock: Clock, listen: Listen | None = None,
                 cfg: RuntimeConfig | None = None) -> None:
        self.path = path
        self.bus = bus
        self.cfg = cfg
        self.commands = LocalCommands(bus, clock, listen=listen)
        self.status = bus.latest(VesselStatus)

    async def _request(self, line: bytes, peer: str) -> Any:
        """The reply to one request line."""
        def bad(why: str, cid: str | None = None) -> dict[str, Any]:
            return {"ok": False, "id": cid, "mode": self.commands._mode(),
                    "reason": f"bad request: {why}"}

        try:
            if not nesting_ok(line, MAX_DEPTH + 1):
                raise _Unread(f"not JSON, or nested deeper than {MAX_DEPTH} levels")
            try:
                req = _REQUEST.decode(line)
            except msgspec.ValidationError as exc:
                raise _Unread(f"expected {{\"name\": ..., \"args\": {{...}}, \"id\"?: ...}} "
                              f"({exc})") from None
            except msgspec.DecodeError as exc:
                raise _Unread(str(exc)) from None
        except _Unread as exc:
            if not _STOP.match(line):
                return bad(str(exc))
            # stop is always accepted: a line that asks for it stops, whatever follows
            req = _Request("stop")
        if req.name == "status":
            return status_json(self.status.value)
        if req.name == "params":
            if self.cfg is None:
                return bad("no parameters here", req.id)
            return [dataclasses.asdict(p) for p in param_table(self.cfg)]
        ack = await self.commands.send(req.name, bytes(req.args), source=peer,
                                       cmd_id=req.id)
        return {"ok": ack.ok, "id": ack.id, "mode": ack.mode, "reason": ack.reason}

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
            while True:
                try:
                    line = await reader.readuntil(b"\n")
                except asyncio.IncompleteReadError as exc:
                    line = exc.partial  # the last line, without its newline
                    if not line.strip():
                        break
                except asyncio.LimitOverrunError:
                    await _discard_line(reader)
                    line = b""
                    out: Any = {"ok": False, "id": None, "mode": self.commands._mode(),
                                "reason": f"bad request: longer than {MAX_LINE} bytes"}
                if line:
                    try:
                        out = await self._request(line, peer)
                    except Exception as exc:  # one reply per line, whatever happened
                        log.exception("control socket request")
                        out = {"ok": False, "id": None, "mode": self.commands._mode(),
                               "reason": f"bad request: {type(exc).__name__}"}
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
        server = await asyncio.start_unix_server(self._client, path=self.path, limit=MAX_LINE)
        os.chmod(self.path, 0o660)
        log.info("local commands on %s", self.path)
        try:
            async with server:
                await server.serve_forever()
        finally:
            with contextlib.suppress(OSError):
                p.unlink()
