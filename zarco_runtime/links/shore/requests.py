"""What comes in from shore, read and bounded before anything acts on it.

A ``cmd/<name>`` query is read into a :class:`Request` (the command's name,
its JSON arguments, the operator's name and the command's id from the
attachment) or refused with a :class:`BadRequest` naming the field and the
reason.  The bounds (the shore protocol's, stated in docs/protocols.md):

=====================  ===================================================
key                    ``zarco/<vessel>/cmd/<name>``, ``<name>`` of 1 to 32
                       characters ``a-z``, ``0-9``, ``_``
payload                at most :data:`MAX_COMMAND_BYTES` bytes of UTF-8 JSON,
                       an object (empty: ``{}``), nested at most
                       :data:`MAX_NESTING` levels
attachment             optional; at most :data:`MAX_ATTACHMENT_BYTES` bytes
                       of UTF-8 JSON, an object with ``user`` and ``id``
                       (each at most :data:`MAX_NAME_CHARS` printable
                       characters; ``id`` may also be an integer)
operator heartbeat     at most :data:`MAX_HEARTBEAT_BYTES` bytes of UTF-8
                       JSON, an object; ``user`` as above, ``t`` a number
=====================  ===================================================

The nesting is counted on the raw bytes before anything is decoded
(:func:`zarco_core.commands.nesting_ok`, a few C-speed passes), so a payload
nested thousands deep is refused as quickly as any other.  What each
command's fields must be is the command schema's (:mod:`zarco_core.commands`,
applied when the command is sent to the supervisor): this module only makes
sure that what it passes on is a small JSON object, and leaves its fields'
values unread (msgspec.Raw), so that a number beyond a float's range is
refused by the schema naming its field rather than here as a whole payload.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import msgspec

from zarco_core.commands import MAX_DEPTH, MAX_PAYLOAD_BYTES, nesting_ok

#: a command payload larger than this is refused unread (bytes)
MAX_COMMAND_BYTES = MAX_PAYLOAD_BYTES
#: an attachment larger than this is refused unread (bytes)
MAX_ATTACHMENT_BYTES = 1024
#: an operator heartbeat larger than this is dropped unread (bytes)
MAX_HEARTBEAT_BYTES = 1024
#: objects and arrays nested deeper than this are refused (a mission's
#: waypoints are 3: the object, the list, a point)
MAX_NESTING = MAX_DEPTH
#: a user name or a command id: at most this many printable characters
MAX_NAME_CHARS = 64
NAME_RE = re.compile(r"[a-z0-9_]{1,32}")


class BadRequest(ValueError):
    """Refused before reaching the supervisor: ``field`` and ``reason``."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason


@dataclass(slots=True)
class Request:
    """A command as read from a query."""

    name: str
    args: dict[str, msgspec.Raw]
    user: str
    id: str | None


def depth(obj: Any) -> int:
    """How deeply ``obj``'s objects and arrays nest (a scalar: 0), iteratively."""
    deepest = 0
    stack: list[tuple[Any, int]] = [(obj, 1)]
    while stack:
        o, d = stack.pop()
        if isinstance(o, dict):
            deepest = max(deepest, d)
            stack.extend((v, d + 1) for v in o.values())
        elif isinstance(o, list):
            deepest = max(deepest, d)
            stack.extend((v, d + 1) for v in o)
    return deepest


def json_object(data: bytes, field: str, limit: int) -> dict[str, Any]:
    """``data`` as a bounded JSON object, or :class:`BadRequest` naming ``field``."""
    if len(data) > limit:
        raise BadRequest(field, f"{len(data)} bytes, more than {limit}")
    try:
        obj = msgspec.json.decode(data)
    except RecursionError:
        raise BadRequest(field, f"nested deeper than {MAX_NESTING} levels") from None
    except (msgspec.DecodeError, UnicodeDecodeError) as exc:
        # msgspec names the byte where the JSON (or its UTF-8) went wrong
        raise BadRequest(field, f"not UTF-8 JSON ({exc})") from None
    if not isinstance(obj, dict):
        raise BadRequest(field, f"must be a JSON object, got {_kind(obj)}")
    if depth(obj) > MAX_NESTING:
        raise BadRequest(field, f"nested deeper than {MAX_NESTING} levels")
    return obj


