"""GNSS parser: unit cases, plausible-value refusals, and speed, course, GST
and ZDA against GPSD's regression captures.

Position and fix class against GPSD are in ``test_gpsd_conformance.py``.
Each ``tests/data/gpsd-logs/*.log.chk`` interleaves every input sentence with
the JSON reports GPSD emitted after processing it; the comparisons here only
use the report printed right after a sentence.  Counts of comparisons are
asserted so the tests cannot pass vacuously.
"""

from __future__ import annotations

import contextlib
import json
import math
from collections import Counter
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest

from drivers.gps_parser import KNOT_MPS, fix_from_gga_quality, parse_gps
from drivers.nmea import NmeaError, format_sentence
from zarco_core.messages import (
    FixQuality,
    GpsErrorStats,
    GpsFix,
    GpsTime,
    GpsVelocity,
)

DATA = Path(__file__).parent / "data" / "gpsd-logs"
ALL_LOGS = sorted(p.name for p in DATA.glob("*.log"))
GPS_LOGS = [n for n in ALL_LOGS if n != "pypilot.log"]


# ----------------------------------------------------------- .chk reading


@dataclass
class Entry:
    """One input sentence and the JSON reports GPSD printed right after it."""

    line: str
    reports: list[dict[str, Any]] = field(default_factory=list)

    @property
    def stype(self) -> str:
        return self.line[3:6]

    @property
    def time_field(self) -> str | None:
        """The hhmmss field of GGA/RMC (None for other sentences)."""
        if self.stype in ("GGA", "RMC"):
            return self.line.split(",")[1]
        return None


def load_chk(name: str) -> list[Entry]:
    entries: list[Entry] = []
    for raw in (DATA / f"{name}.chk").read_text(errors="replace").splitlines():
        if raw.startswith("{"):
            if entries:
                entries[-1].reports.append(json.loads(raw))
        elif raw.strip():
            entries.append(Entry(raw.strip()))
    return entries


def tod_s(iso: str) -> float:
    """Seconds of the UTC day of a GPSD time string ``...THH:MM:SS.sssZ``."""
    hh, mm, ss = iso.split("T")[1].rstrip("Z").split(":")
    return int(hh) * 3600 + int(mm) * 60 + float(ss)


def epoch_s(iso: str) -> float:
    return datetime.strptime(iso, "%Y-%m-%dT%H:%M:%S.%fZ").replace(tzinfo=UTC).timestamp()


def only(msgs: list[Any], cls: type) -> Any:
    found = [m for m in msgs if isinstance(m, cls)]
    assert len(found) == 1, msgs
    return found[0]


def try_parse(line: str) -> list[Any] | NmeaError:
    try:
        return parse_gps(line, 1.0)
    except NmeaError as exc:
        return exc


# ------------------------------------------------------------- the logs


@pytest.mark.parametrize("name", ALL_LOGS)
def test_chk_sentences_are_the_log(name: str) -> None:
    """The .chk really is this log, sentence for sentence (else the comparisons lie)."""
    log = [ln.strip() for ln in (DATA / name).read_text(errors="replace").splitlines()
           if ln.startswith(("$", "!"))]
    assert [e.line for e in load_chk(name) if e.line.startswith(("$", "!"))] == log


def test_rtk_transition_is_seen() -> None:
    """nmea-rtk.log goes from DGPS to RTK fixed, and GPSD's status with it."""
    entries = load_chk("nmea-rtk.log")
    fixes = Counter(only(parse_gps(e.line, 0.0), GpsFix).fix
                    for e in entries if e.stype == "GGA")
    assert fixes[FixQuality.DGPS] >= 100 and fixes[FixQuality.RTK_FIXED] >= 15
    statuses = Counter(r.get("status") for e in entries for r in e.reports
                       if r["class"] == "TPV")
    assert statuses[2] > 0 and statuses[3] > 0


# ----------------------------------------------------- velocity, GST, ZDA


