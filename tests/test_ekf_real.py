"""Navigation EKF over real receiver captures (tests/data/gpsd-logs, from GPSD's
regression suite), through the real parsers, and ``zarco navreport``.

* hemi.log (Hemisphere, GGA + HDT + VTG + ZDA): a static antenna; most of the
  capture has no fix (empty HDT, GGA with zero satellites, VTG mode N), then
  six single-point fixes with four satellites and true headings of ≈ 274.1°.
* pypilot.log (pypilot autopilot, HDM + ROT + XDR): a magnetic heading of
  ≈ 218.65° and rates of a few hundredths of a degree per minute.

The captures carry no arrival times: :func:`read_capture` times sentences by
the UTC of the GGA/ZDA that carry one (hemi, 2 Hz epochs) or at 5 sentences
per second (pypilot).
"""

from __future__ import annotations

import itertools
import json
import math
import re
import statistics
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from drivers.nmea import format_sentence
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import FixQuality, GpsFix, GpsTime, Heading, RateOfTurn
from zarco_runtime.cli import main
from zarco_runtime.navigation.ekf import EkfNavigator
from zarco_runtime.navigation.ekf_config import EkfSettings
from zarco_tools import capture_report as cr
from zarco_tools.capture_report import capture_report, read_capture
from zarco_tools.decode import Rejected, decode_lines

LOGS = Path(__file__).resolve().parent / "data" / "gpsd-logs"
HEMI = LOGS / "hemi.log"
PYPILOT = LOGS / "pypilot.log"


def feed(nav: EkfNavigator, m: Any) -> None:
    handler = nav.handler(m)
    if handler is not None:
        handler(m)


def decode_refusals(path: Path) -> Counter[str]:
    """Refusals by reason, as ``zarco decode`` (a separate path) sees them."""
    with path.open("rb") as fh:
        return Counter(it.reason for it in decode_lines(fh) if isinstance(it, Rejected))


def write_capture(path: Path, bodies: list[str], extra: tuple[bytes, ...] = ()) -> Path:
    """A capture file of checksummed sentences (``bodies`` without ``$``/``*hh``)."""
    path.write_bytes(b"# a comment\r\n\r\n" + b"".join(format_sentence(b) for b in bodies)
                     + b"".join(extra))
    return path


# ------------------------------------------------------------------ hemi
def test_hemi_capture_position_and_true_heading() -> None:
    cap = read_capture(HEMI)
    msgs, refused = cap.messages, sum(cap.refused.values())
    assert cap.timed
    assert refused > 300 and len(msgs) > 300
    fixes = [m for m in msgs if isinstance(m, GpsFix) and m.fix > FixQuality.NONE]
    headings = [m for m in msgs if isinstance(m, Heading)]
    assert len(fixes) == 6 and len(headings) == 4  # what the capture holds
    first = fixes[0]
    assert first.lat_deg is not None and first.lon_deg is not None
    nav = EkfNavigator(EkfSettings(), LocalFrame(first.lat_deg, first.lon_deg))
    for m in msgs:
        feed(nav, m)
        st = nav.state(m.t)
        assert all(math.isfinite(v) for v in (st.x_m, st.y_m, st.vn_mps, st.psi_rad))
        if isinstance(m, GpsFix) and m.fix > FixQuality.NONE:
            assert m.lat_deg is not None and m.lon_deg is not None
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


def test_hemi_capture_is_timed_by_its_utc() -> None:
    """Timed by ZDA/GGA: times never go back, an epoch's sentences stay within a few ms,
    and the span is the capture's own (the ZDAs' first to last, ±1 s)."""
    msgs = read_capture(HEMI).messages
    ts = [m.t for m in msgs]
    assert ts == sorted(ts)
    zda = [m for m in msgs if isinstance(m, GpsTime)]
    for a, b in itertools.pairwise(zda):
        assert b.t - a.t == pytest.approx(b.utc_epoch_s - a.utc_epoch_s, abs=0.01)
    timed = [(m.t, m.utc_s) for m in msgs if isinstance(m, GpsFix) and m.utc_s is not None]
    assert len(timed) > 6
    for (ta, ua), (tb, ub) in itertools.pairwise(timed):
        assert tb - ta == pytest.approx(ub - ua, abs=0.01)
    span = zda[-1].utc_epoch_s - zda[0].utc_epoch_s
    assert ts[-1] - ts[0] == pytest.approx(span, abs=1.0)


