"""``zarco decode`` against GPSD's regression captures and their ``.chk`` output."""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path
from typing import Any

import pytest

from zarco_runtime.cli import main
from zarco_tools.decode import DecodeStats, Rejected, decode_lines

DATA = Path(__file__).parent / "data" / "gpsd-logs"
GPS_LOGS = ["hemi.log", "nmea-rtk.log", "polarx2.log", "ublox-zed-f9p-nmea.log"]
FIX_LABELS = {"none", "single", "dgps", "rtk_float", "rtk_fixed"}
#: GPSD TPV status → our fix label (absent = 1: plain GPS)
STATUS_FIX = {1: "single", 2: "dgps", 3: "rtk_fixed", 4: "rtk_float"}
FIX_ORDER = ["none", "single", "dgps", "rtk_float", "rtk_fixed"]


def decoded(name: str) -> tuple[dict[int, dict[str, Any]], list[Rejected]]:
    """Decode a capture: accepted sentences by input line number, and refusals."""
    ok: dict[int, dict[str, Any]] = {}
    bad: list[Rejected] = []
    with (DATA / name).open("rb") as fh:
        for item in decode_lines(fh):
            if isinstance(item, Rejected):
                bad.append(item)
            else:
                assert item["n"] not in ok  # one sentence per line in these captures
                ok[item["n"]] = item
    return ok, bad


def chk_entries(name: str) -> list[tuple[int, str, list[dict[str, Any]]]]:
    """(input line number, sentence, GPSD reports printed after it) for each sentence."""
    numbers = [n for n, ln in enumerate((DATA / name).read_text().splitlines(), 1)
               if ln.strip() and not ln.startswith("#")]
    entries: list[tuple[str, list[dict[str, Any]]]] = []
    for raw in (DATA / f"{name}.chk").read_text().splitlines():
        if raw.startswith("{"):
            entries[-1][1].append(json.loads(raw))
        elif raw.strip():
            entries.append((raw, []))
    assert len(entries) == len(numbers)
    return [(n, line, reps) for n, (line, reps) in zip(numbers, entries, strict=True)]


def _tod(hhmmss: str) -> float:
    return int(hhmmss[:2]) * 3600 + int(hhmmss[2:4]) * 60 + float(hhmmss[4:])


def _iso_tod(iso: str) -> float:
    hh, mm, ss = iso.split("T")[1].rstrip("Z").split(":")
    return int(hh) * 3600 + int(mm) * 60 + float(ss)


def _time_field(line: str) -> str | None:
    return line.split(",")[1] if line[3:6] in ("GGA", "RMC") else None


def epoch_tpvs(entries: list[tuple[int, str, list[dict[str, Any]]]], i: int
               ) -> list[dict[str, Any]]:
    """GPSD's TPV reports about the epoch of GGA/RMC ``entries[i]``: printed after it
    or after a later sentence of the same epoch, with the same time (a report
    without time only if printed right after it).  GPSD reports once per cycle,
    so this is how a report is tied to a sentence (as in test_gps_parser)."""
    tf = _time_field(entries[i][1])
    utc = _tod(tf) if tf else None
    out = []
    for j in range(i, len(entries)):
        _n, line, reps = entries[j]
        other = _time_field(line)
        if j > i and other is not None and (other != tf or not tf):
            break
        for r in reps:
            if r["class"] != "TPV":
                continue
            if "time" in r and utc is not None:
                if abs(_iso_tod(r["time"]) - utc) < 1e-3:
                    out.append(r)
            elif j == i:
                out.append(r)
    return out


@pytest.mark.parametrize("name", GPS_LOGS)
def test_positions_and_fix_agree_with_gpsd(name: str) -> None:
    ok, _bad = decoded(name)
    entries = chk_entries(name)
    n_pos = n_nofix = 0
    for i, (n, line, _reps) in enumerate(entries):
        if line[3:6] not in ("GGA", "RMC"):
            continue
        out = ok[n]  # every GGA/RMC of these captures is accepted
        assert out["kind"] == line[3:6] and out["fix"] in FIX_LABELS
        for tpv in epoch_tpvs(entries, i):
            if tpv["mode"] >= 2:
                assert out["fix"] != "none", (line, tpv)
                assert out["lat"] == pytest.approx(tpv["lat"], abs=1e-7), line
                assert out["lon"] == pytest.approx(tpv["lon"], abs=1e-7), line
                want = STATUS_FIX[tpv.get("status", 1)]
                if out["kind"] == "GGA":
                    assert out["fix"] == want, (line, tpv)
                else:  # RMC's FAA mode may say less than the merged GGA quality
                    assert FIX_ORDER.index(out["fix"]) <= FIX_ORDER.index(want)
                n_pos += 1
            else:
                assert out["fix"] == "none", (line, tpv)
                n_nofix += 1
    minimum = {"hemi.log": (19, 230), "nmea-rtk.log": (245, 0), "polarx2.log": (35, 0),
               "ublox-zed-f9p-nmea.log": (69, 0)}[name]
    assert n_pos >= minimum[0] and n_nofix >= minimum[1], (n_pos, n_nofix)