def text(v: Any, field: str, *, allow_int: bool = False) -> str:
    """A bounded, printable name (``user``, ``id``)."""
    if allow_int and isinstance(v, int) and not isinstance(v, bool):
        v = str(v)
    if not isinstance(v, str):
        raise BadRequest(field, f"must be a string, got {_kind(v)}")
    if len(v) > MAX_NAME_CHARS or not v.isprintable():
        raise BadRequest(field, f"at most {MAX_NAME_CHARS} printable characters")
    return v


def _kind(v: Any) -> str:
    return {dict: "an object", list: "an array", str: "a string", bool: "a boolean",
            int: "a number", float: "a number", type(None): "null"}.get(type(v), type(v).__name__)


def attachment(att: bytes, size: int | None = None) -> tuple[str, str | None]:
    """(user, id) from a query's attachment (both optional); ``size`` as in
    :func:`request`."""
    n = len(att) if size is None else size
    if n > MAX_ATTACHMENT_BYTES:
        raise BadRequest("attachment", f"{n} bytes, more than {MAX_ATTACHMENT_BYTES}")
    if not att:
        return "", None
    meta = json_object(att, "attachment", MAX_ATTACHMENT_BYTES)
    user = text(meta["user"], "attachment.user") if meta.get("user") is not None else ""
    cid = text(meta["id"], "attachment.id", allow_int=True) if meta.get("id") is not None \
        else None
    return user, cid


def peek_user(att: bytes) -> str:
    """The attachment's ``user`` if it reads as one, else ``""`` (never raises: the
    rate limit's key, read before the attachment is judged)."""
    if not att:
        return ""
    try:
        meta = msgspec.json.decode(att)
    except Exception:
        return ""
    user = meta.get("user") if isinstance(meta, dict) else None
    return user if isinstance(user, str) and len(user) <= MAX_NAME_CHARS \
        and user.isprintable() else ""


def command_name(key: str, prefix: str) -> str:
    """``<name>`` of ``<prefix>/cmd/<name>``."""
    base = f"{prefix}/cmd/"
    name = key[len(base):] if key.startswith(base) else ""
    if not NAME_RE.fullmatch(name):
        raise BadRequest("key", f"expected {base}<name>, one command "
                         f"(a-z, 0-9, _; at most 32), got {key[:80]!r}")
    return name


def request(key: str, prefix: str, payload: bytes, att: bytes,
            size: int | None = None, att_size: int | None = None) -> Request:
    """A command query read and bounded (see the module docstring); ``size`` and
    ``att_size`` are the payload's and the attachment's sizes when they were too
    large to be copied (then empty)."""
    user, cid = attachment(att, att_size)
    name = command_name(key, prefix)
    n = len(payload) if size is None else size
    if n > MAX_COMMAND_BYTES:
        raise BadRequest("payload", f"{n} bytes, more than {MAX_COMMAND_BYTES}")
    return Request(name, command_object(payload) if payload.strip() else {}, user, cid)


_FIELDS = msgspec.json.Decoder(dict[str, msgspec.Raw])


def command_object(payload: bytes) -> dict[str, msgspec.Raw]:
    """A command payload checked as a bounded JSON object, its fields left unread:
    their values (a number beyond a float's range, ``1e999``, included) are the
    command schema's to judge, which names the field."""
    if not nesting_ok(payload, MAX_NESTING):
        raise BadRequest("payload", f"not JSON, or nested deeper than {MAX_NESTING} levels")
    try:
        return _FIELDS.decode(payload)
    except msgspec.ValidationError as exc:
        got = str(exc).rpartition("got `")[2].rstrip("`")
        what = {"array": "an array", "str": "a string", "int": "a number", "float": "a number",
                "bool": "a boolean", "null": "null"}.get(got, got)
        raise BadRequest("payload", f"must be a JSON object, got {what}") from None
    except (msgspec.DecodeError, RecursionError) as exc:
        raise BadRequest("payload", f"not UTF-8 JSON ({exc})") from None


def heartbeat(payload: bytes) -> str:
    """The ``user`` of an operator heartbeat (``""`` if not given)."""
    obj = json_object(payload, "heartbeat", MAX_HEARTBEAT_BYTES)
    t = obj.get("t")
    if t is not None and (isinstance(t, bool) or not isinstance(t, (int, float))):
        raise BadRequest("heartbeat.t", f"must be a number, got {_kind(t)}")
    return text(obj["user"], "heartbeat.user") if obj.get("user") is not None else ""