def test_velocity_agrees_with_gpsd() -> None:
    """RMC/VTG speed and true course against the TPV GPSD printed right after.

    Only that TPV is used (and for RMC only if its time is the RMC's), since
    later ones may carry another sentence's speed.  GPSD prints speed to
    1 mm/s and track to 1e-4°.
    """
    n: Counter[str] = Counter()
    for name in GPS_LOGS:
        for e in load_chk(name):
            if e.stype not in ("RMC", "VTG"):
                continue
            r = try_parse(e.line)
            vel = [] if isinstance(r, NmeaError) else [m for m in r if isinstance(m, GpsVelocity)]
            if not vel:
                continue
            v: GpsVelocity = vel[0]
            for tpv in (x for x in e.reports if x["class"] == "TPV" and "speed" in x):
                if e.stype == "RMC" and v.utc_s is not None and (
                        "time" not in tpv or abs(tod_s(tpv["time"]) - v.utc_s) > 1e-3):
                    continue
                assert v.sog_mps == pytest.approx(tpv["speed"], abs=6e-4), e.line
                n["speed"] += 1
                if v.cog_rad is None:
                    # empty course field: GPSD has no track for this sentence
                    assert "track" not in tpv, (e.line, tpv)
                    continue
                diff = (math.degrees(v.cog_rad) - tpv["track"] + 180.0) % 360.0 - 180.0
                assert abs(diff) < 1e-3, e.line
                n["course"] += 1
    assert n["speed"] >= 130 and n["course"] >= 129, n


def test_gst_agrees_with_gpsd() -> None:
    n = 0
    for name in ("polarx2.log", "ublox-zed-f9p-nmea.log"):
        for e in load_chk(name):
            if e.stype != "GST":
                continue
            st: GpsErrorStats = only(parse_gps(e.line, 0.0), GpsErrorStats)
            for gst in (r for r in e.reports if r["class"] == "GST"):
                assert st.std_lat_m == pytest.approx(gst["lat"], abs=1e-3)
                assert st.std_lon_m == pytest.approx(gst["lon"], abs=1e-3)
                assert st.std_alt_m == pytest.approx(gst["alt"], abs=1e-3)
                assert st.rms_m == pytest.approx(gst["rms"], abs=1e-3)
                n += 1
    assert n >= 34


def test_zda_agrees_with_gpsd() -> None:
    """ZDA → epoch seconds equals the time of the TPV GPSD printed after it."""
    n = 0
    for name in GPS_LOGS:
        for e in load_chk(name):
            if e.stype != "ZDA":
                continue
            gt: GpsTime = only(parse_gps(e.line, 0.0), GpsTime)
            for tpv in (r for r in e.reports if r["class"] == "TPV" and "time" in r):
                assert gt.utc_epoch_s == pytest.approx(epoch_s(tpv["time"]), abs=1e-6)
                n += 1
    assert n >= 111


# ------------------------------------------------------------ unit tests


GGA_RTK = ("$GNGGA,133859.80,4134.50180205,N,09345.03586649,W,4,19,0.7,280.827,M,"
           "-31.442,M,5.8,0002*6D")


def test_gga_fields() -> None:
    (fix,) = parse_gps(GGA_RTK, 12.5, "gps0")
    assert fix == GpsFix(
        t=12.5, source="gps0", sentence="GGA", talker="GN", fix=FixQuality.RTK_FIXED,
        lat_deg=pytest.approx(41 + 34.50180205 / 60, abs=1e-12),
        lon_deg=pytest.approx(-(93 + 45.03586649 / 60), abs=1e-12),
        alt_m=280.827, utc_s=13 * 3600 + 38 * 60 + 59.8, num_sats=19, hdop=0.7, age_s=5.8,
    )


@pytest.mark.parametrize(("q", "want"), [
    (0, FixQuality.NONE), (1, FixQuality.SINGLE), (2, FixQuality.DGPS),
    (3, FixQuality.SINGLE), (4, FixQuality.RTK_FIXED), (5, FixQuality.RTK_FLOAT),
    (6, FixQuality.NONE), (7, FixQuality.NONE), (8, FixQuality.NONE), (9, FixQuality.DGPS),
])
def test_gga_quality_mapping(q: int, want: FixQuality) -> None:
    assert fix_from_gga_quality(q) is want
    line = format_sentence(f"GPGGA,120000.00,4807.038,N,01131.324,E,{q},08,0.9,545.4,M,46.9,M,,")
    assert parse_gps(line.decode().strip(), 0.0)[0].fix is want


