"""NMEA 0183 framing, checksums and strict sentence parsing.

The checksum is the XOR of every character between ``$``/``!`` and ``*``,
written as two upper-case hex digits (NMEA 0183 §5.3).  Every sentence the
runtime uses must carry a valid checksum (DESIGN.md §7): pynmea2's default
parse accepts sentences without one, so :func:`parse_sentence` checks first.

Layers, from bytes to values:

* :class:`NmeaFramer` cuts a byte stream into candidate sentences (``str``,
  starting at ``$``/``!``, without CR/LF) and counts what it throws away;
* :func:`split_checked` verifies framing and checksum and splits the fields
  (used for the project's own ``$PZ...`` sentences and for types pynmea2 does
  not know);
* :func:`parse_sentence` does the same check, then ``pynmea2.parse``;
* the ``field_*`` helpers convert raw field strings strictly, raising
  ``NmeaError("field", ...)`` instead of ``ValueError``; drivers use them on
  ``msg.data`` rather than pynmea2's lazy attribute properties, which raise
  arbitrary exceptions (or return None) on bad or truncated input.

Every rejection is an :class:`NmeaError` whose ``reason`` is a short counter key:
``framing``, ``no_checksum``, ``checksum``, ``parse``, ``unsupported``,
``field``, ``empty``, ``invalid``, ``range``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from typing import Any

import pynmea2

#: the two characters that start a sentence
START_CHARS = b"$!"
#: printable ASCII, the only bytes allowed inside a sentence
_PRINTABLE = bytes(range(0x20, 0x7F))
_START_RE = re.compile(rb"[$!]")
#: what ends (CR/LF) or restarts ($/!) a frame in progress
_STOP_RE = re.compile(rb"[\r\n$!]")
_ADDRESS_RE = re.compile(r"[A-Z0-9]{2,8}")
_HEX = frozenset("0123456789ABCDEFabcdef")
#: a plain decimal number: no exponent, no whitespace, no ``nan``/``inf``/``_``
_DECIMAL_RE = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)")
_INT_RE = re.compile(r"[+-]?\d+")
_TIME_RE = re.compile(r"(\d\d)(\d\d)(\d\d(?:\.\d+)?)")
_LATLON_RE = re.compile(r"(\d{1,3})(\d\d(?:\.\d*)?)")


class NmeaError(ValueError):
    """A sentence was rejected. ``reason`` is a short counter key."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason
        self.detail = detail


def sentence_type(line: str) -> str:
    """Sentence type of a framed line, without checking it: ``GGA`` for
    ``$GPGGA,...``; the whole address for a proprietary one (``PZTHR``)."""
    end = min(x for x in (line.find(","), line.find("*"), len(line)) if x >= 0)
    address = line[1:end]
    return address if address.startswith("P") else address[2:]


def nmea_checksum(body: str) -> int:
    """XOR checksum of ``body`` (the text between ``$`` and ``*``)."""
    cs = 0
    for ch in body.encode("ascii"):
        cs ^= ch
    return cs


def format_sentence(body: str, start: str = "$") -> bytes:
    """Frame ``body`` as ``$body*hh\\r\\n`` bytes."""
    return f"{start}{body}*{nmea_checksum(body):02X}\r\n".encode("ascii")


# ------------------------------------------------------------------ framing


def _not_crlf(chunk: bytes) -> int:
    """Number of bytes in ``chunk`` that are not CR or LF (line ends are not garbage)."""
    return len(chunk) - chunk.count(b"\r") - chunk.count(b"\n")


