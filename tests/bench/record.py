"""Recorder benchmark: what recording costs, how much it writes, what a kill -9 loses,
and how fast a recording replays.

* ``sim_*``: the whole ``zarco sim rectangle.toml`` run, end to end (process start,
  imports, the simulation, the writer drained and the file finished), with and
  without ``--record``, alternating, ``--pairs`` times.  ``sim_wall_ratio`` is the
  median over the pairs of wall(with) / wall(without) (goal ≤ 1.10: recording
  costs at most 10 % of the simulation speed); ``sim_slowdown`` = 1 − 1/ratio.
  The CPU of each process is reported too: the runtime's own (``RUSAGE_SELF``) and
  the writer's (``RUSAGE_CHILDREN``: the writer process and the ``git describe`` it
  runs), with the machine's load average (the figures are taken on a shared
  machine).
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

SCENARIO = ROOT / "config" / "scenarios" / "rectangle.toml"
ZARCO = [sys.executable, "-m", "zarco_runtime.cli"]
TICK = os.sysconf("SC_CLK_TCK")


def say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


#: ``zarco sim`` as its entry point runs it, reporting the CPU of the process and
#: of its waited-for children (the recorder's writer) into the file $ZARCO_CPU_OUT
_CLI = ("import json, os, resource, sys\n"
        "from zarco_runtime.cli import main\n"
        "try:\n"
        "    rc = main(sys.argv[1:])\n"
        "finally:\n"
        "    s = resource.getrusage(resource.RUSAGE_SELF)\n"
        "    c = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
        "    with open(os.environ['ZARCO_CPU_OUT'], 'w') as f:\n"
        "        json.dump([s.ru_utime + s.ru_stime, c.ru_utime + c.ru_stime], f)\n"
        "sys.exit(rc)\n")


def _sim_run(tmp: Path, record: Path | None) -> tuple[float, float, float, float]:
    """One ``zarco sim`` run: wall (s), runtime CPU (s), writer CPU (s), simulated s."""
    cpu_out, report = tmp / "cpu.json", tmp / "report.json"
    args = [sys.executable, "-c", _CLI, "sim", str(SCENARIO), "-q", "--report", str(report)]
    if record is not None:
        args += ["--record", str(record)]
    w0 = time.perf_counter()
    subprocess.run(args, cwd=ROOT, check=True, stdout=subprocess.DEVNULL,
                   env={**os.environ, "ZARCO_CPU_OUT": str(cpu_out)})
    wall = time.perf_counter() - w0
    own, children = json.loads(cpu_out.read_text())
    return wall, own, children, float(json.loads(report.read_text())["sim_seconds"])


def sim_pairs(pairs: int, tmp: Path) -> dict[str, object]:
    runs: dict[bool, list[tuple[float, float, float, float]]] = {False: [], True: []}
    path = tmp / "sim.mcap"
    load0 = os.getloadavg()
    for i in range(pairs):
        for rec in ((False, True) if i % 2 == 0 else (True, False)):
            r = _sim_run(tmp, path if rec else None)
            runs[rec].append(r)
            say(f"sim pair {i + 1}/{pairs}: {'with' if rec else 'without'} recording "
                f"{r[0]:.2f} s wall ({r[3] / r[0]:.0f}× real time), runtime CPU {r[1]:.2f} s, "
                f"writer CPU {r[2]:.2f} s")
    load1 = os.getloadavg()
    ratios = [b[0] / a[0] for a, b in zip(runs[False], runs[True], strict=True)]
    ratio = statistics.median(ratios)

    def med(rec: bool, k: int) -> float:
        return statistics.median(r[k] for r in runs[rec])

    sim_s = runs[True][-1][3]
    return {"sim_wall_without_s": round(med(False, 0), 3),
            "sim_wall_with_s": round(med(True, 0), 3),
            "sim_wall_ratio": round(ratio, 4),
            "sim_wall_ratio_pairs": [round(r, 4) for r in ratios],
            "sim_slowdown": round(1.0 - 1.0 / ratio, 4),
            "sim_speed_without_x": round(sim_s / med(False, 0), 1),
            "sim_speed_with_x": round(sim_s / med(True, 0), 1),
            "sim_cpu_runtime_without_s": round(med(False, 1), 3),
            "sim_cpu_runtime_with_s": round(med(True, 1), 3),
            "sim_cpu_writer_s": round(med(True, 2), 3),
            "sim_cpu_ratio_runtime": round(med(True, 1) / med(False, 1), 4),
            "sim_cpu_ratio_total": round((med(True, 1) + med(True, 2)) / med(False, 1), 4),
            "sim_messages": _count(path),
            "load_avg_1min": [round(load0[0], 2), round(load1[0], 2)],
            "cores": os.cpu_count(),
            "mb_per_hour_sim": round(path.stat().st_size / 1e6 / sim_s * 3600.0, 1)}


def _count(path: Path) -> int:
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    return int(summary.statistics.message_count) if summary and summary.statistics else -1


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
    ap.add_argument("--pairs", type=int, default=8)
    ap.add_argument("--cpu-s", type=float, default=30.0, help="0: skip the real-time CPU")
    ap.add_argument("--kills", type=int, default=10, help="0: skip the kill -9 runs")
    ap.add_argument("--no-replay", action="store_true", help="skip the replay")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    out: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        out.update(sim_pairs(a.pairs, tmp))
        if not a.no_replay:
            say("replaying the simulation's recording")
            r = report(replay(open_recording(str(tmp / "sim.mcap"))))
            out["replay_x_realtime"] = r["speed_x_realtime"]
            out["replay_nav_exact"] = r["nav"]["exact"]
        if a.cpu_s > 0:
            out.update(cpu(a.cpu_s, tmp))
        if a.kills > 0:
            out.update(kills(a.kills, tmp, random.Random(a.seed)))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