def test_hemi_report() -> None:
    rep = capture_report(HEMI)
    assert rep["errors"] == 0 and rep["error_samples"] == []
    assert rep["timing"] == "utc" and rep["sentences"] == 753
    # refusals: empty HDT and VTG mode N, as `zarco decode` counts them
    ref = rep["refused"]
    assert ref["by_reason"] == dict(decode_refusals(HEMI)) == {"empty": 211, "invalid": 194}
    assert ref["by_kind"] == {"HDT": 211, "VTG": 194} and ref["total"] == 405
    assert rep["messages"]["GpsFix"] == 215 and rep["messages"]["Heading"] == 4
    assert rep["fix_types"] == {"none": 209, "single": 6}
    assert rep["fixes_fused"] == 6
    cap = read_capture(HEMI)
    fixes = [m for m in cap.messages if isinstance(m, GpsFix) and m.fix > FixQuality.NONE]
    hdt = [m.raw_deg for m in cap.messages if isinstance(m, Heading)]
    assert rep["origin"] == {"lat_deg": fixes[0].lat_deg, "lon_deg": fixes[0].lon_deg,
                             "from": "first_fix"}
    assert rep["variation"]["headings"] == {"true": 4}
    assert not rep["variation"]["magnetic_uncorrected"]
    assert rep["t_span_s"] == pytest.approx(107.0, abs=1.0)
    e = rep["estimate"]
    assert e["pos_valid"] and e["heading_valid"] and e["fix"] == "single"
    assert e["heading_deg"] == pytest.approx(274.1, abs=0.1)
    assert e["heading_deg"] == pytest.approx(statistics.fmean(hdt), abs=0.1)
    assert 0.0 < e["heading_sigma_deg"] < 5.0
    # the antenna does not move: within a single-point σ of the fixes, no speed, no turn
    frame = LocalFrame(fixes[0].lat_deg, fixes[0].lon_deg)  # type: ignore[arg-type]
    n, e_ = frame.to_ned(fixes[-1].lat_deg, fixes[-1].lon_deg)  # type: ignore[arg-type]
    assert math.hypot(e["x_m"] - n, e["y_m"] - e_) < 0.5
    back = frame.to_geodetic(e["x_m"], e["y_m"])
    assert e["lat_deg"] == pytest.approx(back[0], abs=1e-7)
    assert e["lon_deg"] == pytest.approx(back[1], abs=1e-7)
    assert e["speed_mps"] < 0.1 and abs(e["yaw_rate_dps"]) < 0.5
    # no compass and no gyro: no bias is claimed, and the report says why
    assert e["compass_bias_deg"] is None and e["compass_bias_sigma_deg"] is None
    assert "no compass heading" in e["not_estimated"]["compass_bias"]
    assert e["gyro_bias_dps"] is None and "no rate of turn" in e["not_estimated"]["gyro_bias"]
    assert rep["gate_rejections"]["total"] == 0 and rep["resets"]["total"] == 0
    assert rep["counters"]["pos_ok"] == 5 and rep["counters"]["true_heading_ok"] == 3


