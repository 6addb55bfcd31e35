"""``zarco replay``: schedules from a capture's clocks, and bytes through a real pty."""

from __future__ import annotations

import itertools
import os
import re
import select
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

import pytest

from drivers.nmea import format_sentence
from zarco_tools.replay import build_schedule, play, sentence_time

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "gpsd-logs"


def nmea_lines(name: str) -> list[bytes]:
    return [ln + b"\r\n" for ln in (DATA / name).read_bytes().splitlines()
            if ln.strip() and not ln.startswith(b"#")]


def test_sentence_times() -> None:
    assert sentence_time(b"$GNZDA,004024.00,12,04,2019,00,00*77") == pytest.approx(2424.0)
    rmc = b"$GNRMC,003956.00,A,4552.65403,S,17030.00668,E,0.025,,120419,,,A,V*07"
    assert sentence_time(rmc) == pytest.approx(2396.0)
    assert sentence_time(rmc.replace(b"*07", b"*08")) is None  # bad checksum: not trusted
    assert sentence_time(b"$GPGGA,,,,,,0,,,,M,,M,,*66") is None
    assert sentence_time(b"$APHDM,218.634,M*39") is None


def test_schedule_follows_the_capture_clock() -> None:
    s = build_schedule((DATA / "ublox-zed-f9p-nmea.log").read_bytes().splitlines())
    assert s.timed and s.lines == nmea_lines("ublox-zed-f9p-nmea.log")
    assert s.offsets_s == sorted(s.offsets_s) and s.offsets_s[0] == 0.0
    assert s.duration_s == pytest.approx(28.0)  # 00:39:56 → 00:40:24
    # one epoch per second: 29 distinct send times
    assert len(set(s.offsets_s)) == 29


def test_long_silences_are_shortened() -> None:
    raw = (DATA / "nmea-rtk.log").read_bytes().splitlines()
    full = build_schedule(raw, max_gap_s=None)
    short = build_schedule(raw, max_gap_s=2.0)
    assert full.duration_s == pytest.approx(10 * 60 + 41.9)  # 13:28:19.6 → 13:39:01.5
    assert short.duration_s < full.duration_s / 5
    gaps = [b - a for a, b in itertools.pairwise(short.offsets_s)]
    assert max(gaps) <= 2.0 + 1e-9


def test_midnight_and_untimed_captures() -> None:
    a = format_sentence("GPZDA,235959.50,31,12,2025,00,00")
    b = format_sentence("GPHDT,10.0,T")
    c = format_sentence("GPZDA,000000.50,01,01,2026,00,00")
    s = build_schedule([b, a, b, c, b])
    assert s.offsets_s == [0.0, 0.0, 0.0, 1.0, 1.0]
    u = build_schedule([b, b"# comment", b, b""], line_rate_hz=4.0)
    assert not u.timed and u.offsets_s == [0.0, 0.25] and len(u.lines) == 2


def test_play_paces_and_loops() -> None:
    s = build_schedule([format_sentence(f"GPZDA,1200{ss:02d}.00,01,06,2026,00,00")
                        for ss in range(5)])
    fake = [0.0]
    writes: list[tuple[float, bytes]] = []
    st = play(s, lambda b: writes.append((fake[0], b)), rate=2.0, loops=2,
              clock=lambda: fake[0], sleep=lambda d: fake.__setitem__(0, fake[0] + d))
    assert st.lines == 10
    assert [round(t, 6) for t, _ in writes] == [0.0, 0.5, 1.0, 1.5, 2.0,
                                                 2.5, 3.0, 3.5, 4.0, 4.5]


def _read_pty(master: int, out: list[tuple[float, bytes]], stop: threading.Event) -> None:
    while not stop.is_set():
        r, _, _ = select.select([master], [], [], 0.05)
        if r:
            try:
                data = os.read(master, 65536)
            except OSError:
                return
            out.append((time.monotonic(), data))


def test_replay_into_a_pty_keeps_order_and_pace(tmp_path: Path) -> None:
    """The CLI writes the ublox capture into a pseudo-terminal at 20× its pace:
    every byte arrives, in order, and the epochs are paced (never sooner than the
    schedule; how close to it on this machine is the benchmark's figure,
    tests/bench/replay_pace.py)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    got: list[tuple[float, bytes]] = []
    stop = threading.Event()
    reader = threading.Thread(target=_read_pty, args=(master, got, stop), daemon=True)
    reader.start()
    rate = 20.0
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "zarco_runtime.cli", "replay",
             str(DATA / "ublox-zed-f9p-nmea.log"), "--port", path, "--rate", str(rate)],
            capture_output=True, text=True, timeout=30, cwd=ROOT)
        time.sleep(0.2)
    finally:
        stop.set()
        reader.join(2)
        os.close(slave)
        os.close(master)
    assert proc.returncode == 0, proc.stderr
    assert "replay: sent 1015 lines" in proc.stderr
    stream = b"".join(c for _, c in got)
    want = b"".join(nmea_lines("ublox-zed-f9p-nmea.log"))
    assert stream == want
    # pacing: the arrival time of each ZDA (one per epoch) against the schedule
    sched = build_schedule((DATA / "ublox-zed-f9p-nmea.log").read_bytes().splitlines())
    ends = []
    pos = 0
    for t, c in got:
        pos += len(c)
        ends.append((pos, t))
    arrivals, expected = [], []
    offset = 0
    for line, off in zip(sched.lines, sched.offsets_s, strict=True):
        if b"ZDA" in line[:7]:
            t = next(t for p, t in ends if p > offset)
            arrivals.append(t)
            expected.append(off / rate)
        offset += len(line)
    assert len(arrivals) == 29 and arrivals == sorted(arrivals)
    # paced, not as fast as the port takes them: the replay, which never writes a
    # line before its time, took at least the schedule's 28 s / 20 (as fast as the
    # port takes it, it takes milliseconds)
    m = re.search(r"bytes in ([\d.]+) s", proc.stderr)
    assert m is not None, proc.stderr
    assert float(m.group(1)) >= sched.offsets_s[-1] / rate - 0.005
    assert expected[-1] - expected[0] == pytest.approx(28.0 / rate)


def test_replay_refuses_a_missing_port(tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    from zarco_runtime.cli import main

    assert main(["replay", str(DATA / "pypilot.log"), "--port", str(tmp_path / "nope"),
                 "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--port" in err and str(tmp_path / "nope") in err
