"""Benchmark: what one acoustic event costs the AUV tracker.

    python tests/bench/tracker_event.py [--runs 5] [--seeds 1 2 3] [--duration 600]

For each seed, a simulated 3-beacon network hears an AUV flying an L-shaped
route (220 m north, then 280 m east) for ``--duration`` simulated seconds; the
events are generated first, then fed one by one to a fresh
:class:`~zarco_runtime.tracking.tracker.AuvTracker`, each call timed (wall
time, ``time.perf_counter``; and the process's CPU time,
``time.process_time``, less sensitive to other jobs on a shared machine).
``--runs`` runs per seed; figures are the per-event median, p95 and p99 of
each run, and their medians over the runs.  The tracker runs on the vessel
once per event (a few per second); the JSON line compares the median with a
budget of 200 µs per event.  Most events are cheap (a range kept for the
next fix); the p95 and p99 are the events that update the filter (a few
milliseconds), which is what a burst of stale events costs the loop.

Progress goes to stderr; the last line on stdout is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from drivers.sim.acoustics import AcousticWorld, LblParams  # noqa: E402
from drivers.sim.auv import Auv, AuvParams  # noqa: E402
from zarco_core.auv_messages import AcousticEvent  # noqa: E402
from zarco_runtime.tracking.params import TrackerParams  # noqa: E402
from zarco_runtime.tracking.tracker import AuvTracker  # noqa: E402

EPOCH = 1_780_308_000.0
ROUTE = [[100.0, 100.0], [320.0, 100.0], [320.0, 380.0]]
BUDGET_S = 200e-6


def events(seed: int, duration_s: float) -> tuple[list[AcousticEvent], TrackerParams]:
    """The acoustic events of ``duration_s`` simulated seconds, and the tracker's
    parameters for that network."""
    lp = LblParams()
    world = AcousticWorld(lp, Auv(AuvParams(waypoints=ROUTE)), seed, start_utc_epoch_s=EPOCH)
    out: list[AcousticEvent] = []
    t = 0.0
    while t < duration_s:
        t += 0.5
        out.extend(world.events_exact_until(t))
    return out, TrackerParams(network=lp.network(), auv_depth_m=10.0)


def one_run(evs: list[AcousticEvent], params: TrackerParams) -> dict[str, float]:
    """Per-event figures (µs) of one fresh tracker over ``evs``."""
    tracker = AuvTracker(params)
    wall: list[float] = []
    cpu: list[float] = []
    for ev in evs:
        w0, c0 = time.perf_counter(), time.process_time()
        tracker.process(ev)
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    w, c = np.array(wall) * 1e6, np.array(cpu) * 1e6
    return {"wall_median_us": float(np.median(w)),
            "wall_p95_us": float(np.percentile(w, 95)),
            "wall_p99_us": float(np.percentile(w, 99)),
            "cpu_median_us": float(np.median(c)), "cpu_p95_us": float(np.percentile(c, 95))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--duration", type=float, default=600.0, help="simulated seconds")
    a = ap.parse_args()
    per_seed = {}
    for seed in a.seeds:
        evs, params = events(seed, a.duration)
        runs = []
        for k in range(a.runs):
            r = one_run(evs, params)
            runs.append(r)
            print(f"seed {seed} run {k + 1}/{a.runs}: {len(evs)} events, per event median "
                  f"{r['wall_median_us']:.1f} µs, p95 {r['wall_p95_us']:.1f} µs, p99 "
                  f"{r['wall_p99_us']:.1f} µs (CPU median {r['cpu_median_us']:.1f} µs)",
                  file=sys.stderr, flush=True)
        per_seed[str(seed)] = {"events": len(evs),
                               **{key: round(statistics.median(r[key] for r in runs), 1)
                                  for key in runs[0]}}
    med = statistics.median(s["wall_median_us"] for s in per_seed.values())
    print(json.dumps({"bench": "tracker_event", "runs": a.runs, "seeds": per_seed,
                      "wall_median_us": round(med, 1),
                      "budget_us": BUDGET_S * 1e6,
                      "median_within_budget": med < BUDGET_S * 1e6}))


if __name__ == "__main__":
    main()
