"""The buoy's radio feed (the project's ``$PZBAE``/``$PZBST`` protocol, see
docs/protocols.md) → bus messages, and the matching encoders.

::

    $PZBAE,hhmmss.ssssss,ddmmyy,K,C,Q*hh    acoustic event heard by the buoy
    $PZBST,hhmmss.ss,ddmmyy,lat,N|S,lon,E|W,V,S*hh    buoy status, 1 Hz

Pure functions: :func:`parse_buoy` takes one framed line and returns a list
with one :class:`~zarco_core.auv_messages.AcousticEvent` or
:class:`~zarco_core.auv_messages.BuoyStatus`, or raises
:class:`~drivers.nmea.NmeaError`.  Strict: the ``*hh`` checksum is required
(:func:`~drivers.nmea.split_checked`), the field count must be exact, and a
malformed or out-of-range field is ``NmeaError("field")`` (an empty mandatory
field ``NmeaError("empty")``; another sentence ``NmeaError("unsupported")``).

Times: ``utc_epoch_s`` is UTC seconds since 1970 built from the time and date
fields.  The time is read digit by digit into integer microseconds (up to six
decimals; more is refused), so the only rounding is the final conversion to a
float (≤ 0.12 µs at today's epoch).  Two-digit years are 2000–2079 for
00–79 and 1980–1999 for 80–99 (GPS era).  A leap second (ss = 60) is
accepted and counted as the first second of the next minute.

Status position: WGS-84 degrees, south and west negative; both coordinates
empty (the buoy has no GPS fix) gives NaN for both.

Plausible values only (``NmeaError("range")`` otherwise, never clamped):
time of day 00:00:00–23:59:60.999999, a date that exists; beacon id
0–``BEACON_ID_MAX``; SNR within ±``SNR_MAX_DB``; latitude ±90°, longitude
±180°; battery 0–``BATTERY_MAX_V``; fault code 0–``FAULT_CODE_MAX``.
"""

from __future__ import annotations

import math
import re
from datetime import date

from drivers.nmea import (
    NmeaError,
    field_int_range,
    field_latlon,
    field_range,
    format_sentence,
    split_checked,
)
from zarco_core.auv_messages import AcousticEvent, BuoyStatus

#: what a buoy sentence gives
BuoyMessage = AcousticEvent | BuoyStatus

_TIME_RE = re.compile(r"(\d\d)(\d\d)(\d\d)(?:\.(\d{1,6}))?")
_DATE_RE = re.compile(r"(\d\d)(\d\d)(\d\d)")
_EPOCH = date(1970, 1, 1)
#: µs in a day
_DAY_US = 86_400_000_000
#: acoustic event kinds: interrogation, reply
KINDS = ("I", "R")
#: largest beacon id on the wire (the LBL network's ids are 0..9999)
BEACON_ID_MAX = 9999
#: magnitude of a detection SNR, dB (a detection below -60 dB or above
#: +140 dB is not something a hydrophone chain produces)
SNR_MAX_DB = 140.0
SNR_MIN_DB = -60.0
#: buoy battery voltage limit (V)
BATTERY_MAX_V = 100.0
#: largest buoy fault code
FAULT_CODE_MAX = 9999


def _time_us(s: str) -> int:
    """``hhmmss[.ffffff]`` → microseconds of the UTC day."""
    if not s:
        raise NmeaError("empty", "no time")
    m = _TIME_RE.fullmatch(s)
    if m is None:
        raise NmeaError("field", f"time {s[:16]!r}")
    hh, mm, ss = int(m[1]), int(m[2]), int(m[3])
    if hh > 23 or mm > 59 or ss > 60:
        raise NmeaError("range", f"time {s!r} out of range")
    frac = m[4] or ""
    us = int(frac.ljust(6, "0")) if frac else 0
    return ((hh * 60 + mm) * 60 + ss) * 1_000_000 + us


def _date_days(s: str) -> int:
    """``ddmmyy`` → days since 1970-01-01."""
    if not s:
        raise NmeaError("empty", "no date")
    m = _DATE_RE.fullmatch(s)
    if m is None:
        raise NmeaError("field", f"date {s[:16]!r}")
    dd, mo, yy = int(m[1]), int(m[2]), int(m[3])
    year = 2000 + yy if yy < 80 else 1900 + yy
    try:
        return (date(year, mo, dd) - _EPOCH).days
    except ValueError as exc:
        raise NmeaError("range", f"date {s!r} is not a date") from exc


def _utc_epoch_s(time_s: str, date_s: str) -> float:
    return (_date_days(date_s) * _DAY_US + _time_us(time_s)) / 1e6


def _decode_pzbae(fields: list[str], t: float, source: str) -> AcousticEvent:
    if len(fields) != 5:
        raise NmeaError("field", f"PZBAE: {len(fields)} fields, need 5")
    utc = _utc_epoch_s(fields[0], fields[1])
    kind = fields[2]
    if not kind:
        raise NmeaError("empty", "PZBAE kind")
    if kind not in KINDS:
        raise NmeaError("field", f"PZBAE kind {kind[:4]!r} not I/R")
    beacon = field_int_range(fields[3], "PZBAE beacon", 0, BEACON_ID_MAX)
    if beacon is None:
        raise NmeaError("empty", "PZBAE beacon")
    snr = field_range(fields[4], "PZBAE snr", SNR_MIN_DB, SNR_MAX_DB)
    if snr is None:
        raise NmeaError("empty", "PZBAE snr")
    return AcousticEvent(t, source, utc, kind, beacon, snr)