def test_hemi_true_headings_agree_with_gpsd() -> None:
    ok, bad = decoded("hemi.log")
    compared = 0
    for n, line, reps in chk_entries("hemi.log"):
        if line[3:6] != "HDT":
            continue
        atts = [r for r in reps if r["class"] == "ATT"]
        if n not in ok:
            assert not atts
            assert any(b.n == n and b.reason == "empty" for b in bad)
            continue
        out = ok[n]
        assert out["kind"] == "HDT" and out["true"] is True
        assert out["heading_deg"] == pytest.approx(atts[0]["heading"], abs=1e-3)
        compared += 1
    assert compared == 4


def test_pypilot_magnetic_headings_agree_with_gpsd() -> None:
    ok, bad = decoded("pypilot.log")
    assert not bad
    n_hdm = n_rot = 0
    for n, _line, reps in chk_entries("pypilot.log"):
        att = next(r for r in reps if r["class"] == "ATT")
        out = ok[n]
        if out["kind"] == "HDM":
            assert out["true"] is False
            assert out["heading_deg"] == pytest.approx(att["mheading"], abs=1e-6)
            n_hdm += 1
        elif out["kind"] == "ROT":
            assert out["rot_dpm"] == pytest.approx(att["rot"], abs=1e-9)
            n_rot += 1
        else:
            assert out["kind"] == "XDR"
            for k in ("pitch", "roll"):
                if f"{k}_deg" in out:
                    assert out[f"{k}_deg"] == pytest.approx(att[k], abs=1e-9)
    assert (n_hdm, n_rot) == (7, 7)


def test_variation_makes_magnetic_headings_true() -> None:
    items = list(decode_lines([b"$APHDM,218.634,M*39"], variation_deg=-2.0))
    assert items[0]["true"] is True and items[0]["heading_deg"] == pytest.approx(216.634)


def test_refusals_carry_their_reason() -> None:
    stats = DecodeStats()
    src = [
        b"# a comment, not NMEA\n",
        b"\n",
        b"$GPGGA,,,,,,0,,,,M,,M,,*67\r\n",  # wrong checksum
        b"$GPGGA,,,,,,0,,,,M,,M,,\r\n",  # none
        b"\x00\xff noise \x07\n",
        b"$GPGSV,1,1,00*79\n",  # valid, not read by any driver
        b"$PZTHR,12.5,-3.0*5C\n",
        b"$HCHDG,98.3,0.0,E,12.6,W*57\n",
    ]
    items = list(decode_lines(src, stats=stats))
    reasons = [(i.n, i.reason) for i in items if isinstance(i, Rejected)]
    assert reasons == [(3, "checksum"), (4, "no_checksum"), (5, "framing"), (6, "unsupported")]
    ok = [i for i in items if not isinstance(i, Rejected)]
    assert [(i["kind"], i["device"]) for i in ok] == [("PZTHR", "thrusters"), ("HDG", "compass")]
    assert ok[0]["u1"] == 12.5 and ok[1]["heading_deg"] == pytest.approx(85.7)
    assert stats.comments == 1 and stats.bytes_discarded > 0


def test_cli_file_and_stdin(capsys: pytest.CaptureFixture[str],
                            monkeypatch: pytest.MonkeyPatch) -> None:
    assert main(["decode", str(DATA / "polarx2.log"), "--summary"]) == 0
    cap = capsys.readouterr()
    lines = [json.loads(x) for x in cap.out.splitlines()]
    assert len(lines) == 25 and {x["kind"] for x in lines} == {"GGA", "RMC", "VTG", "GST", "ZDA"}
    assert "unsupported" in cap.err and "accepted 25" in cap.err
    data = (DATA / "pypilot.log").read_bytes()
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    assert main(["decode", "-"]) == 0
    cap = capsys.readouterr()
    assert len(cap.out.splitlines()) == 29 and cap.err == ""


def test_cli_missing_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["decode", str(tmp_path / "nope.log")]) == 1
    assert "nope.log" in capsys.readouterr().err
