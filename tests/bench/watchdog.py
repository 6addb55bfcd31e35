"""Benchmark: how steadily ``zarco run`` pings systemd's watchdog.

    python tests/bench/watchdog.py [--runs 3] [--seconds 30] [--watchdog-s 2]
                                   [--load N]

Each run starts the real ``zarco run`` on pseudo-terminals (a GPS, a compass
and a thruster controller that answers, so the control loop and the
supervisor run as on the boat) with ``NOTIFY_SOCKET`` on a real unix datagram
socket and ``WATCHDOG_USEC`` as ``WatchdogSec=`` sets it, and records the
arrival of every ``WATCHDOG=1`` for ``--seconds``.  The runtime pings every
half watchdog period while its control loop ticks and its supervisor
evaluates; systemd kills it after a whole period without one.

Figures (one JSON line at the end): ``gap_p50_s``, ``gap_p99_s``, ``gap_max_s``
over all runs; ``gap_max_over_watchdog``: the worst gap as a share of the
watchdog period (≥ 1 would have been a kill); ``late_pings``: gaps longer than
0.75 of the period.  ``--load N`` runs N CPU-bound ``zarco sim`` loops beside
it (a loaded 2-core machine).  Progress on stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from drivers.nmea import NmeaFramer  # noqa: E402
from drivers.thruster_protocol import encode_pzths, parse_pzthr  # noqa: E402

ZARCO = str(Path(sys.executable).with_name("zarco"))


def say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, round(q / 100.0 * (len(s) - 1)))]


class Devices:
    """Three pseudo-terminals; the thruster controller answers $PZTHS at 5 Hz."""

    def __init__(self) -> None:
        self.masters: dict[str, int] = {}
        self.paths: dict[str, str] = {}
        for name in ("gps", "compass", "thrusters"):
            m, s = os.openpty()
            tty.setraw(s)
            self.paths[name] = os.ttyname(s)
            os.close(s)
            os.set_blocking(m, False)
            self.masters[name] = m
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        framer = NmeaFramer()
        m = self.masters["thrusters"]
        last = (0.0, 0.0)
        while not self.stop.wait(0.2):
            for dev_m in self.masters.values():  # drain what the runtime writes
                with contextlib.suppress(OSError):
                    data = os.read(dev_m, 65536)
                    if dev_m == m:
                        for line in framer.feed(data):
                            with contextlib.suppress(Exception):
                                last = parse_pzthr(line)
            with contextlib.suppress(OSError):
                os.write(m, encode_pzths(last[0], last[1], 0, 0, 0.0, 0.0))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=2.0)
        for m in self.masters.values():
            os.close(m)


def one_run(tmp: Path, seconds: float, watchdog_s: float) -> list[float]:
    dev = Devices()
    cfg = tmp / "zarco.toml"
    cfg.write_text("".join(f'[devices.{n}]\nurl = "{p}"\n' for n, p in dev.paths.items())
                   + "[record]\nenabled = false\n")
    sock_path = tmp / "notify.sock"
    sock_path.unlink(missing_ok=True)
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(str(sock_path))
    env = dict(os.environ, NOTIFY_SOCKET=str(sock_path),
               WATCHDOG_USEC=str(int(watchdog_s * 1e6)))
    p = subprocess.Popen([ZARCO, "run", "--config", str(cfg)], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    pings: list[float] = []
    ready = False
    try:
        end = time.monotonic() + 60.0  # until READY=1, then the measured window
        while (left := end - time.monotonic()) > 0:
            sock.settimeout(left)
            try:
                msg = sock.recv(4096).decode()
            except TimeoutError:
                break
            if msg == "READY=1" and not ready:
                ready = True
                end = time.monotonic() + seconds
            elif msg == "WATCHDOG=1" and ready:
                pings.append(time.monotonic())
    finally:
        p.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            p.communicate(timeout=30)
        if p.poll() is None:
            p.kill()
            p.wait()
        sock.close()
        dev.close()
    if not ready:
        raise RuntimeError("zarco run never said READY=1")
    return [b - a for a, b in itertools.pairwise(pings)]


def loaders(n: int) -> list[subprocess.Popen[bytes]]:
    loop = (f"while true; do {ZARCO} sim {ROOT / 'config/scenarios/follow_turn.toml'} -q "
            ">/dev/null 2>&1; done")
    return [subprocess.Popen(["bash", "-c", loop], start_new_session=True)
            for _ in range(n)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--watchdog-s", type=float, default=2.0,
                    help="WatchdogSec= (the unit's: 2 s)")
    ap.add_argument("--load", type=int, default=0, help="CPU-bound zarco sim loops beside it")
    args = ap.parse_args()
    load = loaders(args.load)
    gaps: list[float] = []
    try:
        with tempfile.TemporaryDirectory(prefix="zarco-watchdog-") as d:
            for k in range(args.runs):
                g = one_run(Path(d), args.seconds, args.watchdog_s)
                gaps += g
                say(f"run {k + 1}/{args.runs}: {len(g)} gaps, p50 {statistics.median(g):.3f} s,"
                    f" max {max(g):.3f} s")
    finally:
        for p in load:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, 15)
            p.wait()
    period = args.watchdog_s
    print(json.dumps({
        "runs": args.runs, "seconds": args.seconds, "watchdog_s": period,
        "load_processes": args.load, "loadavg_1min": round(os.getloadavg()[0], 2),
        "gaps": len(gaps), "gap_p50_s": round(pct(gaps, 50), 4),
        "gap_p99_s": round(pct(gaps, 99), 4), "gap_max_s": round(max(gaps), 4),
        "gap_max_over_watchdog": round(max(gaps) / period, 3),
        "late_pings": sum(1 for g in gaps if g > 0.75 * period),
    }))


if __name__ == "__main__":
    main()
