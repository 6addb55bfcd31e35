"""Benchmark: line tracking on the paper's rectangle, and simulation speed.

    python tests/bench/lines.py [--seeds 1 2 3] [--quick]

* cross-track RMS / p95 / corner overshoot at 0.5, 1.0, 1.5 m/s with the
  disturbances of config/scenarios/rectangle.toml, over several seeds
  (reported: mean RMS, worst RMS, worst p95);
* the same with the harsher world (current 0.4 m/s, φ = ±3°, Δf = 10 %);
* speed: the rectangle at 1.0 m/s with every NMEA byte through the drivers
  (median speed-up over the seeds) and one simulated hour (12 laps) timed; then
  side by side with a checkout of ``--base-rev`` (with the EKF, and with its
  default estimator), alternating in this run, and the profile shares;
* determinism: two runs with the same seed give identical reports.

Ends by printing one JSON line of its figures.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from zarco_tools.scenario import load_scenario  # noqa: E402
from zarco_tools.simulation import run_scenario  # noqa: E402

RECT = ROOT / "config" / "scenarios" / "rectangle.toml"
SPEEDS = (0.5, 1.0, 1.5)
HARSH = [
    "world.current.speed_mps=0.4",
    "world.thrusters.phi1_deg=3.0",
    "world.thrusters.phi2_deg=-3.0",
    "world.thrusters.mismatch=0.10",
]
WALL_KEYS = ("wall_seconds", "speedup")
#: the code before the EKF became the default (speed comparison)
BASE_REV = "7cfb0fbf819266b56547384332a0817006a234df"


def run(speed: float, seed: int, extra: list[str] | None = None) -> dict[str, Any]:
    scn = load_scenario(RECT, [f"mission.speed_mps={speed}", *(extra or [])], seed)
    return run_scenario(scn).report


def summarise(reports: list[dict[str, Any]]) -> dict[str, float]:
    rms = [r["xtrack_rms_m"] for r in reports]
    return {
        "xtrack_rms_m": round(statistics.fmean(rms), 4),
        "xtrack_rms_worst_m": round(max(rms), 4),
        "xtrack_p95_m": round(max(r["xtrack_p95_m"] for r in reports), 4),
        "xtrack_max_m": round(max(r["xtrack_max_m"] for r in reports), 4),
        "overshoot_max_m": round(max(r["corner_overshoot_max_m"] for r in reports), 3),
        "saturation_fraction": round(statistics.fmean(r["saturation_fraction"]
                                                      for r in reports), 4),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--quick", action="store_true", help="skip the simulated hour")
    ap.add_argument("--base-rev", default=BASE_REV, help="the code to compare the speed with")
    ap.add_argument("--rounds", type=int, default=3, help="speed runs per checkout")
    args = ap.parse_args()
    out: dict[str, Any] = {"bench": "lines", "seeds": args.seeds}
    speedups: list[float] = []
    print(f"{'case':<22}{'RMS mean':>10}{'RMS worst':>11}{'p95':>8}{'max':>8}{'overshoot':>11}",
          file=sys.stderr)
    for label, extra in (("nominal", []), ("harsh", HARSH)):
        for speed in SPEEDS:
            reports = []
            for seed in args.seeds:
                r = run(speed, seed, extra)
                reports.append(r)
                if label == "nominal" and speed == 1.0:
                    speedups.append(r["speedup"])
            s = summarise(reports)
            key = f"{label}_{speed:.1f}" if label != "nominal" else f"{speed:.1f}"
            out[key] = s
            print(f"{label + ' ' + str(speed) + ' m/s':<22}{s['xtrack_rms_m']:>10.4f}"
                  f"{s['xtrack_rms_worst_m']:>11.4f}{s['xtrack_p95_m']:>8.3f}"
                  f"{s['xtrack_max_m']:>8.3f}{s['overshoot_max_m']:>11.2f}", file=sys.stderr)
    out["speedup"] = round(statistics.median(speedups), 1)
    out["speedup_runs"] = speedups
    # determinism
    a, b = run(1.0, args.seeds[0]), run(1.0, args.seeds[0])
    for k in WALL_KEYS:
        a.pop(k)
        b.pop(k)
    out["deterministic"] = json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    # one simulated hour
    if not args.quick:
        scn = load_scenario(RECT, ["mission.speed_mps=1.0", "mission.laps=12",
                                   "scenario.max_duration_s=3600"], args.seeds[0])
        w = time.perf_counter()
        r = run_scenario(scn).report
        wall = time.perf_counter() - w
        out["sim_hour_wall_s"] = round(wall * 3600.0 / r["sim_seconds"], 1)
        out["sim_hour_xtrack_rms_m"] = round(r["xtrack_rms_m"], 4)
    else:
        out["sim_hour_wall_s"] = round(3600.0 / out["speedup"], 1)
    print(f"speed-up (1.0 m/s, median of {len(speedups)}): {out['speedup']}×; "
          f"one simulated hour: {out['sim_hour_wall_s']} s wall; "
          f"deterministic: {out['deterministic']}", file=sys.stderr)
    out.update(speed_against_base(args.base_rev, args.rounds))
    print(json.dumps(out))


def speed_against_base(rev: str, rounds: int) -> dict[str, Any]:
    """The rectangle at 1.0 m/s with this code (EKF) against a checkout of ``rev``
    with the EKF and with its default estimator, alternating in this run; and where
    this code's time goes (``zarco_tools.sim_profile``)."""
    from zarco_tools.sim_profile import checkout, profile_call, speed_side_by_side

    ov = ["mission.speed_mps=1.0"]
    ekf = ["runtime.navigation.estimator=ekf"]
    with checkout(ROOT, rev) as base:
        sp = speed_side_by_side({"ekf": (ROOT, RECT, ov + ekf), "base_ekf": (base, RECT, ov + ekf),
                                 "base_default": (base, RECT, ov)}, rounds,
                                progress=lambda m: print(m, file=sys.stderr, flush=True))
    _r, shares, n, _w = profile_call(run_scenario, load_scenario(RECT, ov, 1))
    print("profile: " + ", ".join(f"{k} {v:.0%}" for k, v in shares.items()), file=sys.stderr)
    return {"base_rev": rev,
            "speedup_ekf_side_by_side": sp["ekf"]["speedup"],
            "speedup_base_ekf": sp["base_ekf"]["speedup"],
            "speedup_base_default": sp["base_default"]["speedup"],
            "speed_ratio_vs_base_ekf": round(sp["ekf"]["speedup"] / sp["base_ekf"]["speedup"], 3),
            "speed_ratio_vs_base_default": round(sp["ekf"]["speedup"]
                                                 / sp["base_default"]["speedup"], 3),
            "cpu_speed_ratio_vs_base_ekf": round(sp["ekf"]["cpu_speedup"]
                                                 / sp["base_ekf"]["cpu_speedup"], 3),
            "profile_shares": shares, "profile_samples": n}


if __name__ == "__main__":
    main()