# --------------------------------------------------------------- pypilot
@pytest.mark.parametrize("variation_deg", [None, -14.5])
def test_pypilot_capture_magnetic_heading_and_rate(variation_deg: float | None) -> None:
    cap = read_capture(PYPILOT, variation_deg)
    msgs = cap.messages
    assert not cap.timed and msgs[1].t - msgs[0].t == pytest.approx(0.2)  # 5 sentences/s
    hdm = [m for m in msgs if isinstance(m, Heading)]
    rot = [m for m in msgs if isinstance(m, RateOfTurn)]
    assert len(hdm) == 7 and len(rot) == 7
    assert all(m.true == (variation_deg is not None) for m in hdm)
    nav = EkfNavigator(EkfSettings(), LocalFrame(41.185, -8.705))
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


@pytest.mark.parametrize("variation_deg", [None, -14.5])
def test_pypilot_report(variation_deg: float | None) -> None:
    rep = capture_report(PYPILOT, variation_deg)
    assert rep["errors"] == 0
    assert rep["timing"] == "line_rate" and rep["line_rate_hz"] == 5.0
    assert rep["sentences"] == 29 and rep["t_span_s"] == pytest.approx(28 / 5.0)
    assert rep["refused"] == {"total": 0, "by_reason": {}, "by_kind": {}}
    assert not decode_refusals(PYPILOT)
    assert rep["messages"] == {"Attitude": 15, "Heading": 7, "RateOfTurn": 7}
    assert rep["fix_types"] == {} and rep["fixes_fused"] == 0
    assert rep["origin"] == {"lat_deg": 0.0, "lon_deg": 0.0, "from": "none"}
    raw = [float(ln.split(",")[1]) for ln in PYPILOT.read_text().splitlines()
           if ln.startswith("$APHDM")]
    var = rep["variation"]
    if variation_deg is None:
        assert var == {"deg": 0.0, "source": "none", "headings": {"uncorrected": 7},
                       "magnetic_uncorrected": True}
    else:
        assert var == {"deg": variation_deg, "source": "argument",
                       "headings": {"variation_argument": 7}, "magnetic_uncorrected": False}
    e = rep["estimate"]
    expect = (statistics.fmean(raw) + (variation_deg or 0.0)) % 360.0
    assert e["heading_deg"] == pytest.approx(expect, abs=0.1)
    assert e["heading_valid"] and not e["pos_valid"] and not e["pos_ever_valid"]
    assert e["lat_deg"] is None and e["x_m"] is None and e["gps_age_s"] is None
    assert abs(e["yaw_rate_dps"]) < 0.05 and abs(e["gyro_bias_dps"]) < 0.05
    assert e["compass_faults"] == []
    # no GPS: no speed, no current, and a compass bias nothing could reveal
    why = e["not_estimated"]
    assert e["speed_mps"] is None and "no GPS velocity" in why["speed"]
    assert e["current_n_mps"] is None and "not observable" in why["current"]
    assert e["compass_bias_deg"] is None and "not observable" in why["compass_bias"]
    assert why["position"] == "no GPS fix in the capture"
    assert rep["counters"] == {"compass_ok": 6, "rot_ok": 7}
    assert rep["gate_rejections"]["total"] == 0 and rep["resets"]["total"] == 0


# ------------------------------------------------------- synthetic edges
def test_hdg_own_variation_wins_and_refusals_are_counted(tmp_path: Path) -> None:
    """HDG's variation beats --variation, HDM takes --variation; bad sentences are
    counted by reason and type and never raised."""
    log = write_capture(tmp_path / "c.log", [
        "HCHDG,100.0,1.0,E,10.0,W",  # magnetic 101, true 91 with its own variation
        "HCHDM,95.0,M",  # true 95 + 3 = 98 with the argument
        "GPGSV,1,1,00",  # a type neither parser takes
        "HCROT,,A",  # empty rate
        "HCHDG,100.0,1.0,E,10.0,W",
    ], (b"$HCHDM,95.0,M*00\r\n", b"\x01\x02garbage\r\n"))
    rep = capture_report(log, variation_deg=3.0, line_rate_hz=10.0)
    assert rep["errors"] == 0 and rep["sentences"] == 6
    assert rep["refused"]["by_reason"] == {"checksum": 1, "empty": 1, "framing": 1,
                                           "unsupported": 1}
    assert rep["refused"]["by_kind"] == {"?": 1, "GSV": 1, "HDM": 1, "ROT": 1}
    assert rep["refused"]["total"] == 4
    assert rep["variation"]["source"] == "sentence" and rep["variation"]["deg"] == -10.0
    assert rep["variation"]["headings"] == {"variation_argument": 1,
                                            "variation_sentence": 2}
    hdg = [m for m in read_capture(log, 3.0).messages if isinstance(m, Heading)]
    assert [round(math.degrees(m.heading_rad), 6) for m in hdg] == [91.0, 98.0, 91.0]
    assert all(m.true for m in hdg)


