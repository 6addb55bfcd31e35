"""The operator's commands as typed, bounded payloads: one schema per command.

Every way into the supervisor (the shore link's ``cmd/<name>`` queries, the
local control socket behind ``zarco ctl``, the MAVLink endpoint's mapping of
its messages, a scenario's ``[[commands]]``) turns what it received into one
of the structs below with :func:`decode`, and the supervisor only ever sees a
:class:`~zarco_core.messages.Command` whose ``args`` is that struct.

What a payload may hold (anything else is refused with the field and the
reason, and nothing of it acts):

* a JSON object (or an already-parsed mapping) of at most
  :data:`MAX_PAYLOAD_BYTES` bytes, with only the fields of its command;
* numbers are finite JSON numbers within the field's range: no strings, no
  booleans standing for numbers, no integers beyond a float's range, no NaN;
* booleans are ``true`` / ``false``, nothing else;
* text is bounded (:data:`MAX_TEXT`) and printable (no terminal escapes);
* lists are bounded (:data:`MAX_POINTS` points);
* nesting is bounded by the schema itself: a value where a number is expected
  is refused at once, before anything below it is read (so a payload of
  thirty thousand ``[`` costs microseconds, not a recursion).

``stop`` takes no argument and is never refused here: whatever its payload,
it is a :class:`StopArgs`.

Angles are WGS-84 degrees (``lat_deg`` −90..90, ``lon_deg`` −180..180),
speeds m/s over ground, thruster commands on the normalised −100..100 scale
(1 port, 2 starboard).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Annotated, Any, ClassVar, Final, TypeAlias, cast

import msgspec

from zarco_core.modes import Mode

#: largest raw payload (bytes) read at all
MAX_PAYLOAD_BYTES: Final = 65536
#: most points in a mission, an AUV plan or a geofence polygon
MAX_POINTS: Final = 1000
#: longest text field (characters): a mission name, a parameter's text value
MAX_TEXT: Final = 64
#: deepest nesting of arrays and objects a payload may have (a mission's
#: ``{"waypoints": [[lat, lon], ...]}`` is 3 deep)
MAX_DEPTH: Final = 8
#: the normalised thruster scale
U_MAX: Final = 100.0
#: the fastest speed any command may ask (m/s); the supervisor's own
#: ``supervisor.max_speed_mps`` is the tighter, configured bound
MAX_SPEED_MPS: Final = 3.0
MIN_SPEED_MPS: Final = 0.05

LatDeg = Annotated[float, msgspec.Meta(ge=-90.0, le=90.0)]
LonDeg = Annotated[float, msgspec.Meta(ge=-180.0, le=180.0)]
#: a point as ``[lat_deg, lon_deg]``
Point = tuple[LatDeg, LonDeg]
Points = Annotated[list[Point], msgspec.Meta(max_length=MAX_POINTS)]
SpeedMps = Annotated[float, msgspec.Meta(ge=MIN_SPEED_MPS, le=MAX_SPEED_MPS)]
ThrustU = Annotated[float, msgspec.Meta(ge=-U_MAX, le=U_MAX)]
Text = Annotated[str, msgspec.Meta(max_length=MAX_TEXT)]
#: a parameter's canonical name: a dotted configuration key (``failsafe.link_lost_s``)
ParamName = Annotated[str, msgspec.Meta(min_length=3, max_length=MAX_TEXT,
                                        pattern=r"^[a-z][a-z0-9_]*(\.[a-z0-9_]+)+$")]
#: a parameter's value: a finite number, a boolean, a word, or a list of points
#: (the geofence polygon); the parameter's own type and range are the registry's
ParamValue = Annotated[float, msgspec.Meta(ge=-1e12, le=1e12)] | bool | Text | Points


def _printable(field: str, text: str) -> None:
    if not text.isprintable():
        raise ValueError(f"{field}: must be printable text (no control characters)")


class _Args(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """The arguments of one command (``NAME`` is the command)."""

    NAME: ClassVar[str] = ""


class StopArgs(_Args, frozen=True):
    """``stop {}``: zero thrust, idle and disarmed.  Always accepted."""

    NAME: ClassVar[str] = "stop"


class ArmArgs(_Args, frozen=True):
    """``arm {}``: allow thrust (needs a valid position and heading, the thruster
    controller answering, no failsafe active)."""

    NAME: ClassVar[str] = "arm"


class DisarmArgs(_Args, frozen=True):
    """``disarm {}``: idle and disarmed."""

    NAME: ClassVar[str] = "disarm"


class ResumeArgs(_Args, frozen=True):
    """``resume {}``: continue the last mission from its leg."""

    NAME: ClassVar[str] = "resume"


class ParamArgs(_Args, frozen=True):
    """``param {"name", "value"}``: set one parameter of the running configuration
    (``name`` a dotted key such as ``failsafe.link_lost_s``)."""

    NAME: ClassVar[str] = "param"
    name: ParamName
    value: ParamValue


class ModeArgs(_Args, frozen=True):
    """``mode {"mode", "lat_deg"?, "lon_deg"?}``: enter a mode; ``hold`` may be
    given its point (both coordinates or neither)."""

    NAME: ClassVar[str] = "mode"
    mode: Mode
    lat_deg: LatDeg | None = None
    lon_deg: LonDeg | None = None

    def __post_init__(self) -> None:
        if (self.lat_deg is None) != (self.lon_deg is None):
            raise ValueError("lat_deg, lon_deg: give both or neither")
        if self.lat_deg is not None and self.mode is not Mode.HOLD:
            raise ValueError(f"lat_deg, lon_deg: a point is for mode hold, not "
                             f"{self.mode.value}")


class MissionArgs(_Args, frozen=True):
    """``mission {"waypoints", "speed_mps", "start", "name"?, "leg_speeds_mps"?,
    "start_leg"?}`` loads a lines mission (and starts it unless ``start`` is
    false); ``mission {"clear": true}`` forgets the loaded one."""

    NAME: ClassVar[str] = "mission"
    waypoints: Points = []
    speed_mps: SpeedMps = 1.0
    start: bool = True
    name: Text = ""
    leg_speeds_mps: Annotated[list[SpeedMps], msgspec.Meta(max_length=MAX_POINTS - 1)] \
        | None = None
    start_leg: Annotated[int, msgspec.Meta(ge=0, le=MAX_POINTS - 2)] = 0
    clear: bool = False

    def __post_init__(self) -> None:
        _printable("name", self.name)
        if self.clear:
            if self.waypoints or self.leg_speeds_mps is not None:
                raise ValueError("clear: takes no waypoints")
            return
        n = len(self.waypoints)
        if n < 2:
            raise ValueError(f"waypoints: need at least 2 [lat_deg, lon_deg], got {n}")
        if self.leg_speeds_mps is not None and len(self.leg_speeds_mps) != n - 1:
            raise ValueError(f"leg_speeds_mps: need one speed per leg ({n - 1}), got "
                             f"{len(self.leg_speeds_mps)}")
        if self.start_leg > n - 2:
            raise ValueError(f"start_leg: must be within 0..{n - 2}, got {self.start_leg}")


class FollowArgs(_Args, frozen=True):
    """``follow {"auv_plan"?}``: follow the AUV; ``auv_plan`` is its a-priori
    mission as ``[[lat_deg, lon_deg], ...]`` (empty or absent: none)."""

    NAME: ClassVar[str] = "follow"
    auv_plan: Points | None = None


class ThrustArgs(_Args, frozen=True):
    """``thrust {"u1", "u2"}``: the thruster commands in manual mode (renews the
    lease)."""

    NAME: ClassVar[str] = "thrust"
    u1: ThrustU
    u2: ThrustU


CommandArgs: TypeAlias = (StopArgs | ArmArgs | DisarmArgs | ResumeArgs | ParamArgs | ModeArgs
                          | MissionArgs | FollowArgs | ThrustArgs)

#: the command names and their argument types
SCHEMAS: Final[dict[str, type[_Args]]] = {
    c.NAME: c for c in (StopArgs, ArmArgs, DisarmArgs, ParamArgs, ModeArgs, MissionArgs,
                        FollowArgs, ThrustArgs, ResumeArgs)}
_DECODERS: Final = {name: msgspec.json.Decoder(c) for name, c in SCHEMAS.items()}


class CommandRefused(ValueError):
    """A payload that is not a valid command: ``field`` (a path such as
    ``waypoints[3][0]``, "" for the payload as a whole) and ``reason``."""

    def __init__(self, field: str, reason: str) -> None:
        # what the sender wrote may be in either (an unknown field's name): a
        # refusal is shown on terminals and in the event stream, so it carries
        # no control characters (a terminal escape shows as ``\x1b``)
        self.field = shown(field)
        self.reason = shown(reason)
        super().__init__(f"{self.field}: {self.reason}" if field else self.reason)


def shown(text: str) -> str:
    """``text`` with every character that is not printable written as its
    escape (``\x1b``, ``\n``, ``\u2028``): safe on a terminal."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii")
                   for c in text)


