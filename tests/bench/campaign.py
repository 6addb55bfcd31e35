"""Benchmark: a campaign of randomised follow-the-AUV missions.

    python tests/bench/campaign.py [--seed 1] [--n 60] [--jobs 2] [--quick]
                                   [--set KEY=VALUE ...] [--out out]

Draws ``--n`` missions from one seed (mission k depends only on the seed and k),
each a variation of config/scenarios/follow_turn.toml given as ``--set``
overrides (so any mission is reproduced with ``zarco sim``; the command line of
the worst is printed).  They span:

* 2–4 beacons (listener at any of them) 250–550 m apart, in regular, random and
  elongated layouts, 15–60 m deep; the AUV 3–25 m deep, inside the network (or
  beside the baseline with two beacons);
* AUV speed 0.5–1.2 m/s, turn rate 6–15 °/s; lawnmower missions (legs of
  80–130 s, 15–40 m apart: a U-turn, or two 90° turns when the crossing takes
  30 s or more) and random-leg missions (turns of 30–180°, a quarter of
  them full reversals);
* 0–20 % missed and 0–5 % false detections, 0.3–0.8 ms jitter;
* current 0–0.3 m/s from any direction;
* a plant that is not the controller's model: every hull mass, added mass,
  damping and inertia of ``world.vessel`` scaled by 0.75–1.25, the thrust curve
  by 0.85–1.15, thruster lag 0.1–0.3 s, misalignment ±3°, mismatch ±10 %, while
  ``[runtime.vessel]``/``[runtime.thrusters]`` keep the nominal model;
* the ASV starts 2–25 m from the AUV, the tracker's prior up to 15 m off.

Targets per mission: distance median ≤ 1 m and p95 ≤ 4 m on straight legs;
per turn up to 90°: max ≤ 12 m and recovery ≤ 40 s; per turn beyond 90° (a
U-turn): max ≤ 15 m and recovery ≤ 45 s; never without a usable track for more
than 10 s; a report that is valid JSON (no NaN).

Physics: each mission's closing speed — the ASV's top ground speed along the
AUV's course (the true plant's full thrust against its damping, crabbing into
the current) minus the AUV's speed, the least over its legs — is reported with
the figures, and ``<out>/campaign_closing.png`` plots the figures against it
with the closing speed over AUV speed for the extreme plants.

Runs ``--jobs`` processes; progress on stderr; writes ``<out>/campaign_worst.png``
(the worst mission) and ends with one JSON line on stdout.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

BASE = ROOT / "config" / "scenarios" / "follow_turn.toml"

#: targets (m, s)
MEDIAN_M, P95_M = 1.0, 4.0
TURN_MAX_M, TURN_REC_S = 12.0, 40.0
UTURN_MAX_M, UTURN_REC_S = 15.0, 45.0
LOST_S = 10.0
#: hull parameters scaled ±25 % in the simulated plant
HULL = ("m_kg", "iz_kgm2", "x_udot", "y_vdot", "n_rdot", "x_u", "x_uu", "y_v", "y_vv",
        "n_r", "n_rr")
#: closing-speed classes (m/s) of the pass table
CLOSING_BINS = ((-9.0, 0.0), (0.0, 0.2), (0.2, 0.4), (0.4, 0.6), (0.6, 9.0))
#: nominal hull (the runtime's model) and thrust, for the closing-speed figure
NOM_XU, NOM_XUU, NOM_FWD = -25.0, -82.0, 125.0


@dataclass
class Mission:
    """One drawn mission: ``--set`` overrides of the base scenario, and what was drawn."""

    index: int
    seed: int
    overrides: list[str] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)

    def command(self) -> str:
        sets = " ".join(f"--set '{o}'" for o in self.overrides)
        return f"zarco sim {BASE.relative_to(ROOT)} --seed {self.seed} {sets}"


def _r(v: float, nd: int = 3) -> float:
    return round(float(v), nd)


def _toml(v: Any) -> str:
    """A value as a TOML literal for ``--set``."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return repr(_r(v, 4)) if isinstance(v, float) else repr(v)


