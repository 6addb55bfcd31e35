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
* determinism: two runs with the same seed give identical reports;
* the plant-mismatch grid (``--grid-only`` runs only it, ``--no-grid`` skips it):
  line tracking against a simulated boat that is not the runtime's model.

The plant-mismatch grid
-----------------------
The runtime keeps its nominal vessel model and thruster tables; the simulated
boat differs in eight factors, each at both ends of its range:

==========  =============================================  ==================
factor      −1                                             +1
==========  =============================================  ==================
mass        m, X_u', Y_v' × 0.75                           × 1.25
inertia     Iz, N_r' × 0.75                                × 1.25
damping     all six damping coefficients × 1.25            × 0.75
thrust      thrust curve (forward and reverse) × 1.15      × 0.85
lag         thruster lag 0.1 s                             0.3 s
phi1        port thruster misalignment −3°                 +3°
phi2        starboard thruster misalignment −3°            +3°
mismatch    Δf −10 %                                       +10 %
==========  =============================================  ==================

(+1 is the harder side where there is one.)  The 16 plants are the 2^(8−4)
resolution-IV fractional factorial (:func:`plant_rows`): every factor at each
end in 8 of them, no main effect aliased with a two-factor interaction, and the
all-harder and all-easier corners among them.  Each plant runs the rectangle
at 0.5, 1.0 and 1.5 m/s with a 0.35 m/s current flowing towards 0° and towards
45°: on the rectangle's four legs (N, W, S, E) that puts the current at every
45° to the leg, behind, ahead, across and quartering.  The runtime uses its
navigation EKF; the rectangle's gusts and sensor noise are on.  96 cases,
each on every grid seed (default: ``--seeds``).

Per case: whole-run cross-track RMS and p95 (on the truth, from 15 m into each
leg), the worst leg's RMS, thruster command steps, saturation, the EKF's heading
error and, for the leg the current runs along, the largest line of its
cross-track spectrum between 5 and 50 s periods with the RMS of the leg's
first and last thirds (a sustained oscillation shows as a strong line that
does not shrink).  Targets: RMS ≤ 0.06 m and p95 ≤ 0.12 m on every case.

Progress on stderr; ends by printing one JSON line of its figures (the grid
under ``"grid"``: per-case figures, the worst case, the following-current legs).
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


# ---------------------------------------------------------------- mismatch grid
# (line tracking against a plant that is not the controller's model; kept apart
# from the nominal figures above)

#: the runtime's nominal hull (zarco_core.vessel / drivers.sim.params defaults)
HULL_MASS = {"m_kg": 45.0, "x_udot": -4.5, "y_vdot": -67.5}
HULL_INERTIA = {"iz_kgm2": 9.0, "n_rdot": -15.3}
HULL_DAMPING = {"x_u": -25.0, "x_uu": -82.0, "y_v": -112.5, "y_vv": -150.0, "n_r": -24.3,
                "n_rr": -250.0}
THRUST_MAX = {"fwd_max_n": 125.0, "rev_max_n": 75.0}
#: factor → (override at level −1, override at level +1); "+" is the harder side
#: where there is one (heavier, less damped, weaker, slower thrusters)
FACTORS: dict[str, tuple[list[str], list[str]]] = {
    "mass": ([f"world.vessel.{k}={v * 0.75}" for k, v in HULL_MASS.items()],
             [f"world.vessel.{k}={v * 1.25}" for k, v in HULL_MASS.items()]),
    "inertia": ([f"world.vessel.{k}={v * 0.75}" for k, v in HULL_INERTIA.items()],
                [f"world.vessel.{k}={v * 1.25}" for k, v in HULL_INERTIA.items()]),
    "damping": ([f"world.vessel.{k}={v * 1.25}" for k, v in HULL_DAMPING.items()],
                [f"world.vessel.{k}={v * 0.75}" for k, v in HULL_DAMPING.items()]),
    "thrust": ([f"world.thrusters.{k}={v * 1.15}" for k, v in THRUST_MAX.items()],
               [f"world.thrusters.{k}={v * 0.85}" for k, v in THRUST_MAX.items()]),
    "lag": (["world.thrusters.lag_s=0.1"], ["world.thrusters.lag_s=0.3"]),
    "phi1": (["world.thrusters.phi1_deg=-3.0"], ["world.thrusters.phi1_deg=3.0"]),
    "phi2": (["world.thrusters.phi2_deg=-3.0"], ["world.thrusters.phi2_deg=3.0"]),
    "mismatch": (["world.thrusters.mismatch=-0.1"], ["world.thrusters.mismatch=0.1"]),
}


