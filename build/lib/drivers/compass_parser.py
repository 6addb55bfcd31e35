"""Compass / IMU sentences → bus messages (HDG, HDM, HDT, THS, ROT, XDR).

Pure functions: :func:`parse_compass` takes one framed line and returns a
list of messages or raises :class:`~drivers.nmea.NmeaError`.  Any talker is
accepted (``HC``, ``AP``, ``II``, ``TI``, ``GP``, ...).

Conventions (DESIGN.md §3): headings clockwise from north, returned in
radians normalised to [0, 2π); variation and deviation east positive;
rate of turn positive turning to starboard (clockwise), rad/s; pitch and
roll passed through with the sign the sentence uses (XDR convention: pitch
positive bow up, roll positive starboard side down), radians.

Heading algebra (NMEA 0183 HDG): magnetic = sensor + deviation,
true = magnetic + variation.
"""

from __future__ import annotations

import math
from typing import Any

from drivers.nmea import (
    Handler,
    NmeaError,
    dispatch,
    field_char,
    field_float,
    field_signed,
    require_fields,
    wrap_2pi,
)
from zarco_core.messages import Attitude, Heading, RateOfTurn

#: XDR transducer names for pitch and roll (upper-cased before lookup)
PITCH_NAMES = frozenset({"PTCH", "PITCH"})
ROLL_NAMES = frozenset({"ROLL"})
#: THS mode indicators accepted as a usable heading (V = not valid is refused)
THS_OK_MODES = "AEMS"


def _heading_value(s: str) -> float:
    """A heading field in degrees; empty → ``NmeaError("empty")``."""
    deg = field_float(s, "heading")
    if deg is None:
        raise NmeaError("empty", "no heading")
    return deg


def heading_from_magnetic(t: float, source: str, sentence: str, raw_deg: float,
                          deviation_deg: float | None,
                          variation_deg: float | None) -> Heading:
    """Build a Heading from a magnetic sensor reading.

    ``true`` is set, and ``heading_rad`` is the true heading, only when a
    variation is known; otherwise ``heading_rad`` is the magnetic heading
    (sensor + deviation) with ``true=False``.
    """
    magnetic = raw_deg + (deviation_deg or 0.0)
    if variation_deg is None:
        return Heading(t, source, sentence, wrap_2pi(math.radians(magnetic)), False,
                       raw_deg, None, deviation_deg)
    return Heading(t, source, sentence, wrap_2pi(math.radians(magnetic + variation_deg)),
                   True, raw_deg, variation_deg, deviation_deg)


def decode_hdt(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--HDT,x.x,T`` true heading.  Empty heading → ``NmeaError("empty")``."""
    require_fields(fields, 2, "HDT")
    field_char(fields[1], "T", "HDT reference")
    deg = _heading_value(fields[0])
    return [Heading(t, source, "HDT", wrap_2pi(math.radians(deg)), True, deg)]


def decode_ths(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--THS,x.x,m`` true heading with mode (A/E/M/S usable, V refused)."""
    require_fields(fields, 2, "THS")
    mode = field_char(fields[1], THS_OK_MODES + "V", "THS mode")
    if mode == "V" or mode is None:
        raise NmeaError("invalid", f"THS mode {fields[1]!r}")
    deg = _heading_value(fields[0])
    return [Heading(t, source, "THS", wrap_2pi(math.radians(deg)), True, deg)]


def decode_hdg(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--HDG,sensor,dev,E|W,var,E|W``.

    The sentence's own variation wins; without it the configured
    ``variation_deg`` is used; with neither the heading stays magnetic.
    """
    require_fields(fields, 5, "HDG")
    raw = _heading_value(fields[0])
    dev = field_signed(fields[1], fields[2], "E", "W", "HDG deviation")
    var = field_signed(fields[3], fields[4], "E", "W", "HDG variation")
    return [heading_from_magnetic(t, source, "HDG", raw, dev,
                                  var if var is not None else variation_deg)]


def decode_hdm(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--HDM,x.x,M`` magnetic heading; true if ``variation_deg`` is given."""
    require_fields(fields, 2, "HDM")
    field_char(fields[1], "M", "HDM reference")
    raw = _heading_value(fields[0])
    return [heading_from_magnetic(t, source, "HDM", raw, None, variation_deg)]


def decode_rot(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--ROT,x.x,A`` rate of turn, deg/min on the wire → rad/s (+ = starboard)."""
    require_fields(fields, 2, "ROT")
    status = field_char(fields[1], "AV", "ROT status")
    if status != "A":
        raise NmeaError("invalid", f"ROT status {fields[1]!r}")
    deg_per_min = field_float(fields[0], "rate of turn")
    if deg_per_min is None:
        raise NmeaError("empty", "no rate of turn")
    return [RateOfTurn(t, source, math.radians(deg_per_min) / 60.0)]


def decode_xdr(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--XDR,type,value,units,name[,...]`` transducer quadruplets.

    Angle transducers (type ``A``, units ``D``) named PTCH/PITCH and ROLL
    give an Attitude with the fields present; other transducers are
    ignored (``[]`` if nothing of interest).  A pitch/roll quadruplet in
    units other than degrees, or a malformed value, is ``NmeaError("field")``.
    """
    if not fields or len(fields) % 4:
        raise NmeaError("field", f"XDR: {len(fields)} fields, not quadruplets")
    pitch = roll = None
    for i in range(0, len(fields), 4):
        kind, value, units, name = fields[i:i + 4]
        name = name.upper()
        is_pitch = name in PITCH_NAMES
        if kind != "A" or not (is_pitch or name in ROLL_NAMES):
            continue
        if units != "D":
            raise NmeaError("field", f"XDR {name} in units {units!r}, want D")
        deg = field_float(value, f"XDR {name}")
        if deg is None:
            continue
        if is_pitch:
            pitch = math.radians(deg)
        else:
            roll = math.radians(deg)
    if pitch is None and roll is None:
        return []
    return [Attitude(t, source, pitch, roll)]


COMPASS_HANDLERS: dict[str, Handler] = {
    "HDG": decode_hdg,
    "HDM": decode_hdm,
    "HDT": decode_hdt,
    "THS": decode_ths,
    "ROT": decode_rot,
    "XDR": decode_xdr,
}


def parse_compass(line: str, t: float, source: str = "compass",
                  variation_deg: float | None = None) -> list[Any]:
    """Parse one compass/IMU sentence received at runtime time ``t`` (s).

    ``variation_deg`` (east positive) is the configured magnetic variation,
    used when the sentence carries none.  Returns Heading, RateOfTurn or
    Attitude messages (``[]`` for an XDR without pitch/roll); raises
    ``NmeaError`` for anything rejected.
    """
    return dispatch(line, COMPASS_HANDLERS, t, source, variation_deg)
