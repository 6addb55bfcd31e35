"""Benchmark: the navigation EKF in the whole runtime, against the simulator's truth,
and its cost, side by side with the code before this work.

    python tests/bench/navigation.py [--seeds 1 2 3] [--quick] [--base-rev REV]
                                      [--rounds 3]

* **speed**: the rectangle (1 m/s) and the follow survey with the EKF, against a
  checkout of ``--base-rev`` (a temporary git worktree) with the EKF and with its
  default estimator, alternating in one run (``rounds`` each); wall-clock speed-up
  (simulated / wall seconds) and the CPU-time one (less sensitive to other work
  on the machine), medians, and their ratios;
* **profile**: shares of the rectangle's CPU time (``zarco_tools.sim_profile``):
  NMEA byte path, EKF, NavState publication, asyncio, the simulator, control;
* **heading**: the rectangle with a current across the first leg (0.2 and
  0.35 m/s), thrusters misaligned ±3° and mismatched by 10 %, at 0.5, 1.0 and
  1.5 m/s, per case the heading RMS against the truth over the whole run and over
  the first leg (mean and worst over the seeds), the NEES of (x, y, vn, ve, ψ)
  (5 when honest) and the cross-track RMS; then the same at 0.35 m/s with plants
  the runtime's model does not match (``PLANTS``: hull ±25 %, thrust ±15 %,
  thrust lag 0.1–0.3 s);
* **lines**: cross-track RMS / p95 / max at the three speeds (the rectangle as
  it ships, and the harsher world of tests/bench/lines.py), this code against
  the base code's default estimator on the same seeds;
* **filter**: the estimator figures of ``zarco_tools.ekf_eval`` (RTK fixed /
  float position, outage, fix jump, update cost);
* **captures**: what ``zarco navreport`` gives on GPSD's real captures.

Progress on stderr; ends by printing one JSON line of its figures.
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

from zarco_tools.capture_report import capture_report  # noqa: E402
from zarco_tools.ekf_eval import figures  # noqa: E402
from zarco_tools.scenario import load_scenario  # noqa: E402
from zarco_tools.sim_profile import (  # noqa: E402
    checkout,
    profile_call,
    run_report,
    speed_side_by_side,
)
from zarco_tools.simulation import run_scenario  # noqa: E402

RECT = ROOT / "config" / "scenarios" / "rectangle.toml"
SURVEY = ROOT / "config" / "scenarios" / "follow_survey.toml"
LOGS = ROOT / "tests" / "data" / "gpsd-logs"
#: the code before the EKF became the default, with the thrusters as its input
BASE_REV = "7cfb0fbf819266b56547384332a0817006a234df"
SPEEDS = (0.5, 1.0, 1.5)
CURRENTS = (0.2, 0.35)
THRUSTERS = ["world.thrusters.phi1_deg=3.0", "world.thrusters.phi2_deg=-3.0",
             "world.thrusters.mismatch=0.1"]
#: plants the runtime's model (config/zarco.toml's [vessel], [thrusters]) does not match
PLANTS = {
    "heavy_weak_slow": ["world.vessel.m_kg=56.0", "world.vessel.iz_kgm2=11.0",
                        "world.vessel.x_u=-31.0", "world.vessel.x_uu=-100.0",
                        "world.vessel.y_v=-90.0", "world.vessel.n_r=-30.0",
                        "world.thrusters.fwd_max_n=106.0", "world.thrusters.rev_max_n=64.0",
                        "world.thrusters.lag_s=0.3"],
    "light_strong_quick": ["world.vessel.m_kg=36.0", "world.vessel.iz_kgm2=7.0",
                           "world.vessel.x_u=-19.0", "world.vessel.x_uu=-62.0",
                           "world.vessel.y_v=-140.0", "world.vessel.n_r=-18.0",
                           "world.thrusters.fwd_max_n=144.0", "world.thrusters.rev_max_n=86.0",
                           "world.thrusters.lag_s=0.1"],
}
#: the harsher world of tests/bench/lines.py
HARSH = ["world.current.speed_mps=0.4", "world.thrusters.phi1_deg=3.0",
         "world.thrusters.phi2_deg=-3.0", "world.thrusters.mismatch=0.10"]


def say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def heading_case(label: str, overrides: list[str], seeds: list[int]) -> dict[str, float]:
    reps = [run_scenario(load_scenario(RECT, overrides, s)).report for s in seeds]
    h = [r["nav_heading_rms_deg"] for r in reps]
    h1 = [r["nav_heading_first_leg_rms_deg"] for r in reps]
    out = {
        "heading_rms_deg": round(statistics.fmean(h), 3),
        "heading_rms_worst_deg": round(max(h), 3),
        "heading_first_leg_rms_deg": round(statistics.fmean(h1), 3),
        "heading_first_leg_rms_worst_deg": round(max(h1), 3),
        "nees_mean": round(statistics.fmean(r["nav_nees_mean"] for r in reps), 2),
        "nees_above_99": round(statistics.fmean(r["nav_nees_above_99"] for r in reps), 3),
        "xtrack_rms_m": round(statistics.fmean(r["xtrack_rms_m"] for r in reps), 4),
    }
    say(f"  {label:<34}{out['heading_rms_deg']:>7.2f}{out['heading_rms_worst_deg']:>7.2f}"
        f"{out['heading_first_leg_rms_deg']:>8.2f}{out['heading_first_leg_rms_worst_deg']:>7.2f}"
        f"{out['nees_mean']:>7.1f}{out['xtrack_rms_m']:>8.4f}")
    return out


def line_figures(reps: list[dict[str, Any]]) -> dict[str, float]:
    return {"xtrack_rms_m": round(statistics.fmean(r["xtrack_rms_m"] for r in reps), 4),
            "xtrack_p95_m": round(max(r["xtrack_p95_m"] for r in reps), 4),
            "xtrack_max_m": round(max(r["xtrack_max_m"] for r in reps), 4)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--quick", action="store_true", help="fewer filter figures, no survey")
    ap.add_argument("--base-rev", default=BASE_REV, help="the code to compare with")
    ap.add_argument("--rounds", type=int, default=3, help="speed runs per checkout")
    args = ap.parse_args()
    seeds = args.seeds
    out: dict[str, Any] = {"bench": "navigation", "seeds": seeds, "base_rev": args.base_rev}
    w0 = time.perf_counter()
    with checkout(ROOT, args.base_rev) as base:
        # ------------------------------------------------------------ speed
        say(f"speed, side by side with {args.base_rev[:10]} ({args.rounds} rounds)")
        ekf = ["runtime.navigation.estimator=ekf"]
        cases = {"rectangle": (RECT, ["mission.speed_mps=1.0"])}
        if not args.quick:
            cases["follow_survey"] = (SURVEY, [])
        for case, (scn, ov) in cases.items():
            say(f" {case}")
            sp = speed_side_by_side({"ekf": (ROOT, scn, ov + ekf),
                                     "base_ekf": (base, scn, ov + ekf),
                                     "base_default": (base, scn, ov)}, args.rounds,
                                    progress=say)
            for k, v in sp.items():
                out[f"speed_{case}_{k}"] = v["speedup"]
                out[f"speed_{case}_{k}_runs"] = v["speedup_runs"]
                out[f"cpu_speed_{case}_{k}"] = v["cpu_speedup"]
            for b in ("base_ekf", "base_default"):
                out[f"speed_{case}_ratio_vs_{b}"] = round(
                    sp["ekf"]["speedup"] / sp[b]["speedup"], 3)
                out[f"cpu_speed_{case}_ratio_vs_{b}"] = round(
                    sp["ekf"]["cpu_speedup"] / sp[b]["cpu_speedup"], 3)
        # ---------------------------------------------------------- profile
        scn = load_scenario(RECT, ["mission.speed_mps=1.0"], seeds[0])
        _r, shares, n, _wall = profile_call(run_scenario, scn)
        out["profile_shares"] = shares
        out["profile_samples"] = n
        say(f"profile ({n} samples): " + ", ".join(f"{k} {v:.0%}" for k, v in shares.items()))
        # ---------------------------------------------------------- heading
        say(f"heading (seeds {seeds})           RMS  worst   first  worst   NEES  xtrack")
        heading: dict[str, Any] = {}
        for cur in CURRENTS:
            for v in SPEEDS:
                key = f"current{cur:.2f}_speed{v:.1f}"
                heading[key] = heading_case(key, [f"mission.speed_mps={v}",
                                                  f"world.current.speed_mps={cur}",
                                                  *THRUSTERS], seeds)
        for plant, ov in PLANTS.items():
            for v in SPEEDS:
                key = f"{plant}_current0.35_speed{v:.1f}"
                heading[key] = heading_case(key, [f"mission.speed_mps={v}",
                                                  "world.current.speed_mps=0.35",
                                                  *THRUSTERS, *ov], seeds)
        out["heading"] = heading
        grid = [heading[f"current{c:.2f}_speed{v:.1f}"] for c in CURRENTS for v in SPEEDS]
        out["heading_rms_deg_mean"] = round(statistics.fmean(g["heading_rms_deg"]
                                                             for g in grid), 3)
        out["heading_rms_deg_worst"] = max(g["heading_rms_worst_deg"] for g in grid)
        out["heading_first_leg_rms_deg_mean"] = round(statistics.fmean(
            g["heading_first_leg_rms_deg"] for g in grid), 3)
        out["heading_first_leg_rms_deg_worst"] = max(g["heading_first_leg_rms_worst_deg"]
                                                     for g in grid)
        out["nees_mean"] = round(statistics.fmean(g["nees_mean"] for g in grid), 2)
        # ------------------------------------------------------------ lines
        say("lines: cross-track RMS / p95 / max, this code (EKF) and the base's default")
        lines: dict[str, Any] = {}
        for world, extra in (("nominal", []), ("harsh", HARSH)):
            for v in SPEEDS:
                ov = [f"mission.speed_mps={v}", *extra]
                new = [run_scenario(load_scenario(RECT, ov, s)).report for s in seeds]
                old = [run_report(base, RECT, ov, s) for s in seeds]
                key = f"{world}_{v:.1f}"
                lines[key] = {"ekf": line_figures(new), "base_default": line_figures(old)}
                a, b = lines[key]["ekf"], lines[key]["base_default"]
                say(f"  {key:<12} {a['xtrack_rms_m']:.4f} / {a['xtrack_p95_m']:.3f} / "
                    f"{a['xtrack_max_m']:.3f}   base {b['xtrack_rms_m']:.4f} / "
                    f"{b['xtrack_p95_m']:.3f} / {b['xtrack_max_m']:.3f}")
        out["lines"] = lines
    # ------------------------------------------------------------ filter
    say("filter figures (zarco_tools.ekf_eval)")
    out["filter"] = figures(seeds, quick=True)
    # ---------------------------------------------------------- captures
    caps: dict[str, Any] = {}
    for log in sorted(LOGS.glob("*.log")):
        rep = capture_report(log)
        est = rep["estimate"]
        caps[log.stem] = {"ekf_errors": rep["errors"], "refused": rep["refused"]["total"],
                          "fixes_fused": rep["fixes_fused"],
                          "heading_deg": est["heading_deg"],
                          "heading_sigma_deg": est["heading_sigma_deg"],
                          "not_estimated": sorted(est["not_estimated"])}
    out["captures"] = caps
    out["bench_wall_s"] = round(time.perf_counter() - w0, 1)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
