"""Navigation EKF over real receiver captures (tests/data/gpsd-logs, from GPSD's
regression suite), through the real parsers.

* hemi.log (Hemisphere, GGA + HDT + VTG + ZDA): a static antenna; most of the
  capture has no fix (empty HDT, GGA with zero satellites, VTG mode N), then
  six single-point fixes with four satellites and true headings of ≈ 274.1°.
* pypilot.log (pypilot autopilot, HDM + ROT + XDR): a magnetic heading of
  ≈ 218.65° and rates of a few hundredths of a degree per minute.

The captures carry no arrival times: sentences are timed by the UTC of the
GGA/ZDA that carry one (hemi, 2 Hz epochs) or at 5 Hz (pypilot).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from drivers.compass_parser import parse_compass
from drivers.gps_parser import parse_gps
from drivers.nmea import NmeaError, NmeaFramer
from zarco_runtime.geodesy import LocalFrame
from zarco_runtime.messages import (
    FixQuality,
    GpsErrorStats,
    GpsFix,
    GpsTime,
    GpsVelocity,
    Heading,
    RateOfTurn,
)
from zarco_runtime.navigation.ekf import EkfNavigator
from zarco_runtime.navigation.ekf_config import EkfSettings

LOGS = Path(__file__).resolve().parent / "data" / "gpsd-logs"


def sentences(name: str) -> list[str]:
    """The capture's sentences, comments (``#``) left out, through the real framer."""
    text = "".join(line + "\r\n" for line in (LOGS / name).read_text().splitlines()
                   if line.strip() and not line.startswith("#"))
    return NmeaFramer().feed(text.encode("ascii"))


def feed(nav: EkfNavigator, m: Any) -> None:
    handler = {GpsFix: nav.on_fix, GpsVelocity: nav.on_velocity, GpsErrorStats: nav.on_gst,
               Heading: nav.on_heading, RateOfTurn: nav.on_rate}.get(type(m))
    if handler is not None:
        handler(m)


def hemi_messages() -> tuple[list[Any], int]:
    """(messages timed by the capture's UTC, sentences the parser refused)."""
    out: list[Any] = []
    refused = 0
    t = 0.0
    utc0: float | None = None
    for line in sentences("hemi.log"):
        t += 0.001  # keeps the capture's order within an epoch
        try:
            msgs = parse_gps(line, t)
        except NmeaError:
            refused += 1  # empty HDT, VTG mode N: what a receiver without a fix sends
            continue
        for m in msgs:
            utc = m.utc_epoch_s % 86400.0 if isinstance(m, GpsTime) else getattr(m, "utc_s",
                                                                                  None)
            if utc is not None:
                utc0 = utc - t if utc0 is None else utc0
                t = max(t, utc - utc0)
                m.t = t
            out.append(m)
    return out, refused


def test_hemi_capture_position_and_true_heading() -> None:
    msgs, refused = hemi_messages()
    assert refused > 300 and len(msgs) > 300
    fixes = [m for m in msgs if isinstance(m, GpsFix) and m.fix > FixQuality.NONE]
    headings = [m for m in msgs if isinstance(m, Heading)]
    assert len(fixes) == 6 and len(headings) == 4  # what the capture holds
    first = fixes[0]
    nav = EkfNavigator(EkfSettings(), LocalFrame(first.lat_deg, first.lon_deg))
    for m in msgs:
        feed(nav, m)
        st = nav.state(m.t)
        assert all(math.isfinite(v) for v in (st.x_m, st.y_m, st.vn_mps, st.psi_rad))
        if isinstance(m, GpsFix) and m.fix > FixQuality.NONE:
            n, e = nav.geo.to_ned(m.lat_deg, m.lon_deg)
            assert st.pos_valid and st.fix is FixQuality.SINGLE
            assert math.hypot(st.x_m - n, st.y_m - e) < 0.5  # 4-satellite single point
        elif isinstance(m, Heading):
            assert m.true and m.sentence == "HDT"
            err = math.remainder(st.psi_rad - m.heading_rad, math.tau)
            assert abs(math.degrees(err)) < 0.2  # dual antenna: the filter follows it
    end = nav.status(msgs[-1].t)
    c = end.counters
    assert c["pos_ok"] == 5 and c["true_heading_ok"] == 3  # (+ the first of each initialises)
    assert not any(k.endswith("_rejected") for k in c)
    assert end.heading_valid and end.pos_valid
    assert math.degrees(end.state["psi_rad"]) % 360.0 == pytest.approx(274.1, abs=0.1)
    assert math.hypot(nav.state(msgs[-1].t).vn_mps, nav.state(msgs[-1].t).ve_mps) < 0.1
    # the zero-satellite positions before (3 m away) never reached the filter
    assert end.gps_age_s < 1.0 and "pos_below_min_fix" not in c


def pypilot_messages(variation_deg: float | None = None) -> list[Any]:
    out: list[Any] = []
    t = 0.0
    for line in sentences("pypilot.log"):
        t += 0.1
        out.extend(parse_compass(line, t, variation_deg=variation_deg))
    return out


@pytest.mark.parametrize("variation_deg", [None, -14.5])
def test_pypilot_capture_magnetic_heading_and_rate(variation_deg: float | None) -> None:
    msgs = pypilot_messages(variation_deg)
    hdm = [m for m in msgs if isinstance(m, Heading)]
    rot = [m for m in msgs if isinstance(m, RateOfTurn)]
    assert len(hdm) == 7 and len(rot) == 7
    nav = EkfNavigator(EkfSettings(), LocalFrame(41.185, -8.705), variation_deg)
    for m in msgs:
        feed(nav, m)
    t = msgs[-1].t
    st = nav.state(t)
    mean_raw = sum(m.raw_deg for m in hdm) / len(hdm)
    expect = mean_raw + (variation_deg or 0.0)
    assert math.degrees(st.psi_rad) % 360.0 == pytest.approx(expect % 360.0, abs=0.1)
    assert abs(math.degrees(st.r_rps)) < 0.05  # ROT says a few 1e-4 °/s
    assert st.heading_valid and not st.pos_valid and nav.has_gyro(t)
    status = nav.status(t)
    assert not status.compass_frozen and not status.compass_jumping
    assert status.counters["compass_ok"] == 6 and status.counters["rot_ok"] == 7