def _beacons(rng: np.random.Generator, nb: int) -> tuple[list[list[float]], str, float]:
    """Beacon layout (north, east, depth), its kind, and its spread (m)."""
    spread = float(rng.uniform(250.0, 550.0))
    if nb == 2:
        a = rng.uniform(0.0, math.tau)
        pts = [(0.0, 0.0), (spread * math.cos(a), spread * math.sin(a))]
        kind = "pair"
    else:
        kind = str(rng.choice(["regular", "random", "elongated"]))
        while True:
            if kind == "regular":
                a0 = rng.uniform(0.0, math.tau)
                pts = []
                for j in range(nb):
                    a = a0 + j * math.tau / nb + rng.uniform(-0.35, 0.35)
                    rad = 0.5 * spread * rng.uniform(0.8, 1.2)
                    pts.append((rad * math.cos(a), rad * math.sin(a)))
            else:
                w = spread * (0.45 if kind == "elongated" else 1.0)
                a = rng.uniform(0.0, math.tau)
                ca, sa = math.cos(a), math.sin(a)
                pts = []
                for _ in range(nb):
                    u, v = rng.uniform(-0.5, 0.5) * spread, rng.uniform(-0.5, 0.5) * w
                    pts.append((u * ca - v * sa, u * sa + v * ca))
            if min(math.dist(p, q) for i, p in enumerate(pts)
                   for q in pts[i + 1:]) >= 0.3 * spread:
                break
    beacons = [[_r(x, 1), _r(y, 1), _r(rng.uniform(15.0, 60.0), 1)] for x, y in pts]
    return beacons, kind, spread


def _centre(rng: np.random.Generator, beacons: list[list[float]], spread: float
            ) -> tuple[float, float]:
    """Centre of the AUV's mission: inside the network, or beside a single baseline."""
    if len(beacons) == 2:
        (x0, y0, _), (x1, y1, _) = beacons
        bx, by = x1 - x0, y1 - y0
        n = math.hypot(bx, by)
        ux, uy = bx / n, by / n
        off = rng.uniform(90.0, 220.0) * rng.choice([-1.0, 1.0])
        along = rng.uniform(0.3, 0.7) * n
        return x0 + along * ux - off * uy, y0 + along * uy + off * ux
    cx = sum(b[0] for b in beacons) / len(beacons)
    cy = sum(b[1] for b in beacons) / len(beacons)
    return (cx + rng.uniform(-0.12, 0.12) * spread, cy + rng.uniform(-0.12, 0.12) * spread)


def _route(rng: np.random.Generator, shape: str, cx: float, cy: float, v: float
           ) -> tuple[list[list[float]], list[float]]:
    """Waypoints of the mission around (cx, cy) and the planned turn angles (deg)."""
    h = rng.uniform(0.0, math.tau)
    turns: list[float] = []
    if shape == "lawnmower":
        n_legs = int(rng.integers(3, 5))
        length = v * rng.uniform(80.0, 130.0)
        spacing = rng.uniform(15.0, 40.0)
        side = float(rng.choice([-1.0, 1.0]))
        ux, uy = math.cos(h), math.sin(h)
        px, py = -uy * side, ux * side  # towards the next leg
        x = cx - 0.5 * length * ux - 0.5 * (n_legs - 1) * spacing * px
        y = cy - 0.5 * length * uy - 0.5 * (n_legs - 1) * spacing * py
        wps = [[x, y]]
        for k in range(n_legs):
            d = 1.0 if k % 2 == 0 else -1.0
            x += d * length * ux
            y += d * length * uy
            wps.append([x, y])
            if k + 1 < n_legs:
                x += spacing * px
                y += spacing * py
                wps.append([x, y])
                turns.append(180.0)
        # the last leg carries on (at_end = continue) past its end
        return [[_r(a, 1), _r(b, 1)] for a, b in wps], turns
    n_legs = int(rng.integers(3, 5))
    x, y = cx, cy
    wps = [[x, y]]
    for k in range(n_legs):
        length = v * rng.uniform(80.0, 130.0)
        x += length * math.cos(h)
        y += length * math.sin(h)
        wps.append([x, y])
        if k + 1 < n_legs:
            a = 180.0 if rng.random() < 0.25 else float(rng.uniform(30.0, 180.0))
            a *= float(rng.choice([-1.0, 1.0]))
            turns.append(a)
            h += math.radians(a)
    # centre the route on (cx, cy)
    mx = 0.5 * (min(w[0] for w in wps) + max(w[0] for w in wps))
    my = 0.5 * (min(w[1] for w in wps) + max(w[1] for w in wps))
    return [[_r(a - mx + cx, 1), _r(b - my + cy, 1)] for a, b in wps], turns