class NmeaFramer:
    """Cuts a byte stream into NMEA sentences.

    :meth:`feed` takes whatever the port delivered and returns the complete
    sentences it closed, as ``str`` starting at ``$`` or ``!`` without the
    CR/LF (CR, LF or CRLF all end a line).  Nothing is checked beyond framing
    here (checksums are :func:`split_checked`'s job).

    Counters (attributes, monotonic):

    * ``bytes_discarded`` – every byte not delivered inside a sentence, CR/LF
      excepted: noise between sentences, frames cut short by a new start
      character, overlong and garbage lines;
    * ``overlong`` – lines longer than ``max_len`` characters (dropped);
    * ``garbage_lines`` – lines holding a non-printable or non-ASCII byte;
    * ``restarts`` – frames abandoned because ``$``/``!`` appeared inside them
      (both are reserved characters in NMEA 0183, never field content).
    """

    def __init__(self, max_len: int = 200) -> None:
        if max_len < 8:
            raise ValueError(f"max_len {max_len} too small for any sentence")
        self.max_len = max_len
        self.bytes_discarded = 0
        self.overlong = 0
        self.garbage_lines = 0
        self.restarts = 0
        self.sentences = 0
        # the frame in progress (starts with $ or !), or b"" when between frames
        self._partial = b""

    def reset(self) -> None:
        """Forget any frame in progress (e.g. after the port reopened)."""
        self._partial = b""

    def feed(self, data: bytes) -> list[str]:
        """Add ``data`` to the stream; return the sentences it completed."""
        out: list[str] = []
        buf = self._partial + data if self._partial else bytes(data)
        self._partial = b""
        n = len(buf)
        pos = 0
        while pos < n:
            if buf[pos] not in START_CHARS:  # between frames: skip to a start char
                m = _START_RE.search(buf, pos)
                if m is None:
                    self.bytes_discarded += _not_crlf(buf[pos:])
                    break
                self.bytes_discarded += _not_crlf(buf[pos:m.start()])
                pos = m.start()
            m = _STOP_RE.search(buf, pos + 1)
            if m is None:  # frame still open
                rest = buf[pos:]
                if len(rest) > self.max_len:
                    # cannot become a valid line; drop it and resync on the next start
                    self.overlong += 1
                    self.bytes_discarded += len(rest)
                else:
                    self._partial = rest
                break
            end = m.start()
            line = buf[pos:end]
            if buf[end] in START_CHARS:  # a new sentence began before this one ended
                self.restarts += 1
                self.bytes_discarded += len(line)
                pos = end
                continue
            pos = end + 1
            if len(line) > self.max_len:
                self.overlong += 1
                self.bytes_discarded += len(line)
            elif line.translate(None, _PRINTABLE):
                self.garbage_lines += 1
                self.bytes_discarded += len(line)
            else:
                self.sentences += 1
                out.append(line.decode("ascii"))
        return out


# ------------------------------------------------------- checked splitting


def _check(line: str) -> str:
    """Verify start char and ``*hh``; return the body between them."""
    line = line.rstrip("\r\n")
    if not line or line[0] not in "$!":
        raise NmeaError("framing", f"does not start with $ or !: {line[:20]!r}")
    if not line.isascii():
        raise NmeaError("framing", "non-ASCII character")
    star = line.rfind("*")
    if star < 0:
        raise NmeaError("no_checksum", line[:20])
    hh = line[star + 1:]
    if len(hh) != 2 or hh[0] not in _HEX or hh[1] not in _HEX:
        raise NmeaError("checksum", f"malformed checksum field {hh[:4]!r}")
    body = line[1:star]
    want = nmea_checksum(body)
    if int(hh, 16) != want:
        raise NmeaError("checksum", f"got {hh}, computed {want:02X}")
    return body


def split_checked(line: str) -> tuple[str, list[str]]:
    """Check framing and checksum of ``line``; return (address, fields).

    ``address`` is what follows the start character up to the first comma
    (``"GPGGA"``, ``"PZTHR"``); ``fields`` are the comma-separated strings
    after it (raw, possibly empty).  Raises ``NmeaError`` with reason
    ``framing``, ``no_checksum`` or ``checksum``.
    """
    body = _check(line)
    address, *fields = body.split(",")
    if not _ADDRESS_RE.fullmatch(address):
        raise NmeaError("framing", f"bad address {address[:10]!r}")
    return address, fields


def parse_sentence(line: str) -> pynmea2.NMEASentence:
    """Strictly parse one sentence with pynmea2.

    The line must start with ``$``/``!`` and carry a correct ``*hh`` checksum
    (checked here, since pynmea2 accepts sentences without one).  Raises
    ``NmeaError``: ``framing`` / ``no_checksum`` / ``checksum`` for the frame,
    ``parse`` for anything pynmea2 refuses, ``unsupported`` for sentence
    types pynmea2 does not know (and for queries / unknown proprietary ones).

    pynmea2 maps fields lazily and accepts truncated sentences: callers must
    check ``len(msg.data)`` and convert fields with the ``field_*`` helpers.
    """
    body = _check(line)
    # pynmea2 only knows "$"; the checksum was verified above, so hand it the
    # body alone and it does not compute the checksum again
    try:
        msg = pynmea2.parse("$" + body, check=False)
    except pynmea2.SentenceTypeError as exc:
        raise NmeaError("unsupported", line[1:].split(",", 1)[0]) from exc
    except Exception as exc:  # pynmea2 raises ParseError, but be safe
        raise NmeaError("parse", str(exc)) from exc
    if isinstance(msg, pynmea2.TalkerSentence):
        return msg
    if type(msg) in (pynmea2.ProprietarySentence, pynmea2.QuerySentence):
        raise NmeaError("unsupported", line[1:].split(",", 1)[0])
    return msg


# ------------------------------------------------------- field converters


def require_fields(fields: list[str], n: int, what: str) -> None:
    """Refuse a truncated sentence: at least ``n`` fields must be present."""
    if len(fields) < n:
        raise NmeaError("field", f"{what}: {len(fields)} fields, need {n}")


def field_float(s: str, name: str) -> float | None:
    """A decimal field, or None if empty.  No exponents, nan, inf or spaces."""
    if not s:
        return None
    if not _DECIMAL_RE.fullmatch(s):
        raise NmeaError("field", f"{name}={s[:16]!r} is not a number")
    return float(s)


