"""Benchmark: where the boat loses the AUV — the AUV's estimate or the boat
following it.  Each mission of the follow campaign runs as the runtime runs,
with the follow guidance's target (the AUV now, as the guidance has it:
:attr:`zarco_runtime.guidance.follow.FollowGuidance.target`) logged at every
control tick beside the boat's and the AUV's true positions, and the distance
split three ways:

* target – AUV: what the estimate costs (the tracker, and the guidance's
  low-pass of it);
* boat – target: what following that target costs (the guidance's geometry,
  the boat's speed and turning);
* boat – AUV: what the campaign judges.

    python tests/bench/follow_lag.py [--seed 1] [--n 12] [--first 0]
                                     [--plan none|any|all] [--jobs 2]

Per kind of manoeuvre (the report's turns: from 5 s before each to 40 s
after it): the share of the time each distance is beyond 3 m (the recovery
threshold) and its mean.  On straight legs (no manoeuvre from 10 s before to
30 s after, a minute after acquisition, the boat on a virtual leg): how far
the target is ahead of the AUV and the boat behind the target along the
AUV's course, by the mission's closing speed (the boat's top speed over the
AUV's: ≥ 0.7, 0.3–0.7, < 0.3 m/s), the boat's heading rate RMS (weaving)
and the thrust it uses (mean of |u1| and |u2|, % of full).  Which estimate
the guidance followed (``line``, ``kf``, ``plan``), as shares of the
followed time.  Progress per mission on stderr; one JSON line at the end.
Nothing of the mission is changed: the target is read after each
:meth:`~zarco_runtime.guidance.follow.FollowGuidance.update`, in this
process only.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

SPEC = ROOT / "config" / "campaigns" / "follow.toml"
#: a manoeuvre's window: from this long before its start to this long after (s)
WINDOW_BEFORE_S = 5.0
WINDOW_AFTER_S = 40.0
#: straight legs: no manoeuvre from this long before to this long after (s),
#: and this long after acquisition
STRAIGHT_BEFORE_S = 10.0
STRAIGHT_AFTER_S = 30.0
STRAIGHT_FROM_ACQ_S = 60.0
#: beyond this (m) a distance counts as lost (the campaign's recovery threshold)
FAR_M = 3.0
#: closing-speed bands (m/s) of the straight-leg figures
BANDS = ((0.7, math.inf, "fast"), (0.3, 0.7, "mid"), (-math.inf, 0.3, "slow"))


def run_one(seed: int, k: int) -> dict[str, Any]:
    """Mission ``k`` of campaign ``seed``, run as the runtime runs, with the
    guidance's target logged: its split distances (module docstring)."""
    import zarco_runtime.guidance.follow as follow
    from zarco_tools.campaign.draw import draw_mission
    from zarco_tools.campaign.spec import load_spec
    from zarco_tools.scenario import scenario_from_data
    from zarco_tools.simulation import run_scenario

    spec = load_spec(SPEC)
    m = draw_mission(spec, seed, k)
    rows: list[tuple[float, float, float, float, float, int, str]] = []
    original = follow.FollowGuidance.update

    def logged(self: Any, track: Any, t: float, x: float, y: float) -> Any:
        st = original(self, track, t, x, y)
        tg = self.target
        on_leg = int(st.mode == "follow" and st.leg is not None)
        rows.append((t, x, y, tg.x if tg else math.nan, tg.y if tg else math.nan, on_leg,
                     tg.source if tg and st.mode == "follow" else ""))
        return st

    follow.FollowGuidance.update = logged  # type: ignore[method-assign]
    try:
        scn = scenario_from_data(spec.scenario_data(), spec.scenario_file, m.overrides,
                                 m.scenario_seed)
        res = run_scenario(scn)
    finally:
        follow.FollowGuidance.update = original  # type: ignore[method-assign]
    rep = res.report
    out: dict[str, Any] = {"seed": seed, "k": k, "family": m.family,
                           "plan": m.factors.get("plan"),
                           "closing_mps": m.factors.get("closing_mps"),
                           "manoeuvres": [], "straight": None, "sources": {}}
    auv = np.array(res.extra.get("auv_log") or [], dtype=float)
    if not rows or auv.size == 0:
        return out
    g = np.array([r[:6] for r in rows], dtype=float)
    t = g[:, 0]
    ax = np.interp(t, auv[:, 0], auv[:, 1])
    ay = np.interp(t, auv[:, 0], auv[:, 2])
    course = np.interp(t, auv[:, 0], np.unwrap(auv[:, 3]))
    boat_auv = np.hypot(g[:, 1] - ax, g[:, 2] - ay)
    tgt_auv = np.hypot(g[:, 3] - ax, g[:, 4] - ay)
    boat_tgt = np.hypot(g[:, 1] - g[:, 3], g[:, 2] - g[:, 4])
    turns = rep.get("turns") or []
    for tu in turns:
        sel = (t >= tu["t_s"] - WINDOW_BEFORE_S) & (t <= tu["t_s"] + WINDOW_AFTER_S)
        sel &= np.isfinite(tgt_auv)
        if not sel.any():
            continue
        out["manoeuvres"].append({
            "kind": tu["kind"], "t_s": tu["t_s"], "peak_m": tu.get("distance_max_m"),
            "boat_far": float(np.mean(boat_auv[sel] > FAR_M)),
            "target_far": float(np.mean(tgt_auv[sel] > FAR_M)),
            "boat_target_far": float(np.mean(boat_tgt[sel] > FAR_M)),
            "boat_auv_m": float(np.mean(boat_auv[sel])),
            "target_auv_m": float(np.mean(tgt_auv[sel])),
            "boat_target_m": float(np.mean(boat_tgt[sel]))})
    near = np.zeros(t.size, dtype=bool)
    for tu in turns:
        end = tu.get("end_s", tu["t_s"])
        near |= (t >= tu["t_s"] - STRAIGHT_BEFORE_S) & (t <= end + STRAIGHT_AFTER_S)
    acq = rep.get("acquired_s")
    straight = ((g[:, 5] > 0) & ~near & np.isfinite(tgt_auv)
                & (t >= (acq if acq is not None else math.inf) + STRAIGHT_FROM_ACQ_S))
    if straight.any():
        c, s = np.cos(course), np.sin(course)
        tgt_ahead = (g[:, 3] - ax) * c + (g[:, 4] - ay) * s
        boat_ahead = (g[:, 1] - ax) * c + (g[:, 2] - ay) * s
        lt = np.array(res.log.t)
        psi = np.unwrap(np.array(res.log.psi))
        thrust = 0.5 * (np.abs(np.array(res.log.u1)) + np.abs(np.array(res.log.u2)))
        rate = np.degrees(np.gradient(psi, lt)) if lt.size > 1 else np.zeros(lt.size)
        on = np.interp(lt, t, straight.astype(float)) > 0.5
        out["straight"] = {
            "s": float(straight.sum() * np.median(np.diff(t))) if t.size > 1 else 0.0,
            "target_ahead_m": float(np.mean(tgt_ahead[straight])),
            "boat_behind_target_m": float(np.mean(tgt_ahead[straight] - boat_ahead[straight])),
            "heading_rate_rms_dps": float(np.sqrt(np.mean(rate[on] ** 2))) if on.any()
            else math.nan,
            "thrust_pct": float(np.mean(thrust[on])) if on.any() else math.nan}
    src = Counter(r[6] for r in rows if r[6])
    total = sum(src.values())
    out["sources"] = {k2: v / total for k2, v in src.items()} if total else {}
    return out


