"""GNSS sentences → bus messages (GGA, RMC, GLL, GNS, VTG, GST, ZDA, HDT, THS).

Pure functions: :func:`parse_gps` takes one framed line and returns a list
of messages or raises :class:`~drivers.nmea.NmeaError`.  Any talker is
accepted (``GP``, ``GN``, ``GL``, ``GA``, ``GB``, ``GQ``, ...).

Units: positions WGS-84 degrees (``lat_deg``/``lon_deg``, south and west
negative), speeds m/s (1 kn = 1852/3600 m/s exactly), courses and headings
radians clockwise from true north in [0, 2π), ``utc_s`` seconds of the UTC
day taken from the sentence's time field.

Plausible values only
---------------------
Every field of an accepted sentence is checked, whether the drivers use it
or not: a field that is not what its type says (a letter where a number
goes, a date that does not exist, a unit letter other than ``M``) is
``NmeaError("field")``; a well-formed value no receiver on a vessel can
report is ``NmeaError("range")``.  Nothing is clamped or wrapped: a course
of 400° is refused, not read as 40°.  The limits (module constants) are:
latitude ±90°, longitude ±180°, minutes below 60; course/heading [0, 360];
speed [0, ``SOG_MAX_KN``]; satellites [0, ``NSAT_MAX``]; HDOP [0,
``HDOP_MAX``]; altitude [``ALT_MIN_M``, ``ALT_MAX_M``]; geoid separation
±``GEOID_SEP_MAX_M``; DGPS age [0, ``DGPS_AGE_MAX_S``], station 0–4095;
magnetic variation 0–180° E/W; GST deviations [0, ``SIGMA_MAX_M``], range
RMS [0, ``RMS_MAX_M``] and orientation [0, 360]; time of day
00:00:00–23:59:60.999; dates that exist, years 1980–2099; ZDA zone ±13 h,
0–59 min.

Field counts follow GPSD: a sentence may end early, before fields that
would be empty (older or terse receivers: an RMC without FAA mode, a GGA
without DGPS station, a GLL without mode); the missing trailing fields
read as empty.  A sentence shorter than the fields its type needs (RMC 7,
GLL 6, GNS 12, VTG 5, GST 8, ZDA 4) is refused as ``field``: the remaining
fields are never shifted into other meanings.  One step beyond GPSD (which
needs all 12 GGA fields): a GGA that ends right after its fix quality, as
some terse receivers send it, is accepted with its quality, the satellite
count, HDOP and altitude unknown.

Fix class
---------
GGA quality, as GPSD reads it: 0 → NONE, 1 → SINGLE, 2 → DGPS, 3 (PPS) →
SINGLE, 4 → RTK_FIXED, 5 → RTK_FLOAT, 6 (dead reckoning), 7 (manual), 8
(simulator) → NONE, 9 (SBAS, some vendors) → DGPS; empty → NONE.  A ``GP``
or ``GN`` GGA with fewer than 3 satellites used (an empty count is 0) is
NONE whatever its quality says, as in GPSD: a position from fewer
satellites is not a GNSS fix (hemi.log's receiver sends quality 1 with 00
satellites while acquiring; the Saab R4 sends quality 2 and no count).

The FAA mode indicator of RMC, GLL, GNS (first letter) and VTG maps as
GPSD's ``faa_mode()``: A (autonomous), C (caution) and U (unsafe, both
Quectel) → SINGLE; D (differential), P (precise) → DGPS; F → RTK_FLOAT;
R → RTK_FIXED; E (dead reckoning), M (manual), S (simulator), N (not
valid), V (invalid) and O (unknown) → NONE.  Any other letter is refused
(``field``).  RMC/GLL status V, an empty GNS mode or a GNS navigational
status U/V → NONE; an RMC or GLL without a mode indicator (before NMEA 2.3)
with status A → SINGLE.  A sentence with empty lat/lon gives ``lat_deg``/
``lon_deg`` None and NONE.

Velocities (RMC, VTG) are only emitted with a usable fix / mode: an RMC with
status V or a NONE mode gives its GpsFix (NONE) and no GpsVelocity; such a
VTG is refused (``invalid``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

from drivers.compass_parser import decode_hdt, decode_ths, fast_hdt, fast_ths
from drivers.nmea import (
    RE_POS,
    RE_SDEC,
    RE_TIME,
    RE_UDEC,
    FastHandler,
    Handler,
    NmeaError,
    days_since_epoch,
    dispatch,
    field_angle_deg,
    field_char,
    field_date_days,
    field_int_range,
    field_latlon,
    field_range,
    field_signed,
    field_time_s,
    padded,
    wrap_2pi,
)
from zarco_core.messages import (
    FixQuality,
    GpsErrorStats,
    GpsFix,
    GpsTime,
    GpsVelocity,
    Heading,
)

#: what a GNSS receiver's sentence gives (HDT/THS: a receiver with two antennas)
GpsMessage = GpsFix | GpsVelocity | GpsErrorStats | GpsTime | Heading

#: knots → m/s, exact (1 international nautical mile = 1852 m)
KNOT_MPS = 1852.0 / 3600.0
#: km/h → m/s
KMH_MPS = 1000.0 / 3600.0

#: fastest speed over ground accepted, knots: beyond any vessel carrying this
#: runtime (including one on a trailer on a motorway)
SOG_MAX_KN = 100.0
#: most satellites a receiver reports as used (the field has two digits)
NSAT_MAX = 99
#: largest HDOP: receivers print 99.9 / 99.99 when they have no solution
HDOP_MAX = 99.99
#: altitude above mean sea level of a surface vessel's antenna, metres (with
#: room for a receiver without a fix yet; the Dead Sea is at -430 m)
ALT_MIN_M, ALT_MAX_M = -1000.0, 10000.0
#: magnitude of the geoid separation, metres (EGM96 spans -107..+86 m)
GEOID_SEP_MAX_M = 200.0
#: age of differential corrections, seconds
DGPS_AGE_MAX_S = 9999.0
#: differential reference station id (RTCM 3 allows 0..4095)
STATION_MAX = 4095
#: largest GST error deviation, metres (a receiver without a solution yet)
SIGMA_MAX_M = 100_000.0
#: largest GST range-residual RMS, metres: u-blox ZED-F9P reports hundreds of
#: kilometres while it converges; a pseudorange itself is ~2e7 m
RMS_MAX_M = 1e7
#: magnitude of a magnetic variation, degrees
VARIATION_MAX_DEG = 180.0

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
    9: FixQuality.DGPS,  # SBAS-corrected (NovAtel and others)
}

#: FAA mode indicator (NMEA 2.3+, RMC/GLL/GNS/VTG) → FixQuality, as GPSD's faa_mode()
FAA_MODE: dict[str, FixQuality] = {
    "A": FixQuality.SINGLE,
    "C": FixQuality.SINGLE,  # caution (Quectel)
    "U": FixQuality.SINGLE,  # unsafe (Quectel)
    "D": FixQuality.DGPS,
    "P": FixQuality.DGPS,  # precise (NMEA 4+): GPSD counts it as differential
    "F": FixQuality.RTK_FLOAT,
    "R": FixQuality.RTK_FIXED,
    "E": FixQuality.NONE,  # estimated (dead reckoning)
    "M": FixQuality.NONE,  # manual input
    "S": FixQuality.NONE,  # simulator
    "N": FixQuality.NONE,  # data not valid
    "V": FixQuality.NONE,  # invalid
    "O": FixQuality.NONE,  # unknown (Skytraq)
}
_FAA_LETTERS = "".join(FAA_MODE)
_GP_GN = ("GP", "GN")


def fix_from_gga_quality(q: int) -> FixQuality:
    """Map the GGA fix-quality field to FixQuality (unknown values → NONE)."""
    return _GGA_QUALITY.get(q, FixQuality.NONE)


def fix_from_faa_mode(mode: str) -> FixQuality:
    """Map an FAA mode indicator letter to FixQuality (unknown letters → NONE)."""
    return FAA_MODE.get(mode, FixQuality.NONE)


def _course_rad(deg: float | None) -> float | None:
    return None if deg is None else wrap_2pi(math.radians(deg))


def _faa(s: str, name: str) -> str | None:
    return field_char(s, _FAA_LETTERS, name)


def decode_gga(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[GpsFix]:
    """``$--GGA``: time, position, quality, satellites, HDOP, altitude MSL, DGPS age."""
    # a terse receiver may end the sentence right after the fix quality: accepted,
    # with satellites, HDOP and altitude unknown (GPSD itself needs all 12 fields)
    terse = len(fields) < 7
    f = padded(fields, 6, 14, "GGA")
    utc = field_time_s(f[0])
    pos = field_latlon(f[1], f[2], f[3], f[4])
    q = field_int_range(f[5], "GGA quality", 0, 9)
    nsat = field_int_range(f[6], "GGA satellites", 0, NSAT_MAX)
    hdop = field_range(f[7], "GGA hdop", 0.0, HDOP_MAX)
    alt = field_range(f[8], "GGA altitude", ALT_MIN_M, ALT_MAX_M)
    field_char(f[9], "M", "GGA altitude units")
    field_range(f[10], "GGA geoid separation", -GEOID_SEP_MAX_M, GEOID_SEP_MAX_M)
    field_char(f[11], "M", "GGA separation units")
    age = field_range(f[12], "GGA dgps age", 0.0, DGPS_AGE_MAX_S)
    field_int_range(f[13], "GGA station", 0, STATION_MAX)
    if pos is None:
        return [GpsFix(t, source, "GGA", talker, FixQuality.NONE, None, None, alt, utc,
                       nsat, hdop, age)]
    # too few satellites in use is no fix (as GPSD); a count the receiver does not
    # send at all (a terse GGA) says nothing either way
    few = talker in _GP_GN and not terse and (nsat or 0) < 3
    fix = FixQuality.NONE if q is None or few else _GGA_QUALITY[q]
    return [GpsFix(t, source, "GGA", talker, fix, pos[0], pos[1], alt, utc, nsat, hdop, age)]


def decode_rmc(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[GpsFix | GpsVelocity]:
    """``$--RMC``: a GpsFix, plus a GpsVelocity when the fix is usable.

    Field 12 (NMEA 2.3+) is the FAA mode; field 13 (NMEA 4.1 navigational
    status: S/C/U/V) is checked and not used.  The sentence's magnetic
    variation is checked and not used: RMC course is already true.
    """
    f = padded(fields, 7, 13, "RMC")
    utc = field_time_s(f[0])
    status = field_char(f[1], "AV", "RMC status")
    pos = field_latlon(f[2], f[3], f[4], f[5])
    sog_kn = field_range(f[6], "RMC speed", 0.0, SOG_MAX_KN)
    cog_deg = field_angle_deg(f[7], "RMC course")
    field_date_days(f[8], "RMC date")
    field_signed(f[9], f[10], "E", "W", "RMC variation", VARIATION_MAX_DEG)
    mode = _faa(f[11], "RMC mode")
    field_char(f[12], "SCUV", "RMC navigational status")
    if pos is None or status != "A":
        fix = FixQuality.NONE
    elif mode is not None:
        fix = FAA_MODE[mode]
    else:
        fix = FixQuality.SINGLE
    lat, lon = pos if pos is not None else (None, None)
    out: list[GpsFix | GpsVelocity] = [GpsFix(t, source, "RMC", talker, fix, lat, lon, utc_s=utc)]
    if fix is not FixQuality.NONE and sog_kn is not None:
        out.append(GpsVelocity(t, source, "RMC", sog_kn * KNOT_MPS, _course_rad(cog_deg), utc))
    return out


def decode_gll(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[GpsFix]:
    """``$--GLL,lat,N,lon,E,hhmmss.ss,A[,mode]``: a GpsFix (no altitude, no satellites)."""
    f = padded(fields, 6, 7, "GLL")
    pos = field_latlon(f[0], f[1], f[2], f[3])
    utc = field_time_s(f[4])
    status = field_char(f[5], "AV", "GLL status")
    mode = _faa(f[6], "GLL mode")
    if pos is None or status != "A":
        fix = FixQuality.NONE
    elif mode is not None:
        fix = FAA_MODE[mode]
    else:
        fix = FixQuality.SINGLE
    lat, lon = pos if pos is not None else (None, None)
    return [GpsFix(t, source, "GLL", talker, fix, lat, lon, utc_s=utc)]


def decode_gns(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[GpsFix]:
    """``$--GNS``: time, position, mode per constellation, satellites, HDOP,
    altitude MSL, geoid separation, DGPS age and station, navigational status.

    The fix class comes from the first mode letter (GPS), as in GPSD.
    """
    f = padded(fields, 12, 13, "GNS")
    utc = field_time_s(f[0])
    pos = field_latlon(f[1], f[2], f[3], f[4])
    modes = f[5]
    if len(modes) > 8 or any(c not in FAA_MODE for c in modes):
        raise NmeaError("field", f"GNS mode {modes[:10]!r}")
    nsat = field_int_range(f[6], "GNS satellites", 0, NSAT_MAX)
    hdop = field_range(f[7], "GNS hdop", 0.0, HDOP_MAX)
    alt = field_range(f[8], "GNS altitude", ALT_MIN_M, ALT_MAX_M)
    field_range(f[9], "GNS geoid separation", -GEOID_SEP_MAX_M, GEOID_SEP_MAX_M)
    age = field_range(f[10], "GNS dgps age", 0.0, DGPS_AGE_MAX_S)
    field_int_range(f[11], "GNS station", 0, STATION_MAX)
    nav = field_char(f[12], "SCUV", "GNS navigational status")
    usable = pos is not None and modes and nav not in ("U", "V")
    fix = FAA_MODE[modes[0]] if usable else FixQuality.NONE
    lat, lon = pos if pos is not None else (None, None)
    return [GpsFix(t, source, "GNS", talker, fix, lat, lon, alt, utc, nsat, hdop, age)]


def decode_vtg(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[GpsVelocity]:
    """``$--VTG``: speed and course over ground.

    Speed from knots (km/h if knots are empty).  Course true; if only the
    magnetic track is given and ``variation_deg`` is known, true = magnetic +
    variation; else None.  A NONE mode → ``invalid``; no speed → ``empty``.
    """
    f = padded(fields, 5, 9, "VTG")
    cog_deg = field_angle_deg(f[0], "VTG true track")
    field_char(f[1], "T", "VTG true track reference")
    mag_deg = field_angle_deg(f[2], "VTG magnetic track")
    field_char(f[3], "M", "VTG magnetic track reference")
    kn = field_range(f[4], "VTG knots", 0.0, SOG_MAX_KN)
    field_char(f[5], "N", "VTG knots unit")
    kmh = field_range(f[6], "VTG km/h", 0.0, SOG_MAX_KN * 1.852)
    field_char(f[7], "K", "VTG km/h unit")
    mode = _faa(f[8], "VTG mode")
    if mode is not None and FAA_MODE[mode] is FixQuality.NONE:
        raise NmeaError("invalid", f"VTG mode {mode!r}")
    if kn is not None:
        sog = kn * KNOT_MPS
    elif kmh is not None:
        sog = kmh * KMH_MPS
    else:
        raise NmeaError("empty", "VTG without speed")
    if cog_deg is None and variation_deg is not None and mag_deg is not None:
        cog_deg = mag_deg + variation_deg
    return [GpsVelocity(t, source, "VTG", sog, _course_rad(cog_deg))]


def decode_gst(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[GpsErrorStats]:
    """``$--GST``: 1σ latitude / longitude / altitude errors and range RMS (m)."""
    f = padded(fields, 8, 8, "GST")
    utc = field_time_s(f[0])
    rms = field_range(f[1], "GST rms", 0.0, RMS_MAX_M)
    field_range(f[2], "GST semi-major", 0.0, SIGMA_MAX_M)
    field_range(f[3], "GST semi-minor", 0.0, SIGMA_MAX_M)
    field_angle_deg(f[4], "GST orientation")
    s_lat = field_range(f[5], "GST lat sigma", 0.0, SIGMA_MAX_M)
    s_lon = field_range(f[6], "GST lon sigma", 0.0, SIGMA_MAX_M)
    s_alt = field_range(f[7], "GST alt sigma", 0.0, SIGMA_MAX_M)
    if s_lat is None and s_lon is None and s_alt is None:
        raise NmeaError("empty", "GST without error estimates")
    return [GpsErrorStats(t, source, s_lat, s_lon, s_alt, rms, utc)]


def decode_zda(talker: str, fields: list[str], t: float, source: str,
               variation_deg: float | None = None) -> list[GpsTime]:
    """``$--ZDA,hhmmss.ss,dd,mm,yyyy,zh,zm``: UTC date and time → epoch seconds."""
    f = padded(fields, 4, 6, "ZDA")
    sod = field_time_s(f[0])
    day = field_int_range(f[1], "ZDA day", 1, 31)
    month = field_int_range(f[2], "ZDA month", 1, 12)
    year = field_int_range(f[3], "ZDA year", 0, 9999)
    field_int_range(f[4], "ZDA zone hours", -13, 13)
    field_int_range(f[5], "ZDA zone minutes", 0, 59)
    if sod is None or day is None or month is None or year is None:
        raise NmeaError("empty", "ZDA without date/time")
    return [GpsTime(t, source, days_since_epoch(year, month, day, "ZDA date") * 86400.0 + sod)]


# ------------------------------------------------------------- fast paths
#
# The common layouts of the sentences the simulator and most receivers send,
# matched by one regular expression each and converted with a few range
# checks; anything else (or any doubt) returns None and goes to the decoder
# above, which is the reference and raises the precise error.


def _tod(hh: str | None, mm: str, ss: str) -> float | None:
    """Seconds of the day of matched time groups; None if absent, -1 if out of range."""
    if hh is None:
        return None
    h, m, sec = int(hh), int(mm), float(ss)
    if h > 23 or m > 59 or sec >= 61.0:
        return -1.0
    return h * 3600 + m * 60 + sec


#: what _pos returns for a position out of range
_BAD_POS = (math.nan, math.nan)


def _pos(ld: str | None, lm: str, ns: str, od: str, om: str, ew: str
         ) -> tuple[float, float] | None:
    """Matched position groups → (lat, lon); None if absent, _BAD_POS if out of range."""
    if ld is None:
        return None
    a, b = float(lm), float(om)
    lat, lon = int(ld) + a / 60.0, int(od) + b / 60.0
    if a >= 60.0 or b >= 60.0 or lat > 90.0 or lon > 180.0:
        return _BAD_POS
    return (-lat if ns == "S" else lat), (-lon if ew == "W" else lon)


_GGA_RE = re.compile(rf"{RE_TIME},{RE_POS},(\d)?,(\d\d?)?,{RE_UDEC},{RE_SDEC},M?,{RE_SDEC},M?,"
                     rf"{RE_UDEC},(\d{{1,4}})?")


def _opt(text: str | None) -> float | None:
    """An optional numeric field of a fast-parsed sentence: None where it is empty."""
    return None if text is None else float(text)


def _fast_gga(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[GpsFix] | None:
    m = _GGA_RE.fullmatch(rest)
    if m is None:
        return None
    hh, mi, ss, ld, lm, ns, od, om, ew, q, nsat_s, hdop_s, alt_s, sep_s, age_s, sta = m.groups()
    if hh is None:
        utc = None
    else:  # _tod and _pos inlined: this is the hottest sentence
        h, mn, sec = int(hh), int(mi), float(ss)
        if h > 23 or mn > 59 or sec >= 61.0:
            return None
        utc = h * 3600 + mn * 60 + sec
    if ld is None:
        pos = None
    else:
        a, b = float(lm), float(om)
        lat, lon = int(ld) + a / 60.0, int(od) + b / 60.0
        if a >= 60.0 or b >= 60.0 or lat > 90.0 or lon > 180.0:
            return None
        pos = ((-lat if ns == "S" else lat), (-lon if ew == "W" else lon))
    hdop = _opt(hdop_s)
    alt = _opt(alt_s)
    age = _opt(age_s)
    if ((hdop is not None and hdop > HDOP_MAX)
            or (alt is not None and not ALT_MIN_M <= alt <= ALT_MAX_M)
            or (sep_s is not None and abs(float(sep_s)) > GEOID_SEP_MAX_M)
            or (age is not None and age > DGPS_AGE_MAX_S)
            or (sta is not None and int(sta) > STATION_MAX)):
        return None
    nsat = None if nsat_s is None else int(nsat_s)
    if pos is None:
        return [GpsFix(t, source, "GGA", talker, FixQuality.NONE, None, None, alt, utc,
                       nsat, hdop, age)]
    few = talker in _GP_GN and (nsat or 0) < 3
    fix = FixQuality.NONE if q is None or few else _GGA_QUALITY[int(q)]
    return [GpsFix(t, source, "GGA", talker, fix, pos[0], pos[1], alt, utc, nsat, hdop, age)]


_FAA_RE = "[" + _FAA_LETTERS + "]"
_RMC_RE = re.compile(rf"{RE_TIME},([AV]),{RE_POS},{RE_UDEC},{RE_UDEC},(\d{{6}})?,"
                     rf"(?:(\d+(?:\.\d+)?),([EW])|,)(?:,({_FAA_RE})?(?:,([SCUV])?)?)?")


def _fast_rmc(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[GpsFix | GpsVelocity] | None:
    m = _RMC_RE.fullmatch(rest)
    if m is None:
        return None
    hh, mi, ss, status, ld, lm, ns, od, om, ew, sog_s, cog_s, day, var, _vd, mode, _nav = (
        m.groups())
    utc = _tod(hh, mi, ss)
    pos = _pos(ld, lm, ns, od, om, ew)
    sog = _opt(sog_s)
    cog = _opt(cog_s)
    if ((utc is not None and utc < 0.0) or pos is _BAD_POS
            or (sog is not None and sog > SOG_MAX_KN) or (cog is not None and cog > 360.0)
            or (var is not None and float(var) > VARIATION_MAX_DEG)):
        return None
    if day is not None:
        try:
            field_date_days(day, "RMC date")
        except NmeaError:
            return None
    if pos is None or status != "A":
        fix = FixQuality.NONE
    else:
        fix = FixQuality.SINGLE if mode is None else FAA_MODE[mode]
    lat, lon = (None, None) if pos is None else pos
    out: list[GpsFix | GpsVelocity] = [GpsFix(t, source, "RMC", talker, fix, lat, lon, utc_s=utc)]
    if fix is not FixQuality.NONE and sog is not None:
        out.append(GpsVelocity(t, source, "RMC", sog * KNOT_MPS,
                               None if cog is None else wrap_2pi(math.radians(cog)), utc))
    return out


_VTG_RE = re.compile(rf"{RE_UDEC},T?,{RE_UDEC},M?,{RE_UDEC},N?,{RE_UDEC},K?(?:,({_FAA_RE})?)?")


def _fast_vtg(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[GpsVelocity] | None:
    m = _VTG_RE.fullmatch(rest)
    if m is None:
        return None
    cog_s, mag_s, kn_s, kmh_s, mode = m.groups()
    if mode is not None and FAA_MODE[mode] is FixQuality.NONE:
        return None
    cog = _opt(cog_s)
    mag = _opt(mag_s)
    kn = _opt(kn_s)
    kmh = _opt(kmh_s)
    if ((cog is not None and cog > 360.0) or (mag is not None and mag > 360.0)
            or (kn is not None and kn > SOG_MAX_KN)
            or (kmh is not None and kmh > SOG_MAX_KN * 1.852)):
        return None
    if kn is not None:
        sog = kn * KNOT_MPS
    elif kmh is not None:
        sog = kmh * KMH_MPS
    else:
        return None
    if cog is not None and cog == 360.0:
        cog = 0.0
    if cog is None and variation_deg is not None and mag is not None:
        cog = (0.0 if mag == 360.0 else mag) + variation_deg
    return [GpsVelocity(t, source, "VTG", sog, _course_rad(cog))]


_GST_RE = re.compile(rf"{RE_TIME}" + rf",{RE_UDEC}" * 7)


def _fast_gst(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[GpsErrorStats] | None:
    m = _GST_RE.fullmatch(rest)
    if m is None:
        return None
    hh, mi, ss, rms_s, a, b, o, la, lo, al = m.groups()
    utc = _tod(hh, mi, ss)
    if utc is not None and utc < 0.0:
        return None
    rms = _opt(rms_s)
    s_lat = _opt(la)
    s_lon = _opt(lo)
    s_alt = _opt(al)
    if s_lat is None and s_lon is None and s_alt is None:
        return None
    if ((rms is not None and rms > RMS_MAX_M) or (o is not None and float(o) > 360.0)
            or any(x is not None and float(x) > SIGMA_MAX_M for x in (a, b, la, lo, al))):
        return None
    return [GpsErrorStats(t, source, s_lat, s_lon, s_alt, rms, utc)]


_ZDA_RE = re.compile(rf"{RE_TIME},(\d\d),(\d\d),(\d{{4}})(?:,(-?\d\d?)?,(\d\d?)?)?")


def _fast_zda(talker: str, rest: str, t: float, source: str,
              variation_deg: float | None) -> list[GpsTime] | None:
    m = _ZDA_RE.fullmatch(rest)
    if m is None:
        return None
    hh, mi, ss, dd, mo, yyyy, zh, zm = m.groups()
    sod = _tod(hh, mi, ss)
    if (sod is None or sod < 0.0 or (zh is not None and not -13 <= int(zh) <= 13)
            or (zm is not None and int(zm) > 59)):
        return None
    try:
        days = days_since_epoch(int(yyyy), int(mo), int(dd), "ZDA date")
    except NmeaError:
        return None
    return [GpsTime(t, source, days * 86400.0 + sod)]


GPS_FAST: dict[str, FastHandler[GpsMessage]] = {
    "GGA": _fast_gga,
    "RMC": _fast_rmc,
    "VTG": _fast_vtg,
    "GST": _fast_gst,
    "ZDA": _fast_zda,
    "HDT": fast_hdt,
    "THS": fast_ths,
}

GPS_HANDLERS: dict[str, Handler[GpsMessage]] = {
    "GGA": decode_gga,
    "RMC": decode_rmc,
    "GLL": decode_gll,
    "GNS": decode_gns,
    "VTG": decode_vtg,
    "GST": decode_gst,
    "ZDA": decode_zda,
    "HDT": decode_hdt,
    "THS": decode_ths,
}


def parse_gps(line: str, t: float, source: str = "gps",
              variation_deg: float | None = None) -> Sequence[GpsMessage]:
    """Parse one GNSS sentence received at runtime time ``t`` (s).

    Returns GpsFix / GpsVelocity / GpsErrorStats / GpsTime / Heading
    messages (RMC gives a GpsFix and, with a usable fix, a GpsVelocity).
    ``variation_deg`` (east positive) is only used for a VTG that carries a
    magnetic but no true track.  Raises ``NmeaError`` for anything rejected.
    """
    return dispatch(line, GPS_HANDLERS, t, source, variation_deg, GPS_FAST)
