"""Recorder benchmark: what recording costs, how much it writes, what a kill -9 loses,
and how fast a recording replays.

* ``sim_speed_*``: the same simulation (rectangle) with and without ``--record``,
  alternating, ``--pairs`` times; ``sim_slowdown`` = 1 − speed_with / speed_without
  (median of the pairs; goal ≤ 10 %).
* ``cpu_*``: ``zarco sim --realtime`` (the boat at 1× on a real clock) with and
  without recording, CPU of the runtime and its writer process (``/proc``) over
  ``--cpu-s`` seconds after a warm-up; ``cpu_recording_pct_core`` is the
  difference (goal ≤ 2 % of a core).
* ``mb_per_hour_realtime`` (chunks every 0.25 s, as on the boat) and
  ``mb_per_hour_sim`` (simulation: large chunks).
* ``kill9_lost_s_*``: ``--kills`` times, ``zarco sim --realtime --record`` is
  killed with SIGKILL (the runtime *and* its writer, the worst case) at a random
  moment; lost = the kill's time − the last recorded message's time (goal ≤ 1 s),
  and every file must read with mcap's streaming reader.
* ``replay_x_realtime``: ``zarco log replay`` of the simulation's recording.

Progress on stderr; one JSON line on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from zarco_tools.log.reader import iter_messages, open_recording  # noqa: E402
from zarco_tools.log.replay import replay, report  # noqa: E402
from zarco_tools.scenario import load_scenario  # noqa: E402
from zarco_tools.simulation import run_scenario  # noqa: E402

SCENARIO = ROOT / "config" / "scenarios" / "rectangle.toml"
ZARCO = [sys.executable, "-m", "zarco_runtime.cli"]
TICK = os.sysconf("SC_CLK_TCK")


def say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def sim_pairs(pairs: int, tmp: Path) -> dict[str, float]:
    with_, without = [], []
    size = sim_s = 0.0
    path = tmp / "sim.mcap"
    for i in range(pairs):
        for rec in ((False, True) if i % 2 == 0 else (True, False)):
            scn = load_scenario(SCENARIO)
            res = run_scenario(scn, record=str(path) if rec else None)
            speed = res.report["sim_seconds"] / res.report["wall_seconds"]
            (with_ if rec else without).append(speed)
            if rec:
                size, sim_s = path.stat().st_size, res.report["sim_seconds"]
            say(f"sim pair {i + 1}/{pairs}: {'with' if rec else 'without'} recording "
                f"{speed:.0f}× real time")
    ratios = [1.0 - a / b for a, b in zip(with_, without, strict=True)]
    return {"sim_speed_without_x": round(statistics.median(without), 1),
            "sim_speed_with_x": round(statistics.median(with_), 1),
            "sim_slowdown": round(statistics.median(ratios), 4),
            "sim_slowdown_pairs": [round(r, 4) for r in ratios],
            "mb_per_hour_sim": round(size / 1e6 / sim_s * 3600.0, 1)}


def _cpu_ticks(pid: int) -> int:
    """utime + stime of ``pid`` and its children (the recorder's writer)."""
    total = 0
    pids = [pid]
    try:
        for task in Path(f"/proc/{pid}/task").iterdir():
            kids = (task / "children").read_text().split()
            pids += [int(k) for k in kids]
    except OSError:
        pass
    for p in pids:
        try:
            f = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
            total += int(f[11]) + int(f[12])
        except (OSError, IndexError, ValueError):
            pass
    return total


def _realtime(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen([*ZARCO, "sim", str(SCENARIO), "--realtime", "-q",
                             "--set", "scenario.max_duration_s=600", *args], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=log.open("ab"),
                            start_new_session=True)


def cpu(window_s: float, tmp: Path) -> dict[str, float]:
    out: dict[str, float] = {}
    for rec in (False, True):
        path = tmp / "rt.mcap"
        p = _realtime(["--record", str(path)] if rec else [], tmp / "rt.log")
        try:
            time.sleep(5.0)  # start-up: imports, the writer process
            c0, w0 = _cpu_ticks(p.pid), time.monotonic()
            s0 = path.stat().st_size if rec and path.exists() else 0
            time.sleep(window_s)
            c1, w1 = _cpu_ticks(p.pid), time.monotonic()
            s1 = path.stat().st_size if rec and path.exists() else 0
        finally:
            p.send_signal(signal.SIGTERM)
            p.wait(timeout=30)
        pct = 100.0 * (c1 - c0) / TICK / (w1 - w0)
        out["cpu_with_pct_core" if rec else "cpu_without_pct_core"] = round(pct, 2)
        if rec:
            out["mb_per_hour_realtime"] = round((s1 - s0) / 1e6 / (w1 - w0) * 3600.0, 1)
        say(f"realtime {'with' if rec else 'without'} recording: {pct:.2f} % of a core")
    out["cpu_recording_pct_core"] = round(out["cpu_with_pct_core"]
                                          - out["cpu_without_pct_core"], 2)
    return out


def kills(n: int, tmp: Path, rng: random.Random) -> dict[str, object]:
    lost: list[float] = []
    readable = 0
    for i in range(n):
        path = tmp / f"kill{i}.mcap"
        p = _realtime(["--record", str(path)], tmp / "kill.log")
        try:
            end = time.monotonic() + 60.0
            while time.monotonic() < end and not (path.exists() and path.stat().st_size > 0):
                time.sleep(0.05)
            time.sleep(2.0 + 3.0 * rng.random())
            killed_at = time.time()
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=10)
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
        rec = open_recording(str(path))
        last = max((m.log_ns for m in iter_messages(rec)), default=0)
        from mcap.exceptions import EndOfFile
        from mcap.reader import NonSeekingReader

        with path.open("rb") as fh:
            try:
                for _ in NonSeekingReader(fh).iter_messages(log_time_order=False):
                    pass
                readable += 1
            except EndOfFile:  # the torn end: every message before it was read
                readable += 1
        lost.append(killed_at - last / 1e9)
        say(f"kill -9 {i + 1}/{n}: {lost[-1]:.3f} s lost")
    return {"kill9_lost_s_median": round(statistics.median(lost), 3),
            "kill9_lost_s_max": round(max(lost), 3),
            "kill9_lost_s": [round(x, 3) for x in lost], "kill9_files_readable": readable}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--pairs", type=int, default=4)
    ap.add_argument("--cpu-s", type=float, default=30.0)
    ap.add_argument("--kills", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    out: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        out.update(sim_pairs(a.pairs, tmp))
        say("replaying the simulation's recording")
        r = report(replay(open_recording(str(tmp / "sim.mcap"))))
        out["replay_x_realtime"] = r["speed_x_realtime"]
        out["replay_nav_exact"] = r["nav"]["exact"]
        out.update(cpu(a.cpu_s, tmp))
        out.update(kills(a.kills, tmp, random.Random(a.seed)))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