def _mean(v: list[float]) -> float | None:
    w = [x for x in v if x is not None and math.isfinite(x)]
    return round(float(np.mean(w)), 3) if w else None


def summary(results: list[dict[str, Any]]) -> dict[str, Any]:
    """The missions' figures pooled: per manoeuvre kind, per closing-speed band
    on the straight legs, and the estimate followed."""
    kinds: dict[str, list[dict[str, Any]]] = {}
    for r in results:
        for mv in r["manoeuvres"]:
            kinds.setdefault(mv["kind"], []).append(mv)
    by_kind = {kind: {"n": len(mv), **{key: _mean([x[key] for x in mv]) for key in (
        "boat_far", "target_far", "boat_target_far", "boat_auv_m", "target_auv_m",
        "boat_target_m")}} for kind, mv in sorted(kinds.items())}
    bands: dict[str, Any] = {}
    for lo, hi, name in BANDS:
        st = [r["straight"] for r in results if r["straight"] is not None
              and r["closing_mps"] is not None and lo <= r["closing_mps"] < hi]
        bands[name] = {"missions": len(st), **{key: _mean([x[key] for x in st]) for key in (
            "target_ahead_m", "boat_behind_target_m", "heading_rate_rms_dps", "thrust_pct")}}
    src: Counter[str] = Counter()
    for r in results:
        src.update(r["sources"])
    n = max(1, sum(1 for r in results if r["sources"]))
    return {"manoeuvres": by_kind, "straight": bands,
            "sources": {k: round(v / n, 3) for k, v in sorted(src.items())}}