@pytest.mark.parametrize("talker", ["GP", "GN", "GL", "GA", "GB", "GQ", "GI"])
def test_any_talker(talker: str) -> None:
    line = format_sentence(f"{talker}GGA,120000.00,4807.038,S,01131.324,W,1,08,0.9,5.4,M,,M,,")
    (fix,) = parse_gps(line.decode(), 0.0)
    assert fix.talker == talker
    assert fix.lat_deg == pytest.approx(-(48 + 7.038 / 60))
    assert fix.lon_deg == pytest.approx(-(11 + 31.324 / 60))


def test_gga_without_position_is_no_fix() -> None:
    (fix,) = parse_gps("$GPGGA,,,,,,0,,,,M,,M,,*66", 0.0)
    assert fix.fix is FixQuality.NONE and fix.lat_deg is None and fix.lon_deg is None
    assert fix.utc_s is None and fix.num_sats is None
    # a quality claiming a fix does not help without a position
    line = format_sentence("GPGGA,120000,,,,,1,05,1.0,,M,,M,,").decode()
    assert parse_gps(line, 0.0)[0].fix is FixQuality.NONE


@pytest.mark.parametrize(("talker", "sats", "want"), [
    ("GP", "00", FixQuality.NONE), ("GP", "02", FixQuality.NONE), ("GN", "", FixQuality.NONE),
    ("GP", "03", FixQuality.DGPS), ("GN", "12", FixQuality.DGPS),
    ("GL", "02", FixQuality.DGPS),  # GPSD counts satellites of GP/GN talkers only
])
def test_gga_too_few_satellites_is_no_fix(talker: str, sats: str, want: FixQuality) -> None:
    """As GPSD: a GP/GN GGA using fewer than 3 satellites is no fix whatever its
    quality says (hemi.log: quality 1 with 00; saab-r4.log: quality 2, no count)."""
    line = format_sentence(f"{talker}GGA,194050.00,4221.8237733,N,07101.9411707,W,2,{sats},"
                           "3.3,10.835,M,-33.320,M,,").decode()
    (fix,) = parse_gps(line, 0.0)
    assert fix.fix is want
    assert fix.lat_deg == pytest.approx(42 + 21.8237733 / 60)  # still reported


def test_trailing_fields_left_off_read_as_empty() -> None:
    """GPSD's minimum field counts: what a terse receiver leaves off is empty."""
    # saab-r4.log: the GGA stops before the DGPS station (13 fields)
    (fix,) = parse_gps("$GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,*6A", 0.0)
    assert fix.lat_deg == pytest.approx(50.21318) and fix.age_s is None
    # GGA with 12 fields (no age, no station)
    line = format_sentence("GPGGA,120000,4807.038,N,01131.324,E,1,08,0.9,545.4,M,46.9,M")
    assert parse_gps(line.decode(), 0.0)[0].fix is FixQuality.SINGLE
    # an RMC that stops after the speed; a GLL without status mode; a VTG without mode
    fix, vel = parse_gps(format_sentence("GPRMC,120000,A,4807.038,N,01131.324,E,1.0").decode(), 0)
    assert fix.fix is FixQuality.SINGLE and vel.cog_rad is None
    (gll,) = parse_gps(format_sentence("GPGLL,4807.038,N,01131.324,E,120000,A").decode(), 0.0)
    assert gll.fix is FixQuality.SINGLE and gll.sentence == "GLL"
    (v,) = parse_gps(format_sentence("GPVTG,10.0,T,,M,1.0").decode(), 0.0)
    assert v.sog_mps == pytest.approx(KNOT_MPS)
    (z,) = parse_gps(format_sentence("GPZDA,120000,07,09,2018").decode(), 0.0)
    assert z.utc_epoch_s == datetime(2018, 9, 7, 12, tzinfo=UTC).timestamp()
    # extra fields (later revisions, vendor additions) are ignored
    line = format_sentence("GPGGA,120000,4807.038,N,01131.324,E,1,08,0.9,545.4,M,46.9,M,,,X,Y")
    assert parse_gps(line.decode(), 0.0)[0].fix is FixQuality.SINGLE


