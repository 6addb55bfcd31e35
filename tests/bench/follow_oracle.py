"""Benchmark: what the AUV's estimate costs the following.  The follow
campaign's missions, each run several times with the follow guidance fed a
different estimate of the AUV:

* ``tracker``: the tracker's track, as the runtime runs;
* ``truth``: the simulator's true AUV position and velocity;
* ``true_velocity``: the tracker's position with the true velocity;
* ``true_position``: the true position with the tracker's velocity;
* ``lagL``: the tracker's position with the true velocity of L seconds
  before (``--lags``): what an estimator whose course lags the AUV's by L s
  would give.

    python tests/bench/follow_oracle.py [--seed 1] [--n 12] [--first 0]
                                        [--lags 1 2 3] [--jobs 2]

Everything else — the boat, the guidance and control, the tracker running
beside it, the world — is the mission's own; the estimate the guidance is
given (``zarco_runtime.guidance.follow.target_now``, what it turns the track
into) is swapped in this process only.  The AUV's true path does not depend on
the boat, so it is taken from the mission's ``tracker`` run.  Each run is
judged as ``zarco campaign`` judges it (config/campaigns/follow.toml's targets).

Per mode: missions meeting every target, missions within the p95 target,
manoeuvres within their targets, the time above 4 m summed over the missions,
the median of the missions' whole-time p95 and of their manoeuvres' peaks.
Progress per mission on stderr; one JSON line at the end.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

SPEC = ROOT / "config" / "campaigns" / "follow.toml"
#: the true velocity is the mean over this long (s) about the moment
VEL_WINDOW_S = 1.0


class Truth:
    """The AUV's true path (time s, north m, east m) of one run, interpolated
    linearly (held at its ends)."""

    def __init__(self, log: list[tuple[float, float, float, float]]) -> None:
        self.t = np.array([r[0] for r in log])
        self.x = np.array([r[1] for r in log])
        self.y = np.array([r[2] for r in log])

    def position(self, t: float) -> tuple[float, float]:
        return float(np.interp(t, self.t, self.x)), float(np.interp(t, self.t, self.y))

    def velocity(self, t: float) -> tuple[float, float]:
        h = 0.5 * VEL_WINDOW_S
        (x0, y0), (x1, y1) = self.position(t - h), self.position(t + h)
        return (x1 - x0) / VEL_WINDOW_S, (y1 - y0) / VEL_WINDOW_S


def _feed(mode: str, truth: Truth, target_now: Callable[..., Any]) -> Callable[..., Any]:
    """The estimate the guidance is given in ``mode``, in place of ``target_now``."""
    from zarco_runtime.guidance.follow_path import Target

    def fed(track: Any, t: float, *args: Any, **kw: Any) -> Target:
        est = target_now(track, t, *args, **kw)
        if mode == "truth":
            (x, y), (vx, vy) = truth.position(t), truth.velocity(t)
        elif mode == "true_velocity":
            (x, y), (vx, vy) = (est.x, est.y), truth.velocity(t)
        elif mode == "true_position":
            (x, y), (vx, vy) = truth.position(t), (est.vx, est.vy)
        else:  # lagL
            (x, y), (vx, vy) = (est.x, est.y), truth.velocity(t - float(mode[3:]))
        return Target(x, y, vx, vy, est.source)

    return fed


def run_one(seed: int, k: int, modes: list[str]) -> dict[str, Any]:
    """Mission ``k`` of campaign ``seed`` in every mode: each run's figures and judgement."""
    import zarco_runtime.guidance.follow as follow
    from zarco_tools.campaign.draw import draw_mission, drawer
    from zarco_tools.campaign.spec import load_spec
    from zarco_tools.scenario import scenario_from_data
    from zarco_tools.simulation import run_scenario

    spec = load_spec(SPEC)
    m = draw_mission(spec, seed, k)
    judge = drawer(spec.kind)

    def one() -> tuple[dict[str, Any], dict[str, Any]]:
        scn = scenario_from_data(spec.scenario_data(), spec.scenario_file, m.overrides,
                                 m.scenario_seed)
        res = run_scenario(scn)
        return res.report, res.extra

    original = follow.target_now
    out: dict[str, Any] = {"seed": seed, "k": k, "family": m.family,
                           "plan": m.factors.get("plan"), "runs": {}}
    report, extra = one()
    truth = Truth(extra["auv_log"])
    for mode in modes:
        if mode != "tracker":
            follow.target_now = _feed(mode, truth, original)
            try:
                report, _ = one()
            finally:
                follow.target_now = original
        j = judge.judge(spec, m.factors, report)
        tur = report.get("turns") or []
        out["runs"][mode] = {
            "every": not j.fails, "fails": sorted(j.fails),
            "median_m": report.get("distance_median_m"), "p95_m": report.get("distance_p95_m"),
            "above_4m_s": (report.get("time_above_4m_s") or {}).get("total"),
            "manoeuvres": len(j.turns_ok), "manoeuvres_ok": sum(j.turns_ok),
            "peaks_m": [t.get("distance_max_m") for t in tur],
        }
    return out