def _one_side(beacons: list[list[float]], wps: list[list[float]], margin: float) -> bool:
    """Whether the route (and its carry-on past the end) stays on one side of the
    baseline of two beacons, ``margin`` m clear of it (a two-beacon network cannot
    tell the sides apart)."""
    (x0, y0, _), (x1, y1, _) = beacons
    n = math.dist((x0, y0), (x1, y1))
    (ax, ay), (bx, by) = wps[-2], wps[-1]
    ext = [bx + 150.0 * (bx - ax) / max(math.dist((ax, ay), (bx, by)), 1e-9),
           by + 150.0 * (by - ay) / max(math.dist((ax, ay), (bx, by)), 1e-9)]
    side = [((x - x0) * (y1 - y0) - (y - y0) * (x1 - x0)) / n for x, y in [*wps, ext]]
    return min(side) > margin or max(side) < -margin


def top_speed(x_u: float, x_uu: float, thrust_n: float) -> float:
    """Steady water speed (m/s) where the damping −X_u u − X_|u|u u² equals
    ``thrust_n`` (both thrusters at full forward)."""
    a, b = -x_uu, -x_u
    return (-b + math.sqrt(b * b + 4.0 * a * thrust_n)) / (2.0 * a)


def closing_speed(u_max: float, course: float, cur_speed: float, cur_dir: float,
                  v_auv: float) -> float:
    """The ASV's top ground speed along ``course`` (rad) in a current
    (m/s, towards ``cur_dir`` rad), crabbing to cancel its cross component,
    minus the AUV's speed (m/s)."""
    along = cur_speed * math.cos(cur_dir - course)
    cross = cur_speed * math.sin(cur_dir - course)
    if abs(cross) >= u_max:
        return -v_auv
    return along + math.sqrt(u_max * u_max - cross * cross) - v_auv