@pytest.mark.parametrize("body", [
    "GPGGA,120000,4807.038,N,01131.324,E",  # 5, need 6 (up to the fix quality)
    "GPRMC,120000,A,4807.038,N,01131.324,E",  # 6, need 7
    "GPGLL,4807.038,N,01131.324,E,120000",  # 5, need 6
    "GNGNS,120000,4807.038,N,01131.324,E,AA,08,0.9,545.4,46.9",  # 11, need 12
    "GPVTG,10.0,T,,M",  # 4, need 5
    "GPGST,120000,0.3,1.0,1.0,0.0,1.0,1.0",  # 7, need 8
    "GPZDA,120000,07,09",  # 3, need 4
    "GPTHS,12.0",  # 1, need 2
    "GPHDT",  # 0, need 1
])
def test_short_sentences_are_refused(body: str) -> None:
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence(body).decode(), 0.0)
    assert ei.value.reason == "field"


def test_eleven_field_rmc_never_takes_course_from_the_date() -> None:
    """An RMC with its course left out has the date where the course goes:
    191194 is no course, and the next field is no date."""
    body = "GPRMC,225446,A,4916.45,N,12311.12,W,000.5,191194,020.3,E,A"
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence(body).decode(), 0.0)
    assert ei.value.reason == "range"
    # the same with a course field that is a valid angle: the date field is not a date
    body = "GPRMC,225446,A,4916.45,N,12311.12,W,000.5,054.7,020.3,E,A"
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence(body).decode(), 0.0)
    assert ei.value.reason == "field"


RMC_UBLOX = "$GNRMC,003956.00,A,4552.65403,S,17030.00668,E,0.025,,120419,,,A,V*07"


def test_rmc_fix_and_velocity() -> None:
    fix, vel = parse_gps(RMC_UBLOX, 3.0)
    assert fix.sentence == "RMC" and fix.fix is FixQuality.SINGLE
    assert fix.lat_deg == pytest.approx(-(45 + 52.65403 / 60), abs=1e-12)
    assert fix.utc_s == pytest.approx(39 * 60 + 56.0)
    assert vel == GpsVelocity(3.0, "gps", "RMC", 0.025 * 1852 / 3600, None, fix.utc_s)
    assert KNOT_MPS == 1852 / 3600


#: FAA mode letter → fix class, as GPSD's faa_mode() (status 1 GPS → SINGLE,
#: 2 DGPS, 3 RTK fixed, 4 RTK float; unknown, dead reckoning, manual, simulator → NONE)
FAA_CASES = [
    ("N", FixQuality.NONE), ("A", FixQuality.SINGLE), ("D", FixQuality.DGPS),
    ("R", FixQuality.RTK_FIXED), ("F", FixQuality.RTK_FLOAT), ("E", FixQuality.NONE),
    ("M", FixQuality.NONE), ("S", FixQuality.NONE), ("P", FixQuality.DGPS),
    ("C", FixQuality.SINGLE), ("U", FixQuality.SINGLE), ("V", FixQuality.NONE),
    ("O", FixQuality.NONE), ("", FixQuality.SINGLE),
]


@pytest.mark.parametrize(("mode", "want"), FAA_CASES)
def test_rmc_faa_mode(mode: str, want: FixQuality) -> None:
    body = f"GPRMC,225446.33,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E,{mode}"
    msgs = parse_gps(format_sentence(body).decode(), 0.0)
    assert msgs[0].fix is want
    # velocity only with a usable fix
    assert len(msgs) == (1 if want is FixQuality.NONE else 2)
    if len(msgs) == 2:
        assert msgs[1].cog_rad == pytest.approx(math.radians(54.7))
        assert msgs[1].sog_mps == pytest.approx(0.5 * 1852 / 3600)