def _decode_pzbst(fields: list[str], t: float, source: str) -> BuoyStatus:
    if len(fields) != 8:
        raise NmeaError("field", f"PZBST: {len(fields)} fields, need 8")
    utc = _utc_epoch_s(fields[0], fields[1])
    pos = field_latlon(*fields[2:6])
    lat, lon = pos if pos is not None else (math.nan, math.nan)
    volts = field_range(fields[6], "PZBST battery", 0.0, BATTERY_MAX_V)
    if volts is None:
        raise NmeaError("empty", "PZBST battery")
    fault = field_int_range(fields[7], "PZBST status", 0, FAULT_CODE_MAX)
    if fault is None:
        raise NmeaError("empty", "PZBST status")
    return BuoyStatus(t, source, utc, lat, lon, volts, fault)


def parse_buoy(line: str, t: float, source: str = "buoy") -> list[BuoyMessage]:
    """Parse one buoy sentence received at runtime time ``t`` (s).

    Returns ``[AcousticEvent]`` for ``$PZBAE`` and ``[BuoyStatus]`` for
    ``$PZBST``; raises ``NmeaError`` for anything else or anything malformed.
    """
    address, fields = split_checked(line)
    if address == "PZBAE":
        return [_decode_pzbae(fields, t, source)]
    if address == "PZBST":
        return [_decode_pzbst(fields, t, source)]
    raise NmeaError("unsupported", address)


# ------------------------------------------------------------------ encoders


def utc_text(utc_epoch_s: float, decimals: int) -> tuple[str, str]:
    """(``hhmmss.f…``, ``ddmmyy``) of a UTC time, rounded once to ``decimals``
    (1..6) so the time and the date always agree."""
    if not 1 <= decimals <= 6:
        raise ValueError(f"decimals must be 1..6, got {decimals}")
    if not math.isfinite(utc_epoch_s) or utc_epoch_s < 0.0:
        raise ValueError(f"UTC time {utc_epoch_s} not encodable")
    scale = 10 ** decimals
    units = round(utc_epoch_s * scale)
    days, rem = divmod(units, 86_400 * scale)
    sec, frac = divmod(rem, scale)
    hh, rem_s = divmod(sec, 3600)
    mm, ss = divmod(rem_s, 60)
    d = date.fromordinal(_EPOCH.toordinal() + days)
    if not 1980 <= d.year <= 2079:
        raise ValueError(f"year {d.year} not representable as ddmmyy")
    return (f"{hh:02d}{mm:02d}{ss:02d}.{frac:0{decimals}d}",
            f"{d.day:02d}{d.month:02d}{d.year % 100:02d}")


def encode_pzbae(utc_epoch_s: float, kind: str, beacon: int, snr_db: float) -> bytes:
    """``$PZBAE`` for a detection at ``utc_epoch_s`` (UTC s since 1970, written
    with µs resolution) of ``kind`` (``"I"``/``"R"``) for ``beacon``, SNR (dB,
    one decimal)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be I or R, got {kind!r}")
    if beacon < 0:
        raise ValueError(f"beacon id must be ≥ 0, got {beacon}")
    tm, dt = utc_text(utc_epoch_s, 6)
    snr = f"{snr_db:.1f}"
    if snr == "-0.0":
        snr = "0.0"
    return format_sentence(f"PZBAE,{tm},{dt},{kind},{int(beacon)},{snr}")


def _dm(value_deg: float, deg_digits: int, pos: str, neg: str) -> tuple[str, str]:
    """Degrees → (``d…dmm.mmmmmm``, hemisphere), 1e-6 minute resolution."""
    units = round(abs(value_deg) * 60e6)
    deg, rem = divmod(units, 60_000_000)
    mins, frac = divmod(rem, 1_000_000)
    return f"{deg:0{deg_digits}d}{mins:02d}.{frac:06d}", (pos if value_deg >= 0.0 else neg)


def encode_pzbst(utc_epoch_s: float, lat_deg: float, lon_deg: float, battery_v: float,
                 fault_code: int = 0) -> bytes:
    """``$PZBST`` status: time (10 ms), position (1e-6 minute; NaN → empty
    fields), battery (V, two decimals), fault code (0 = ok)."""
    tm, dt = utc_text(utc_epoch_s, 2)
    if math.isnan(lat_deg) or math.isnan(lon_deg):
        pos = ",,,"
    else:
        lat, ns = _dm(lat_deg, 2, "N", "S")
        lon, ew = _dm(lon_deg, 3, "E", "W")
        pos = f"{lat},{ns},{lon},{ew}"
    if fault_code < 0:
        raise ValueError(f"fault code must be ≥ 0, got {fault_code}")
    return format_sentence(f"PZBST,{tm},{dt},{pos},{battery_v:.2f},{int(fault_code)}")