def draw(seed: int, k: int) -> Mission:
    """Mission ``k`` of the campaign of ``seed`` (independent of how many are drawn)."""
    rng = np.random.default_rng([seed, k])
    nb = int(rng.integers(2, 5))
    beacons, layout, spread = _beacons(rng, nb)
    listener = int(rng.integers(0, nb))
    cx, cy = _centre(rng, beacons, spread)
    v = _r(rng.uniform(0.5, 1.2), 3)
    shape = str(rng.choice(["lawnmower", "random"]))
    while True:
        wps, planned = _route(rng, shape, cx, cy, v)
        if nb > 2 or _one_side(beacons, wps, 30.0):
            break
    start_delay = _r(rng.uniform(30.0, 80.0), 1)
    path = sum(math.dist(a, b) for a, b in itertools.pairwise(wps))
    duration = _r(start_delay + path / v + rng.uniform(100.0, 140.0), 1)
    depth = _r(rng.uniform(3.0, 25.0), 1)
    turn_rate = _r(rng.uniform(6.0, 15.0), 1)
    tau = [_r(rng.uniform(0.05, 0.2), 3) for _ in range(nb)]
    delay = _r(rng.uniform(0.3, 0.8), 3)
    c = _r(rng.uniform(1480.0, 1520.0), 1)
    p_miss = _r(rng.uniform(0.0, 0.20), 3)
    p_false = _r(rng.uniform(0.0, 0.05), 3)
    jitter = _r(rng.uniform(0.0003, 0.0008), 5)
    cur = _r(rng.uniform(0.0, 0.3), 3)
    cur_dir = _r(rng.uniform(0.0, 360.0), 1)
    hull = {p: _r(rng.uniform(0.75, 1.25), 3) for p in HULL}
    thrust = _r(rng.uniform(0.85, 1.15), 3)
    lag = _r(rng.uniform(0.1, 0.3), 3)
    phi1, phi2 = _r(rng.uniform(-3.0, 3.0), 2), _r(rng.uniform(-3.0, 3.0), 2)
    mismatch = _r(rng.uniform(-0.1, 0.1), 3)
    a0 = rng.uniform(0.0, math.tau)
    r0 = rng.uniform(2.0, 25.0)
    asv = (_r(wps[0][0] + r0 * math.cos(a0), 1), _r(wps[0][1] + r0 * math.sin(a0), 1))
    heading = _r(rng.uniform(0.0, 360.0), 1)
    a1 = rng.uniform(0.0, math.tau)
    r1 = rng.uniform(0.0, 15.0)
    prior = (_r(wps[0][0] + r1 * math.cos(a1), 1), _r(wps[0][1] + r1 * math.sin(a1), 1))
    compass_noise = _r(rng.uniform(0.5, 1.0), 2)
    compass_bias = _r(rng.uniform(-2.0, 2.0), 2)
    from drivers.sim.params import ThrusterParams, VesselParams

    vp, tp = VesselParams(), ThrusterParams()
    sets: dict[str, Any] = {
        "scenario.name": f"campaign-{seed}-{k}",
        "scenario.max_duration_s": duration,
        "world.x_m": asv[0], "world.y_m": asv[1], "world.heading_deg": heading,
        "world.current.speed_mps": cur, "world.current.direction_deg": cur_dir,
        "world.thrusters.fwd_max_n": _r(tp.fwd_max_n * thrust, 2),
        "world.thrusters.rev_max_n": _r(tp.rev_max_n * thrust, 2),
        "world.thrusters.lag_s": lag,
        "world.thrusters.phi1_deg": phi1, "world.thrusters.phi2_deg": phi2,
        "world.thrusters.mismatch": mismatch,
        "world.compass.noise_deg": compass_noise, "world.compass.bias_deg": compass_bias,
        **{f"world.vessel.{p}": _r(getattr(vp, p) * f, 3) for p, f in hull.items()},
        "auv.waypoints": wps, "auv.speed_mps": v, "auv.depth_m": depth,
        "auv.turn_rate_dps": turn_rate, "auv.start_delay_s": start_delay,
        "auv.at_end": "continue",
        "lbl.beacons": beacons, "lbl.turnaround_s": tau, "lbl.auv_delay_s": delay,
        "lbl.sound_speed_mps": c, "lbl.listener_beacon": listener, "lbl.jitter_s": jitter,
        "lbl.p_miss": p_miss, "lbl.p_false": p_false,
        "runtime.tracker.auv_depth_m": depth,
        "runtime.tracker.prior_north_m": prior[0], "runtime.tracker.prior_east_m": prior[1],
        "runtime.tracker.network.beacons": beacons,
        "runtime.tracker.network.turnaround_s": tau,
        "runtime.tracker.network.auv_delay_s": delay,
        "runtime.tracker.network.sound_speed_mps": c,
        "runtime.tracker.network.listener_beacon": listener,
        "runtime.navigation.estimator": "ekf",
    }
    # the closing speed of the true plant on each leg
    u_max = top_speed(vp.x_u * hull["x_u"], vp.x_uu * hull["x_uu"],
                      2.0 * tp.fwd_max_n * thrust * math.cos(math.radians(
                          0.5 * (abs(phi1) + abs(phi2)))))
    courses = [math.atan2(b[1] - a[1], b[0] - a[0]) for a, b in itertools.pairwise(wps)]
    margin = min(closing_speed(u_max, co, cur, math.radians(cur_dir), v) for co in courses)
    meta = {"shape": shape, "beacons": nb, "layout": layout, "speed_mps": v,
            "planned_turns_deg": [_r(a, 0) for a in planned], "p_miss": p_miss,
            "p_false": p_false, "current_mps": cur, "thrust_scale": thrust, "lag_s": lag,
            "damping_scale": hull["x_uu"], "duration_s": duration,
            "top_speed_mps": _r(u_max), "closing_mps": _r(margin)}
    return Mission(k, seed * 1000 + k, [f"{key}={_toml(val)}" for key, val in sets.items()],
                   meta)