@pytest.mark.parametrize(("mode", "want"), FAA_CASES)
def test_gll_gns_vtg_faa_mode(mode: str, want: FixQuality) -> None:
    (gll,) = parse_gps(format_sentence(f"GPGLL,4916.45,N,12311.12,W,225444,A,{mode}").decode(), 0)
    assert gll.fix is want
    gns_mode = mode + "N" if mode else ""  # the first letter (GPS) decides, as in GPSD
    body = f"GNGNS,224749.00,3333.4268304,N,11153.3538273,W,{gns_mode},19,0.6,406.110,-26.294,,"
    (gns,) = parse_gps(format_sentence(body).decode(), 0.0)
    assert gns.fix is (want if mode else FixQuality.NONE)
    vtg = format_sentence(f"GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,{mode}").decode()
    if want is FixQuality.NONE and mode:
        with pytest.raises(NmeaError) as ei:
            parse_gps(vtg, 0.0)
        assert ei.value.reason == "invalid"
    else:
        assert parse_gps(vtg, 0.0)[0].sog_mps == pytest.approx(5.5 * KNOT_MPS)


@pytest.mark.parametrize("mode", ["X", "Z", "1", "AA", "a"])
def test_unknown_mode_letters_are_refused(mode: str) -> None:
    for body in (f"GPRMC,225446.33,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E,{mode}",
                 f"GPGLL,4916.45,N,12311.12,W,225444,A,{mode}",
                 f"GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,{mode}"):
        with pytest.raises(NmeaError) as ei:
            parse_gps(format_sentence(body).decode(), 0.0)
        assert ei.value.reason == "field", body


def test_gns_fields_and_status() -> None:
    body = "GNGNS,224749.00,3333.4268304,N,11153.3538273,W,DD,19,0.6,406.110,-26.294,6.0,0138,S"
    (f,) = parse_gps(format_sentence(body).decode(), 1.5, "g")
    assert f == GpsFix(1.5, "g", "GNS", "GN", FixQuality.DGPS,
                       pytest.approx(33 + 33.4268304 / 60, abs=1e-12),
                       pytest.approx(-(111 + 53.3538273 / 60), abs=1e-12), 406.110,
                       22 * 3600 + 47 * 60 + 49.0, 19, 0.6, 6.0)
    for nav in ("U", "V"):  # navigational status unsafe / not valid
        (f,) = parse_gps(format_sentence(body[:-1] + nav).decode(), 0.0)
        assert f.fix is FixQuality.NONE


def test_rmc_status_v_is_no_fix() -> None:
    body = "GPRMC,225446.33,V,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E,A"
    msgs = parse_gps(format_sentence(body).decode(), 0.0)
    assert len(msgs) == 1 and msgs[0].fix is FixQuality.NONE
    assert msgs[0].lat_deg == pytest.approx(49 + 16.45 / 60)


def test_rmc_pre_nmea23_without_mode() -> None:
    body = "GPRMC,225446,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E"
    fix, vel = parse_gps(format_sentence(body).decode(), 0.0)
    assert fix.fix is FixQuality.SINGLE and vel.sog_mps > 0


def test_vtg() -> None:
    (v,) = parse_gps("$GPVTG,339.1,T,333.5,M,0.1,N,0.1,K,A*2D", 0.0)
    assert v.sentence == "VTG"
    assert v.sog_mps == pytest.approx(0.1 * 1852 / 3600)
    assert v.cog_rad == pytest.approx(math.radians(339.1))
    # magnetic track only: true course needs the variation
    line = format_sentence("GPVTG,,T,10.0,M,1.0,N,1.852,K,A").decode()
    assert parse_gps(line, 0.0)[0].cog_rad is None
    assert parse_gps(line, 0.0, variation_deg=-14.5)[0].cog_rad == pytest.approx(
        math.radians(360 - 4.5))
    # km/h only
    line = format_sentence("GPVTG,90.0,T,,M,,N,3.6,K,D").decode()
    assert parse_gps(line, 0.0)[0].sog_mps == pytest.approx(1.0)