def field_int(s: str, name: str) -> int | None:
    """An integer field, or None if empty."""
    if not s:
        return None
    if not _INT_RE.fullmatch(s):
        raise NmeaError("field", f"{name}={s[:16]!r} is not an integer")
    return int(s)


def field_char(s: str, allowed: str, name: str) -> str | None:
    """A one-letter field from ``allowed``, or None if empty."""
    if not s:
        return None
    if len(s) != 1 or s not in allowed:
        raise NmeaError("field", f"{name}={s[:8]!r} not one of {allowed}")
    return s


def field_time_s(s: str) -> float | None:
    """``hhmmss[.ss]`` → seconds of the UTC day, or None if empty."""
    if not s:
        return None
    m = _TIME_RE.fullmatch(s)
    if m is None:
        raise NmeaError("field", f"time {s[:16]!r}")
    hh, mm, ss = int(m[1]), int(m[2]), float(m[3])
    if hh > 23 or mm > 59 or ss >= 61.0:  # 60.x is a leap second
        raise NmeaError("field", f"time {s!r} out of range")
    return hh * 3600 + mm * 60 + ss


def _angle_dm(value: str, hemi: str, pos: str, neg: str, limit: float) -> float:
    m = _LATLON_RE.fullmatch(value)
    if m is None:
        raise NmeaError("field", f"coordinate {value[:16]!r}")
    minutes = float(m[2])
    if minutes >= 60.0:
        raise NmeaError("field", f"coordinate {value!r}: minutes >= 60")
    deg = int(m[1]) + minutes / 60.0
    if deg > limit:
        raise NmeaError("field", f"coordinate {value!r} beyond {limit}")
    if hemi == neg:
        return -deg
    if hemi != pos:
        raise NmeaError("field", f"hemisphere {hemi[:4]!r} not {pos}/{neg}")
    return deg


def field_latlon(lat: str, ns: str, lon: str, ew: str) -> tuple[float, float] | None:
    """NMEA ``ddmm.mmmm,N,dddmm.mmmm,E`` → (lat_deg, lon_deg); None if any is empty.

    South and west are negative.  Malformed values raise ``NmeaError("field")``.
    """
    if not (lat and ns and lon and ew):
        return None
    return _angle_dm(lat, ns, "N", "S", 90.0), _angle_dm(lon, ew, "E", "W", 180.0)


def field_signed(value: str, direction: str, pos: str, neg: str, name: str) -> float | None:
    """A magnitude with a direction letter (``11.6,E``) → signed value, None if empty."""
    v = field_float(value, name)
    if v is None:
        return None
    if direction == pos or (v == 0.0 and not direction):
        return v
    if direction == neg:
        return -v
    raise NmeaError("field", f"{name} direction {direction[:4]!r} not {pos}/{neg}")


def wrap_2pi(angle_rad: float) -> float:
    """Normalise an angle to [0, 2π)."""
    a = angle_rad % math.tau
    return 0.0 if a >= math.tau else a


def sentence_fields(line: str) -> tuple[str, str, list[str]]:
    """Checked (talker, sentence type, raw fields) of a talker sentence.

    Types pynmea2 knows go through :func:`parse_sentence`; others (``THS``
    in pynmea2 1.19, and anything unknown) through :func:`split_checked`, so
    the checksum is always verified and the caller decides what it supports.
    """
    comma = line.find(",")
    address = line[1:comma] if comma > 0 else ""
    if len(address) == 5 and address[2:] in pynmea2.TalkerSentence.sentence_types:
        msg = parse_sentence(line)
        if not isinstance(msg, pynmea2.TalkerSentence):
            raise NmeaError("unsupported", address)
        return msg.talker, msg.sentence_type, msg.data
    address, fields = split_checked(line)
    if len(address) != 5 or address[0] == "P":  # proprietary: not a talker sentence
        raise NmeaError("unsupported", address)
    return address[:2], address[2:], fields


#: a sentence decoder: (talker, fields, t, source, variation_deg) -> messages
Handler = Callable[[str, list[str], float, str, float | None], list[Any]]


def dispatch(line: str, handlers: Mapping[str, Handler], t: float, source: str,
             variation_deg: float | None) -> list[Any]:
    """Check ``line``, pick the handler for its sentence type and run it.

    Whatever goes wrong comes out as ``NmeaError``: an unknown type is
    ``unsupported``; a stray ``ValueError``/``IndexError``/... from a handler
    (a field it failed to validate) becomes ``field`` rather than escaping.
    """
    talker, stype, fields = sentence_fields(line)
    handler = handlers.get(stype)
    if handler is None:
        raise NmeaError("unsupported", talker + stype)
    try:
        return handler(talker, fields, t, source, variation_deg)
    except NmeaError:
        raise
    except (ValueError, TypeError, AttributeError, IndexError, ArithmeticError) as exc:
        raise NmeaError("field", f"{talker}{stype}: {exc}") from exc
