"""NMEA framing (NmeaFramer), checked splitting (split_checked) and the strict field converters."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from drivers.gps_parser import parse_gps
from drivers.nmea import (
    NmeaError,
    NmeaFramer,
    days_since_epoch,
    field_angle_deg,
    field_date_days,
    field_float,
    field_int,
    field_latlon,
    field_range,
    field_signed,
    field_time_s,
    format_sentence,
    nmea_checksum,
    padded,
    split_checked,
)

DATA = Path(__file__).parent / "data" / "gpsd-logs"
GGA = "$GNGGA,132819.60,4134.49795459,N,09345.03431408,W,2,10,0.9,278.161,M,-31.442,M,6.6,0133*6A"
HDT = "$GPHDT,274.07,T*03"


def feed_bytewise(framer: NmeaFramer, data: bytes) -> list[str]:
    out: list[str] = []
    for i in range(len(data)):
        out += framer.feed(data[i:i + 1])
    return out


def counters(f: NmeaFramer) -> tuple[int, int, int]:
    return f.bytes_discarded, f.overlong, f.garbage_lines


# ------------------------------------------------------------------ framer


def test_clean_stream() -> None:
    f = NmeaFramer()
    assert f.feed(f"{GGA}\r\n{HDT}\r\n".encode()) == [GGA, HDT]
    assert counters(f) == (0, 0, 0)


@pytest.mark.parametrize("eol", [b"\r\n", b"\n", b"\r", b"\n\r", b"\r\n\r\n"])
def test_any_line_end(eol: bytes) -> None:
    f = NmeaFramer()
    assert f.feed(GGA.encode() + eol + HDT.encode() + eol) == [GGA, HDT]
    assert counters(f) == (0, 0, 0)  # line ends are never counted as garbage


def test_partial_line_waits_for_its_end() -> None:
    f = NmeaFramer()
    assert f.feed(GGA[:30].encode()) == []
    assert f.feed(GGA[30:].encode()) == []
    assert f.feed(b"\r\n") == [GGA]
    assert counters(f) == (0, 0, 0)


def test_garbage_before_start_is_discarded_and_counted() -> None:
    f = NmeaFramer()
    noise = b"\x00\xff\xb5b junk "
    assert f.feed(noise + HDT.encode() + b"\r\n") == [HDT]
    assert f.bytes_discarded == len(noise)
    assert f.garbage_lines == 0 and f.overlong == 0
    assert f.feed(b"more noise\r\n") == []
    assert f.bytes_discarded == len(noise) + len(b"more noise")


def test_byte_at_a_time_equals_whole() -> None:
    stream = b"xx" + f"{GGA}\r\n{HDT}\n".encode() + b"$GP\x01bad\r\n" + b"!AIVDM,1*00\r\n"
    whole, single = NmeaFramer(), NmeaFramer()
    assert whole.feed(stream) == feed_bytewise(single, stream) == [GGA, HDT, "!AIVDM,1*00"]
    assert counters(whole) == counters(single) == (2 + len("$GP\x01bad"), 0, 1)


def test_overlong_line_dropped_and_counted() -> None:
    long_line = b"$GPXXX," + b"1," * 150 + b"*00"
    stream = long_line + b"\r\n" + HDT.encode() + b"\r\n"
    for feed in (lambda f, d: f.feed(d), feed_bytewise):
        f = NmeaFramer()
        assert feed(f, stream) == [HDT]
        assert f.overlong == 1
        assert f.bytes_discarded == len(long_line)
        assert f.garbage_lines == 0


def test_max_len_is_inclusive() -> None:
    body = "GPTXT," + "A" * (40 - 10)
    line = format_sentence(body).rstrip(b"\r\n")
    assert len(line) == 40
    f = NmeaFramer(max_len=40)
    assert f.feed(line + b"\r\n") == [line.decode()]
    longer = format_sentence(body + "A").rstrip(b"\r\n")
    assert f.feed(longer + b"\r\n") == []  # 41 characters
    assert f.overlong == 1 and f.bytes_discarded == 41


def test_non_printable_or_non_ascii_line_rejected() -> None:
    for bad in (b"$GPHDT,27\x004.07,T*03", b"$GPHDT,27\xc3\xa94.07,T*03", b"$GPHDT,1\t,T*00"):
        f = NmeaFramer()
        assert f.feed(bad + b"\r\n" + HDT.encode() + b"\r\n") == [HDT]
        assert f.garbage_lines == 1
        assert f.bytes_discarded == len(bad)


def test_new_dollar_restarts_the_frame() -> None:
    cut = b"$GNGGA,132819.60,4134.4979"
    for feed in (lambda f, d: f.feed(d), feed_bytewise):
        f = NmeaFramer()
        assert feed(f, cut + HDT.encode() + b"\r\n") == [HDT]
        assert f.bytes_discarded == len(cut)
        assert f.restarts == 1
    # and across chunk boundaries
    f = NmeaFramer()
    assert f.feed(cut) == []
    assert f.feed(HDT.encode()[:5]) == []
    assert f.feed(HDT.encode()[5:] + b"\n") == [HDT]
    assert f.bytes_discarded == len(cut)


def test_real_logs_through_the_framer_in_random_chunks() -> None:
    """Every capture, cut at random, frames back to exactly its lines.

    Comment lines (and GPSD's own JSON lines in some) are discarded, except
    from a ``$`` on: pypilot.log's
    "# Note: Use of $AP prefix" comes out as the candidate "$AP prefix"
    (a framer cannot know better; the checksum check refuses it).
    """
    rng = random.Random(7)
    for path in sorted(DATA.glob("*.log")):
        data = path.read_bytes()
        want: list[str] = []
        comments = 0
        for ln in data.splitlines():
            start = min((i for i in (ln.find(b"$"), ln.find(b"!")) if i >= 0), default=-1)
            comments += len(ln) if start < 0 else start
            if start >= 0:
                want.append(ln[start:].decode())
        f = NmeaFramer()
        got: list[str] = []
        i = 0
        while i < len(data):
            n = rng.randint(1, 64)
            got += f.feed(data[i:i + n])
            i += n
        got += f.feed(b"\r\n")  # pypilot.log has no final newline
        assert got == want, path.name
        assert counters(f) == (comments, 0, 0), path.name


# ----------------------------------------------------------- split_checked


def test_split_checked() -> None:
    assert split_checked("$PZTHR,1.0,-2.5*6F") == ("PZTHR", ["1.0", "-2.5"])
    assert split_checked(HDT) == ("GPHDT", ["274.07", "T"])
    assert split_checked(HDT + "\r\n") == ("GPHDT", ["274.07", "T"])
    assert split_checked(GGA[:-2] + "6a")[0] == "GNGGA"  # lower-case hex is accepted


@pytest.mark.parametrize(("line", "reason"), [
    ("", "framing"),
    ("$AP prefix", "no_checksum"),  # what the framer makes of pypilot.log's comment
    ("GPHDT,274.07,T*03", "framing"),
    ("$GPHDT,274.07,T", "no_checksum"),
    ("$GPHDT,274.07,T*04", "checksum"),
    ("$GPHDT,274.07,T*0", "checksum"),
    ("$GPHDT,274.07,T*0G", "checksum"),
    ("$GPHDT,274.07,T*030", "checksum"),
    ("$GPHDT,274.07,T*03 ", "checksum"),
    ("$GPHDT,274.0é,T*03", "framing"),
    (format_sentence(",1,2").decode(), "framing"),
    (format_sentence("gphdt,1,T").decode(), "framing"),
])
def test_split_checked_refuses(line: str, reason: str) -> None:
    with pytest.raises(NmeaError) as ei:
        split_checked(line)
    assert ei.value.reason == reason


def test_checksum_helpers() -> None:
    assert nmea_checksum("GPHDT,274.07,T") == 0x03
    assert format_sentence("GPHDT,274.07,T") == (HDT + "\r\n").encode()
    assert format_sentence("AIVDM,1", "!").startswith(b"!AIVDM,1*")


# ---------------------------------------------------------- checksum


def test_checksum_is_the_xor_of_every_byte() -> None:
    """The folded XOR equals a byte-by-byte XOR for every length (odd, even, 0..300)."""
    rng = random.Random(4)
    for n in range(0, 300):
        body = "".join(chr(rng.randrange(0x20, 0x7F)) for _ in range(n))
        want = 0
        for ch in body.encode():
            want ^= ch
        assert nmea_checksum(body) == want, body


# ------------------------------------------------------------ fields


def test_truncated_with_valid_checksum_is_refused_not_shifted() -> None:
    short = format_sentence("GNGGA,132819.60,4134.49795459,N").decode().strip()
    assert split_checked(short)[1] == ["132819.60", "4134.49795459", "N"]
    with pytest.raises(NmeaError) as ei:
        parse_gps(short, 0.0)
    assert ei.value.reason == "field"


def test_padded_reads_missing_trailing_fields_as_empty() -> None:
    assert padded(["1", "2"], 2, 4, "X") == ["1", "2", "", ""]
    assert padded(["1", "2", "3", "4", "5"], 2, 4, "X") == ["1", "2", "3", "4", "5"]
    with pytest.raises(NmeaError) as ei:
        padded(["1"], 2, 4, "X")
    assert ei.value.reason == "field"


@pytest.mark.parametrize("s", ["1e5", "1E-3", "nan", "inf", "-inf", " 1", "1 ", "1_0", "-",
                               "+", ".", "..", "1.2.3", "0x1F", "--1", "+-1", "٣", "1,0"])
def test_numbers_are_plain_decimals(s: str) -> None:
    with pytest.raises(NmeaError) as ei:
        field_float(s, "x")
    assert ei.value.reason == "field"


def test_number_forms_accepted() -> None:
    assert [field_float(s, "x") for s in ("1", "-1", "+1", "1.", ".5", "-0.25", "007")] == [
        1.0, -1.0, 1.0, 1.0, 0.5, -0.25, 7.0]
    assert field_float("", "x") is None
    assert field_int("-05", "x") == -5 and field_int("", "x") is None
    for bad in ("1.0", "1e2", " 1", "٣"):
        with pytest.raises(NmeaError):
            field_int(bad, "x")


def test_range_is_refused_not_clamped() -> None:
    assert field_range("-5", "x", -5.0, 5.0) == -5.0
    for s in ("5.0001", "-5.01", "99999"):
        with pytest.raises(NmeaError) as ei:
            field_range(s, "x", -5.0, 5.0)
        assert ei.value.reason == "range"


@pytest.mark.parametrize(("s", "want"), [("0", 0.0), ("359.99", 359.99), ("360", 0.0),
                                         ("360.0", 0.0), ("", None)])
def test_angles(s: str, want: float | None) -> None:
    assert field_angle_deg(s, "h") == want


@pytest.mark.parametrize("s", ["360.01", "400", "720.5", "999999", "-0.1", "-360"])
def test_angles_out_of_range_are_refused_not_wrapped(s: str) -> None:
    with pytest.raises(NmeaError) as ei:
        field_angle_deg(s, "h")
    assert ei.value.reason == "range"


def test_time_of_day() -> None:
    assert field_time_s("235959.99") == pytest.approx(86399.99)
    assert field_time_s("000000") == 0.0
    assert field_time_s("235960.5") == pytest.approx(86400.5)  # leap second
    for s, reason in [("240000", "range"), ("126000", "range"), ("120061", "range"),
                      ("12:00:00", "field"), ("1200", "field"), ("120000.x", "field"),
                      ("120000,1", "field"), ("1200001", "field"), ("123519.", "field")]:
        with pytest.raises(NmeaError) as ei:
            field_time_s(s)
        assert ei.value.reason == reason, s


def test_dates() -> None:
    assert field_date_days("010170") == days_since_epoch(2070, 1, 1)  # 00-79: 2000-2079
    assert field_date_days("070918") == days_since_epoch(2018, 9, 7)
    assert field_date_days("311299") == days_since_epoch(1999, 12, 31)
    assert days_since_epoch(1980, 1, 6) == 3657  # GPS time zero
    for s, reason in [("310226", "range"), ("290223", "range"), ("001224", "range"),
                      ("011324", "range"), ("1234", "field"), ("12a456", "field")]:
        with pytest.raises(NmeaError) as ei:
            field_date_days(s)
        assert ei.value.reason == reason, s
    for y in (1979, 2100, 9999):
        with pytest.raises(NmeaError) as ei:
            days_since_epoch(y, 1, 1)
        assert ei.value.reason == "range"


def test_positions() -> None:
    lat, lon = field_latlon("4807.038", "N", "01131.324", "E") or (0.0, 0.0)
    assert lat == pytest.approx(48 + 7.038 / 60) and lon == pytest.approx(11 + 31.324 / 60)
    assert field_latlon("9000.000", "S", "18000.0", "W") == (-90.0, -180.0)
    assert field_latlon("", "", "", "") is None
    for args, reason in [(("9000.001", "N", "00000.0", "E"), "range"),
                         (("0000.0", "N", "18000.001", "E"), "range"),
                         (("4860.000", "N", "01131.3", "E"), "field"),  # minutes >= 60
                         (("4807.038", "X", "01131.3", "E"), "field"),
                         (("4807", "N", "01131.3", "E"), "field"),  # no decimal point
                         (("4807.", "N", "01131.3", "E"), "field"),  # no decimals
                         (("48.07", "N", "01131.3", "E"), "field"),
                         (("4807.038", "", "01131.3", "E"), "field"),  # partly empty
                         (("", "", "01131.3", "E"), "field")]:
        with pytest.raises(NmeaError) as ei:
            field_latlon(*args)
        assert ei.value.reason == reason, args


def test_signed_offsets() -> None:
    assert field_signed("2.5", "W", "E", "W", "v", 180.0) == -2.5
    assert field_signed("0", "", "E", "W", "v", 180.0) == 0.0
    assert field_signed("", "A", "E", "W", "v", 180.0) is None  # nothing to read
    with pytest.raises(NmeaError) as ei:
        field_signed("180.5", "E", "E", "W", "v", 180.0)
    assert ei.value.reason == "range"
    with pytest.raises(NmeaError) as ei:
        field_signed("-2", "E", "E", "W", "v", 180.0)
    assert ei.value.reason == "range"
    with pytest.raises(NmeaError) as ei:
        field_signed("2", "X", "E", "W", "v", 180.0)
    assert ei.value.reason == "field"