def test_vtg_refusals() -> None:
    with pytest.raises(NmeaError) as ei:
        parse_gps("$GPVTG,,T,,M,,N,,K,N*2C", 0.0)
    assert ei.value.reason == "invalid"
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence("GPVTG,10.0,T,,M,,N,,K,A").decode(), 0.0)
    assert ei.value.reason == "empty"
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence("GPVTG,10.0,T,,M,-1.0,N,,K,A").decode(), 0.0)
    assert ei.value.reason == "range"
    with pytest.raises(NmeaError) as ei:  # NMEA 1.x layout without unit letters
        parse_gps(format_sentence("GPVTG,054.7,034.4,005.5,010.2").decode(), 0.0)
    assert ei.value.reason == "field"


def test_gst() -> None:
    (g,) = parse_gps("$GPGST,112257.00,0.387,317.719,3.872,1.791,317.563,10.659,180.746*61",
                     2.0)
    assert g == GpsErrorStats(2.0, "gps", 317.563, 10.659, 180.746, 0.387,
                              11 * 3600 + 22 * 60 + 57.0)
    (g,) = parse_gps("$GNGST,003956.00,235111,,,,2.3,3.5,4.0*46", 0.0)
    assert (g.std_lat_m, g.std_lon_m, g.std_alt_m) == (2.3, 3.5, 4.0)
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence("GPGST,112257.00,0.3,,,,,,").decode(), 0.0)
    assert ei.value.reason == "empty"


def test_zda() -> None:
    (z,) = parse_gps("$GPZDA,193913.00,07,09,2018,00,00*63", 4.0)
    assert z == GpsTime(4.0, "gps", datetime(2018, 9, 7, 19, 39, 13, tzinfo=UTC).timestamp())
    (z,) = parse_gps(format_sentence("GPZDA,094737,20,08,2018,-01,00").decode(), 0.0)
    assert z.utc_epoch_s == datetime(2018, 8, 20, 9, 47, 37, tzinfo=UTC).timestamp()
    for body, reason in [("GPZDA,193913.00,31,02,2018,00,00", "range"),
                         ("GPZDA,193913.00,,,,00,00", "empty"),
                         ("GPZDA,253913.00,07,09,2018,00,00", "range"),
                         ("GPZDA,193913.00,07,09,9999,00,00", "range"),
                         ("GPZDA,193913.00,07,09,1979,00,00", "range"),
                         ("GPZDA,193913.00,07,13,2018,00,00", "range"),
                         ("GPZDA,193913.00,00,09,2018,00,00", "range"),
                         ("GPZDA,193913.00,07,09,2018,14,00", "range"),
                         ("GPZDA,193913.00,07,09,2018,00,60", "range"),
                         ("GPZDA,193913.00,07,09,18,00,00", "range")]:
        with pytest.raises(NmeaError) as ei:
            parse_gps(format_sentence(body).decode(), 0.0)
        assert ei.value.reason == reason, body


def test_true_heading_sentences() -> None:
    (h,) = parse_gps("$GPHDT,274.07,T*03", 1.0)
    assert h.true and h.heading_rad == pytest.approx(math.radians(274.07))
    with pytest.raises(NmeaError) as ei:
        parse_gps("$GPHDT,,T*1B", 1.0)
    assert ei.value.reason == "empty"
    (h,) = parse_gps(format_sentence("GNTHS,359.99,A").decode(), 1.0)
    assert h.sentence == "THS" and h.true
    assert h.heading_rad == pytest.approx(math.radians(359.99))
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence("GNTHS,12.0,V").decode(), 1.0)
    assert ei.value.reason == "invalid"
    (h,) = parse_gps(format_sentence("GPHDT,360.0,T").decode(), 1.0)
    assert h.heading_rad == 0.0  # 360 is north, written after rounding 359.96
    (h,) = parse_gps(format_sentence("GPHDT,12.5").decode(), 1.0)  # no reference letter
    assert h.heading_rad == pytest.approx(math.radians(12.5))