def plant_rows() -> list[dict[str, int]]:
    """The 2^(8−4) resolution-IV fractional factorial over FACTORS: the first four
    factors take all 16 sign combinations, the others are generated as
    lag = mass·inertia·damping, φ1 = mass·inertia·thrust, φ2 = mass·damping·thrust,
    Δf = inertia·damping·thrust.  Every factor is at each extreme in 8 rows, no main
    effect is aliased with a two-factor interaction, and the all-harder and
    all-easier corners are rows."""
    rows = []
    for i in range(16):
        a, b, c, d = ((1 if i >> k & 1 else -1) for k in (3, 2, 1, 0))
        rows.append({"mass": a, "inertia": b, "damping": c, "thrust": d, "lag": a * b * c,
                     "phi1": a * b * d, "phi2": a * c * d, "mismatch": b * c * d})
    return rows


def row_overrides(row: dict[str, int]) -> list[str]:
    return [o for f, lv in row.items() for o in FACTORS[f][lv > 0]]


def row_label(row: dict[str, int]) -> str:
    return "".join("+" if row[f] > 0 else "-" for f in FACTORS)


#: every case runs on the vessel's estimator, with a 0.35 m/s current in two
#: directions: on the rectangle's four legs (N, W, S, E) these put the current at
#: 0/90/180/270° and 45/135/225/315° to the leg, i.e. every 45°
GRID_CURRENT_MPS = 0.35
GRID_CURRENT_DIRS = (0.0, 45.0)
GRID_BASE = ["runtime.navigation.estimator=ekf",
             f"world.current.speed_mps={GRID_CURRENT_MPS}"]
RMS_TARGET_M = 0.06
P95_TARGET_M = 0.12


def grid_cases(speeds: tuple[float, ...] = SPEEDS,
               dirs: tuple[float, ...] = GRID_CURRENT_DIRS) -> list[dict[str, Any]]:
    cases = []
    for k, row in enumerate(plant_rows()):
        for cdir in dirs:
            for speed in speeds:
                cases.append({"plant": k, "signs": row_label(row), "current_dir_deg": cdir,
                              "speed_mps": speed,
                              "overrides": [*GRID_BASE, f"world.current.direction_deg={cdir}",
                                            *row_overrides(row)]})
    return cases


