"""``zarco log replay`` benchmark: speed and exactness on recorded simulations.

For each scenario and seed, the simulation is recorded once (``--record``),
then replayed ``--runs`` times; the best run counts (the machine is shared).

* ``speed_x_realtime``: recorded seconds / wall seconds of the whole replay
  (reading the file, building the runtime, playing), median over the
  recordings, and its minimum;
* ``run_x_realtime``: the same without the reading;
* ``exact``: recordings whose NavState, AuvFix, AuvTrack and thruster commands
  all came back identical, out of all.

Progress on stderr; one JSON line on stdout.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from zarco_tools.log.reader import open_recording  # noqa: E402
from zarco_tools.log.replay import replay, report  # noqa: E402
from zarco_tools.scenario import load_scenario  # noqa: E402
from zarco_tools.simulation import run_scenario  # noqa: E402

SCENARIOS = {"rectangle": 120.0, "follow_turn": 150.0, "follow_survey": 200.0}


def say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--runs", type=int, default=3, help="replays per recording (best)")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name in args.scenarios.split(","):
            for seed in range(1, args.seeds + 1):
                path = Path(d) / f"{name}-{seed}.mcap"
                scn = load_scenario(ROOT / "config" / "scenarios" / f"{name}.toml",
                                    [f"scenario.max_duration_s={SCENARIOS[name]}",
                                     f"scenario.seed={seed}"])
                run_scenario(scn, record=str(path))
                best = None
                for _ in range(args.runs):
                    r = report(replay(open_recording(str(path))))
                    if best is None or r["wall_seconds"] < best["wall_seconds"]:
                        best = r
                assert best is not None
                exact = all(best[k]["exact"] for k in ("nav", "auv_fix", "auv_track",
                                                         "thruster_commands"))
                run_x = best["sim_seconds"] / (best["wall_seconds"] - best["read_seconds"])
                rows.append({"scenario": name, "seed": seed, "exact": exact,
                             "speed_x_realtime": best["speed_x_realtime"],
                             "run_x_realtime": round(run_x, 1),
                             "read_seconds": best["read_seconds"],
                             "sim_seconds": best["sim_seconds"]})
                say(f"{name} seed {seed}: {best['speed_x_realtime']:.0f}× real time "
                    f"({run_x:.0f}× without reading), exact: {exact}")
    speeds = [r["speed_x_realtime"] for r in rows]
    runs = [r["run_x_realtime"] for r in rows]
    print(json.dumps({
        "recordings": len(rows), "exact": sum(r["exact"] for r in rows),
        "speed_x_realtime_median": round(statistics.median(speeds), 1),
        "speed_x_realtime_min": round(min(speeds), 1),
        "run_x_realtime_median": round(statistics.median(runs), 1),
        "rows": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
