"""Compass / IMU sentences → bus messages (HDG, HDM, HDT, THS, ROT, XDR).

Pure functions: :func:`parse_compass` takes one framed line and returns a
list of messages or raises :class:`~drivers.nmea.NmeaError`.  Any talker is
accepted (``HC``, ``AP``, ``II``, ``TI``, ``GP``, ...).

Conventions (the project's, as in :mod:`zarco_core.messages`): headings
clockwise from north, returned in radians normalised to [0, 2π); variation
and deviation east positive; rate of turn positive turning to starboard
(clockwise), rad/s; pitch and roll passed through with the sign the
sentence uses (XDR convention: pitch positive bow up, roll positive
starboard side down), radians.

Heading algebra (NMEA 0183 HDG): magnetic = sensor + deviation,
true = magnetic + variation.

Plausible values only: headings in [0, 360] (360 reads as 0; anything else
outside is ``NmeaError("range")``, never wrapped), deviation and variation
0–180° with their E/W letter, rate of turn within ±``ROT_MAX_DPM``, pitch
within ±90° and roll within ±180°; reference and status letters must be the
ones the sentence defines.  Field counts follow GPSD (HDT 1, HDG 1, HDM 2,
THS 2, ROT 2, XDR one quadruplet): trailing fields a sender leaves off read
as empty; fewer than that is refused (``field``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence

from drivers.nmea import (
    FastHandler,
    Handler,
    NmeaError,
    dispatch,
    field_angle_deg,
    field_char,
    field_range,
    field_signed,
    padded,
    wrap_2pi,
)
from zarco_core.messages import Attitude, Heading, RateOfTurn

#: what a compass/IMU sentence gives
CompassMessage = Heading | RateOfTurn | Attitude

#: XDR transducer names for pitch and roll (upper-cased before lookup)
PITCH_NAMES = frozenset({"PTCH", "PITCH"})
ROLL_NAMES = frozenset({"ROLL"})
#: THS mode indicators accepted as a usable heading (V = not valid is refused)
THS_OK_MODES = "AEMS"
#: largest rate of turn accepted, degrees per minute (60 °/s: beyond any hull
#: this runtime steers, and beyond the range of marine rate-of-turn sensors)
ROT_MAX_DPM = 3600.0
#: magnitude of a compass deviation or a magnetic variation, degrees
OFFSET_MAX_DEG = 180.0
#: pitch and roll limits, degrees (Euler angles: pitch ±90, roll ±180)
PITCH_MAX_DEG, ROLL_MAX_DEG = 90.0, 180.0


def _heading_value(s: str) -> float:
    """A heading field in degrees in [0, 360]; empty → ``NmeaError("empty")``."""
    deg = field_angle_deg(s, "heading")
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
               variation_deg: float | None = None) -> list[Heading]:
    """``$--HDT,x.x,T`` true heading.  Empty heading → ``NmeaError("empty")``."""
    f = padded(fields, 1, 2, "HDT")
    field_char(f[1], "T", "HDT reference")
    deg = _heading_value(f[0])
    return [Heading(t, source, "HDT", wrap_2pi(math.radians(deg)), True, deg)]


def decode_ths(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Heading]:
    """``$--THS,x.x,m`` true heading with mode (A/E/M/S usable, V refused)."""
    f = padded(fields, 2, 2, "THS")
    mode = field_char(f[1], THS_OK_MODES + "V", "THS mode")
    deg = _heading_value(f[0]) if f[0] else None
    if mode == "V" or mode is None:
        raise NmeaError("invalid", f"THS mode {f[1]!r}")
    if deg is None:
        raise NmeaError("empty", "no heading")
    return [Heading(t, source, "THS", wrap_2pi(math.radians(deg)), True, deg)]


def decode_hdg(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Heading]:
    """``$--HDG,sensor,dev,E|W,var,E|W``.

    The sentence's own variation wins; without it the configured
    ``variation_deg`` is used; with neither the heading stays magnetic.
    """
    f = padded(fields, 1, 5, "HDG")
    dev = field_signed(f[1], f[2], "E", "W", "HDG deviation", OFFSET_MAX_DEG)
    var = field_signed(f[3], f[4], "E", "W", "HDG variation", OFFSET_MAX_DEG)
    raw = _heading_value(f[0])
    return [heading_from_magnetic(t, source, "HDG", raw, dev,
                                  var if var is not None else variation_deg)]


def decode_hdm(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Heading]:
    """``$--HDM,x.x,M`` magnetic heading; true if ``variation_deg`` is given."""
    f = padded(fields, 2, 2, "HDM")
    field_char(f[1], "M", "HDM reference")
    raw = _heading_value(f[0])
    return [heading_from_magnetic(t, source, "HDM", raw, None, variation_deg)]


def decode_rot(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[RateOfTurn]:
    """``$--ROT,x.x,A`` rate of turn, deg/min on the wire → rad/s (+ = starboard)."""
    f = padded(fields, 2, 2, "ROT")
    status = field_char(f[1], "AV", "ROT status")
    deg_per_min = field_range(f[0], "rate of turn", -ROT_MAX_DPM, ROT_MAX_DPM)
    if status != "A":
        raise NmeaError("invalid", f"ROT status {f[1]!r}")
    if deg_per_min is None:
        raise NmeaError("empty", "no rate of turn")
    return [RateOfTurn(t, source, math.radians(deg_per_min) / 60.0)]


def decode_xdr(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Attitude]:
    """``$--XDR,type,value,units,name[,...]`` transducer quadruplets.

    Angle transducers (type ``A``, units ``D``) named PTCH/PITCH and ROLL
    give an Attitude with the fields present; other transducers are
    ignored (``[]`` if nothing of interest).  A pitch/roll quadruplet in
    units other than degrees, or a malformed value, is ``NmeaError("field")``;
    pitch beyond ±90° or roll beyond ±180° is ``NmeaError("range")``.  A last
    quadruplet cut short reads its missing trailing fields as empty (GPSD).
    """
    n = len(fields)
    f = padded(fields, 4, n + (-n % 4), "XDR")
    pitch = roll = None
    for i in range(0, len(f), 4):
        kind, value, units, name = f[i:i + 4]
        name = name.upper()
        is_pitch = name in PITCH_NAMES
        if kind != "A" or not value or not (is_pitch or name in ROLL_NAMES):
            continue
        if units != "D":
            raise NmeaError("field", f"XDR {name} in units {units!r}, want D")
        if is_pitch:
            deg = field_range(value, f"XDR {name}", -PITCH_MAX_DEG, PITCH_MAX_DEG)
            if deg is not None:
                pitch = math.radians(deg)
        else:
            deg = field_range(value, f"XDR {name}", -ROLL_MAX_DEG, ROLL_MAX_DEG)
            if deg is not None:
                roll = math.radians(deg)
    if pitch is None and roll is None:
        return []
    return [Attitude(t, source, pitch, roll)]


# ------------------------------------------------------------- fast paths
#
# The common layouts, one regular expression each; anything else returns
# None and goes to the decoders above (the reference, with the precise error).

_DEC = r"(\d+(?:\.\d+)?)"
_OFFSET = rf"(?:{_DEC},([EW])|,)"
_HDT_RE = re.compile(rf"{_DEC}(?:,T?)?")
_THS_RE = re.compile(rf"{_DEC},([AEMS])")
_HDM_RE = re.compile(rf"{_DEC},M")
_HDG_RE = re.compile(rf"{_DEC},{_OFFSET},{_OFFSET}")
_ROT_RE = re.compile(r"(-?\d+(?:\.\d+)?),A")


def _bearing(text: str) -> float | None:
    """A heading field (°) in [0, 360]: 360 is 0; beyond it, None (implausible)."""
    deg = float(text)
    if deg > 360.0:
        return None
    return 0.0 if deg == 360.0 else deg


def _true_heading(rx: re.Pattern[str], sentence: str) -> Callable[
        [str, str, float, str, float | None], list[Heading] | None]:
    """The fast parser of a true-heading sentence whose body ``rx`` matches."""

    def parse(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[Heading] | None:
        m = rx.fullmatch(rest)
        deg = None if m is None else _bearing(m[1])
        if deg is None:
            return None
        return [Heading(t, source, sentence, wrap_2pi(math.radians(deg)), True, deg)]

    return parse


fast_hdt = _true_heading(_HDT_RE, "HDT")
fast_ths = _true_heading(_THS_RE, "THS")


def _fast_hdm(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[Heading] | None:
    m = _HDM_RE.fullmatch(rest)
    deg = None if m is None else _bearing(m[1])
    if deg is None:
        return None
    return [heading_from_magnetic(t, source, "HDM", deg, None, variation_deg)]


def _fast_hdg(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[Heading] | None:
    m = _HDG_RE.fullmatch(rest)
    if m is None:
        return None
    raw_s, dev_s, dev_d, var_s, var_d = m.groups()
    raw = float(raw_s)
    dev = None if dev_s is None else float(dev_s)
    var = None if var_s is None else float(var_s)
    if (raw > 360.0 or (dev is not None and dev > OFFSET_MAX_DEG)
            or (var is not None and var > OFFSET_MAX_DEG)):
        return None
    if dev is not None and dev_d == "W":
        dev = -dev
    if var is not None and var_d == "W":
        var = -var
    return [heading_from_magnetic(t, source, "HDG", 0.0 if raw == 360.0 else raw, dev,
                                  var if var is not None else variation_deg)]


def _fast_rot(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[RateOfTurn] | None:
    m = _ROT_RE.fullmatch(rest)
    if m is None:
        return None
    dpm = float(m[1])
    if abs(dpm) > ROT_MAX_DPM:
        return None
    return [RateOfTurn(t, source, math.radians(dpm) / 60.0)]


COMPASS_FAST: dict[str, FastHandler[CompassMessage]] = {
    "HDG": _fast_hdg,
    "HDM": _fast_hdm,
    "HDT": fast_hdt,
    "THS": fast_ths,
    "ROT": _fast_rot,
}

COMPASS_HANDLERS: dict[str, Handler[CompassMessage]] = {
    "HDG": decode_hdg,
    "HDM": decode_hdm,
    "HDT": decode_hdt,
    "THS": decode_ths,
    "ROT": decode_rot,
    "XDR": decode_xdr,
}


def parse_compass(line: str, t: float, source: str = "compass",
                  variation_deg: float | None = None) -> Sequence[CompassMessage]:
    """Parse one compass/IMU sentence received at runtime time ``t`` (s).

    ``variation_deg`` (east positive) is the configured magnetic variation,
    used when the sentence carries none.  Returns Heading, RateOfTurn or
    Attitude messages (``[]`` for an XDR without pitch/roll); raises
    ``NmeaError`` for anything rejected.
    """
    return dispatch(line, COMPASS_HANDLERS, t, source, variation_deg, COMPASS_FAST)