def oscillation(d: Any, rate_hz: float) -> dict[str, float]:
    """Is there a sustained oscillation in the cross-track series ``d`` (m, sampled
    at ``rate_hz``)?  The largest line of its amplitude spectrum between periods
    of 5 and 50 s (Hann window, mean removed: the amplitude (m) a sinusoid of that
    period would have), and the RMS over its first and last thirds (an oscillation
    that dies out has a smaller last third; a growing or sustained one not)."""
    import numpy as np

    x = np.asarray(d, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < 10 * rate_hz:
        return {"peak_amplitude_m": math.nan, "peak_period_s": math.nan,
                "rms_first_third_m": math.nan, "rms_last_third_m": math.nan}
    w = np.hanning(x.size)
    spec = np.abs(np.fft.rfft((x - x.mean()) * w)) * 2.0 / w.sum()
    f = np.fft.rfftfreq(x.size, 1.0 / rate_hz)
    band = (f >= 1.0 / 50.0) & (f <= 1.0 / 5.0)
    i = int(np.argmax(np.where(band, spec, -1.0)))
    n3 = x.size // 3
    return {"peak_amplitude_m": round(float(spec[i]), 4),
            "peak_period_s": round(float(1.0 / f[i]), 1),
            "rms_first_third_m": round(float(np.sqrt(np.mean(x[:n3] ** 2))), 4),
            "rms_last_third_m": round(float(np.sqrt(np.mean(x[-n3:] ** 2))), 4)}


def following_leg(c: dict[str, Any], res: Any) -> dict[str, Any] | None:
    """Figures of the leg the current runs along (within 10°), if the case has one:
    its settled cross-track RMS and :func:`oscillation`."""
    import numpy as np

    from zarco_tools.sim_report import SETTLE_M, xtrack_series

    along, d, leg_idx = xtrack_series(res.log, res.legs)
    for leg in res.legs:
        rel = math.remainder(math.radians(c["current_dir_deg"]) - leg.course_rad, math.tau)
        if abs(rel) > math.radians(10.0):
            continue
        sel = (leg_idx == leg.index) & (along >= SETTLE_M)
        dd = d[sel]
        return {"leg": leg.index, "rms_m": round(float(np.sqrt(np.mean(dd**2))), 4),
                **oscillation(dd, res.scenario.scenario.record_hz)}
    return None


def run_grid(seeds: list[int], speeds: tuple[float, ...] = SPEEDS,
             dirs: tuple[float, ...] = GRID_CURRENT_DIRS,
             plants: list[int] | None = None) -> dict[str, Any]:
    """Every grid case on every seed; per case the figures and whether it meets the
    targets, and the worst case."""
    cases = [c for c in grid_cases(speeds, dirs) if plants is None or c["plant"] in plants]
    n = len(cases) * len(seeds)
    print(f"mismatch grid: {len(cases)} cases × {len(seeds)} seeds = {n} runs "
          f"(factors {' '.join(FACTORS)})", file=sys.stderr)
    out = []
    i = 0
    w0 = time.perf_counter()
    for seed in seeds:
        for c in cases:
            i += 1
            scn = load_scenario(RECT, [f"mission.speed_mps={c['speed_mps']}", *c["overrides"]],
                                seed)
            res = run_scenario(scn)
            r = res.report
            fig = {"plant": c["plant"], "signs": c["signs"],
                   "current_dir_deg": c["current_dir_deg"], "speed_mps": c["speed_mps"],
                   "seed": seed,
                   "rms_m": round(r["xtrack_rms_m"], 4), "p95_m": round(r["xtrack_p95_m"], 4),
                   "max_m": round(r["xtrack_max_m"], 3),
                   "leg_rms_max_m": round(max(g["xtrack_rms_m"] for g in r["legs"]), 4),
                   "command_step_rms": r["command_step_rms"],
                   "saturation_fraction": round(r["saturation_fraction"], 3),
                   "nav_heading_rms_deg": round(r["nav_heading_rms_deg"], 2),
                   "stop": r["stop"]}
            fol = following_leg(c, res)
            if fol is not None:
                fig["following_leg"] = fol
            fig["ok"] = bool(fig["rms_m"] <= RMS_TARGET_M and fig["p95_m"] <= P95_TARGET_M
                             and r["stop"] == "mission complete")
            out.append(fig)
            tail = (f" | following leg RMS {fol['rms_m']:.3f}, peak "
                    f"{fol['peak_amplitude_m']:.3f} m at {fol['peak_period_s']:.0f} s"
                    if fol else "")
            print(f"[{i}/{n} {time.perf_counter() - w0:6.0f} s] plant {c['plant']:2d} "
                  f"{c['signs']} cur {c['current_dir_deg']:3.0f}° {c['speed_mps']:.1f} m/s "
                  f"seed {seed}: RMS {fig['rms_m']:.4f} p95 {fig['p95_m']:.3f} "
                  f"max {fig['max_m']:.3f} steps {fig['command_step_rms']:.1f}{tail}"
                  f"{'' if fig['ok'] else '  FAIL'}", file=sys.stderr)
    worst = max(out, key=lambda f: max(f["rms_m"] / RMS_TARGET_M, f["p95_m"] / P95_TARGET_M))
    return {"factors": list(FACTORS), "current_mps": GRID_CURRENT_MPS,
            "current_dirs_deg": list(dirs), "speeds_mps": list(speeds), "seeds": seeds,
            "runs": n, "passed": sum(f["ok"] for f in out),
            "rms_max_m": max(f["rms_m"] for f in out), "p95_max_m": max(f["p95_m"] for f in out),
            "command_step_rms_max": max(f["command_step_rms"] for f in out),
            "worst": worst, "following_legs": following_summary(out), "cases": out}


def following_summary(out: list[dict[str, Any]]) -> dict[str, Any]:
    """The legs with the current running along them, per speed: the worst RMS and
    the largest oscillation line (amplitude, period) with its case."""
    res: dict[str, Any] = {}
    for speed in sorted({f["speed_mps"] for f in out}):
        fl = [f for f in out if f["speed_mps"] == speed and "following_leg" in f]
        if not fl:
            continue
        peak = max(fl, key=lambda f: f["following_leg"]["peak_amplitude_m"])
        res[f"{speed:.1f}"] = {
            "legs": len(fl),
            "rms_max_m": max(f["following_leg"]["rms_m"] for f in fl),
            "peak_amplitude_max_m": peak["following_leg"]["peak_amplitude_m"],
            "peak_period_s": peak["following_leg"]["peak_period_s"],
            "peak_case": {k: peak[k] for k in ("plant", "signs", "seed")},
            "rms_last_over_first_third_max": round(max(
                f["following_leg"]["rms_last_third_m"]
                / max(1e-9, f["following_leg"]["rms_first_third_m"]) for f in fl), 2),
        }
    return res


def add_grid_args(ap: argparse.ArgumentParser) -> None:
    g = ap.add_argument_group("mismatch grid")
    g.add_argument("--no-grid", action="store_true", help="skip the mismatch grid")
    g.add_argument("--grid-only", action="store_true", help="run only the mismatch grid")
    g.add_argument("--grid-seeds", type=int, nargs="+", help="seeds of the grid "
                   "(default: --seeds)")
    g.add_argument("--grid-speeds", type=float, nargs="+", default=list(SPEEDS))
    g.add_argument("--grid-plants", type=int, nargs="+", help="only these rows of the "
                   "plant design (0-15)")


def grid_figures(args: argparse.Namespace) -> dict[str, Any]:
    seeds = args.grid_seeds or args.seeds
    g = run_grid(seeds, tuple(args.grid_speeds), plants=args.grid_plants)
    print(f"mismatch grid: {g['passed']}/{g['runs']} runs within RMS ≤ {RMS_TARGET_M} m and "
          f"p95 ≤ {P95_TARGET_M} m; worst RMS {g['rms_max_m']:.4f} m, worst p95 "
          f"{g['p95_max_m']:.3f} m; worst case {g['worst']}", file=sys.stderr)
    for speed, fl in g["following_legs"].items():
        print(f"  current along the leg at {speed} m/s: leg RMS ≤ {fl['rms_max_m']:.3f} m, "
              f"largest oscillation {fl['peak_amplitude_max_m']:.3f} m at "
              f"{fl['peak_period_s']:.0f} s ({fl['peak_case']})", file=sys.stderr)
    return {"grid": g}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--quick", action="store_true", help="skip the simulated hour")
    ap.add_argument("--base-rev", default=BASE_REV, help="the code to compare the speed with")
    ap.add_argument("--rounds", type=int, default=3, help="speed runs per checkout")
    add_grid_args(ap)
    args = ap.parse_args()
    if args.grid_only:
        print(json.dumps({"bench": "lines", **grid_figures(args)}))
        return
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
    if not args.no_grid:
        out.update(grid_figures(args))
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