#: one valid sentence of each type, and for each of its numeric fields values
#: just outside the physical range (index of the data field, value)
GOOD = {
    "GGA": "GNGGA,120000.00,4807.038,N,01131.324,E,4,14,0.7,5.0,M,46.9,M,1.0,0000",
    "RMC": "GNRMC,120000.00,A,4807.038,N,01131.324,E,1.944,12.34,010626,2.0,E,R,S",
    "GLL": "GNGLL,4807.038,N,01131.324,E,120000.00,A,D",
    "GNS": "GNGNS,120000.00,4807.038,N,01131.324,E,DD,14,0.7,5.0,46.9,1.0,0000,S",
    "VTG": "GNVTG,12.34,T,10.0,M,1.944,N,3.600,K,R",
    "GST": "GNGST,120000.00,0.015,0.02,0.01,12.0,0.015,0.015,0.030",
    "ZDA": "GNZDA,120000.00,01,06,2026,00,00",
    "HDT": "GNHDT,123.4,T",
    "THS": "GNTHS,123.4,A",
}
OUT_OF_RANGE = [
    ("GGA", 0, "240000.00"), ("GGA", 1, "9100.000"), ("GGA", 3, "18100.000"),
    ("GGA", 5, "10"), ("GGA", 6, "100"), ("GGA", 6, "-1"), ("GGA", 7, "-5"),
    ("GGA", 7, "100.0"), ("GGA", 8, "99999"), ("GGA", 8, "-1001"), ("GGA", 10, "250"),
    ("GGA", 12, "-1"), ("GGA", 12, "10000"), ("GGA", 13, "4096"),
    ("RMC", 0, "126000"), ("RMC", 6, "99999"), ("RMC", 6, "-0.1"), ("RMC", 6, "100.1"),
    ("RMC", 7, "400"), ("RMC", 7, "999999"), ("RMC", 7, "-1"), ("RMC", 8, "320226"),
    ("RMC", 9, "181"),
    ("GLL", 0, "9000.001"), ("GLL", 4, "236000"),
    ("GNS", 6, "100"), ("GNS", 7, "-0.5"), ("GNS", 8, "20000"), ("GNS", 10, "-3"),
    ("VTG", 0, "360.1"), ("VTG", 2, "400"), ("VTG", 4, "99999"), ("VTG", 6, "200")
    , ("GST", 1, "-1"), ("GST", 2, "-0.1"), ("GST", 4, "361"), ("GST", 5, "-0.01"),
    ("GST", 6, "1e"), ("GST", 7, "200000"), ("GST", 1, "20000000"),
    ("ZDA", 3, "9999"), ("ZDA", 1, "32"), ("ZDA", 2, "0"),
    ("HDT", 0, "400"), ("HDT", 0, "999999"), ("HDT", 0, "-0.5"), ("HDT", 0, "360.5"),
    ("THS", 0, "720.5"),
]


@pytest.mark.parametrize("stype", list(GOOD))
def test_valid_sentences_of_every_type(stype: str) -> None:
    assert parse_gps(format_sentence(GOOD[stype]).decode(), 0.0)


@pytest.mark.parametrize(("stype", "k", "value"), OUT_OF_RANGE)
def test_out_of_range_values_are_refused(stype: str, k: int, value: str) -> None:
    """Checksum-valid, well-formed, impossible: refused (``range``; ``field``
    where the value cannot even be read), never clamped or wrapped."""
    address, *fields = GOOD[stype].split(",")
    fields[k] = value
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence(",".join([address, *fields])).decode(), 0.0)
    assert ei.value.reason == ("field" if value == "1e" else "range"), (stype, k, value)


@pytest.mark.parametrize(("stype", "k", "value"), [
    ("GGA", 9, "F"), ("GGA", 11, "X"), ("GGA", 2, "E"), ("GGA", 4, "N"), ("RMC", 1, "D"),
    ("RMC", 10, "N"), ("RMC", 12, "A"), ("GLL", 5, "X"), ("GNS", 5, "DX"), ("GNS", 12, "A"),
    ("VTG", 1, "M"), ("VTG", 3, "T"), ("VTG", 5, "K"), ("VTG", 7, "N"), ("HDT", 1, "M"),
    ("THS", 1, "X"), ("RMC", 8, "1206"), ("GGA", 5, "1.0"),
])
def test_malformed_letters_and_fields_are_refused(stype: str, k: int, value: str) -> None:
    address, *fields = GOOD[stype].split(",")
    fields[k] = value
    with pytest.raises(NmeaError) as ei:
        parse_gps(format_sentence(",".join([address, *fields])).decode(), 0.0)
    assert ei.value.reason == "field", (stype, k, value)


