"""Failsafe benchmark: every row of the failsafe table provoked in simulation by a
scripted fault, over several seeds; the time from each condition to its action
(and to zero thrust at the thruster controller for the ``idle`` actions).

    python tests/bench/failsafes.py [--seeds 1 2 3]

One line per run on stderr, one JSON line at the end: per failsafe the worst
and median condition → action time, the configured time, and whether every
run took the right action.  Targets: heading lost and thruster controller
silent → idle within 1 s.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any


def one(job: tuple[int, int]) -> dict[str, Any]:
    from zarco_tools.failsafe_cases import CASES, measure

    i, seed = job
    return {"case": i, **measure(CASES[i], seed)}


def main() -> int:
    from zarco_tools.failsafe_cases import CASES

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    jobs = [(i, s) for i in range(len(CASES)) for s in args.seeds]
    runs: list[dict[str, Any]] = []
    w0 = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as ex:
        for k, r in enumerate(ex.map(one, jobs), 1):
            runs.append(r)
            print(f"[{k}/{len(jobs)} {time.perf_counter() - w0:4.0f} s] {r['failsafe']:17s} "
                  f"seed {r['seed']}: condition → {r['action']} in "
                  f"{r['condition_to_action_s']} s ({r['note']})", file=sys.stderr, flush=True)
    table: dict[str, Any] = {}
    for i, c in enumerate(CASES):
        rs = [r for r in runs if r["case"] == i]
        ts = [r["condition_to_action_s"] for r in rs if r["condition_to_action_s"] is not None]
        zs = [r["condition_to_zero_thrust_s"] for r in rs
              if r["condition_to_zero_thrust_s"] is not None]
        table[f"{c.name}: {c.note}"] = {
            "action": c.expect, "configured_s": rs[0]["configured_delay_s"],
            "condition_to_action_median_s": statistics.median(ts) if ts else None,
            "condition_to_action_max_s": max(ts) if ts else None,
            "condition_to_zero_thrust_max_s": max(zs) if zs else None,
            "all_ok": all(r["ok"] for r in rs), "runs": len(rs)}
    fast = [r for r in runs if r["failsafe"] in ("heading_lost", "thruster_silent")]
    print(json.dumps({
        "bench": "failsafes", "seeds": args.seeds,
        "heading_and_thruster_to_idle_max_s": max(r["condition_to_action_s"] or 99.0
                                                  for r in fast),
        "target_1s_met": all((r["condition_to_action_s"] or 99.0) <= 1.0 for r in fast),
        "all_ok": all(r["ok"] for r in runs),
        "failsafes": table}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