_PATH = re.compile(r" - at `\$(.*)`$")
_FIELD_IN = re.compile(r"`([^`]*)`")
_EXPECT_CMP = re.compile(r"^Expected `(\w+)` (>=|<=|>|<) (\S+)$")
_EXPECT_LEN = re.compile(r"^Expected `(\w+)` of length (>=|<=) (\d+)$")
_EXPECT_TYPE = re.compile(r"^Expected `([^`]+)`, got `(\w+)`$")
_WORDS = {"float": "a number", "int": "an integer", "bool": "true or false", "str": "text",
          "array": "a list", "object": "an object", "null": "null", "Mode": "a mode",
          "bool | float | str | array": "a number, true/false, text or a list of points"}
_CMP = {">=": "≥", "<=": "≤", ">": ">", "<": "<"}


def _readable(message: str) -> CommandRefused:
    """msgspec's ``Expected `float` <= 90.0 - at `$.waypoints[3][0]``` as
    ``waypoints[3][0]: must be ≤ 90``."""
    field = ""
    m = _PATH.search(message)
    if m:
        field = m.group(1).lstrip(".")
        message = message[:m.start()]
    if message.startswith("Object contains unknown field"):
        f = _FIELD_IN.search(message)
        return CommandRefused(f.group(1)[:MAX_TEXT] if f else field, "unknown field")
    if message.startswith("Object missing required field"):
        f = _FIELD_IN.search(message)
        name = f.group(1) if f else ""
        return CommandRefused(f"{field}.{name}" if field else name, "missing")
    if message == "Number out of range":
        return CommandRefused(field, "number out of range (beyond a 64-bit float)")
    if message.startswith("Invalid enum value"):
        modes = ", ".join(m.value for m in Mode)
        return CommandRefused(field, f"unknown {field or 'value'} "
                              f"{message.split('value ', 1)[1][:MAX_TEXT + 2]} "
                              f"(one of {modes})")
    if m := _EXPECT_CMP.match(message):
        return CommandRefused(field, f"must be {_CMP[m.group(2)]} {float(m.group(3)):g}")
    if m := _EXPECT_LEN.match(message):
        unit = "characters" if m.group(1) == "str" else "items"
        most = "at most" if m.group(2) == "<=" else "at least"
        return CommandRefused(field, f"{most} {m.group(3)} {unit}")
    if m := _EXPECT_TYPE.match(message):
        wanted = m.group(1).removesuffix(" | null")
        want = _WORDS.get(wanted, wanted)
        got = _WORDS.get(m.group(2), m.group(2))
        return CommandRefused(field, f"must be {want}, got {got}")
    if message.startswith("Expected `str` matching regex"):
        return CommandRefused(field, "must be a dotted configuration key "
                              "(section.key, lower case)")
    if ": " in message and not field:  # our own checks: "field: reason"
        where, _, why = message.partition(": ")
        return CommandRefused(where, why)
    return CommandRefused(field, message)