@pytest.mark.parametrize(("line", "reason"), [
    ("$GPGGA,120000,4807.038,N,01131.324,E,1,08,0.9,545.4,M,46.9,M,,", "no_checksum"),
    ("$GPGGA,120000,4807.038,N,01131.324,E,1,08,0.9,545.4,M,46.9,M,,*00", "checksum"),
    ("GPGGA,120000,4807.038,N,01131.324,E,1,08,0.9,545.4,M,46.9,M,,*00", "framing"),
    (format_sentence("GPGGA,120000,4807.038,N,01131.324,E").decode(), "field"),
    (format_sentence("GPGGA,120000,4807.038,X,01131.324,E,1,08,0.9,5,M,4,M,,").decode(),
     "field"),
    (format_sentence("GPGGA,120000,4867.038,N,01131.324,E,1,08,0.9,5,M,4,M,,").decode(),
     "field"),
    (format_sentence("GPGGA,120000,4807.038,N,01131.324,E,x,08,0.9,5,M,4,M,,").decode(),
     "field"),
    (format_sentence("GPGGA,120000,4807.038,N,01131.324,E,1,08,nan,5,M,4,M,,").decode(),
     "field"),
    (format_sentence("GPGGA,12:00:00,4807.038,N,01131.324,E,1,08,0.9,5,M,4,M,,").decode(),
     "field"),
    (format_sentence("GPRMC,225446,A,4916.45,N,12311.12,W,abc,054.7,191194").decode(),
     "field"),
    (format_sentence("GPGSV,1,1,00").decode(), "unsupported"),
    (format_sentence("GPXYZ,1,2").decode(), "unsupported"),
    (format_sentence("PZTHR,1.0,2.0").decode(), "unsupported"),
    (format_sentence("APHDM,218.6,M").decode(), "unsupported"),
])
def test_rejections(line: str, reason: str) -> None:
    with pytest.raises(NmeaError) as ei:
        parse_gps(line, 0.0)
    assert ei.value.reason == reason


def test_garbage_never_escapes_as_another_exception() -> None:
    """Fields of every kind of junk, with valid checksums: only NmeaError comes out."""
    junk = ["", "-", "1e5", "inf", "NaN", "1_0", " 1", "99999999", "-0", ".", "A", "ÿ"]
    for stype, n in [("GGA", 14), ("RMC", 13), ("GLL", 7), ("GNS", 13), ("VTG", 9),
                     ("GST", 8), ("ZDA", 6), ("HDT", 2), ("THS", 2)]:
        for j in junk:
            for k in range(n):
                fields = ["1"] * n
                fields[k] = j
                body = f"GP{stype}," + ",".join(fields)
                if not body.isascii():
                    line = "$" + body + "*00"
                else:
                    line = format_sentence(body).decode().strip()
                with contextlib.suppress(NmeaError):
                    parse_gps(line, 0.0)


def _with_checksum(body: str) -> str:
    cs = 0
    for ch in body:
        cs ^= ord(ch)
    return f"${body}*{cs:02X}"


def test_a_terse_gga_ending_after_the_fix_quality_is_accepted() -> None:
    """Some receivers end GGA right after the fix quality: the fix is taken, with the
    satellites, HDOP and altitude unknown; one field shorter is refused."""
    (fix,) = parse_gps(_with_checksum("GPGGA,123519.00,4807.038,N,01131.000,E,4"), 1.0)
    assert fix.fix is FixQuality.RTK_FIXED
    assert fix.lat_deg == pytest.approx(48.1173) and fix.lon_deg == pytest.approx(11.516667)
    assert fix.num_sats is None and fix.hdop is None and fix.alt_m is None
    with pytest.raises(NmeaError) as e:
        parse_gps(_with_checksum("GPGGA,123519.00,4807.038,N,01131.000,E"), 1.0)
    assert e.value.reason == "field"
    # a sentence that carries the satellite field, empty, still says "too few"
    (full,) = parse_gps(_with_checksum("GPGGA,123519.00,4807.038,N,01131.000,E,1,,,,,,,,"), 1.0)
    assert full.fix is FixQuality.NONE
