"""Benchmark: the tracker's sound-speed estimate and track on the follow
campaign's missions, the tracker alone (the acoustic world and the AUV, no boat).

    python tests/bench/tracker_calibration.py [--seeds 1 2 3] [--n 40] [--jobs 2]

Draws ``--n`` missions per campaign seed from config/campaigns/follow.toml (the
same networks, routes, detections and calibration errors as ``zarco campaign``:
true sound speed ±1 % off the configured one, beacons surveyed up to 2 m off,
turnarounds up to 2 ms off, or all three), runs the tracker on each mission's
acoustic feed, and measures against the simulator's truth:

* the sound-speed error |ĉ − c|/c from 300 s after acquisition to the end (its
  largest value: the target is 0.2 %), and ĉ's σ and whether it says
  ``converged`` then;
* the filter's position, carried to each moment along its velocity, against
  the AUV (median and 95th percentile over the tracked time);
* per mission (on stderr), the survey's own scale: how much larger the
  surveyed network is than the true one, which no timing can tell from a
  faster sound.

Figures by calibration error and by number of beacons, over every seed;
progress on stderr; one JSON line at the end.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

SPEC = ROOT / "config" / "campaigns" / "follow.toml"
SETTLE_S = 300.0


def run_one(seed: int, k: int) -> dict[str, Any]:
    """One mission of campaign ``seed``: its factors and the tracker's figures."""
    from drivers.sim.acoustics import AcousticWorld
    from drivers.sim.auv import Auv
    from zarco_core.auv_messages import AuvTrack, TrackFlags
    from zarco_runtime.tracking.tracker import AuvTracker
    from zarco_tools.campaign.draw import draw_mission
    from zarco_tools.campaign.spec import load_spec
    from zarco_tools.scenario import load_scenario

    spec = load_spec(SPEC)
    m = draw_mission(spec, seed, k)
    scn = load_scenario(ROOT / "config" / "scenarios" / "follow_turn.toml", m.overrides,
                        m.scenario_seed)
    assert scn.auv is not None and scn.lbl is not None
    auv = Auv(scn.auv)
    world = AcousticWorld(scn.lbl, auv, scn.scenario.seed)
    tracker = AuvTracker(scn.runtime.tracker)
    c_true = scn.lbl.sound_speed_mps
    t, dt = 0.0, 0.5
    last: AuvTrack | None = None
    acquired = math.nan
    rows = []
    while t < scn.scenario.max_duration_s:
        t += dt
        for ev in world.events_exact_until(t):
            for msg in tracker.process(ev):
                if isinstance(msg, AuvTrack):
                    last = msg
        last = tracker.tick(t) or last
        if last is None or last.lost or not last.flags & TrackFlags.INITIALISED:
            continue
        if math.isnan(acquired):
            acquired = t
        tr = world.auv_truth(t)
        age = t - (last.t0_utc_s - world.epoch0_s)
        err = math.hypot(last.kf_x_m + last.kf_vx_mps * age - tr.x_m,
                         last.kf_y_m + last.kf_vy_mps * age - tr.y_m)
        rows.append((t, err, last.sound_speed_mps, last.sound_speed_sigma_mps,
                     last.sound_speed_converged))
    a = np.array([r[:4] for r in rows]) if rows else np.zeros((0, 4))
    late = a[a[:, 0] >= acquired + SETTLE_S] if a.size else a
    conv = [r[4] for r in rows if r[0] >= acquired + SETTLE_S]
    f = m.factors
    net_true, net_cfg = scn.lbl.beacons, scn.runtime.tracker.network.beacons
    return {
        "seed": seed, "k": k, "family": m.family, "calibration": f["calibration"],
        "beacons": f["beacons"], "c_true": c_true,
        "c_configured": scn.runtime.tracker.network.sound_speed_mps,
        "survey_scale_pct": survey_scale_pct(net_true, net_cfg),
        "acquired_s": acquired if math.isfinite(acquired) else None,
        "c_error_max_pct": (float(np.max(np.abs(late[:, 2] / c_true - 1.0))) * 100.0
                            if late.size else None),
        "c_error_end_pct": float(a[-1, 2] / c_true - 1.0) * 100.0 if a.size else None,
        "c_sigma_settled_mps": float(late[0, 3]) if late.size else None,
        "converged_settled": bool(conv[0]) if conv else None,
        "pos_median_m": float(np.median(a[:, 1])) if a.size else None,
        "pos_p95_m": float(np.percentile(a[:, 1], 95)) if a.size else None,
    }


