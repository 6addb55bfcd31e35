"""Benchmark: following the AUV from the buoy's acoustic feed (the shipped scenarios).

    python tests/bench/follow.py [--seeds 1 2 3]

Runs config/scenarios/follow_turn.toml and follow_survey.toml over several
seeds with the scenario's detection statistics (0.5 ms jitter, 10 % missed,
2 % false), then both again with 20 % missed and 5 % false detections, and
times the tracker per acoustic event on a recorded event stream.  Ends by
printing one JSON line of its figures.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from drivers.sim.acoustics import AcousticWorld  # noqa: E402
from drivers.sim.auv import Auv  # noqa: E402
from zarco_runtime.tracking.tracker import AuvTracker  # noqa: E402
from zarco_tools.scenario import load_scenario  # noqa: E402
from zarco_tools.simulation import run_scenario  # noqa: E402

SCN = ROOT / "config" / "scenarios"
HARSH = ["lbl.p_miss=0.20", "lbl.p_false=0.05"]


def fin(v: float | None) -> float | None:
    return round(v, 3) if isinstance(v, float) and math.isfinite(v) else None


def _vals(reports: list[dict[str, Any]], key: str) -> list[float]:
    return [r[key] for r in reports if r.get(key) is not None]


def summarise(reports: list[dict[str, Any]]) -> dict[str, Any]:
    turns = [t for r in reports for t in r["turns"]]
    rec = [t["recovery_s"] for t in turns if t["recovery_s"] is not None]
    det = [t["detect_s"] for t in turns if t["detect_s"] is not None]

    def agg(key: str, fn: Any) -> float | None:
        v = _vals(reports, key)
        return fin(float(fn(v))) if v else None

    return {
        "fix_interval_s": agg("fix_interval_s", statistics.median),
        "fix_error_rms_m": agg("fix_error_rms_m", statistics.fmean),
        "track_error_rms_m": agg("track_error_rms_m", statistics.fmean),
        "course_error_rms_deg": agg("course_error_rms_deg", max),
        "distance_median_m": agg("distance_median_m", max),
        "distance_p95_m": agg("distance_p95_m", max),
        "distance_max_m": agg("distance_max_m", max),
        "turns": len(turns),
        "detect_s_max": fin(max(det)) if det else None,
        "recovery_s_max": fin(max(rec)) if rec else None,
        "recovery_unrecovered": len(turns) - len(rec),
        "lost_max_s": agg("lost_max_s", max),
        "track_lost_events": sum(r["track_lost_events"] for r in reports),
    }


def event_timing(seed: int) -> dict[str, float]:
    scn = load_scenario(SCN / "follow_survey.toml", seed=seed)
    assert scn.auv is not None and scn.lbl is not None
    world = AcousticWorld(scn.lbl, Auv(scn.auv), seed, 1_780_308_000.0)
    events = world.events_exact_until(1200.0)
    tracker = AuvTracker(scn.runtime.tracker)
    per: list[float] = []
    clock = time.perf_counter_ns
    for ev in events:
        t0 = clock()
        tracker.process(ev)
        per.append((clock() - t0) / 1000.0)
    per.sort()
    return {"events": len(per), "event_median_us": round(per[len(per) // 2], 1),
            "event_p99_us": round(per[int(0.99 * len(per))], 1)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    args = ap.parse_args()
    out: dict[str, Any] = {"bench": "follow", "seeds": args.seeds}
    for name in ("follow_turn", "follow_survey"):
        for label, extra in (("", []), ("_harsh", HARSH)):
            reps = []
            for seed in args.seeds:
                r = run_scenario(load_scenario(SCN / f"{name}.toml", extra, seed)).report
                reps.append(r)
            s = summarise(reps)
            out[name + label] = s
            print(f"{name + label:<22} {json.dumps(s)}", file=sys.stderr)
    out.update(event_timing(args.seeds[0]))
    print(json.dumps(out, allow_nan=False))


if __name__ == "__main__":
    main()
