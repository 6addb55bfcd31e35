"""Compass / IMU parser: unit cases and GPSD's pypilot capture."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from drivers.compass_parser import parse_compass
from drivers.nmea import NmeaError, format_sentence
from zarco_core.messages import Attitude, Heading, RateOfTurn

DATA = Path(__file__).parent / "data" / "gpsd-logs"


def s(body: str) -> str:
    """A correctly framed and checksummed line for ``body``."""
    return format_sentence(body).decode().rstrip("\r\n")


def reason(line: str, **kw: object) -> str:
    with pytest.raises(NmeaError) as ei:
        parse_compass(line, 0.0, **kw)  # type: ignore[arg-type]
    return ei.value.reason


# ------------------------------------------------------------------- HDG


def test_hdg_with_own_variation() -> None:
    # sensor 98.3, deviation 0.0, variation 12.6 W → true 85.7
    (h,) = parse_compass("$HCHDG,98.3,0.0,E,12.6,W*57", 2.0, "cmp")
    assert isinstance(h, Heading)
    assert (h.t, h.source, h.sentence, h.true) == (2.0, "cmp", "HDG", True)
    assert h.heading_rad == pytest.approx(math.radians(85.7))
    assert h.raw_deg == 98.3
    assert h.variation_deg == -12.6 and h.deviation_deg == 0.0


def test_hdg_deviation_and_variation_signs() -> None:
    (h,) = parse_compass(s("HCHDG,10.0,2.5,W,3.0,E"), 0.0)
    assert h.heading_rad == pytest.approx(math.radians(10.0 - 2.5 + 3.0))
    (h,) = parse_compass(s("HCHDG,10.0,2.5,E,3.0,W"), 0.0)
    assert h.heading_rad == pytest.approx(math.radians(10.0 + 2.5 - 3.0))


def test_hdg_sentence_variation_beats_argument() -> None:
    (h,) = parse_compass(s("HCHDG,100.0,,,5.0,E"), 0.0, variation_deg=-20.0)
    assert h.true and h.variation_deg == 5.0
    assert h.heading_rad == pytest.approx(math.radians(105.0))


def test_hdg_falls_back_to_argument_then_magnetic() -> None:
    line = s("HCHDG,100.0,1.0,E,,")
    (h,) = parse_compass(line, 0.0, variation_deg=-2.0)
    assert h.true and h.variation_deg == -2.0
    assert h.heading_rad == pytest.approx(math.radians(99.0))
    (h,) = parse_compass(line, 0.0)
    assert not h.true and h.variation_deg is None
    # magnetic heading = sensor + deviation
    assert h.heading_rad == pytest.approx(math.radians(101.0))


def test_heading_wraps_into_0_2pi() -> None:
    (h,) = parse_compass(s("HCHDG,359.0,,,3.0,E"), 0.0)
    assert h.heading_rad == pytest.approx(math.radians(2.0))
    (h,) = parse_compass(s("HCHDG,1.0,,,3.0,W"), 0.0)
    assert h.heading_rad == pytest.approx(math.radians(358.0))
    (h,) = parse_compass(s("HCHDG,0.0,0.0,E,0.0,E"), 0.0)
    assert h.heading_rad == 0.0
    for deg in ("0.0", "359.999", "360.0"):
        (h,) = parse_compass(s(f"HEHDT,{deg},T"), 0.0)
        assert 0.0 <= h.heading_rad < 2 * math.pi, deg


@pytest.mark.parametrize("body", [
    "HEHDT,720.5,T", "HEHDT,400,T", "HEHDT,999999,T", "HEHDT,-0.0000001,T", "HEHDT,360.01,T",
    "GPTHS,361.0,A", "APHDM,400.0,M", "HCHDG,400.0,,,2.0,W", "HCHDG,98.3,181.0,E,,",
    "HCHDG,98.3,,,180.5,W", "HCHDG,98.3,-2.0,E,,", "TIROT,1000000,A", "TIROT,-3600.1,A",
    "TIROT,99999,V", "YXXDR,A,90.5,D,PTCH", "YXXDR,A,-91,D,PITCH", "YXXDR,A,180.1,D,ROLL",
    "YXXDR,A,0.5,D,PTCH,A,-200,D,ROLL",
])
def test_out_of_range_values_are_refused_not_wrapped(body: str) -> None:
    """Checksum-valid values no instrument produces: refused, never wrapped or clamped."""
    assert reason(s(body)) == "range"


def test_values_at_the_limits_are_accepted() -> None:
    (r,) = parse_compass(s("TIROT,-3600.0,A"), 0.0)
    assert r.rate_rps == pytest.approx(-math.radians(60.0))
    (a,) = parse_compass(s("YXXDR,A,-90.0,D,PTCH,A,180.0,D,ROLL"), 0.0)
    assert a.pitch_rad == pytest.approx(-math.pi / 2) and a.roll_rad == pytest.approx(math.pi)
    (h,) = parse_compass(s("HCHDG,10.0,180.0,W,180.0,E"), 0.0)
    assert h.heading_rad == pytest.approx(math.radians(10.0))


def test_trailing_fields_left_off_read_as_empty() -> None:
    (h,) = parse_compass(s("HCHDG,98.3"), 0.0)  # no deviation, no variation fields
    assert not h.true and h.heading_rad == pytest.approx(math.radians(98.3))
    (h,) = parse_compass(s("HCHDG,98.3,,,2.0,W"), 0.0)
    assert h.true and h.heading_rad == pytest.approx(math.radians(96.3))
    (a,) = parse_compass(s("IIXDR,A,1.0,D,PTCH,A,2.0,D"), 0.0)  # last name left off
    assert a.pitch_rad == pytest.approx(math.radians(1.0)) and a.roll_rad is None
    assert reason(s("APHDM,218.6")) == "field"  # GPSD needs the reference letter
    assert reason(s("TIROT,1.0")) == "field"
    assert reason(s("IIXDR,A,1.0,D")) == "field"


# ------------------------------------------------------------ HDM / HDT / THS


def test_hdm() -> None:
    (h,) = parse_compass("$APHDM,218.634,M*39", 1.0)
    assert not h.true and h.sentence == "HDM"
    assert h.heading_rad == pytest.approx(math.radians(218.634))
    (h,) = parse_compass("$APHDM,218.634,M*39", 1.0, variation_deg=-14.5)
    assert h.true and h.heading_rad == pytest.approx(math.radians(204.134))


@pytest.mark.parametrize("talker", ["HC", "AP", "II", "TI", "HE", "GP"])
def test_any_talker(talker: str) -> None:
    (h,) = parse_compass(s(f"{talker}HDT,12.5,T"), 0.0)
    assert h.true and h.heading_rad == pytest.approx(math.radians(12.5))


def test_ths_modes() -> None:
    for mode in "AEMS":
        (h,) = parse_compass(s(f"GPTHS,45.0,{mode}"), 0.0)
        assert h.true and h.sentence == "THS"
    assert reason(s("GPTHS,45.0,V")) == "invalid"
    assert reason(s("GPTHS,45.0,")) == "invalid"
    assert reason(s("GPTHS,45.0,Q")) == "field"
    assert reason(s("GPTHS,,A")) == "empty"
    assert reason(s("GPTHS,45.0")) == "field"


# -------------------------------------------------------------------- ROT


def test_rot_units_and_sign() -> None:
    (r,) = parse_compass(s("TIROT,60.0,A"), 3.0, "imu")
    assert r == RateOfTurn(3.0, "imu", pytest.approx(math.radians(1.0)))
    (r,) = parse_compass(s("TIROT,-30.0,A"), 3.0)
    assert r.rate_rps == pytest.approx(-math.radians(0.5))  # turning to port
    assert reason(s("TIROT,10.0,V")) == "invalid"
    assert reason(s("TIROT,,A")) == "empty"
    assert reason(s("TIROT,ten,A")) == "field"


# -------------------------------------------------------------------- XDR


def test_xdr_pitch_and_roll() -> None:
    (a,) = parse_compass(s("IIXDR,A,-2.5,D,PITCH,A,10.0,D,ROLL,C,21.3,C,TEMP"), 5.0)
    assert a == Attitude(5.0, "compass", pytest.approx(math.radians(-2.5)),
                         pytest.approx(math.radians(10.0)))
    (a,) = parse_compass("$APXDR,A,3.861,D,ROLL*65", 0.0)
    assert a.pitch_rad is None and a.roll_rad == pytest.approx(math.radians(3.861))


def test_xdr_nothing_of_interest() -> None:
    assert parse_compass(s("IIXDR,C,21.3,C,TEMP,P,1.013,B,BARO"), 0.0) == []
    assert parse_compass(s("IIXDR,A,5.0,D,YAW"), 0.0) == []


def test_xdr_refusals() -> None:
    assert reason(s("IIXDR,A,1.0,D")) == "field"  # not a quadruplet
    assert reason(s("IIXDR,A,1.0,R,PTCH")) == "field"  # pitch not in degrees
    assert parse_compass(s("IIXDR,A,,R,PTCH"), 0.0) == []  # no value: nothing to read
    assert reason(s("IIXDR,A,abc,D,ROLL")) == "field"


# ---------------------------------------------------------------- refusals


@pytest.mark.parametrize(("line", "want"), [
    ("$HCHDG,98.3,0.0,E,12.6,W", "no_checksum"),
    ("$HCHDG,98.3,0.0,E,12.6,W*00", "checksum"),
    ("$HCHDG,98.3,0.0,E,12.6,W*5", "checksum"),
    ("$HCHDG,98.3,0.0,E,12.6,W*57x", "checksum"),
    ("HCHDG,98.3,0.0,E,12.6,W*57", "framing"),
    (s("HCHDG"), "field"),  # nothing after the address (checksum fine)
    (s("HCHDG,98.3,0.0,X,12.6,W"), "field"),
    (s("HCHDG,,0.0,E,12.6,W"), "empty"),
    (s("HCHDG,inf,0.0,E,12.6,W"), "field"),
    (s("HCHDG,1e2,0.0,E,12.6,W"), "field"),
    (s("APHDM,218.6,T"), "field"),
    (s("GPGGA,1,2,3"), "unsupported"),
    (s("IIMWV,1,R,2,N,A"), "unsupported"),
])
def test_refusals(line: str, want: str) -> None:
    assert reason(line) == want


# ---------------------------------------------- pypilot.log against GPSD


def test_pypilot_matches_gpsd_att() -> None:
    """HDM/ROT/XDR against the ATT GPSD printed after each sentence.

    GPSD's ATT carries every attitude field it has seen so far, so each
    sentence is compared only on the field(s) it sets: HDM → mheading,
    ROT → rot (GPSD keeps the wire's deg/min), XDR → pitch and/or roll.
    """
    lines = (DATA / "pypilot.log.chk").read_text().splitlines()
    compared = {"mheading": 0, "rot": 0, "pitch": 0, "roll": 0}
    for i, line in enumerate(lines):
        if not line.startswith("$"):
            continue
        atts = [json.loads(x) for x in lines[i + 1:i + 3] if '"class":"ATT"' in x]
        assert len(atts) == 1, line
        att = atts[0]
        (m,) = parse_compass(line, 0.0)
        if isinstance(m, Heading):
            assert not m.true
            assert math.degrees(m.heading_rad) == pytest.approx(att["mheading"], abs=1e-6)
            compared["mheading"] += 1
        elif isinstance(m, RateOfTurn):
            assert math.degrees(m.rate_rps) * 60.0 == pytest.approx(att["rot"], abs=1e-9)
            compared["rot"] += 1
        else:
            assert isinstance(m, Attitude)
            for key, value in (("pitch", m.pitch_rad), ("roll", m.roll_rad)):
                if value is not None:
                    assert math.degrees(value) == pytest.approx(att[key], abs=1e-9)
                    compared[key] += 1
    # the capture: 7 HDM, 7 ROT, 8 pitch and 7 roll XDRs
    assert compared == {"mheading": 7, "rot": 7, "pitch": 8, "roll": 7}
