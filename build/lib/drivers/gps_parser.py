"""GNSS sentences → bus messages (GGA, RMC, VTG, GST, ZDA, HDT, THS).

Pure functions: :func:`parse_gps` takes one framed line and returns a list
of messages or raises :class:`~drivers.nmea.NmeaError`.  Any talker is
accepted (``GP``, ``GN``, ``GL``, ``GA``, ``GB``, ``GQ``, ...).

Units: positions WGS-84 degrees (``lat_deg``/``lon_deg``, south and west
negative), speeds m/s (1 kn = 1852/3600 m/s exactly), courses and headings
radians clockwise from true north in [0, 2π), ``utc_s`` seconds of the UTC
day taken from the sentence's time field.

Fix quality
-----------
GGA quality: 0 → NONE, 1 → SINGLE, 2 → DGPS, 3 (PPS) → SINGLE,
4 → RTK_FIXED, 5 → RTK_FLOAT, 6 (dead reckoning) / 7 (manual) / 8
(simulator) → NONE.  RMC status V → NONE; otherwise the RMC/VTG FAA mode
indicator, when present: N → NONE, A → SINGLE, D → DGPS, R → RTK_FIXED,
F → RTK_FLOAT, E/M/S → NONE, P → SINGLE.  A sentence with empty lat/lon
gives ``lat_deg``/``lon_deg`` None and NONE.

One rule beyond the quality field: a GGA that reports *zero* satellites
used is NONE whatever its quality says (a position from no satellites is
not a GNSS fix; hemi.log's Hemisphere receiver sends quality 1 with 00
satellites while acquiring, and GPSD treats those as no fix too).

Velocities (RMC, VTG) are only emitted with a usable fix / mode: an RMC with
status V or mode N/E/M/S gives its GpsFix (NONE) and no GpsVelocity; such a
VTG is refused (``invalid``).
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Any

from drivers.compass_parser import decode_hdt, decode_ths
from drivers.nmea import (
    Handler,
    NmeaError,
    dispatch,
    field_char,
    field_float,
    field_int,
    field_latlon,
    field_time_s,
    require_fields,
    wrap_2pi,
)
from zarco_core.messages import FixQuality, GpsErrorStats, GpsFix, GpsTime, GpsVelocity

#: knots → m/s, exact (1 international nautical mile = 1852 m)
KNOT_MPS = 1852.0 / 3600.0
#: km/h → m/s
KMH_MPS = 1000.0 / 3600.0

_GGA_QUALITY: dict[int, FixQuality] = {
    0: FixQuality.NONE,
    1: FixQuality.SINGLE,
    2: FixQuality.DGPS,
    3: FixQuality.SINGLE,  # PPS: a valid fix, no better than autonomous
    4: FixQuality.RTK_FIXED,
    5: FixQuality.RTK_FLOAT,
    6: FixQuality.NONE,  # dead reckoning
    7: FixQuality.NONE,  # manual input
    8: FixQuality.NONE,  # simulator
}

#: FAA mode indicator (NMEA 2.3+, RMC/VTG/GLL/GNS); unknown letters → NONE
FAA_MODE: dict[str, FixQuality] = {
    "N": FixQuality.NONE,
    "A": FixQuality.SINGLE,
    "D": FixQuality.DGPS,
    "R": FixQuality.RTK_FIXED,
    "F": FixQuality.RTK_FLOAT,
    "E": FixQuality.NONE,
    "M": FixQuality.NONE,
    "S": FixQuality.NONE,
    "P": FixQuality.SINGLE,
}


def fix_from_gga_quality(q: int) -> FixQuality:
    """Map the GGA fix-quality field to FixQuality (unknown values → NONE)."""
    return _GGA_QUALITY.get(q, FixQuality.NONE)


def fix_from_faa_mode(mode: str) -> FixQuality:
    """Map an FAA mode indicator letter to FixQuality (unknown letters → NONE)."""
    return FAA_MODE.get(mode, FixQuality.NONE)


def _speed_mps(value: float | None, scale: float, name: str) -> float | None:
    if value is None:
        return None
    if value < 0.0:
        raise NmeaError("field", f"negative {name} {value}")
    return value * scale


def _course_rad(deg: float | None) -> float | None:
    return None if deg is None else wrap_2pi(math.radians(deg))


def decode_gga(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--GGA``: time, position, quality, satellites, HDOP, altitude MSL, DGPS age."""
    require_fields(fields, 14, "GGA")
    utc = field_time_s(fields[0])
    pos = field_latlon(fields[1], fields[2], fields[3], fields[4])
    q = field_int(fields[5], "GGA quality")
    nsat = field_int(fields[6], "GGA satellites")
    hdop = field_float(fields[7], "GGA hdop")
    alt = field_float(fields[8], "GGA altitude")
    age = field_float(fields[12], "GGA dgps age")
    if pos is None:
        return [GpsFix(t, source, "GGA", talker, FixQuality.NONE, None, None, alt, utc,
                       nsat, hdop, age)]
    fix = FixQuality.NONE if q is None or nsat == 0 else fix_from_gga_quality(q)
    return [GpsFix(t, source, "GGA", talker, fix, pos[0], pos[1], alt, utc, nsat, hdop, age)]


