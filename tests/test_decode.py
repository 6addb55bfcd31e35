"""``zarco decode``: output, refusals and the CLI (against GPSD: test_gpsd_conformance.py)."""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import pytest

from zarco_runtime.cli import main
from zarco_tools.decode import DecodeStats, Rejected, decode_lines

DATA = Path(__file__).parent / "data" / "gpsd-logs"


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
    kinds = {"GGA", "GLL", "GNS", "RMC", "VTG", "GST", "ZDA"}  # five epochs of each
    assert len(lines) == 35 and {x["kind"] for x in lines} == kinds
    assert "unsupported" in cap.err and "accepted 35" in cap.err
    data = (DATA / "pypilot.log").read_bytes()
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    assert main(["decode", "-"]) == 0
    cap = capsys.readouterr()
    assert len(cap.out.splitlines()) == 29 and cap.err == ""


def test_cli_missing_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["decode", str(tmp_path / "nope.log")]) == 2
    assert "nope.log" in capsys.readouterr().err