def summary(results: list[dict[str, Any]], modes: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for mode in modes:
        rs = [r["runs"][mode] for r in results]
        p95 = [r["p95_m"] for r in rs if r["p95_m"] is not None]
        peaks = [p for r in rs for p in r["peaks_m"] if p is not None]
        out[mode] = {
            "missions": len(rs),
            "every_target": sum(r["every"] for r in rs),
            "p95_within": sum("p95" not in r["fails"] for r in rs),
            "manoeuvres_within": [sum(r["manoeuvres_ok"] for r in rs),
                                  sum(r["manoeuvres"] for r in rs)],
            "above_4m_s": round(sum(r["above_4m_s"] or 0.0 for r in rs), 1),
            "p95_median_m": round(statistics.median(p95), 2) if p95 else None,
            "peak_median_m": round(statistics.median(peaks), 2) if peaks else None,
        }
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1, help="campaign seed")
    ap.add_argument("--n", type=int, default=12, help="missions")
    ap.add_argument("--first", type=int, default=0, help="index of the first mission")
    ap.add_argument("--lags", type=float, nargs="*", default=[2.0],
                    help="lags (s) of the true velocity given with the tracker's position")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    modes = ["tracker", "truth", "true_velocity", "true_position",
             *(f"lag{lag:g}" for lag in args.lags)]
    ks = list(range(args.first, args.first + args.n))
    t0 = time.monotonic()
    results: list[dict[str, Any]] = []
    with ProcessPoolExecutor(args.jobs) as ex:
        futs = [ex.submit(run_one, args.seed, k, modes) for k in ks]
        for i, fut in enumerate(as_completed(futs), start=1):
            r = fut.result()
            results.append(r)
            cells = "  ".join(f"{mode} p95 {run['p95_m'] or math.nan:.1f} m"
                              f"{' ok' if run['every'] else ''}"
                              for mode, run in r["runs"].items())
            print(f"[{i:3d}/{len(ks)} {time.monotonic() - t0:5.0f} s] m{r['k']:03d} "
                  f"{r['family']:<14} {cells}", file=sys.stderr, flush=True)
    results.sort(key=lambda r: int(r["k"]))
    tab = summary(results, modes)
    print("\nmode: missions meeting every target, within p95, manoeuvres within target, "
          "time above 4 m summed, median p95, median manoeuvre peak", file=sys.stderr)
    for mode, row in tab.items():
        mw = row["manoeuvres_within"]
        print(f"  {mode:<14} {row['every_target']:3d}/{row['missions']}  "
              f"{row['p95_within']:3d}  {mw[0]:3d}/{mw[1]}  {row['above_4m_s']:7.0f} s  "
              f"{row['p95_median_m']} m  {row['peak_median_m']} m", file=sys.stderr)
    print(json.dumps({"bench": "follow_oracle", "seed": args.seed, "first": args.first,
                      "n": args.n, "modes": modes, "by_mode": tab,
                      "missions": results, "wall_s": round(time.monotonic() - t0, 1)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