def test_capture_clock_crosses_midnight_and_tolerates_going_back(tmp_path: Path) -> None:
    gga = "GPGGA,{},4221.8237,N,07101.9439,W,1,08,1.0,5.0,M,-33.0,M,,"
    log = write_capture(tmp_path / "m.log", [
        gga.format("235959.00"), gga.format("000000.00"), gga.format("000001.00"),
        gga.format("000000.50"),  # back by 0.5 s: held
        gga.format("000002.00"),
    ])
    ts = [m.t for m in read_capture(log).messages]
    assert ts[1] - ts[0] == pytest.approx(1.0, abs=0.01)
    assert ts[2] - ts[1] == pytest.approx(1.0, abs=0.01)
    assert ts[3] >= ts[2] and ts[4] - ts[2] == pytest.approx(1.0, abs=0.01)
    rep = capture_report(log)
    assert rep["errors"] == 0 and rep["fixes_fused"] == 5
    assert rep["estimate"]["pos_valid"] and rep["t_span_s"] == pytest.approx(3.0, abs=0.05)


def test_ekf_exceptions_are_counted_not_raised(monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    def boom(self: EkfNavigator, m: Heading) -> None:
        raise RuntimeError("heading exploded")

    monkeypatch.setattr(cr.EkfNavigator, "on_heading", boom)
    rep = capture_report(HEMI)
    assert rep["errors"] == 4  # every HDT; the rest of the capture still ran
    assert "heading exploded" in rep["error_samples"][0]
    assert rep["fixes_fused"] == 6 and rep["estimate"]["pos_valid"]
    assert not rep["estimate"]["heading_ever_valid"]
    assert main(["navreport", str(HEMI)]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out[str(HEMI)]["errors"] == 4


# ------------------------------------------------------------------- CLI
def test_cli_navreport_both_captures(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["navreport", str(HEMI), str(PYPILOT)]) == 0
    cap = capsys.readouterr()
    lines = cap.out.splitlines()
    assert len(lines) == 1
    reports = json.loads(lines[0])
    assert list(reports) == [str(HEMI), str(PYPILOT)]
    assert all(r["errors"] == 0 for r in reports.values())
    assert reports[str(HEMI)]["estimate"]["heading_deg"] == pytest.approx(274.1, abs=0.1)
    assert reports[str(PYPILOT)]["variation"]["magnetic_uncorrected"]
    assert str(HEMI) in cap.err and str(PYPILOT) in cap.err
    assert "NOT corrected" in cap.err
    assert len(re.findall(r"EKF errors +0\n", cap.err)) == 2


def test_cli_navreport_variation(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["navreport", str(PYPILOT), "--variation", "-14.5"]) == 0
    rep = json.loads(capsys.readouterr().out)[str(PYPILOT)]
    assert rep["variation"]["source"] == "argument"
    assert rep["estimate"]["heading_deg"] == pytest.approx(218.65 - 14.5, abs=0.1)


def test_cli_navreport_missing_file(capsys: pytest.CaptureFixture[str],
                                    tmp_path: Path) -> None:
    missing = tmp_path / "nope.log"
    assert main(["navreport", str(missing)]) == 2
    cap = capsys.readouterr()
    err = [ln for ln in cap.err.splitlines() if ln.strip()]
    assert len(err) == 1 and "nope.log" in err[0] and "No such file" in err[0]
    # with a good capture too: still 2, and the good one is reported
    assert main(["navreport", str(HEMI), str(missing)]) == 2
    reports = json.loads(capsys.readouterr().out)
    assert reports[str(HEMI)]["errors"] == 0 and "error" in reports[str(missing)]


# ------------------------------------------------ honest uncertainties
ALL_LOGS = sorted(LOGS.glob("*.log"))
#: σ of an angle that could be anywhere on the circle (deg)
UNIFORM_ANGLE_SIGMA_DEG = 180.0 / math.sqrt(3.0)


@pytest.mark.parametrize("log", ALL_LOGS, ids=lambda p: p.name)
def test_navreport_claims_no_uncertainty_beyond_the_quantity(log: Path) -> None:
    """Every capture: each value comes with a σ smaller than what the quantity can
    be (a heading σ below that of a heading anywhere on the circle), and each value
    not given comes with the reason, in words."""
    rep = capture_report(log)
    e = rep["estimate"]
    why = e["not_estimated"]
    pairs = {"heading_deg": "heading_sigma_deg", "compass_bias_deg": "compass_bias_sigma_deg",
             "gyro_bias_dps": "gyro_bias_sigma_dps", "yaw_rate_dps": "yaw_rate_sigma_dps",
             "speed_mps": "speed_sigma_mps", "current_n_mps": "current_sigma_mps",
             "x_m": "pos_sigma_m"}
    reason = {"heading_deg": "heading", "compass_bias_deg": "compass_bias",
              "gyro_bias_dps": "gyro_bias", "yaw_rate_dps": "yaw_rate",
              "speed_mps": "speed", "current_n_mps": "current", "x_m": "position"}
    for value, sigma in pairs.items():
        if e[value] is None:
            assert e[sigma] is None
            assert len(why[reason[value]]) > 20, (value, why)
        else:
            assert e[sigma] is not None and e[sigma] >= 0.0, value
    if e["heading_deg"] is not None:
        assert e["heading_sigma_deg"] < UNIFORM_ANGLE_SIGMA_DEG
        assert 0.0 <= e["heading_deg"] < 360.0
    if e["compass_bias_deg"] is not None:
        assert e["compass_bias_sigma_deg"] < EkfSettings().compass_bias_sigma_deg
    if e["current_n_mps"] is not None:
        assert e["current_sigma_mps"] < EkfSettings().current_sigma_mps
    table = cr.report_table(rep)
    assert "not estimated" in table or all(e[v] is not None for v in pairs)
    for text in why.values():
        assert text in table


def test_navreport_says_why_a_capture_without_heading_has_none() -> None:
    """A receiver standing still, with no heading sensor: no heading, no yaw rate, no
    current (the σ the filter carries would be anything up to a full turn)."""
    rep = capture_report(LOGS / "ublox-zed-f9p-nmea.log")
    e = rep["estimate"]
    assert e["pos_valid"] and e["heading_deg"] is None and e["yaw_rate_dps"] is None
    assert "no compass or true heading" in e["not_estimated"]["heading"]
    assert e["current_n_mps"] is None and "no heading sensor" in e["not_estimated"]["current"]


def test_navreport_restarts_the_position_after_a_long_gap() -> None:
    """nmea-rtk.log: 10 s of DGPS, a 630 s gap, then RTK fixes 7 m away: the position
    starts again from the fixes (dead reckoning had run out) instead of gating them
    against a stale estimate; the heading (from the course) is reported as lost."""
    rep = capture_report(LOGS / "nmea-rtk.log")
    e = rep["estimate"]
    assert e["pos_valid"] and e["fix"] == "rtk_fixed" and e["pos_sigma_m"] < 0.05
    assert rep["counters"]["pos_restarts"] == 1
    assert e["heading_deg"] is None and "lost" in e["not_estimated"]["heading"]