def check(report: dict[str, Any]) -> dict[str, Any]:
    """Which targets a mission's report fails (a list of short reasons per target)."""
    fails: dict[str, list[str]] = {}

    def fail(key: str, why: str) -> None:
        fails.setdefault(key, []).append(why)

    med, p95 = report.get("distance_median_m"), report.get("distance_p95_m")
    if med is None or med > MEDIAN_M:
        fail("median", f"median {med}")
    if p95 is None or p95 > P95_M:
        fail("p95", f"p95 {p95}")
    for tr in report.get("turns", []):
        u = tr["kind"] == "uturn"
        mx, rec = (UTURN_MAX_M, UTURN_REC_S) if u else (TURN_MAX_M, TURN_REC_S)
        key = "uturn" if u else "turn"
        d, r = tr["distance_max_m"], tr["recovery_s"]
        if d is None or d > mx or r is None or r > rec:
            fail(key, f"{tr['angle_deg']:+.0f}° at {tr['t_s']:.0f} s: max {d and round(d, 1)} m,"
                      f" recovery {r and round(r, 1)} s")
    lost = report.get("lost_max_s")
    if lost is None or lost > LOST_S:
        fail("lost", f"{lost} s without a usable track")
    try:
        json.dumps(report, allow_nan=False)
    except ValueError:
        fail("json", "NaN in the report")
    return fails


def severity(report: dict[str, Any]) -> float:
    """How far the mission is from its targets: the largest ratio figure/target
    (≤ 1: all met; an unrecovered turn counts 3)."""
    ratios = [(report.get("distance_median_m") or math.inf) / MEDIAN_M,
              (report.get("distance_p95_m") or math.inf) / P95_M,
              (report.get("lost_max_s") or 0.0) / LOST_S]
    for tr in report.get("turns", []):
        u = tr["kind"] == "uturn"
        mx, rec = (UTURN_MAX_M, UTURN_REC_S) if u else (TURN_MAX_M, TURN_REC_S)
        ratios.append((tr["distance_max_m"] or math.inf) / mx)
        ratios.append(tr["recovery_s"] / rec if tr["recovery_s"] is not None else 3.0)
    return max(min(r, 99.0) for r in ratios)


KEEP = ("fix_interval_s", "fixes", "fix_error_rms_m", "track_error_rms_m",
        "course_error_rms_deg", "turns", "distance_median_m", "distance_p95_m",
        "distance_max_m", "track_lost_events", "fix_gap_max_s", "hold_max_s", "lost_max_s",
        "saturation_fraction", "nav_position_rms_m", "sim_seconds", "wall_seconds", "faults",
        "tracker")


def run_one(m: Mission, extra: list[str]) -> dict[str, Any]:
    """Simulate one mission (in a worker process); its figures and checks."""
    from zarco_tools.scenario import load_scenario
    from zarco_tools.simulation import run_scenario

    try:
        rep = run_scenario(load_scenario(BASE, [*m.overrides, *extra], m.seed)).report
    except Exception as exc:  # a crash is a result too (and the worst)
        return {"index": m.index, "meta": m.meta, "error": repr(exc), "fails": {"crash": [
            repr(exc)]}, "severity": 99.0}
    fig = {k: rep.get(k) for k in KEEP}
    fails = check(rep)
    return {"index": m.index, "meta": m.meta, "report": fig, "fails": fails,
            "severity": round(severity(rep), 3)}


