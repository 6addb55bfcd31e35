"""Benchmark: how closely ``zarco replay`` keeps a capture's pace.

    python tests/bench/replay_pace.py [--runs 5] [--rate 20] [--load N]

Each run writes the u-blox capture (``tests/data/gpsd-logs/ublox-zed-f9p-nmea.log``:
29 epochs over 28 s) into a pseudo-terminal at ``--rate`` × its recorded pace
with the real command, and a reader on the other side stamps when each epoch's
ZDA arrives.  The error of an epoch is its arrival against the schedule,
counted from the first epoch's arrival.

Figures (one JSON line at the end): ``error_p50_ms``, ``error_p99_ms``,
``error_max_ms`` over every epoch of every run; ``span_error_ms``: the worst
difference between the measured and the scheduled span of a run;
``tool_late_max_ms``: the tool's own worst lateness (it writes no line early).
``--load N`` runs N CPU-bound ``zarco sim`` loops beside it.  Progress on
stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import select
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from zarco_tools.replay import build_schedule  # noqa: E402

ZARCO = str(Path(sys.executable).with_name("zarco"))
CAPTURE = ROOT / "tests" / "data" / "gpsd-logs" / "ublox-zed-f9p-nmea.log"


def say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, round(q / 100.0 * (len(s) - 1)))]


def one_run(rate: float) -> tuple[list[float], float, float]:
    """Errors of each epoch (s), the span's error (s), the tool's worst lateness (s)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    got: list[tuple[float, bytes]] = []
    stop = threading.Event()

    def read() -> None:
        while not stop.is_set():
            if select.select([master], [], [], 0.05)[0]:
                try:
                    got.append((time.monotonic(), os.read(master, 65536)))
                except OSError:
                    return

    th = threading.Thread(target=read, daemon=True)
    th.start()
    try:
        p = subprocess.run([ZARCO, "replay", str(CAPTURE), "--port", os.ttyname(slave),
                            "--rate", str(rate)], capture_output=True, text=True, timeout=300)
    finally:
        stop.set()
        th.join(2.0)
        os.close(slave)
        os.close(master)
    if p.returncode != 0:
        raise RuntimeError(p.stderr)
    sched = build_schedule(CAPTURE.read_bytes().splitlines())
    ends, pos = [], 0
    for t, c in got:
        pos += len(c)
        ends.append((pos, t))
    arrivals, expected, offset = [], [], 0
    for line, off in zip(sched.lines, sched.offsets_s, strict=True):
        if b"ZDA" in line[:7]:
            arrivals.append(next(t for q, t in ends if q > offset))
            expected.append(off / rate)
        offset += len(line)
    t0 = arrivals[0] - expected[0]
    errors = [a - t0 - e for a, e in zip(arrivals, expected, strict=True)]
    span = (arrivals[-1] - arrivals[0]) - (expected[-1] - expected[0])
    m = re.search(r"worst lateness ([\d.]+) ms", p.stderr)
    return errors, span, float(m.group(1)) / 1000.0 if m else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--rate", type=float, default=20.0)
    ap.add_argument("--load", type=int, default=0, help="CPU-bound zarco sim loops beside it")
    args = ap.parse_args()
    loop = (f"while true; do {ZARCO} sim {ROOT / 'config/scenarios/follow_turn.toml'} -q "
            ">/dev/null 2>&1; done")
    load = [subprocess.Popen(["bash", "-c", loop], start_new_session=True)
            for _ in range(args.load)]
    errs: list[float] = []
    spans: list[float] = []
    late: list[float] = []
    try:
        for k in range(args.runs):
            e, s, lt = one_run(args.rate)
            errs += [abs(x) for x in e]
            spans.append(abs(s))
            late.append(lt)
            say(f"run {k + 1}/{args.runs}: max error {1000 * max(map(abs, e)):.1f} ms, "
                f"span error {1000 * s:+.1f} ms, tool's worst lateness {1000 * lt:.1f} ms")
    finally:
        for p in load:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, 15)
            p.wait()
    print(json.dumps({
        "runs": args.runs, "rate": args.rate, "load_processes": args.load,
        "loadavg_1min": round(os.getloadavg()[0], 2), "epochs": len(errs),
        "error_p50_ms": round(1000 * pct(errs, 50), 2),
        "error_p99_ms": round(1000 * pct(errs, 99), 2),
        "error_max_ms": round(1000 * max(errs), 2),
        "span_error_ms": round(1000 * max(spans), 2),
        "tool_late_max_ms": round(1000 * max(late), 2),
    }))


if __name__ == "__main__":
    main()