def _table(title: str, rows: dict[str, dict[str, Any]], keys: tuple[str, ...]) -> None:
    """``rows`` (name → figures) under ``title`` on stderr, the figures ``keys``."""
    print(title, file=sys.stderr)
    for name, row in rows.items():
        print(f"  {name:<6} " + "  ".join(f"{k} {row[k]}" for k in keys), file=sys.stderr)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1, help="campaign seed")
    ap.add_argument("--n", type=int, default=12, help="missions drawn")
    ap.add_argument("--first", type=int, default=0, help="index of the first mission")
    ap.add_argument("--plan", choices=("none", "any", "all"), default="all",
                    help="only the missions without the AUV's plan (none), with one "
                         "(any: given or adaptive), or all")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    from zarco_tools.campaign.draw import draw_mission
    from zarco_tools.campaign.spec import load_spec

    spec = load_spec(SPEC)
    ks = []
    for k in range(args.first, args.first + args.n):
        plan = draw_mission(spec, args.seed, k).factors.get("plan")
        if args.plan == "all" or (args.plan == "none") == (plan == "none"):
            ks.append(k)
    t0 = time.monotonic()
    results: list[dict[str, Any]] = []
    with ProcessPoolExecutor(args.jobs) as ex:
        futs = [ex.submit(run_one, args.seed, k) for k in ks]
        for i, fut in enumerate(as_completed(futs), start=1):
            r = fut.result()
            results.append(r)
            mv = r["manoeuvres"]
            far = (f"boat far {_mean([x['boat_far'] for x in mv])}, target far "
                   f"{_mean([x['target_far'] for x in mv])}" if mv else "no manoeuvre")
            print(f"[{i:3d}/{len(ks)} {time.monotonic() - t0:5.0f} s] m{r['k']:03d} "
                  f"{r['family']:<16} {r['plan']:<9} {far}", file=sys.stderr, flush=True)
    results.sort(key=lambda r: int(r["k"]))
    tab = summary(results)
    _table("\nmanoeuvres (window -5..+40 s): share of the time beyond 3 m (far) and mean "
           "distance (m), boat-AUV / target-AUV / boat-target", tab["manoeuvres"],
           ("n", "boat_far", "target_far", "boat_target_far", "boat_auv_m", "target_auv_m",
            "boat_target_m"))
    _table("straight legs by closing speed: target ahead of the AUV and boat behind the "
           "target (m), heading rate RMS (deg/s), thrust (% of full)", tab["straight"],
           ("missions", "target_ahead_m", "boat_behind_target_m", "heading_rate_rms_dps",
            "thrust_pct"))
    print(f"estimate followed (share of the followed time): {tab['sources']}", file=sys.stderr)
    print(json.dumps({"bench": "follow_lag", "seed": args.seed, "first": args.first,
                      "n": args.n, "plan": args.plan, "missions": len(results),
                      "summary": tab, "per_mission": results,
                      "wall_s": round(time.monotonic() - t0, 1)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
