"""Control-period benchmark: how steady the 20 Hz control tick stays while the
supervisor does its work, in real time, on a loaded machine.

    python tests/bench/control_period.py [--runs 3] [--load 1] [--lines-s 100]
                                         [--changes 100]

Each run is the simulated boat at 1× on a real clock (``zarco sim --realtime``'s
loop), its state file on disk, with ``--load`` CPU-bound processes beside it:

1. *lines*: a mission of 10 m legs at 1 m/s, so a leg switch (and, in a
   runtime that writes it there, a state-file write) every 10 s, for
   ``--lines-s`` seconds;
2. *modes*: ``--changes`` mode changes, hold and lines in turn, one every
   0.5 s (each one a new controller for the control task).

The period is the time between consecutive thruster commands (one per control
tick, stamped with the loop's time at the tick).  Per phase: p50, p99 and max
of the period (ms) and the ticks later than 1.5 periods, over every run; and
the tick's own work (ms, wall clock inside the control task's tick, listeners
it triggers included: what a tick blocks the loop for), whose max shows work
done on the control path (a state-file write, an LQR design) apart from the
machine's scheduling noise.  Progress on stderr; one JSON line at the end.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def _percentile(xs: list[float], q: float) -> float:
    s = sorted(xs)
    if not s:
        return math.nan
    k = min(len(s) - 1, max(0, math.ceil(q / 100.0 * len(s)) - 1))
    return s[k]


def one_run(seed: int, lines_s: float, changes: int,
            state_dir: str) -> tuple[dict[str, list[float]], dict[str, list[float]]]:
    from zarco_core.geodesy import LocalFrame
    from zarco_core.messages import ThrusterCommand
    from zarco_runtime.runtime import Runtime
    from zarco_runtime.supervision.local import LocalCommands
    from zarco_tools.scenario import load_scenario
    from zarco_tools.simulation import run_scenario

    warm_s = 15.0
    total = warm_s + lines_s + changes * 0.5 + 5.0
    scn = load_scenario(ROOT / "config" / "scenarios" / "rectangle.toml", [
        "mission.kind=idle", f"scenario.max_duration_s={total}",
        f"runtime.supervisor.state_file={state_dir}/state-{seed}.json"], seed)
    o = scn.runtime.origin
    frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    n_legs = int(lines_s / 10.0) + 4
    wps = [list(frame.to_geodetic(10.0 * k, 0.0)[:2]) for k in range(n_legs + 1)]
    phase = ["warm"]
    periods: dict[str, list[float]] = {"lines": [], "modes": []}
    work: dict[str, list[float]] = {"lines": [], "modes": []}
    last = [math.nan]

    def on_cmd(m: ThrusterCommand) -> None:
        dt = m.t - last[0]
        last[0] = m.t
        if phase[0] in periods and math.isfinite(dt):
            periods[phase[0]].append(dt)

    async def operator(rt: Runtime) -> None:
        rt.bus.listen(ThrusterCommand, on_cmd)
        while rt.live.control is None:  # built when the runtime starts its components
            await asyncio.sleep(0.05)
        ctl = rt.live.control
        inner = ctl.tick

        def timed(t: float) -> Any:
            w = time.perf_counter()
            out = inner(t)
            if phase[0] in work:
                work[phase[0]].append(time.perf_counter() - w)
            return out

        ctl.tick = timed  # type: ignore[method-assign]
        local = LocalCommands(rt.bus, rt.clock, source="bench")
        t0 = rt.clock.now()
        while True:  # as an operator does: arm once the boat is ready
            ack = await local.send("arm")
            if ack.ok or rt.clock.now() - t0 > warm_s:
                break
            await asyncio.sleep(0.5)
        await asyncio.sleep(max(0.0, t0 + warm_s - rt.clock.now()))
        ack = await local.send("mission", {"waypoints": wps, "speed_mps": 1.0})
        print(f"  mission: {ack.ok} {ack.reason}", file=sys.stderr, flush=True)
        phase[0] = "lines"
        await asyncio.sleep(lines_s)
        phase[0] = "modes"
        refused: dict[str, int] = {}
        for i in range(changes):
            ack = await local.send("mode", {"mode": "hold" if i % 2 == 0 else "lines"})
            if not ack.ok:
                refused[ack.reason] = refused.get(ack.reason, 0) + 1
            await asyncio.sleep(0.5)
        phase[0] = "done"
        print(f"  mode changes refused: {refused}", file=sys.stderr, flush=True)

    run_scenario(scn, realtime=True, extra_tasks=[operator])
    return periods, work


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--load", type=int, default=1, help="CPU-bound processes beside it "
                    "(0 on a machine others already load)")
    ap.add_argument("--lines-s", type=float, default=100.0)
    ap.add_argument("--changes", type=int, default=100)
    args = ap.parse_args()
    import zarco_runtime

    print(f"runtime from {Path(zarco_runtime.__file__).parent}", file=sys.stderr)
    load0 = os.getloadavg()[0]
    load = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
            for _ in range(args.load)]
    all_p: dict[str, list[float]] = {"lines": [], "modes": []}
    all_w: dict[str, list[float]] = {"lines": [], "modes": []}
    w0 = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory() as d:
            for r in range(args.runs):
                p, w = one_run(r + 1, args.lines_s, args.changes, d)
                for k, v in p.items():
                    all_p[k] += v
                    all_w[k] += w[k]
                print(f"[run {r + 1}/{args.runs} {time.perf_counter() - w0:5.0f} s] " + "  ".join(
                    f"{k}: period p99 {_percentile(v, 99) * 1e3:.1f} ms max "
                    f"{max(v) * 1e3:.1f} ms, tick work max {max(w[k]) * 1e3:.1f} ms"
                    for k, v in p.items() if v and w[k]), file=sys.stderr, flush=True)
    finally:
        for proc in load:
            proc.kill()
            proc.wait()
    out: dict[str, Any] = {"runs": args.runs, "load_processes": args.load,
                           "loadavg_1min_start_end": [round(load0, 1),
                                                      round(os.getloadavg()[0], 1)],
                           "cpus": os.cpu_count(), "nominal_period_ms": 50.0}
    for k, v in all_p.items():
        out[k] = {"ticks": len(v),
                  "period_p50_ms": round(_percentile(v, 50) * 1e3, 2),
                  "period_p99_ms": round(_percentile(v, 99) * 1e3, 2),
                  "period_max_ms": round(max(v, default=math.nan) * 1e3, 2),
                  "late_ticks": sum(x > 0.075 for x in v),
                  "tick_work_p99_ms": round(_percentile(all_w[k], 99) * 1e3, 2),
                  "tick_work_max_ms": round(max(all_w[k], default=math.nan) * 1e3, 2)}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