def _line(res: dict[str, Any]) -> str:
    m, r = res["meta"], res.get("report") or {}
    turns = r.get("turns") or []
    tw = max(turns, key=lambda t: t["distance_max_m"] or 1e9, default=None)
    tstr = (f"worst turn {tw['angle_deg']:+4.0f}° {tw['distance_max_m'] or float('nan'):5.1f} m "
            f"{tw['recovery_s'] if tw['recovery_s'] is not None else float('nan'):5.1f} s"
            if tw else "no turn")
    status = "ok" if not res["fails"] else "FAIL " + ",".join(sorted(res["fails"]))
    med, p95 = r.get("distance_median_m"), r.get("distance_p95_m")
    return (f"m{res['index']:03d} {m['shape']:<9} {m['beacons']}b v={m['speed_mps']:.2f} "
            f"miss={m['p_miss']:.2f} cur={m['current_mps']:.2f} close={m['closing_mps']:+.2f} | "
            f"med {med if med is None else round(med, 2)} p95 "
            f"{p95 if p95 is None else round(p95, 2)} "
            f"lost {r.get('lost_max_s')} s | {tstr} | {status}")


def _dist(vals: list[float]) -> dict[str, float] | None:
    v = [x for x in vals if x is not None and math.isfinite(x)]
    if not v:
        return None
    a = np.asarray(v)
    return {"p50": _r(np.median(a)), "p90": _r(np.percentile(a, 90)), "max": _r(a.max()),
            "n": len(v)}


def summarise(results: list[dict[str, Any]]) -> dict[str, Any]:
    ok = [r for r in results if "report" in r]
    turns = [t for r in ok for t in r["report"]["turns"]]
    tt = [t for t in turns if t["kind"] == "turn"]
    ut = [t for t in turns if t["kind"] == "uturn"]
    targets = ("median", "p95", "turn", "uturn", "lost", "json", "crash")
    pass_counts = {k: sum(1 for r in results if k not in r["fails"]) for k in targets}
    turn_pass = sum(1 for t in tt if t["distance_max_m"] is not None and t["distance_max_m"]
                    <= TURN_MAX_M and t["recovery_s"] is not None
                    and t["recovery_s"] <= TURN_REC_S)
    uturn_pass = sum(1 for t in ut if t["distance_max_m"] is not None and t["distance_max_m"]
                     <= UTURN_MAX_M and t["recovery_s"] is not None
                     and t["recovery_s"] <= UTURN_REC_S)
    by_closing = []
    for lo, hi in CLOSING_BINS:
        sel = [r for r in results if lo <= r["meta"]["closing_mps"] < hi]
        by_closing.append({"closing_mps": [lo, hi], "missions": len(sel),
                           "passed": sum(1 for r in sel if not r["fails"]),
                           "failed_targets": sorted({k for r in sel for k in r["fails"]})})
    return {
        "missions": len(results),
        "missions_passed": sum(1 for r in results if not r["fails"]),
        "by_closing_speed": by_closing,
        "pass": pass_counts,
        "turns": {"n": len(tt), "passed": turn_pass,
                  "unrecovered": sum(1 for t in tt if t["recovery_s"] is None)},
        "uturns": {"n": len(ut), "passed": uturn_pass,
                   "unrecovered": sum(1 for t in ut if t["recovery_s"] is None)},
        "distribution": {
            "distance_median_m": _dist([r["report"]["distance_median_m"] for r in ok]),
            "distance_p95_m": _dist([r["report"]["distance_p95_m"] for r in ok]),
            "turn_max_m": _dist([t["distance_max_m"] for t in tt]),
            "turn_recovery_s": _dist([t["recovery_s"] for t in tt]),
            "uturn_max_m": _dist([t["distance_max_m"] for t in ut]),
            "uturn_recovery_s": _dist([t["recovery_s"] for t in ut]),
            "turn_detect_s": _dist([t["detect_s"] for t in turns]),
            "lost_max_s": _dist([r["report"]["lost_max_s"] for r in ok]),
            "fix_error_rms_m": _dist([r["report"]["fix_error_rms_m"] for r in ok]),
            "track_error_rms_m": _dist([r["report"]["track_error_rms_m"] for r in ok]),
            "severity": _dist([r["severity"] for r in results]),
        },
    }


