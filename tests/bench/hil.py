"""Benchmark: the runtime in HIL, in real time, with faults on every device.

    python tests/bench/hil.py [--scenario hil/scenarios/rectangle_faults.toml] [--seed 1]
                              [--set KEY=VALUE ...] [--duration S] [--no-faults]
                              [--report FILE.json] [--plot FILE.png]

Default: the paper's rectangle at 1.0 m/s, two laps (about 10.5 minutes of real
time, so the runtime's memory is watched over 10 minutes), with unplugs, noise,
truncated sentences, bad checksums, split writes, silence, a frozen compass and
the GPS fix degrading RTK fixed → float → single → none and back, on the short
legs; the long legs stay clean.

Figures (one JSON line at the end):

* ``jitter_p99_ms``: |period − 50 ms| of the ``$PZTHR`` stream, 99th percentile,
  read at the thruster pty (so it includes the pty and the simulator's own
  scheduling: an upper bound of the control loop's);
* ``latency_p50_ms`` / ``latency_p99_ms``: from the end of writing a GPS epoch to
  its pty to the next ``$PZTHR`` read from the thruster pty (the first command
  the runtime can have computed from it: waiting for the next 20 Hz control tick
  plus parsing, estimation, control, allocation and the write);
* ``cpu_percent``: the runtime process's CPU time over the run / wall time;
* ``rss_start_mb`` / ``rss_end_mb``: its resident memory when the run starts and
  when it ends (``rss_max_mb`` too);
* ``replug_max_s``: the worst time from a device's pty reappearing to the
  runtime's next valid sentence from it (the device's ``ok`` event in its
  status file);
* ``xtrack_rms_m``: cross-track RMS (true position, ≥ 15 m into each leg) over the
  legs that no fault came near (±5 s); ``xtrack_rms_sim_m``: the same legs of
  ``zarco sim`` on the same scenario, seed and faults.

A scenario that follows the AUV (``--scenario hil/scenarios/follow_short.toml``)
gives instead the ASV–AUV distance figures of ``hil/follow.py``, through HIL
(``distance_*_m``) and ``zarco sim`` on the same scenario, seed and faults
(``sim_distance_*_m``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
# the repository first (this file's own directory would make "hil" this script)
sys.path[:] = [str(ROOT)] + [p for p in sys.path if p != str(ROOT)]

from hil.follow import follow_figures  # noqa: E402
from hil.run import pooled_rms, run_hil, summary  # noqa: E402
from hil.scenario import load_hil_scenario  # noqa: E402
from zarco_tools.simulation import run_scenario  # noqa: E402

SCENARIO = ROOT / "hil" / "scenarios" / "rectangle_faults.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default=str(SCENARIO))
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--duration", type=float, default=None, help="real-time limit (s)")
    ap.add_argument("--no-faults", action="store_true")
    ap.add_argument("--run-dir", default=None)
    ap.add_argument("--report", default=None, help="write the full HIL report here")
    ap.add_argument("--plot", default=None, help="write the HIL track plot here")
    args = ap.parse_args()

    scn, faults = load_hil_scenario(args.scenario, args.set, args.seed)
    if args.no_faults:
        faults = []
    res = run_hil(scn, faults, args.run_dir, args.duration, quiet=False)
    rep = res.report
    h = rep["hil"]
    print(summary(rep), file=sys.stderr)

    # zarco sim: same scenario, same seed, same faults (applied in-process)
    sim_scn, _ = load_hil_scenario(args.scenario, args.set, args.seed)
    if args.duration:
        sim_scn.scenario.max_duration_s = min(sim_scn.scenario.max_duration_s, args.duration)
    if args.no_faults:
        sim_scn.faults = []
    sim_res = run_scenario(sim_scn)
    sim = sim_res.report
    t = h["timing"]
    common: dict[str, Any] = {
        "bench": "hil",
        "scenario": rep["scenario"],
        "seed": rep["seed"],
        "stop": rep["stop"],
        "wall_s": rep["wall_seconds"],
        "faults_injected": len(faults),
        "runtime_exit_code": h["runtime"]["exit_code"],
        "runtime_exited_early": h["runtime"]["exited_before_the_end"],
        "runtime_errors": len(h["runtime"]["errors"]),
        "zero_thrust_on_exit": h["zero_thrust_on_exit"],
        "jitter_p99_ms": t.get("runtime_jitter_p99_ms", t["jitter_p99_ms"]),
        "jitter_p99_wire_ms": t["jitter_p99_ms"],
        "latency_p99_ms": t["latency_p99_ms"],
        "cpu_percent": h["cpu_percent"],
        "rss_end_mb": h["rss_end_mb"],
        "replug_max_s": h["replug_max_s"],
        "modes": h["modes"],
        "failsafes": rep["faults"],
    }
    if "xtrack_rms_m" not in rep:  # following the AUV
        sim_f = follow_figures(sim_res.log, sim_res.extra["auv_log"],
                               sim_res.extra["acoustics"].auv)
        keys = ("distance_start_m", "distance_hover_end_m", "distance_leg_median_m",
                "distance_leg_p95_m", "distance_leg_max_m", "distance_final_median_m",
                "distance_max_m", "auv_travel_m", "asv_travel_m")
        out = {**common, "follow_steering_s": h["follow_steering_s"],
               **{k: rep[k] for k in keys}, **{f"sim_{k}": sim_f[k] for k in keys},
               "turns": rep["turns"], "sim_turns": sim_f["turns"],
               "device_states": {d: v.get("states") for d, v in rep["devices"].items()}}
        out["distance_diff_max_m"] = max(
            abs(rep[k] - sim_f[k]) for k in keys[1:7]
            if rep[k] is not None and sim_f[k] is not None)
        print(f"HIL vs zarco sim: distance max {rep['distance_max_m']} vs "
              f"{sim_f['distance_max_m']} m, last 10 s median {rep['distance_final_median_m']}"
              f" vs {sim_f['distance_final_median_m']} m", file=sys.stderr)
        _write(args, res, rep)
        print(json.dumps(out))
        return
    clean = h["legs_without_faults"]
    rms_hil = h["xtrack_rms_without_faults_m"]
    rms_sim = pooled_rms(sim["legs"], clean)
    reads = [r["read_after_s"] for r in h["replugs"]]
    out: dict[str, Any] = {
        **common,
        # the control loop's own period jitter when the runtime reports it
        # (zarco run --status), else the $PZTHR stream's as read at the pty
        "jitter_source": "runtime" if "runtime_jitter_p99_ms" in t else "ports",
        "jitter_max_wire_ms": t["jitter_max_ms"],
        "period_mean_ms": t["period_mean_ms"],
        "latency_p50_ms": t["latency_p50_ms"],
        "rss_start_mb": h["rss_start_mb"],
        "rss_max_mb": h["rss_max_mb"],
        "replugs": len(reads),
        "replug_opened_max_s": max((r["opened_after_s"] or 0.0 for r in h["replugs"]),
                                   default=None),
        "legs_without_faults": clean,
        "xtrack_rms_m": round(rms_hil, 4) if rms_hil is not None else None,
        "xtrack_rms_sim_m": round(rms_sim, 4) if rms_sim is not None else None,
        "xtrack_rms_all_legs_m": round(rep["xtrack_rms_m"], 4),
        "xtrack_rms_all_legs_sim_m": round(sim["xtrack_rms_m"], 4),
        "device_states": {d: v.get("states") for d, v in rep["devices"].items()},
    }
    if rms_hil is not None and rms_sim is not None:
        out["xtrack_rms_diff_m"] = round(rms_hil - rms_sim, 4)
    out["checks"] = {
        "runtime_never_exited": not out["runtime_exited_early"],
        "replug_read_within_1s": out["replug_max_s"] is not None and out["replug_max_s"] <= 1.0,
        "xtrack_within_0_05_of_sim": "xtrack_rms_diff_m" in out
        and abs(out["xtrack_rms_diff_m"]) <= 0.05,
        "jitter_p99_le_2ms": out["jitter_p99_ms"] is not None and out["jitter_p99_ms"] <= 2.0,
        "cpu_le_10pct": h["cpu_percent"] is not None and h["cpu_percent"] <= 10.0,
    }
    _write(args, res, rep)
    print(f"HIL clean legs {clean}: RMS {out['xtrack_rms_m']} m vs zarco sim "
          f"{out['xtrack_rms_sim_m']} m; checks {out['checks']}", file=sys.stderr)
    print(json.dumps(out))


def _write(args: argparse.Namespace, res: Any, rep: dict[str, Any]) -> None:
    if args.report:
        Path(args.report).parent.mkdir(parents=True, exist_ok=True)
        Path(args.report).write_text(json.dumps(rep, indent=2) + "\n")
    if args.plot:
        from zarco_tools.plot import plot_follow, plot_lines

        Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
        title = f"{rep['scenario']} (HIL): seed {rep['seed']}"
        if "xtrack_rms_m" in rep:
            plot_lines(args.plot, res.log, res.legs, title)
        else:
            plot_follow(args.plot, res.log, {"auv_log": res.auv_log, "auv_msgs": []}, title)


if __name__ == "__main__":
    main()
