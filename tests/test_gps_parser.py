"""GNSS parser against real receivers: GPSD's regression captures.

Each ``tests/data/gpsd-logs/*.log.chk`` interleaves every input sentence with
the JSON reports GPSD emitted after processing it.  GPSD is a stateful
decoder that reports once per cycle, so a report is not always "about" the
sentence just before it; the helpers below pick, for each sentence, only the
reports that are demonstrably about it (see :func:`reports_for_epoch`).

Counts of comparisons are asserted so the tests cannot pass vacuously.
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
    Heading,
)

DATA = Path(__file__).parent / "data" / "gpsd-logs"
GPS_LOGS = ["hemi.log", "nmea-rtk.log", "polarx2.log", "ublox-zed-f9p-nmea.log"]
ALL_LOGS = [*GPS_LOGS, "pypilot.log"]
#: GPSD TPV "status" → our FixQuality (absent = 1, plain GPS)
STATUS_FIX = {
    1: FixQuality.SINGLE,
    2: FixQuality.DGPS,
    3: FixQuality.RTK_FIXED,
    4: FixQuality.RTK_FLOAT,
}
POS_TOL_DEG = 1e-7


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
    for raw in (DATA / f"{name}.chk").read_text().splitlines():
        if raw.startswith("{"):
            entries[-1].reports.append(json.loads(raw))
        elif raw.strip():
            entries.append(Entry(raw))
    return entries


def tod_s(iso: str) -> float:
    """Seconds of the UTC day of a GPSD time string ``...THH:MM:SS.sssZ``."""
    hh, mm, ss = iso.split("T")[1].rstrip("Z").split(":")
    return int(hh) * 3600 + int(mm) * 60 + float(ss)


def epoch_s(iso: str) -> float:
    return datetime.strptime(iso, "%Y-%m-%dT%H:%M:%S.%fZ").replace(tzinfo=UTC).timestamp()


def reports_for_epoch(entries: list[Entry], i: int, cls: str) -> list[dict[str, Any]]:
    """GPSD reports of class ``cls`` that describe the epoch of GGA/RMC ``entries[i]``.

    GPSD reports once per cycle (often after the *last* sentence of the
    epoch: Trimble's GGA gets no TPV, the following RMC does) and re-prints
    its merged state after unrelated sentences, sometimes still the previous
    epoch's (polarx2: a GST of 11:22:59 is followed by the TPV of 11:22:58).
    So the candidates are the reports printed after this sentence and after
    every later sentence up to the next GGA/RMC of another time stamp, and
    of those only the ones whose ``time`` equals this sentence's time field.
    A report with no ``time`` (GPSD has no date yet, or the sentence had no
    time) is only taken when printed directly after this sentence.
    """
    me = entries[i]
    tf = me.time_field
    utc = tod_s("T" + tf[:2] + ":" + tf[2:4] + ":" + tf[4:]) if tf else None
    out: list[dict[str, Any]] = []
    for j in range(i, len(entries)):
        e = entries[j]
        if j > i and e.time_field is not None and (e.time_field != tf or not tf):
            break
        for r in e.reports:
            if r["class"] != cls:
                continue
            if "time" in r and utc is not None:
                if abs(tod_s(r["time"]) - utc) < 1e-3:
                    out.append(r)
            elif j == i:
                out.append(r)
    return out


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


def test_captures_are_in_the_repo() -> None:
    for name in ALL_LOGS:
        assert (DATA / name).is_file() and (DATA / f"{name}.chk").is_file(), name
    assert (DATA / "README.md").is_file()


@pytest.mark.parametrize("name", ALL_LOGS)
def test_chk_sentences_are_the_log(name: str) -> None:
    """The .chk really is this log, sentence for sentence (else the comparisons lie)."""
    log = [ln for ln in (DATA / name).read_text().splitlines()
           if ln.strip() and not ln.startswith("#")]
    assert [e.line for e in load_chk(name)] == log


@pytest.mark.parametrize("name", GPS_LOGS)
def test_every_sentence_decodes_or_is_refused_for_a_reason(name: str) -> None:
    """No framing/checksum/field errors on real receivers' output; no stray exceptions."""
    outcome: Counter[tuple[str, str]] = Counter()
    for e in load_chk(name):
        r = try_parse(e.line)
        outcome[(e.stype, r.reason if isinstance(r, NmeaError) else "ok")] += 1
    bad = {k: v for k, v in outcome.items() if k[1] not in ("ok", "unsupported", "empty",
                                                           "invalid")}
    assert not bad, bad
    for stype in ("GGA", "RMC", "VTG", "GST", "ZDA", "HDT"):
        # every supported type present in a log is decoded at least once
        if any(k[0] == stype for k in outcome):
            assert outcome[(stype, "ok")] > 0, (stype, outcome)
        assert outcome[(stype, "unsupported")] == 0
    # only no-fix placeholders are refused: hemi's empty HDT and mode-N VTG
    for (stype, reason), n in outcome.items():
        if reason in ("empty", "invalid"):
            assert (name, stype) in {("hemi.log", "HDT"), ("hemi.log", "VTG")}, (stype, n)


# ------------------------------------------------------ position and fix


def compare_fixes(name: str) -> Counter[str]:
    """Compare every GGA/RMC position and fix quality with GPSD; count comparisons."""
    n: Counter[str] = Counter()
    entries = load_chk(name)
    for i, e in enumerate(entries):
        if e.stype not in ("GGA", "RMC"):
            continue
        ours: GpsFix = only(parse_gps(e.line, 1.0), GpsFix)
        tpvs = reports_for_epoch(entries, i, "TPV")
        for tpv in tpvs:
            if tpv["mode"] >= 2:
                # GPSD has a fix: so do we, at the same place
                assert ours.fix is not FixQuality.NONE, (e.line, tpv)
                assert ours.lat_deg == pytest.approx(tpv["lat"], abs=POS_TOL_DEG), e.line
                assert ours.lon_deg == pytest.approx(tpv["lon"], abs=POS_TOL_DEG), e.line
                n["position"] += 1
                gpsd_fix = STATUS_FIX[tpv.get("status", 1)]
                if e.stype == "GGA":
                    # GGA quality is exactly what GPSD's status is made of
                    assert ours.fix is gpsd_fix, (e.line, tpv)
                    n["gga_quality"] += 1
                else:
                    # GPSD's cycle report merges GGA and RMC, and GGA's quality
                    # wins: Trimble (nmea-rtk.log) keeps FAA mode "D" in RMC
                    # while its GGA says 4 (RTK fixed), and GPSD reports
                    # status 3.  From the RMC alone we can only say DGPS, so
                    # here we check RMC never claims *more* than GPSD.
                    assert FixQuality.SINGLE <= ours.fix <= gpsd_fix, (e.line, tpv)
                    n["rmc_mode"] += 1
            else:
                # GPSD has no fix (mode 0/1): neither do we.  This includes
                # hemi.log's quality-1 GGA with 00 satellites.
                assert ours.fix is FixQuality.NONE, (e.line, tpv)
                assert "lat" not in tpv
                n["no_fix"] += 1
    return n


#: minimum comparisons per log (position, no_fix) — what the captures hold
MIN_FIX_COMPARISONS = {
    "hemi.log": (19, 230),
    "nmea-rtk.log": (245, 0),
    "polarx2.log": (35, 0),
    "ublox-zed-f9p-nmea.log": (69, 0),
}


@pytest.mark.parametrize("name", GPS_LOGS)
def test_positions_and_fix_quality_agree_with_gpsd(name: str) -> None:
    n = compare_fixes(name)
    min_pos, min_nofix = MIN_FIX_COMPARISONS[name]
    assert n["position"] >= min_pos, n
    assert n["no_fix"] >= min_nofix, n
    assert n["gga_quality"] > 0, n


def test_rtk_transition_is_seen() -> None:
    """nmea-rtk.log goes from DGPS to RTK fixed: both sides of it are compared."""
    entries = load_chk("nmea-rtk.log")
    fixes = Counter(only(parse_gps(e.line, 0.0), GpsFix).fix
                    for e in entries if e.stype == "GGA")
    assert fixes[FixQuality.DGPS] >= 100 and fixes[FixQuality.RTK_FIXED] >= 15
    statuses = Counter(r.get("status") for e in entries for r in e.reports
                       if r["class"] == "TPV")
    assert statuses[2] > 0 and statuses[3] > 0
    assert compare_fixes("nmea-rtk.log")["gga_quality"] >= 100


def test_fix_comparison_total() -> None:
    total = Counter[str]()
    for name in GPS_LOGS:
        total += compare_fixes(name)
    assert total["position"] >= 368
    assert total["gga_quality"] >= 194
    assert total["rmc_mode"] >= 174
    assert total["no_fix"] >= 230


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


# ---------------------------------------------------------------- heading


def test_hemi_hdt_matches_gpsd_att() -> None:
    """Every non-empty HDT gives GPSD's ATT heading; every empty one is refused
    as ``empty`` and GPSD printed no ATT for it either."""
    compared = refused = 0
    for e in load_chk("hemi.log"):
        if e.stype != "HDT":
            continue
        atts = [r for r in e.reports if r["class"] == "ATT"]
        r = try_parse(e.line)
        if isinstance(r, NmeaError):
            assert r.reason == "empty"
            assert not atts
            refused += 1
            continue
        h: Heading = only(r, Heading)
        assert h.true and h.sentence == "HDT"
        assert len(atts) == 1
        assert math.degrees(h.heading_rad) == pytest.approx(atts[0]["heading"], abs=1e-3)
        assert h.raw_deg == pytest.approx(atts[0]["heading"], abs=1e-3)
        compared += 1
    assert compared == 4  # the capture has exactly four headings
    assert refused >= 200


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
    (6, FixQuality.NONE), (7, FixQuality.NONE), (8, FixQuality.NONE), (9, FixQuality.NONE),
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


def test_gga_zero_satellites_is_no_fix() -> None:
    """hemi.log: quality 1 with 00 satellites; GPSD says no fix, so do we."""
    line = "$GPGGA,194050.00,4221.8237733,N,07101.9411707,W,1,00,3.3,10.835,M,-33.320,M,,*62"
    (fix,) = parse_gps(line, 0.0)
    assert fix.fix is FixQuality.NONE
    assert fix.lat_deg == pytest.approx(42 + 21.8237733 / 60)  # still reported


RMC_UBLOX = "$GNRMC,003956.00,A,4552.65403,S,17030.00668,E,0.025,,120419,,,A,V*07"


def test_rmc_fix_and_velocity() -> None:
    fix, vel = parse_gps(RMC_UBLOX, 3.0)
    assert fix.sentence == "RMC" and fix.fix is FixQuality.SINGLE
    assert fix.lat_deg == pytest.approx(-(45 + 52.65403 / 60), abs=1e-12)
    assert fix.utc_s == pytest.approx(39 * 60 + 56.0)
    assert vel == GpsVelocity(3.0, "gps", "RMC", 0.025 * 1852 / 3600, None, fix.utc_s)
    assert KNOT_MPS == 1852 / 3600


@pytest.mark.parametrize(("mode", "want"), [
    ("N", FixQuality.NONE), ("A", FixQuality.SINGLE), ("D", FixQuality.DGPS),
    ("R", FixQuality.RTK_FIXED), ("F", FixQuality.RTK_FLOAT), ("E", FixQuality.NONE),
    ("M", FixQuality.NONE), ("S", FixQuality.NONE), ("P", FixQuality.SINGLE),
    ("", FixQuality.SINGLE),
])
def test_rmc_faa_mode(mode: str, want: FixQuality) -> None:
    body = f"GPRMC,225446.33,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E,{mode}"
    msgs = parse_gps(format_sentence(body).decode(), 0.0)
    assert msgs[0].fix is want
    # velocity only with a usable fix
    assert len(msgs) == (1 if want is FixQuality.NONE else 2)
    if len(msgs) == 2:
        assert msgs[1].cog_rad == pytest.approx(math.radians(54.7))
        assert msgs[1].sog_mps == pytest.approx(0.5 * 1852 / 3600)


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
    for body, reason in [("GPZDA,193913.00,31,02,2018,00,00", "field"),
                         ("GPZDA,193913.00,,,,00,00", "empty"),
                         ("GPZDA,253913.00,07,09,2018,00,00", "field")]:
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
    assert h.heading_rad == 0.0


@pytest.mark.parametrize(("line", "reason"), [
    ("$GPGGA,120000,4807.038,N,01131.324,E,1,08,0.9,545.4,M,46.9,M,,", "no_checksum"),
    ("$GPGGA,120000,4807.038,N,01131.324,E,1,08,0.9,545.4,M,46.9,M,,*00", "checksum"),
    ("GPGGA,120000,4807.038,N,01131.324,E,1,08,0.9,545.4,M,46.9,M,,*00", "framing"),
    (format_sentence("GPGGA,120000,4807.038,N,01131.324,E,1").decode(), "field"),
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
    for stype, n in [("GGA", 14), ("RMC", 12), ("VTG", 9), ("GST", 8), ("ZDA", 6),
                     ("HDT", 2), ("THS", 2)]:
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


def test_parse_time_is_small() -> None:
    """Guard against a gross regression (the budget is ~40 µs; measured ~20 µs)."""
    import timeit

    n = 2000
    best = min(timeit.repeat(lambda: parse_gps(GGA_RTK, 0.0), number=n, repeat=5)) / n
    assert best < 200e-6, best
