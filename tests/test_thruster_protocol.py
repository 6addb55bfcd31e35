"""$PZTHR / $PZTHS (the thruster controller's protocol): encode, parse, round trips and refusals."""

from __future__ import annotations

import math

import pytest

from drivers.nmea import NmeaError, NmeaFramer, format_sentence
from drivers.thruster_protocol import encode_pzthr, encode_pzths, parse_pzthr, parse_pzths
from zarco_core.messages import ThrusterStatus


def line(b: bytes) -> str:
    assert b.endswith(b"\r\n")
    return b[:-2].decode("ascii")


def reason_thr(text: str) -> str:
    with pytest.raises(NmeaError) as ei:
        parse_pzthr(text)
    return ei.value.reason


def test_encode_pzthr_wire_format() -> None:
    # checksums cross-checked with pynmea2.NMEASentence.checksum
    assert encode_pzthr(0.0, 0.0) == b"$PZTHR,0.0,0.0*44\r\n"
    assert encode_pzthr(12.34, -56.78) == b"$PZTHR,12.3,-56.8*62\r\n"


def test_encode_pzthr_clamps_and_never_sends_minus_zero() -> None:
    assert parse_pzthr(line(encode_pzthr(250.0, -1e9))) == (100.0, -100.0)
    assert b"-0.0" not in encode_pzthr(-0.04, -0.0)
    assert parse_pzthr(line(encode_pzthr(-0.04, -0.0))) == (0.0, 0.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_encode_pzthr_refuses_non_finite(bad: float) -> None:
    with pytest.raises(ValueError):
        encode_pzthr(bad, 0.0)
    with pytest.raises(ValueError):
        encode_pzthr(0.0, bad)


@pytest.mark.parametrize(("u1", "u2"), [
    (0.0, 0.0), (100.0, -100.0), (-100.0, 100.0), (33.3, -0.1), (99.9, 0.5), (-7.25, 7.25),
])
def test_pzthr_round_trip(u1: float, u2: float) -> None:
    got = parse_pzthr(line(encode_pzthr(u1, u2)))
    assert got == (round(u1, 1) + 0.0, round(u2, 1) + 0.0)
    assert all(abs(a - b) <= 0.05 + 1e-12 for a, b in zip(got, (u1, u2), strict=True))


def test_pzthr_through_the_framer() -> None:
    f = NmeaFramer()
    stream = b"".join(encode_pzthr(u, -u) for u in (10.0, 20.0, 30.0))
    assert [parse_pzthr(s) for s in f.feed(stream)] == [(10.0, -10.0), (20.0, -20.0),
                                                         (30.0, -30.0)]


@pytest.mark.parametrize(("text", "want"), [
    ("$PZTHR,10.0,20.0", "no_checksum"),
    ("$PZTHR,10.0,20.0*00", "checksum"),
    ("PZTHR,10.0,20.0*47", "framing"),
    (line(format_sentence("PZTHR,10.0")), "field"),
    (line(format_sentence("PZTHR,10.0,20.0,30.0")), "field"),
    (line(format_sentence("PZTHR,10.0,")), "field"),
    (line(format_sentence("PZTHR,nan,0.0")), "field"),
    (line(format_sentence("PZTHR,NaN,0.0")), "field"),
    (line(format_sentence("PZTHR,inf,0.0")), "field"),
    (line(format_sentence("PZTHR,1e1,0.0")), "field"),
    (line(format_sentence("PZTHR, 1.0,0.0")), "field"),
    (line(format_sentence("PZTHR,1_0,0.0")), "field"),
    (line(format_sentence("PZTHR,100.1,0.0")), "range"),
    (line(format_sentence("PZTHR,0.0,-100.5")), "range"),
    (line(format_sentence("PZTHS,0.0,0.0")), "unsupported"),
    (line(format_sentence("GPGGA,0.0,0.0")), "unsupported"),
])
def test_parse_pzthr_refuses(text: str, want: str) -> None:
    assert reason_thr(text) == want


def test_parse_pzthr_accepts_the_limits() -> None:
    assert parse_pzthr(line(format_sentence("PZTHR,100,-100.0"))) == (100.0, -100.0)


def test_pzths_round_trip() -> None:
    wire = encode_pzths(55.56, -20.0, 1234.4, -987.6, 3.456, 0.0)
    assert wire == b"$PZTHS,55.6,-20.0,1234,-988,3.46,0.00*7D\r\n"
    st = parse_pzths(line(wire), 7.5)
    assert st == ThrusterStatus(7.5, 55.6, -20.0, 1234.0, -988.0, 3.46, 0.0)


def test_encode_pzths_refuses_non_finite() -> None:
    with pytest.raises(ValueError):
        encode_pzths(0.0, 0.0, math.nan, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        encode_pzths(0.0, math.inf, 0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize(("body", "want"), [
    ("PZTHS,1.0,2.0,3,4,5.0", "field"),
    ("PZTHS,1.0,2.0,3,4,5.0,6.0,7", "field"),
    ("PZTHS,1.0,2.0,,4,5.0,6.0", "field"),
    ("PZTHS,1.0,2.0,nan,4,5.0,6.0", "field"),
    ("PZTHS,101.0,2.0,3,4,5.0,6.0", "range"),
    ("PZTHS,1.0,2.0,100001,4,5.0,6.0", "range"),  # shaft speed no motor reaches
    ("PZTHS,1.0,2.0,3,-100001,5.0,6.0", "range"),
    ("PZTHS,1.0,2.0,3,4,-0.5,6.0", "range"),  # a current is a magnitude
    ("PZTHS,1.0,2.0,3,4,5.0,1000.5", "range"),
    ("PZTHR,1.0,2.0", "unsupported"),
])
def test_parse_pzths_refuses(body: str, want: str) -> None:
    with pytest.raises(NmeaError) as ei:
        parse_pzths(line(format_sentence(body)), 0.0)
    assert ei.value.reason == want
    with pytest.raises(NmeaError) as ei:
        parse_pzths(line(format_sentence(body))[:-1] + "Z", 0.0)
    assert ei.value.reason == "checksum"
