"""Benchmark: the navigation EKF (issue #5) against the simulator's truth.

    python tests/bench/navigation.py [--seeds 1 2 3] [--quick]

Estimator figures come from ``zarco_tools.ekf_eval`` (the
simulated world's NMEA bytes through the real parsers into the EKF, with a
line-of-sight pilot); line holding is measured with the whole runtime on the
rectangle at 1 m/s (current 0.2 m/s, compass bias 1°, thruster misalignment),
EKF and first estimate side by side on the same seeds, each with its own
default cross-track-rate low-pass (settings.XTRACK_RATE_TAU_S), with the
runtime's navigation error against the truth (``lines_nav_*``).
Ends by printing one JSON line of its figures.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from zarco_tools.capture_report import capture_report  # noqa: E402
from zarco_tools.ekf_eval import figures  # noqa: E402
from zarco_tools.scenario import load_scenario  # noqa: E402
from zarco_tools.simulation import run_scenario  # noqa: E402

RECT = ROOT / "config" / "scenarios" / "rectangle.toml"
LOGS = ROOT / "tests" / "data" / "gpsd-logs"


def lines(estimator: str, seeds: list[int]) -> dict[str, float]:
    reps = [run_scenario(load_scenario(RECT, ["mission.speed_mps=1.0",
                                              f"runtime.navigation.estimator={estimator}"],
                                       s)).report for s in seeds]
    return {"xtrack_rms_m": round(statistics.fmean(r["xtrack_rms_m"] for r in reps), 4),
            "nav_heading_rms_deg": round(statistics.fmean(r["nav_heading_rms_deg"]
                                                          for r in reps), 3),
            "nav_position_rms_m": round(statistics.fmean(r["nav_position_rms_m"]
                                                          for r in reps), 4),
            "command_step_rms": round(statistics.fmean(r["command_step_rms"] for r in reps), 2),
            "speedup": round(statistics.median(r["speedup"] for r in reps), 1)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    out = figures(args.seeds, quick=args.quick)
    ekf, simple = lines("ekf", args.seeds), lines("simple", args.seeds)
    out["lines_xtrack_rms_m"] = ekf["xtrack_rms_m"]
    out["lines_xtrack_rms_simple_m"] = simple["xtrack_rms_m"]
    out["lines_command_step_rms"] = ekf["command_step_rms"]
    out["lines_speedup_ekf"] = ekf["speedup"]
    out["lines_speedup_simple"] = simple["speedup"]
    for k in ("nav_heading_rms_deg", "nav_position_rms_m"):
        out[f"lines_{k}"] = ekf[k]
        out[f"lines_{k}_simple"] = simple[k]
    # the real captures with position and/or heading (GPSD's regression logs)
    for name in ("hemi.log", "pypilot.log"):
        rep = capture_report(LOGS / name)
        est = rep["estimate"]
        key = name.removesuffix(".log")
        out[f"real_{key}_ekf_errors"] = rep["errors"]
        out[f"real_{key}_refused"] = rep["refused"]["total"]
        out[f"real_{key}_fixes_fused"] = rep["fixes_fused"]
        out[f"real_{key}_heading_deg"] = est["heading_deg"]
        out[f"real_{key}_heading_sigma_deg"] = est["heading_sigma_deg"]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