def survey_scale_pct(true: Any, surveyed: Any) -> float:
    """The scale (%) of the surveyed network against the true one (the
    least-squares similarity of their horizontal positions): timings cannot
    tell a network that much larger with sound that much faster."""
    a = np.array([[b[0], b[1]] for b in true], dtype=float)
    b = np.array([[q[0], q[1]] for q in surveyed], dtype=float)
    a -= a.mean(axis=0)
    b -= b.mean(axis=0)
    s = np.linalg.svd(a.T @ b, compute_uv=False)
    return float((s.sum() / (a * a).sum() - 1.0) * 100.0)


def _pct(v: list[float], q: float) -> float | None:
    return round(float(np.percentile(v, q)), 3) if v else None


def table(results: list[dict[str, Any]], key: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in sorted({str(r[key]) for r in results}):
        rs = [r for r in results if str(r[key]) == name]
        errs = [r["c_error_max_pct"] for r in rs if r["c_error_max_pct"] is not None]
        pos = [r["pos_median_m"] for r in rs if r["pos_median_m"] is not None]
        p95 = [r["pos_p95_m"] for r in rs if r["pos_p95_m"] is not None]
        out[name] = {
            "missions": len(rs),
            "within_0_2_pct": sum(1 for e in errs if e <= 0.2),
            "c_error_max_pct": {"p50": _pct(errs, 50), "p90": _pct(errs, 90),
                                "max": _pct(errs, 100)},
            "converged": sum(1 for r in rs if r["converged_settled"]),
            "pos_median_m": {"p50": _pct(pos, 50), "max": _pct(pos, 100)},
            "pos_p95_m": {"p50": _pct(p95, 50), "max": _pct(p95, 100)},
        }
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--n", type=int, default=40, help="missions per seed")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    jobs = [(s, k) for s in args.seeds for k in range(args.n)]
    t0 = time.monotonic()
    results: list[dict[str, Any]] = []
    with ProcessPoolExecutor(args.jobs) as ex:
        futs = [ex.submit(run_one, s, k) for s, k in jobs]
        for i, fut in enumerate(as_completed(futs), start=1):
            r = fut.result()
            results.append(r)
            e = r["c_error_max_pct"]
            print(f"[{i:4d}/{len(jobs)} {time.monotonic() - t0:6.0f} s] seed {r['seed']} "
                  f"m{r['k']:03d} {r['family']:<16} {r['beacons']}b {r['calibration']:<12} "
                  f"c err max {'—' if e is None else f'{e:.3f} %'} σ {r['c_sigma_settled_mps']} "
                  f"conv {r['converged_settled']} survey scale {r['survey_scale_pct']:+.3f} %"
                  f"  pos p50 "
                  f"{r['pos_median_m'] or float('nan'):.2f} m p95 "
                  f"{r['pos_p95_m'] or float('nan'):.2f} m", file=sys.stderr, flush=True)
    results.sort(key=lambda r: (r["seed"], r["k"]))
    by_cal = table(results, "calibration")
    by_nb = table(results, "beacons")
    for title, tab in (("by calibration error", by_cal), ("by beacons", by_nb)):
        print(f"\n{title}: missions, within 0.2 % from 300 s after acquisition, "
              "error max p50/p90/max (%), filter position p50 of medians / p95s (m)",
              file=sys.stderr)
        for name, row in tab.items():
            c = row["c_error_max_pct"]
            print(f"  {name:<12} {row['missions']:3d}  {row['within_0_2_pct']:3d}  "
                  f"{c['p50']} / {c['p90']} / {c['max']}   {row['pos_median_m']['p50']} / "
                  f"{row['pos_p95_m']['p50']}", file=sys.stderr)
    print(json.dumps({"bench": "tracker_calibration", "seeds": args.seeds, "n": args.n,
                      "wall_s": round(time.monotonic() - t0, 1), "by_calibration": by_cal,
                      "by_beacons": by_nb}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