def decode_rmc(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--RMC``: a GpsFix, plus a GpsVelocity when the fix is usable.

    Field 12 (NMEA 2.3+) is the FAA mode; field 13 (NMEA 4.1 navigational
    status) is ignored.  The sentence's magnetic variation is not used:
    RMC course is already true.
    """
    require_fields(fields, 11, "RMC")
    utc = field_time_s(fields[0])
    status = field_char(fields[1], "AVD", "RMC status")
    pos = field_latlon(fields[2], fields[3], fields[4], fields[5])
    mode = fields[11] if len(fields) > 11 else ""
    if pos is None or status not in ("A", "D"):
        fix = FixQuality.NONE
    elif mode:
        fix = fix_from_faa_mode(mode)
    else:
        fix = FixQuality.SINGLE
    lat, lon = pos if pos is not None else (None, None)
    out: list[Any] = [GpsFix(t, source, "RMC", talker, fix, lat, lon, utc_s=utc)]
    if fix is FixQuality.NONE:
        return out
    sog = _speed_mps(field_float(fields[6], "RMC speed"), KNOT_MPS, "RMC speed")
    if sog is not None:
        cog = _course_rad(field_float(fields[7], "RMC course"))
        out.append(GpsVelocity(t, source, "RMC", sog, cog, utc))
    return out


def decode_vtg(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--VTG``: speed and course over ground.

    Speed from knots (km/h if knots are empty).  Course true; if only the
    magnetic track is given and ``variation_deg`` is known, true = magnetic +
    variation; else None.  Mode N/E/M/S → ``invalid``; no speed → ``empty``.
    """
    require_fields(fields, 8, "VTG")
    mode = fields[8] if len(fields) > 8 else ""
    if mode and fix_from_faa_mode(mode) is FixQuality.NONE:
        raise NmeaError("invalid", f"VTG mode {mode!r}")
    sog = _speed_mps(field_float(fields[4], "VTG knots"), KNOT_MPS, "VTG speed")
    if sog is None:
        sog = _speed_mps(field_float(fields[6], "VTG km/h"), KMH_MPS, "VTG speed")
    if sog is None:
        raise NmeaError("empty", "VTG without speed")
    cog_deg = field_float(fields[0], "VTG true track")
    if cog_deg is None and variation_deg is not None:
        mag = field_float(fields[2], "VTG magnetic track")
        cog_deg = None if mag is None else mag + variation_deg
    return [GpsVelocity(t, source, "VTG", sog, _course_rad(cog_deg))]


def decode_gst(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--GST``: 1σ latitude / longitude / altitude errors and range RMS (m)."""
    require_fields(fields, 8, "GST")
    utc = field_time_s(fields[0])
    rms, s_lat, s_lon, s_alt = (field_float(fields[i], f"GST field {i + 1}")
                                for i in (1, 5, 6, 7))
    if s_lat is None and s_lon is None and s_alt is None:
        raise NmeaError("empty", "GST without error estimates")
    for v in (rms, s_lat, s_lon, s_alt):
        if v is not None and v < 0.0:
            raise NmeaError("field", f"negative GST deviation {v}")
    return [GpsErrorStats(t, source, s_lat, s_lon, s_alt, rms, utc)]


def decode_zda(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[Any]:
    """``$--ZDA,hhmmss.ss,dd,mm,yyyy,zh,zm``: UTC date and time → epoch seconds."""
    require_fields(fields, 6, "ZDA")
    sod = field_time_s(fields[0])
    day, month, year = (field_int(fields[i], "ZDA date") for i in (1, 2, 3))
    if sod is None or day is None or month is None or year is None:
        raise NmeaError("empty", "ZDA without date/time")
    if year < 1980:
        raise NmeaError("field", f"ZDA year {year}")
    try:
        midnight = datetime(year, month, day, tzinfo=UTC).timestamp()
    except ValueError as exc:
        raise NmeaError("field", f"ZDA date {fields[1:4]}") from exc
    return [GpsTime(t, source, midnight + sod)]


GPS_HANDLERS: dict[str, Handler] = {
    "GGA": decode_gga,
    "RMC": decode_rmc,
    "VTG": decode_vtg,
    "GST": decode_gst,
    "ZDA": decode_zda,
    "HDT": decode_hdt,
    "THS": decode_ths,
}


def parse_gps(line: str, t: float, source: str = "gps",
              variation_deg: float | None = None) -> list[Any]:
    """Parse one GNSS sentence received at runtime time ``t`` (s).

    Returns GpsFix / GpsVelocity / GpsErrorStats / GpsTime / Heading
    messages (RMC gives a GpsFix and, with a usable fix, a GpsVelocity).
    ``variation_deg`` (east positive) is only used for a VTG that carries a
    magnetic but no true track.  Raises ``NmeaError`` for anything rejected.
    """
    return dispatch(line, GPS_HANDLERS, t, source, variation_deg)
