"""The buoy feed: ``$PZBAE`` / ``$PZBST`` round trips and refusals."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import pytest

from drivers.buoy_parser import encode_pzbae, encode_pzbst, parse_buoy, utc_text
from drivers.nmea import NmeaError, format_sentence
from zarco_core.auv_messages import AcousticEvent, BuoyStatus

EPOCH = datetime(2026, 6, 1, 10, 0, 0, tzinfo=UTC).timestamp()


def _line(b: bytes) -> str:
    return b.decode("ascii").rstrip("\r\n")


def test_pzbae_example_fields() -> None:
    line = _line(format_sentence("PZBAE,101502.123456,010626,I,2,18.5"))
    (ev,) = parse_buoy(line, 12.5)
    assert isinstance(ev, AcousticEvent)
    assert ev.t == 12.5 and ev.source == "buoy"
    assert ev.kind == "I" and ev.beacon == 2 and ev.snr_db == 18.5
    want = datetime(2026, 6, 1, 10, 15, 2, 123456, tzinfo=UTC).timestamp()
    assert ev.utc_epoch_s == pytest.approx(want, abs=1e-6)


@pytest.mark.parametrize("offset_s", [0.0, 0.000001, 0.5, 59.999999, 3599.0000005, 86399.999999,
                                      86400.0 * 200 + 1234.567891])
@pytest.mark.parametrize("kind", ["I", "R"])
def test_pzbae_round_trip_microseconds(offset_s: float, kind: str) -> None:
    utc = EPOCH + offset_s
    (ev,) = parse_buoy(_line(encode_pzbae(utc, kind, 7, -3.25)), 0.0, source="b")
    assert ev.kind == kind and ev.beacon == 7 and ev.source == "b"
    assert ev.snr_db == pytest.approx(-3.2, abs=0.051)
    assert abs(ev.utc_epoch_s - utc) <= 0.5e-6 + 2.4e-7  # µs rounding + float spacing


def test_pzbae_rounding_carries_into_the_date() -> None:
    tm, dt = utc_text(EPOCH + 14 * 3600 - 0.0000004, 6)  # 23:59:59.9999996 → next day
    assert (tm, dt) == ("000000.000000", "020626")


def test_pzbst_round_trip() -> None:
    b = encode_pzbst(EPOCH + 1.0, 41.185123, -8.705456, 12.47, 0)
    assert b.startswith(b"$PZBST,100001.00,010626,4111.10") and b.endswith(b"\r\n")
    (st,) = parse_buoy(_line(b), 3.0)
    assert isinstance(st, BuoyStatus)
    assert st.utc_epoch_s == pytest.approx(EPOCH + 1.0, abs=1e-6)
    assert st.lat_deg == pytest.approx(41.185123, abs=1e-8)
    assert st.lon_deg == pytest.approx(-8.705456, abs=1e-8)
    assert st.battery_v == pytest.approx(12.47) and st.fault_code == 0
    (st2,) = parse_buoy(_line(encode_pzbst(EPOCH, -33.5, 151.25, 11.0, 3)), 0.0)
    assert st2.lat_deg == pytest.approx(-33.5) and st2.lon_deg == pytest.approx(151.25)
    assert st2.fault_code == 3


def test_pzbst_without_position_gives_nan() -> None:
    (st,) = parse_buoy(_line(encode_pzbst(EPOCH, math.nan, math.nan, 12.0, 0)), 0.0)
    assert math.isnan(st.lat_deg) and math.isnan(st.lon_deg) and st.battery_v == 12.0


@pytest.mark.parametrize(
    "body,reason",
    [
        ("PZBAE,101502.123456,010626,X,2,18.5", "field"),       # unknown kind
        ("PZBAE,101502.123456,010626,II,2,18.5", "field"),
        ("PZBAE,101502.123456,010626,I,two,18.5", "field"),     # garbage beacon
        ("PZBAE,101502.123456,010626,I,-1,18.5", "range"),       # negative beacon
        ("PZBAE,101502.123456,010626,I,10000,18.5", "range"),
        ("PZBAE,101502.123456,010626,I,2,140.1", "range"),       # SNR no chain gives
        ("PZBAE,101502.123456,010626,I,2,-60.5", "range"),
        ("PZBAE,101502.123456,010626,I,2,99999", "range"),
        ("PZBAE,101502.123456,010626,I,2,1e3", "field"),        # no exponents
        ("PZBAE,101502.123456,010626,I,2,nan", "field"),
        ("PZBAE,251502.123456,010626,I,2,18.5", "range"),       # hour 25
        ("PZBAE,106002.123456,010626,I,2,18.5", "range"),       # minute 60
        ("PZBAE,101561.000000,010626,I,2,18.5", "range"),       # second 61
        ("PZBAE,101502.1234567,010626,I,2,18.5", "field"),      # below a µs
        ("PZBAE,10150.123456,010626,I,2,18.5", "field"),
        ("PZBAE,101502.123456,310226,I,2,18.5", "range"),       # 31 February
        ("PZBAE,101502.123456,011326,I,2,18.5", "range"),       # month 13
        ("PZBAE,101502.123456,0106,I,2,18.5", "field"),
        ("PZBAE,101502.123456,010626,I,2", "field"),            # truncated
        ("PZBAE,101502.123456,010626,I,2,18.5,9", "field"),     # extra field
        ("PZBAE,,010626,I,2,18.5", "empty"),
        ("PZBAE,101502.123456,,I,2,18.5", "empty"),
        ("PZBAE,101502.123456,010626,,2,18.5", "empty"),
        ("PZBAE,101502.123456,010626,I,,18.5", "empty"),
        ("PZBAE,101502.123456,010626,I,2,", "empty"),
        ("PZBST,100001.00,010626,4111.1,N,00842.3,W,12.5", "field"),  # truncated
        ("PZBST,100001.00,010626,4111.1,X,00842.3,W,12.5,0", "field"),
        ("PZBST,100001.00,010626,4111.1,N,,W,12.5,0", "field"),       # half a position
        ("PZBST,100001.00,010626,4111.1,N,00842.3,W,-1.0,0", "range"),
        ("PZBST,100001.00,010626,4111.1,N,00842.3,W,100.5,0", "range"),
        ("PZBST,100001.00,010626,9111.1,N,00842.3,W,12.5,0", "range"),   # latitude 91
        ("PZBST,100001.00,010626,4111.1,N,18042.3,W,12.5,0", "range"),   # longitude 180.7
        ("PZBST,100001.00,010626,4111.1,N,00842.3,W,12.5,10000", "range"),
        ("PZBST,100001.00,010626,4111.1,N,00842.3,W,12.5,ok", "field"),
        ("PZBST,100001.00,010626,4111.1,N,00842.3,W,12.5,-2", "range"),
        ("PZTHR,10.0,10.0", "unsupported"),
        ("GPGGA,1,2,3", "unsupported"),
    ],
)
def test_refusals(body: str, reason: str) -> None:
    with pytest.raises(NmeaError) as ei:
        parse_buoy(_line(format_sentence(body)), 0.0)
    assert ei.value.reason == reason, ei.value


def test_checksum_required_and_verified() -> None:
    good = _line(encode_pzbae(EPOCH, "R", 3, 20.0))
    assert parse_buoy(good, 0.0)
    with pytest.raises(NmeaError) as ei:
        parse_buoy(good[: good.rindex("*")], 0.0)
    assert ei.value.reason == "no_checksum"
    bad = good[:-2] + ("00" if good[-2:] != "00" else "11")
    with pytest.raises(NmeaError) as ei:
        parse_buoy(bad, 0.0)
    assert ei.value.reason == "checksum"
    with pytest.raises(NmeaError) as ei:
        parse_buoy(good.replace("R,3", "R,4"), 0.0)  # corrupted in transit
    assert ei.value.reason == "checksum"


def test_encoder_refusals() -> None:
    with pytest.raises(ValueError):
        encode_pzbae(EPOCH, "X", 1, 0.0)
    with pytest.raises(ValueError):
        encode_pzbae(math.nan, "I", 1, 0.0)
    with pytest.raises(ValueError):
        encode_pzbae(EPOCH, "I", -1, 0.0)
    with pytest.raises(ValueError):
        encode_pzbst(EPOCH, 0.0, 0.0, 12.0, -1)


def test_leap_second_is_accepted() -> None:
    (ev,) = parse_buoy(_line(format_sentence("PZBAE,235960.500000,311226,R,1,10.0")), 0.0)
    midnight = datetime(2026, 12, 31, tzinfo=UTC).timestamp()
    assert ev.utc_epoch_s == pytest.approx(midnight + 86400.5, abs=1e-6)