_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"')
_NOT_BRACKETS = bytes(b for b in range(256) if b not in b"[]{}")


def nesting_ok(raw: bytes, limit: int = MAX_DEPTH) -> bool:
    """Whether the JSON text ``raw`` nests arrays and objects at most ``limit``
    deep with every bracket matched (brackets inside strings do not count):
    ``limit`` passes that each remove the innermost ``[]`` and ``{}`` pairs
    must leave nothing.  A few C-speed passes over the text: some tens of
    microseconds for a 64 KiB payload, whatever its nesting."""
    rest = _JSON_STRING.sub(b"", raw).translate(None, _NOT_BRACKETS)
    for _ in range(limit):
        if not rest:
            return True
        # the innermost pairs are marked first, then dropped: a pair that only
        # held them (``{[]}``) is one level more, for the next pass
        inner = rest.replace(b"[]", b".").replace(b"{}", b".").replace(b".", b"")
        if len(inner) == len(rest):
            return False  # unmatched brackets
        rest = inner
    return not rest


def decode(name: str, payload: bytes | bytearray | memoryview | str | Mapping[str, Any]
           | _Args | None) -> CommandArgs:
    """The typed arguments of command ``name`` from its payload.

    ``payload`` is the raw JSON (bytes or text; empty means ``{}``), an
    already-parsed mapping (a scenario's TOML table, a MAVLink mapping), an
    argument struct already typed, or None (``{}``).  Raises
    :class:`CommandRefused` naming the field and the reason.
    """
    schema = SCHEMAS.get(name) if isinstance(name, str) else None
    if schema is None:
        shown = repr(name[:MAX_TEXT]) if isinstance(name, str) else type(name).__name__
        raise CommandRefused("", f"unknown command {shown} (one of {', '.join(SCHEMAS)})")
    if schema is StopArgs:
        return StopArgs()  # stop is always accepted, whatever came with it
    out: Any
    try:
        if payload is None:
            out = _DECODERS[name].decode(b"{}")
        elif isinstance(payload, _Args):
            if not isinstance(payload, schema):
                raise CommandRefused("", f"arguments of {payload.NAME}, not of {name}")
            out = payload
        elif isinstance(payload, (bytes, bytearray, memoryview, str)):
            if len(payload) > MAX_PAYLOAD_BYTES:
                raise CommandRefused("", f"payload larger than {MAX_PAYLOAD_BYTES} bytes")
            raw = payload.encode("utf-8", "surrogatepass") if isinstance(payload, str) \
                else bytes(payload)
            if not nesting_ok(raw):
                raise CommandRefused("", f"not JSON, or nested deeper than {MAX_DEPTH} levels")
            out = _DECODERS[name].decode(raw if raw.strip() else b"{}")
        elif isinstance(payload, Mapping):
            out = msgspec.convert(dict(payload), schema, strict=True)
        else:
            raise CommandRefused("", f"the payload must be a JSON object, got "
                                 f"{type(payload).__name__}")
    except msgspec.ValidationError as exc:
        raise _readable(str(exc)) from None
    except msgspec.DecodeError as exc:
        raise CommandRefused("", f"not JSON: {str(exc).removeprefix('JSON is malformed: ')}"
                             ) from None
    except (UnicodeError, RecursionError, OverflowError, TypeError) as exc:
        raise CommandRefused("", f"unreadable payload ({type(exc).__name__})") from None
    assert isinstance(out, schema)
    return cast(CommandArgs, out)


def to_json(args: CommandArgs) -> dict[str, Any]:
    """The arguments as a JSON-able object (``None`` fields left out)."""
    out: dict[str, Any] = msgspec.to_builtins(args)
    return {k: v for k, v in out.items() if v is not None}