def plot_closing(path: Path, results: list[dict[str, Any]]) -> None:
    """The figures against each mission's closing speed, and the closing speed
    over AUV speed for the nominal and the extreme plants."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 3, figsize=(16, 5))
    ax = axs[0]
    va = np.linspace(0.4, 1.3, 50)
    cases = [
        ("nominal plant, no current", 1.0, 1.0, 0.0, "k-"),
        ("nominal, 0.3 m/s head current", 1.0, 1.0, 0.3, "k--"),
        ("thrust −15 %, damping +25 %", 0.85, 1.25, 0.0, "r-"),
        ("thrust −15 %, damping +25 %, 0.3 m/s head", 0.85, 1.25, 0.3, "r--"),
        ("thrust +15 %, damping −25 %", 1.15, 0.75, 0.0, "g-"),
    ]
    for label, th, dmp, cur, st in cases:
        u = top_speed(NOM_XU * dmp, NOM_XUU * dmp, 2.0 * NOM_FWD * th)
        ax.plot(va, [u - cur - v for v in va], st, label=f"{label} (top {u:.2f} m/s)")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("AUV speed (m/s)")
    ax.set_ylabel("closing speed (m/s)")
    ax.set_title("the ASV's top ground speed minus the AUV's")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ok = [r for r in results if "report" in r]
    for ax, kind, mx, rec in ((axs[1], "turn", TURN_MAX_M, TURN_REC_S),
                              (axs[2], "uturn", UTURN_MAX_M, UTURN_REC_S)):
        xs, rs, ms = [], [], []
        for r in ok:
            for t in r["report"]["turns"]:
                if t["kind"] != kind:
                    continue
                xs.append(r["meta"]["closing_mps"])
                rs.append(t["recovery_s"] if t["recovery_s"] is not None else 150.0)
                ms.append(t["distance_max_m"] or 0.0)
        ax.scatter(xs, rs, s=12, c="b", label="recovery (s); unrecovered at 150")
        ax.scatter(xs, [3.0 * m for m in ms], s=12, c="r", marker="x",
                   label="max distance × 3 (m)")
        ax.axhline(rec, color="b", lw=0.8, ls=":")
        ax.axhline(3.0 * mx, color="r", lw=0.8, ls=":")
        ax.set_xlabel("mission's closing speed (m/s), least over its legs")
        ax.set_title(f"{'turns ≤ 90°' if kind == 'turn' else 'U-turns (> 90°)'}: "
                     f"targets {mx:.0f} m, {rec:.0f} s (dotted)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1, help="campaign seed")
    ap.add_argument("--n", type=int, default=60, help="missions")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--quick", action="store_true", help="12 missions (a CI-sized check)")
    ap.add_argument("--only", type=int, nargs="+", help="run only these mission indices")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override applied to every mission (e.g. a runtime setting)")
    ap.add_argument("--out", default=str(ROOT / "out"), help="directory for the plots")
    ap.add_argument("--no-plot", action="store_true")
    args = ap.parse_args()
    n = 12 if args.quick else args.n
    idx = args.only if args.only else list(range(n))
    missions = [draw(args.seed, k) for k in idx]
    w0 = time.perf_counter()
    results: list[dict[str, Any]] = []
    sim_total = sum(m.meta["duration_s"] for m in missions)
    print(f"campaign seed {args.seed}: {len(missions)} missions, {sim_total / 60:.0f} min "
          f"simulated, {args.jobs} processes", file=sys.stderr)
    with ProcessPoolExecutor(max_workers=args.jobs) as ex:
        futs = {ex.submit(run_one, m, args.set): m for m in missions}
        for f in as_completed(futs):
            res = f.result()
            results.append(res)
            el = time.perf_counter() - w0
            print(f"[{len(results):3d}/{len(missions)} {el:5.0f} s] {_line(res)}",
                  file=sys.stderr, flush=True)
    results.sort(key=lambda r: r["index"])
    summ = summarise(results)
    worst = max(results, key=lambda r: r["severity"])
    wm = next(m for m in missions if m.index == worst["index"])
    print("\nfailures:", file=sys.stderr)
    for r in results:
        for key, why in sorted(r["fails"].items()):
            print(f"  m{r['index']:03d} {key}: {'; '.join(why)}", file=sys.stderr)
    print(f"\nworst: mission {worst['index']} (severity {worst['severity']}): "
          f"{json.dumps(worst['meta'])}\n  {_line(worst)}\n  reproduce: {wm.command()} "
          f"{' '.join(repr('--set ' + s) for s in args.set)}", file=sys.stderr)
    print("\ndistribution (p50 / p90 / max):", file=sys.stderr)
    for k, d in summ["distribution"].items():
        if d:
            print(f"  {k:<20} {d['p50']:8.2f} {d['p90']:8.2f} {d['max']:8.2f}  (n={d['n']})",
                  file=sys.stderr)
    print("\nby closing speed (the ASV's top ground speed along the AUV's legs minus "
          "the AUV's, least over the mission):", file=sys.stderr)
    for row in summ["by_closing_speed"]:
        lo, hi = row["closing_mps"]
        print(f"  {lo:+5.1f} … {hi:+5.1f} m/s: {row['passed']:3d} of {row['missions']:3d} "
              f"missions pass; failing: {', '.join(row['failed_targets']) or '—'}",
              file=sys.stderr)
    print(f"pass counts of {len(results)}: {json.dumps(summ['pass'])}; turns "
          f"{summ['turns']['passed']}/{summ['turns']['n']}, U-turns "
          f"{summ['uturns']['passed']}/{summ['uturns']['n']}", file=sys.stderr)
    plots: dict[str, str] = {}
    if not args.no_plot:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        plot_closing(out / "campaign_closing.png", results)
        plots["closing"] = str(out / "campaign_closing.png")
        if "report" in worst:
            from zarco_tools.plot import plot_follow
            from zarco_tools.scenario import load_scenario
            from zarco_tools.simulation import run_scenario

            sr = run_scenario(load_scenario(BASE, [*wm.overrides, *args.set], wm.seed))
            plot_follow(out / "campaign_worst.png", sr.log, sr.extra,
                        f"campaign {args.seed} mission {wm.index} (worst): {wm.meta['shape']}, "
                        f"{wm.meta['beacons']} beacons, AUV {wm.meta['speed_mps']} m/s, "
                        f"{', '.join(sorted(worst['fails'])) or 'all targets met'}")
            plots["worst"] = str(out / "campaign_worst.png")
    wall = time.perf_counter() - w0
    print(f"wall {wall:.0f} s ({sim_total / max(wall, 1e-9):.0f}× real time over "
          f"{args.jobs} processes); plots {plots}", file=sys.stderr)
    print(json.dumps({
        "bench": "campaign", "seed": args.seed, "quick": args.quick, "set": args.set,
        **summ,
        "worst": {"index": worst["index"], "severity": worst["severity"],
                  "fails": worst["fails"], "meta": worst["meta"],
                  "report": worst.get("report"), "reproduce": wm.command()},
        "per_mission": [{"index": r["index"], "severity": r["severity"],
                         "fails": sorted(r["fails"]), "closing_mps": r["meta"]["closing_mps"],
                         "median": (r.get("report") or {}).get("distance_median_m"),
                         "p95": (r.get("report") or {}).get("distance_p95_m"),
                         "lost_max_s": (r.get("report") or {}).get("lost_max_s"),
                         "turns": [[t["angle_deg"], t["distance_max_m"], t["recovery_s"]]
                                   for t in (r.get("report") or {}).get("turns", [])]}
                        for r in results],
        "plots": plots, "wall_s": round(wall, 1),
    }, allow_nan=False))


if __name__ == "__main__":
    main()
