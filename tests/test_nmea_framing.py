"""NMEA framing (NmeaFramer) and strict sentence checks (split_checked, parse_sentence)."""

from __future__ import annotations

import random
import time
from pathlib import Path

import pynmea2
import pytest

from drivers.gps_parser import parse_gps
from drivers.nmea import (
    NmeaError,
    NmeaFramer,
    format_sentence,
    nmea_checksum,
    parse_sentence,
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

    Comment lines are discarded, except from a ``$`` on: pypilot.log's
    "# Note: Use of $AP prefix" comes out as the candidate "$AP prefix"
    (a framer cannot know better; the checksum check refuses it).
    """
    rng = random.Random(7)
    for path in sorted(DATA.glob("*.log")):
        data = path.read_bytes()
        want: list[str] = []
        comments = 0
        for ln in data.splitlines():
            start = ln.find(b"$")
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


def test_framer_throughput() -> None:
    """A 1 MB noisy stream in 1 kB chunks frames quickly (no per-byte Python loop)."""
    unit = (GGA + "\r\n").encode() + b"\x00\x01garbage" + (HDT + "\n").encode()
    data = unit * (1_000_000 // len(unit))
    f = NmeaFramer()
    t0 = time.perf_counter()
    n = 0
    for i in range(0, len(data), 1024):
        n += len(f.feed(data[i:i + 1024]))
    dt = time.perf_counter() - t0
    assert n >= 2 * (len(data) // len(unit)) - 2
    assert dt < 1.0, f"{len(data) / dt / 1e6:.1f} MB/s"


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


# ----------------------------------------------------------- parse_sentence


def test_parse_sentence_ok() -> None:
    msg = parse_sentence(GGA)
    assert isinstance(msg, pynmea2.GGA)
    assert msg.talker == "GN" and msg.sentence_type == "GGA"
    assert msg.data[1] == "4134.49795459"


@pytest.mark.parametrize(("line", "reason"), [
    # no checksum at all (pynmea2 alone would accept this)
    ("$GPHDT,274.07,T", "no_checksum"),
    # wrong checksum
    ("$GPHDT,274.07,T*00", "checksum"),
    # truncated in transit: the checksum went with the tail, or half of it
    (GGA[:40], "no_checksum"),
    (GGA[:-1], "checksum"),
    # not a sentence start
    (GGA[1:], "framing"),
    ("", "framing"),
    # checksum fine, but pynmea2 cannot make sense of it
    ("$GPGGA*56", "parse"),
    # types pynmea2 does not know, queries, unknown proprietary sentences
    (format_sentence("GPXYZ,1,2").decode(), "unsupported"),
    (format_sentence("GPTHS,12.0,A").decode(), "unsupported"),
    (format_sentence("PZTHR,1.0,2.0").decode(), "unsupported"),
    (format_sentence("GPECQ,GGA").decode(), "unsupported"),
    (format_sentence("AIVDM,1,1,,A,13u?etPv2;0n:dDPwUM1U1Cb069D,0", "!").decode(),
     "unsupported"),
])
def test_parse_sentence_refuses(line: str, reason: str) -> None:
    with pytest.raises(NmeaError) as ei:
        parse_sentence(line)
    assert ei.value.reason == reason


def test_truncated_with_valid_checksum_is_caught_by_the_driver() -> None:
    """pynmea2 takes a short GGA silently; the driver level refuses it as ``field``."""
    short = format_sentence("GNGGA,132819.60,4134.49795459,N").decode().strip()
    msg = parse_sentence(short)
    assert len(msg.data) == 3
    with pytest.raises(NmeaError) as ei:
        parse_gps(short, 0.0)
    assert ei.value.reason == "field"
